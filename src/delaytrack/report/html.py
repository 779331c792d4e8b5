"""A self-contained HTML report: one file, figures embedded as base64 PNG, no external assets.

Build it block by block and write it once::

    report = HtmlReport("Two-link arm")
    report.heading("Outcome")
    report.paragraph("AROLC ...")
    report.table(summary)
    report.figure(error_figure(...), "Tracking error under S1")
    with report.folded("Tuning grids"):
        report.table(grid)
    report.write("results/two-link/report.html")

Every page is laid out for reading in a browser window of 1280 px: a table of contents of its
sections (the level-2 headings) under the title; text in a column of readable width, tables
and figures in the window's width; text columns of tables left-aligned, numbers right-aligned
(:func:`~delaytrack.report.tables.frame_to_html`); detail folded (:meth:`HtmlReport.folded`).
Text is HTML-escaped; a path to another report in it (``../robustness/report.html``) is a link.
Tables come from DataFrames and figures from matplotlib Figures (or PNG bytes).
"""

from __future__ import annotations

import base64
import html
import re
from collections.abc import Iterable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

import pandas as pd
from matplotlib.figure import Figure

from delaytrack._io import write_text
from delaytrack.report.figures import png_bytes
from delaytrack.report.tables import frame_to_html

__all__ = ["HtmlReport"]

_STYLE = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; max-width: 76rem;
       margin: 2rem auto; padding: 0 1rem; line-height: 1.45; color: #222; }
p, ul, ol, h1, h2, h3, h4, figcaption, nav, summary { max-width: 60rem; }
h1 { border-bottom: 2px solid #ccc; padding-bottom: .3rem; }
h2 { margin-top: 2rem; border-bottom: 1px solid #ddd; }
nav.toc { background: #f7f7f7; border: 1px solid #e2e2e2; padding: .4rem 1rem; }
nav.toc ol { margin: .3rem 0; }
a { color: #0b57a4; }
table.data, table.settings { border-collapse: collapse; margin: .8rem 0; font-size: .85rem; }
table.data th, table.data td, table.settings th, table.settings td {
       border: 1px solid #ccc; padding: .2rem .45rem; text-align: left; vertical-align: top; }
table.data .num { text-align: right; font-variant-numeric: tabular-nums; }
table.settings th { background: #f5f5f5; }
table.data th { background: #f0f0f0; white-space: normal; }
.wide { overflow-x: auto; max-width: 100%; }
details { margin: .8rem 0; }
summary { cursor: pointer; font-weight: 600; }
figure { margin: 1.2rem 0; }
figure img { max-width: 100%; border: 1px solid #eee; }
figcaption { font-size: .9rem; color: #555; }
code, pre { background: #f6f6f6; font-size: .88rem; }
pre { padding: .6rem; overflow-x: auto; }
footer { margin-top: 2rem; border-top: 1px solid #ddd; color: #555; font-size: .9em; }
.note { background: #fff8e1; border-left: 4px solid #f0c040; padding: .5rem .8rem; }
"""
#: The reference every page ends with: the paper the controller, Theorem 1 and the robot
#: experiment are taken from.
_FOOTER = (
    "<footer><p>AROLC and its certified delay bound (Theorem 1) are those of S. Roy and "
    "I. N. Kar, &ldquo;Adaptive-Robust Control of a Class of Nonlinear Systems with Unknown "
    "Input Delay&rdquo; (arXiv preprint), whose robot experiment the paper job "
    "reproduces.</p></footer>"
)
#: A path to another report in the text: ``../robustness/report.html``, ``report.html``.
_REPORT_PATH = re.compile(r"(?<![\w/.-])((?:\.\./|\./)?(?:[\w.-]+/)*[\w.-]+\.html)(?![\w/])")


def _linked(text: str) -> str:
    """``text`` escaped, each path to another report in it a link."""
    return _REPORT_PATH.sub(r'<a href="\1">\1</a>', html.escape(text))


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
        self._sections: list[tuple[str, str]] = []  # (anchor, text) of each level-2 heading

    def heading(self, text: str, level: int = 2) -> None:
        """A section heading (``level`` 2 to 4); a level-2 heading is listed in the table of
        contents."""
        if level not in (2, 3, 4):
            raise ValueError(f"level must be 2, 3 or 4; got {level!r}")
        if level == 2:
            anchor = f"section-{len(self._sections) + 1}"
            self._sections.append((anchor, text))
            self._blocks.append(f'<h2 id="{anchor}">{html.escape(text)}</h2>')
        else:
            self._blocks.append(f"<h{level}>{html.escape(text)}</h{level}>")

    def paragraph(self, text: str, *, note: bool = False) -> None:
        """A paragraph of plain text (escaped; paths to other reports linked); ``note``
        highlights it."""
        css = ' class="note"' if note else ""
        self._blocks.append(f"<p{css}>{_linked(text)}</p>")

    def bullets(self, items: Iterable[str]) -> None:
        """An unordered list of plain-text items (escaped; paths to other reports linked)."""
        body = "".join(f"<li>{_linked(item)}</li>" for item in items)
        self._blocks.append(f"<ul>{body}</ul>")

    @contextmanager
    def folded(self, summary: str) -> Iterator[None]:
        """The blocks added inside the ``with`` block, folded under ``summary`` (a
        ``<details>`` element the reader opens): detail that most readers skip."""
        self._blocks.append(f"<details><summary>{html.escape(summary)}</summary>")
        try:
            yield
        finally:
            self._blocks.append("</details>")

    def settings(self, rows: Mapping[str, str]) -> None:
        """A two-column table ``name | value`` of plain text."""
        body = "".join(
            f"<tr><th>{html.escape(str(k))}</th><td>{html.escape(str(v))}</td></tr>"
            for k, v in rows.items()
        )
        self._blocks.append(f'<div class="wide"><table class="settings">{body}</table></div>')

    def table(
        self,
        frame: pd.DataFrame,
        caption: str | None = None,
        *,
        digits: int = 4,
        missing: str = "—",
    ) -> None:
        """A DataFrame as a table, with an optional caption above it; a missing value shows as
        ``missing`` ("—" unless said otherwise: a report never shows "NaN"; a caption says what
        "—" means where it is not plain)."""
        if caption:
            self._blocks.append(f"<p><em>{_linked(caption)}</em></p>")
        # A table too wide for the window would scroll inside its own box, never the page.
        table = frame_to_html(frame, digits=digits, missing=missing)
        self._blocks.append(f'<div class="wide">{table}</div>')

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
        """The complete HTML document: the title, the table of contents (with two sections or
        more), the blocks, then the paper's reference."""
        body = "\n".join(self._blocks)
        title = html.escape(self.title)
        return (
            '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8"/>\n'
            '<meta name="viewport" content="width=device-width, initial-scale=1"/>\n'
            f"<title>{title}</title>\n<style>{_STYLE}</style>\n</head>\n<body>\n"
            f"<h1>{title}</h1>\n{self._contents()}{body}\n{_FOOTER}\n</body>\n</html>\n"
        )

    def _contents(self) -> str:
        """The table of contents: a link to each level-2 heading."""
        if len(self._sections) < 2:
            return ""
        items = "".join(
            f'<li><a href="#{anchor}">{html.escape(text)}</a></li>'
            for anchor, text in self._sections
        )
        return f'<nav class="toc"><strong>Contents</strong><ol>{items}</ol></nav>\n'

    def write(self, path: str | Path) -> Path:
        """Write the document atomically to ``path``; return the path."""
        return write_text(path, self.render())
