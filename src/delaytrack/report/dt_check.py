"""The report section of the dt-halving check (:mod:`delaytrack.experiments.convergence`): its
verdict against the tolerance and its table, as the study's
:class:`~delaytrack.experiments.convergence.DtCheck` holds them."""

from __future__ import annotations

import math
import warnings

import pandas as pd

from delaytrack.experiments.convergence import DtCheck, dt_check_verdict
from delaytrack.report.html import HtmlReport

__all__ = ["dt_check_line", "write_dt_check"]


def write_dt_check(
    report: HtmlReport, dt_check: DtCheck | pd.DataFrame | None, half_dt: float
) -> None:
    """The report section: the verdict against the tolerance and the table.

    ``dt_check`` is the study's :class:`~delaytrack.experiments.convergence.DtCheck` (its
    ``dt_verdict``); a table of :func:`~delaytrack.experiments.convergence.dt_check_table`
    is still taken, with a :class:`DeprecationWarning`.
    """
    if isinstance(dt_check, pd.DataFrame):
        warnings.warn(
            "write_dt_check takes the study's DtCheck (its dt_verdict) now; a table will be "
            "refused in a later release",
            DeprecationWarning,
            stacklevel=2,
        )
        dt_check = dt_check_verdict(dt_check)
    report.heading("Numerical check: halving dt")
    if dt_check is None:
        report.paragraph("Not run (check_dt = False).", note=True)
        return
    report.paragraph(
        f"Every run repeated with dt = {half_dt:g} s (T_c unchanged). The largest relative change "
        f"of any summary metric is {_verdict_text(dt_check)}."
        + (
            " Runs above it (their metrics depend on the step; typically a law chattering at its "
            f"stability edge, whose oscillation the step resolves differently): {_above(dt_check)}."
            if len(dt_check.above)
            else ""
        )
    )
    report.table(
        dt_check.table,
        "Metrics at dt/2 and the largest relative change per run, max_relative_change as a "
        f"fraction ({dt_check.tolerance:g} is the {_percent(dt_check.tolerance)} criterion; —: "
        "the run left the path).",
        digits=6,
    )


def _percent(fraction: float) -> str:
    """A relative change as a percentage to three significant digits: ``"19 %"``,
    ``"0.0212 %"``; "not computed" where no run gave one (every run left the path)."""
    return f"{100 * fraction:.3g} %" if math.isfinite(fraction) else "not computed"


def _verdict_text(dt_check: DtCheck) -> str:
    """``"19 %, NOT below the 1 % criterion"``: the change in the criterion's terms."""
    verdict = "below" if dt_check.within_tolerance else "NOT below"
    return f"{_percent(dt_check.largest)}, {verdict} the {_percent(dt_check.tolerance)} criterion"


def _above(dt_check: DtCheck) -> str:
    """The runs at or above the tolerance, each with its largest change."""
    return "; ".join(
        f"{row.scenario} {row.controller} ({_percent(row.max_relative_change)})"
        for row in dt_check.above.itertuples()
    )


def dt_check_line(dt_check: DtCheck) -> str:
    """The check in one line for a terminal: the largest relative change, its verdict against
    the tolerance and the runs above it."""
    line = (
        f"halving dt: the largest relative change of a summary metric is {_verdict_text(dt_check)}"
    )
    return line + (f"; runs above it: {_above(dt_check)}" if len(dt_check.above) else "")
