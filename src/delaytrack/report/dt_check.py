"""The report section of the dt-halving check (:mod:`delaytrack.experiments.convergence`): its
verdict against the tolerance and its table."""

from __future__ import annotations

import pandas as pd

from delaytrack.experiments.convergence import DT_TOLERANCE, largest_change
from delaytrack.report.html import HtmlReport

__all__ = ["write_dt_check"]


def write_dt_check(report: HtmlReport, dt_check: pd.DataFrame | None, half_dt: float) -> None:
    """The report section: the verdict against :data:`DT_TOLERANCE` and the table."""
    report.heading("Numerical check: halving dt")
    if dt_check is None:
        report.paragraph("Not run (check_dt = False).", note=True)
        return
    worst = largest_change(dt_check)
    verdict = "below" if worst < DT_TOLERANCE else "NOT below"
    above = dt_check[dt_check.max_relative_change >= DT_TOLERANCE]
    report.paragraph(
        f"Every run repeated with dt = {half_dt:g} s (T_c unchanged). The largest relative change "
        f"of any summary metric is {worst:.3g}, {verdict} the {DT_TOLERANCE:.0%} criterion."
        + (
            " Runs above it (their metrics depend on the step; typically a law chattering at its "
            "stability edge, whose oscillation the step resolves differently): "
            + "; ".join(
                f"{row.scenario} {row.controller} ({row.max_relative_change:.3g})"
                for row in above.itertuples()
            )
            + "."
            if len(above)
            else ""
        )
    )
    report.table(dt_check, "Metrics at dt/2 and the largest relative change per run.", digits=6)
