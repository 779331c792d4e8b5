"""Experiments: the studies made of scenarios (:mod:`delaytrack.scenario`), from a scenario's
empirical margin to the studies of ``delaytrack reproduce``. Each study returns a frozen result
holding every number its report quotes; the report (prose, tables, figures, page) is
:mod:`delaytrack.report`'s module of the same name, and :mod:`delaytrack.jobs` runs a study and
writes its report to a folder.

- :mod:`delaytrack.experiments.empirical_margin`: :func:`empirical_margin`, the largest delay at
  which a scenario's closed loop still tracks (bisection over batched simulations).
- :mod:`delaytrack.experiments.margins`: certified vs exact vs empirical margins over a grid of
  gains (``delaytrack reproduce --job margins``).
- :mod:`delaytrack.experiments.paper`: the paper's robot experiment (S1–S4, AROLC vs
  PCON/PCONf vs the outer loop; ``delaytrack reproduce``).
- :mod:`delaytrack.experiments.tuning`: the tuning protocol that chooses every compared
  controller's gains (``delaytrack tune-baselines``).
- :mod:`delaytrack.experiments.robustness`: the robustness study, the paper's claims over drawn
  robots and wrong delay estimates (``delaytrack reproduce --job robustness``); its statistics
  are :mod:`~delaytrack.experiments.intervals` (Wilson and bootstrap intervals),
  :mod:`~delaytrack.experiments.outcomes` (divergence and medians per group, the longest clean
  delay) and :mod:`~delaytrack.experiments.verdicts` (claims decided draw by draw, attribution).
- :mod:`delaytrack.experiments.tradeoff`: accuracy against delay margin along a one-parameter
  family of outer-loop gains, for any scenario (``delaytrack tradeoff``);
  :mod:`~delaytrack.experiments.decision` chooses among them for a delay envelope, and
  :mod:`~delaytrack.experiments.decision_study` does so for the P3-DX and the paper's envelopes
  (``delaytrack reproduce --job decision``).
- :mod:`delaytrack.experiments.two_link`: the two-link study, AROLC vs the plain outer loop
  on the two-link arm under S1 and S3 (``delaytrack reproduce --job two-link``).

The scenario names exported here (:class:`Scenario`, :func:`load_builtin`, ...) are those of
:mod:`delaytrack.scenario`.
"""

from delaytrack._deprecated import moved_names
from delaytrack.experiments.empirical_margin import (
    EmpiricalMargin,
    empirical_margin,
)
from delaytrack.scenario import (
    BuiltScenario,
    Scenario,
    ScenarioError,
    builtin_scenario_names,
    builtin_scenario_path,
    load_builtin,
    run_batched,
)

__all__ = [
    "BuiltScenario",
    "EmpiricalMargin",
    "Scenario",
    "ScenarioError",
    "builtin_scenario_names",
    "builtin_scenario_path",
    "empirical_margin",
    "load_builtin",
    "run_batched",
]

#: Running a scenario to its folder is a job (it writes a report): :mod:`delaytrack.jobs`.
__getattr__ = moved_names(
    __name__,
    {
        "RunOutput": "delaytrack.jobs.scenario_run:RunOutput",
        "run_to_folder": "delaytrack.jobs.scenario_run:run_to_folder",
    },
)
