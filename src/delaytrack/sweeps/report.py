"""Deprecated: a sweep's report lives in :mod:`delaytrack.report.sweep`, the facts it states in
:mod:`delaytrack.sweeps.summary`. Reading a name here still works, with a
:class:`DeprecationWarning` naming its new place."""

from delaytrack._deprecated import moved_names

__getattr__ = moved_names(
    __name__,
    {
        "TIE": "delaytrack.sweeps.summary:TIE",
        "metric_units": "delaytrack.sweeps.summary:metric_units",
        **{
            name: f"delaytrack.report.sweep:{name}"
            for name in (
                "ae_vs_h_max_figure",
                "distribution_figure",
                "findings",
                "sweep_figures",
                "sweep_section",
                "with_units",
                "write_sweep_outputs",
            )
        },
    },
)
