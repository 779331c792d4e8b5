"""Deprecated: scenarios live in :mod:`delaytrack.scenario`, and running one to a folder in
:mod:`delaytrack.jobs.scenario_run`. Reading a name here still works, with a
:class:`DeprecationWarning` naming its new place."""

from delaytrack._deprecated import moved_names

__getattr__ = moved_names(
    __name__,
    {
        "BuiltScenario": "delaytrack.scenario:BuiltScenario",
        "Scenario": "delaytrack.scenario:Scenario",
        "ScenarioError": "delaytrack.scenario:ScenarioError",
        "builtin_scenario_names": "delaytrack.scenario:builtin_scenario_names",
        "builtin_scenario_path": "delaytrack.scenario:builtin_scenario_path",
        "load_builtin": "delaytrack.scenario:load_builtin",
        "run_batched": "delaytrack.scenario:run_batched",
        "dumps_toml": "delaytrack.scenario:dumps_toml",
        "RunOutput": "delaytrack.jobs.scenario_run:RunOutput",
        "run_to_folder": "delaytrack.jobs.scenario_run:run_to_folder",
    },
)
