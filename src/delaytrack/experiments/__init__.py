"""Experiments: scenarios as frozen, serialisable specs (TOML files), a registry of the shipped
ones, and the jobs built from them.

- :mod:`delaytrack.experiments.scenario`: :class:`Scenario` (load, validate, dump, build, run),
  :func:`run_batched`, :func:`run_to_folder` and the shipped scenario files.
- :mod:`delaytrack.experiments.two_link`: the interim main job, AROLC vs the plain outer loop on
  the two-link arm under the paper's S1 and S3 delays (``delaytrack reproduce``). Import it
  explicitly; it pulls in the report package.
"""

from delaytrack.experiments.scenario import (
    BuiltScenario,
    RunOutput,
    Scenario,
    ScenarioError,
    builtin_scenario_names,
    builtin_scenario_path,
    load_builtin,
    run_batched,
    run_to_folder,
)

__all__ = [
    "BuiltScenario",
    "RunOutput",
    "Scenario",
    "ScenarioError",
    "builtin_scenario_names",
    "builtin_scenario_path",
    "load_builtin",
    "run_batched",
    "run_to_folder",
]
