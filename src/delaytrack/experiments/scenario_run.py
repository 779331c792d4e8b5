"""Deprecated: running a scenario to its results folder lives in
:mod:`delaytrack.jobs.scenario_run`. Reading a name here still works, with a
:class:`DeprecationWarning` naming its new place."""

from delaytrack._deprecated import moved_names

__getattr__ = moved_names(
    __name__,
    {
        "RunOutput": "delaytrack.jobs.scenario_run:RunOutput",
        "TRAJECTORY_FORMATS": "delaytrack.jobs.scenario_run:TRAJECTORY_FORMATS",
        "run_to_folder": "delaytrack.jobs.scenario_run:run_to_folder",
    },
)
