"""A self-contained HTML report: one file, figures embedded as base64 PNG, no external assets.

Build it block by block and write it once::

    report = HtmlReport("Two-link arm")
    report.heading("Outcome")
    report.paragraph("AROLC ...")
    report.table(summary)
    report.figure(error_figure(...), "Tracking error under S1")
    report.write("results/two-link/report.html")

Text is HTML-escaped; tables come from DataFrames and figures from matplotlib Figures (or PNG
bytes).
"""

from __future__ import annotations

import base64
import html
from collections.abc import Iterable, Mapping
from pathlib import Path

import pandas as pd
from matplotlib.figure import Figure

from delaytrack._io import write_text
from delaytrack.report.figures import png_bytes
from delaytrack.report.tables import frame_to_html

__all__ = ["HtmlReport"]

_STYLE = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; max-width: 60rem;
       margin: 2rem auto; padding: 0 1rem; line-height: 1.45; color: #222; }
h1 { border-bottom: 2px solid #ccc; padding-bottom: .3rem; }
h2 { margin-top: 2rem; border-bottom: 1px solid #ddd; }
table.data, table.settings { border-collapse: collapse; margin: .8rem 0; font-size: .9rem; }
table.data th, table.data td, table.settings th, table.settings td {
       border: 1px solid #ccc; padding: .25rem .6rem; text-align: right; }
table.settings th { text-align: left; background: #f5f5f5; }
table.settings td { text-align: left; }
table.data th { background: #f0f0f0; }
.wide { overflow-x: auto; max-width: 100%; }
table.data th { white-space: normal; }
figure { margin: 1.2rem 0; }
figure img { max-width: 100%; border: 1px solid #eee; }
figcaption { font-size: .9rem; color: #555; }
code, pre { background: #f6f6f6; font-size: .88rem; }
pre { padding: .6rem; overflow-x: auto; }
.note { background: #fff8e1; border-left: 4px solid #f0c040; padding: .5rem .8rem; }
"""


class HtmlReport:
    """Accumulates report blocks and renders them as one HTML document.

    Parameters
    ----------
    title : str
        Document title and top heading.
    """

    def __init__(self, title: str) -> None:
        self.title = title
        self._blocks: list[str] = []

    def heading(self, text: str, level: int = 2) -> None:
        """A section heading (``level`` 2 to 4)."""
        if level not in (2, 3, 4):
            raise ValueError(f"level must be 2, 3 or 4; got {level!r}")
        self._blocks.append(f"<h{level}>{html.escape(text)}</h{level}>")

    def paragraph(self, text: str, *, note: bool = False) -> None:
        """A paragraph of plain text (escaped); ``note`` highlights it."""
        css = ' class="note"' if note else ""
        self._blocks.append(f"<p{css}>{html.escape(text)}</p>")

    def bullets(self, items: Iterable[str]) -> None:
        """An unordered list of plain-text items."""
        body = "".join(f"<li>{html.escape(item)}</li>" for item in items)
        self._blocks.append(f"<ul>{body}</ul>")

    def settings(self, rows: Mapping[str, str]) -> None:
        """A two-column table ``name | value`` of plain text."""
        body = "".join(
            f"<tr><th>{html.escape(str(k))}</th><td>{html.escape(str(v))}</td></tr>"
            for k, v in rows.items()
        )
        self._blocks.append(f'<div class="wide"><table class="settings">{body}</table></div>')

    def table(self, frame: pd.DataFrame, caption: str | None = None, *, digits: int = 4) -> None:
        """A DataFrame as a table, with an optional caption above it."""
        if caption:
            self._blocks.append(f"<p><em>{html.escape(caption)}</em></p>")
        # A wide table scrolls inside its own box; the page never gets wider than the window.
        self._blocks.append(f'<div class="wide">{frame_to_html(frame, digits=digits)}</div>')

    def code(self, text: str) -> None:
        """Preformatted text (e.g. a scenario file)."""
        self._blocks.append(f"<pre>{html.escape(text)}</pre>")

    def figure(self, figure: Figure | bytes, caption: str) -> None:
        """A figure embedded as a base64 PNG, with a caption below it."""
        data = figure if isinstance(figure, bytes) else png_bytes(figure)
        encoded = base64.b64encode(data).decode("ascii")
        self._blocks.append(
            f'<figure><img alt="{html.escape(caption, quote=True)}" '
            f'src="data:image/png;base64,{encoded}"/>'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>"
        )

    def render(self) -> str:
        """The complete HTML document."""
        body = "\n".join(self._blocks)
        title = html.escape(self.title)
        return (
            '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8"/>\n'
            f"<title>{title}</title>\n<style>{_STYLE}</style>\n</head>\n<body>\n"
            f"<h1>{title}</h1>\n{body}\n</body>\n</html>\n"
        )

    def write(self, path: str | Path) -> Path:
        """Write the document atomically to ``path``; return the path."""
        return write_text(path, self.render())
