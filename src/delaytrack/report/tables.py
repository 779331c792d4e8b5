"""Tables for reports: :func:`frame_to_html` renders a DataFrame for the HTML report. The
comparisons of metric tables moved to :mod:`delaytrack.experiments.relative_change` (their old
names here still work, with a warning)."""

from __future__ import annotations

import html
import re

import numpy as np
import pandas as pd

from delaytrack._deprecated import moved_names

__all__ = ["frame_to_html"]

#: The helpers that compare metric tables, now the studies' arithmetic: old name -> new place.
MOVED = {
    name: f"delaytrack.experiments.relative_change:{name}"
    for name in ("metric_columns", "relative_change", "relative_difference")
}
__getattr__ = moved_names(__name__, MOVED)


def frame_to_html(frame: pd.DataFrame, *, digits: int = 4, missing: str = "—") -> str:
    """Render a DataFrame as an HTML table (no index; floats to ``digits`` significant digits,
    a missing value as ``missing``).

    Columns of text are left-aligned, columns of numbers right-aligned (class ``num``): a column
    whose every present cell is a number, or text that starts with one (``"2 / 40"``,
    ``"3.2 (1.1 to 5)"``). A header may break after ``_`` (``ae_mm_1``), so that a table of
    many short numbers stays narrow.
    """
    columns = [frame.iloc[:, j] for j in range(frame.shape[1])]
    cells = [[_cell(value, digits, missing) for value in column] for column in columns]
    numeric = [
        all(
            _reads_as_number(value, text, missing)
            for value, text in zip(column, shown, strict=True)
        )
        and any(text != missing for text in shown)
        for column, shown in zip(columns, cells, strict=True)
    ]
    head = "".join(
        f"<th{_NUMBER_CLASS if number else ''}>{_breakable(str(name))}</th>"
        for name, number in zip(frame.columns, numeric, strict=True)
    )
    rows = "".join(
        "<tr>"
        + "".join(
            f"<td{_NUMBER_CLASS if number else ''}>{html.escape(column[i])}</td>"
            for column, number in zip(cells, numeric, strict=True)
        )
        + "</tr>\n"
        for i in range(len(frame))
    )
    return (
        f'<table class="data">\n<thead><tr>{head}</tr></thead>\n<tbody>\n{rows}</tbody>\n</table>'
    )


_NUMBER_CLASS = ' class="num"'
#: Text that starts with a number: ``12``, ``-0.5``, ``3e-2 (1 to 4)``, ``2 / 40``.
_LEADING_NUMBER = re.compile(r"[−+-]?(\d|\.\d)")
#: Placeholders of a number that is not there.
_PLACEHOLDERS = ("—", "–", "-", "")


def _cell(value: object, digits: int, missing: str) -> str:
    """A value as the table shows it."""
    if isinstance(value, float | np.floating):
        return missing if np.isnan(value) else f"{value:.{digits}g}"
    if value is None or value is pd.NA or value is pd.NaT:
        return missing
    return str(value)


def _reads_as_number(value: object, text: str, missing: str) -> bool:
    """Whether a cell holds a number (or a placeholder of one)."""
    if isinstance(value, bool | np.bool_):
        return False
    if isinstance(value, int | float | np.integer | np.floating):
        return True
    return text in (missing, *_PLACEHOLDERS) or bool(_LEADING_NUMBER.match(text))


def _breakable(text: str) -> str:
    """``text`` escaped, with a break opportunity after each ``_``."""
    return html.escape(text).replace("_", "_<wbr>")
