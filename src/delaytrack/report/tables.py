"""Tables for reports: comparisons between controllers and between numerical settings.

These functions take the metric tables of :func:`delaytrack.metrics.metrics_table` (plain
DataFrames) and return DataFrames; :func:`frame_to_html` renders one for the HTML report.
"""

from __future__ import annotations

import html
import re
from collections.abc import Sequence

import numpy as np
import pandas as pd

__all__ = ["frame_to_html", "metric_columns", "relative_change", "relative_difference"]

_METRIC_PREFIXES = ("ae_", "rms_", "max_")


def metric_columns(frame: pd.DataFrame) -> list[str]:
    """The metric columns of a metrics table: ``ae_*``, ``rms_*``, ``max_*`` and ``tv``."""
    return [c for c in frame.columns if c.startswith(_METRIC_PREFIXES) or c == "tv"]


def relative_change(
    frame: pd.DataFrame,
    *,
    by: str,
    column: str,
    baseline: str,
    candidate: str,
    metrics: Sequence[str] | None = None,
) -> pd.DataFrame:
    """Percent change of ``candidate`` against ``baseline``: ``100 (cand - base) / base``.

    Parameters
    ----------
    frame : DataFrame
        One row per (``by``, ``column``) pair, e.g. per (scenario, controller).
    by : str
        Column identifying the cases compared separately (e.g. ``"scenario"``).
    column : str
        Column naming the two contenders (e.g. ``"controller"``).
    baseline, candidate : str
        Values of ``column`` to compare.
    metrics : sequence of str, optional
        Columns to compare; every metric column by default.

    Returns
    -------
    DataFrame
        One row per case, column ``by`` plus one percent column per metric. Negative means the
        candidate's value is lower (for errors and TV: better).
    """
    metrics = metric_columns(frame) if metrics is None else list(metrics)
    rows = []
    for case, group in frame.groupby(by, sort=False):
        base = group[group[column] == baseline]
        cand = group[group[column] == candidate]
        if len(base) != 1 or len(cand) != 1:
            raise ValueError(
                f"case {case!r} needs exactly one {baseline!r} and one {candidate!r} row in "
                f"column {column!r}; got {len(base)} and {len(cand)}"
            )
        row = {by: case}
        for metric in metrics:
            b = float(base[metric].iloc[0])
            c = float(cand[metric].iloc[0])
            row[metric] = 100.0 * (c - b) / b if b != 0.0 else np.nan
        rows.append(row)
    return pd.DataFrame(rows)


def relative_difference(
    reference: pd.DataFrame, other: pd.DataFrame, metrics: Sequence[str] | None = None
) -> pd.DataFrame:
    """``|other - reference| / |reference|`` per row and metric, for two tables of equal shape.

    Used for numerical checks (e.g. the same runs at ``dt`` and ``dt/2``). NaN where the
    reference is zero or either value is NaN.
    """
    metrics = metric_columns(reference) if metrics is None else list(metrics)
    if len(reference) != len(other):
        raise ValueError(f"tables must have the same rows; got {len(reference)} and {len(other)}")
    base = reference[metrics].to_numpy(dtype=float)
    alt = other[metrics].to_numpy(dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(base != 0.0, np.abs(alt - base) / np.abs(base), np.nan)
    return pd.DataFrame(ratio, columns=metrics, index=reference.index)


def frame_to_html(frame: pd.DataFrame, *, digits: int = 4, missing: str = "NaN") -> str:
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
