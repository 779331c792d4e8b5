"""Reports: figures, tables and a self-contained HTML page, made from results.

This package consumes results (:class:`~delaytrack.sim.SimResult` and metric tables); it never
runs simulations. Figures are matplotlib ``Figure`` objects created without pyplot, so importing it
does not change matplotlib's backend.
"""

from delaytrack._deprecated import moved_names
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
from delaytrack.report.tables import MOVED, frame_to_html

__all__ = [
    "HtmlReport",
    "c_hat_figure",
    "commands_figure",
    "delay_figure",
    "error_figure",
    "margins_figure",
    "frame_to_html",
    "png_bytes",
    "save_figure",
    "tracking_figure",
    "write_run_figures",
]

#: The helpers that compare metric tables are the studies' arithmetic now.
__getattr__ = moved_names(__name__, MOVED)
