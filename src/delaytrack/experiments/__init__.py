"""Experiments: scenarios as frozen, serialisable specs (TOML files), a registry of the shipped
ones, and the jobs built from them.

- :mod:`delaytrack.experiments.scenario`: :class:`Scenario` (load, validate, dump, build, run),
  :func:`run_batched`, :func:`run_to_folder` and the shipped scenario files.
- :mod:`delaytrack.experiments.empirical_margin`: :func:`empirical_margin`, the largest delay at
  which a scenario's closed loop still tracks (bisection over batched simulations).
- :mod:`delaytrack.experiments.margins`: certified vs exact vs empirical margins over a grid of
  gains (``delaytrack reproduce --job margins``).
- :mod:`delaytrack.experiments.paper`: the main job, the paper's robot experiment (S1–S4, AROLC vs
  PCON/PCONf vs the outer loop; ``delaytrack reproduce``).
- :mod:`delaytrack.experiments.tuning`: the tuning protocol that chooses every compared
  controller's gains (``delaytrack tune-baselines``).
- :mod:`delaytrack.experiments.robustness`: the robustness study, the paper's claims over drawn
  robots and wrong delay estimates (``delaytrack reproduce --job robustness``).
- :mod:`delaytrack.experiments.two_link`: the earlier interim job, AROLC vs the plain outer loop
  on the two-link arm under S1 and S3 (``delaytrack reproduce --job two-link``).

Import the jobs explicitly; they pull in the report package.
"""

from delaytrack.experiments.empirical_margin import (
    EmpiricalMargin,
    empirical_margin,
)
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
    "EmpiricalMargin",
    "RunOutput",
    "Scenario",
    "ScenarioError",
    "builtin_scenario_names",
    "builtin_scenario_path",
    "empirical_margin",
    "load_builtin",
    "run_batched",
    "run_to_folder",
]
