"""Reports: figures, tables and a self-contained HTML page, made from results.

This package consumes results (:class:`~delaytrack.sim.SimResult` and metric tables); it never
runs simulations. Figures are matplotlib ``Figure`` objects created without pyplot, so importing it
does not change matplotlib's backend.
"""

from delaytrack.report.figures import (
    c_hat_figure,
    commands_figure,
    delay_figure,
    error_figure,
    margins_figure,
    png_bytes,
    save_figure,
    tracking_figure,
    write_run_figures,
)
from delaytrack.report.html import HtmlReport
from delaytrack.report.tables import (
    frame_to_html,
    metric_columns,
    relative_change,
    relative_difference,
)

__all__ = [
    "HtmlReport",
    "c_hat_figure",
    "commands_figure",
    "delay_figure",
    "error_figure",
    "margins_figure",
    "frame_to_html",
    "metric_columns",
    "png_bytes",
    "relative_change",
    "relative_difference",
    "save_figure",
    "tracking_figure",
    "write_run_figures",
]
