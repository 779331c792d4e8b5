"""The dt-halving check of the experiments: rerun with dt / 2 and compare every metric.

The results must not hinge on the plant step; halving dt (T_c unchanged) may move no
summary metric by more than 1 %.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import pandas as pd

from delaytrack.report.html import HtmlReport
from delaytrack.report.tables import relative_difference

__all__ = ["DT_TOLERANCE", "dt_check_table", "largest_change", "write_dt_check"]

#: Largest accepted relative change of a metric when dt is halved.
DT_TOLERANCE = 0.01


def dt_check_table(
    coarse: pd.DataFrame, fine: pd.DataFrame, metrics: Sequence[str]
) -> pd.DataFrame:
    """``fine`` (the dt / 2 metrics) with the largest relative change per run against ``coarse``."""
    table = fine.copy()
    table["max_relative_change"] = relative_difference(coarse, fine, list(metrics)).max(axis=1)
    return table


def largest_change(dt_check: pd.DataFrame | None) -> float:
    """Largest relative change of any metric (NaN when the check was not run)."""
    if dt_check is None:
        return math.nan
    return float(dt_check["max_relative_change"].max())


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
