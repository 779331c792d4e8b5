"""The paper job's set-up as data (the paper's Section III): the delay scenarios S1–S4, the run
settings, the payload seed, the "left the path" rule, the summary's columns and the paper's own
Tables I–III.

Shared by the study (:mod:`delaytrack.experiments.paper`) and its report
(:mod:`delaytrack.report.paper`); re-exported by the study's module.
"""

from __future__ import annotations

import math

# Theorem 1's free weights β and r of the certified delay bound: the paper's.
from delaytrack.analysis.razumikhin import PAPER_BETA as BETA
from delaytrack.analysis.razumikhin import PAPER_R as R
from delaytrack.delays import AbsSineDelay, ConstantDelay, DelayProfile
from delaytrack.experiments.pairing import BASELINE

__all__ = [
    "BETA",
    "CONTACT_TIME_CONSTANTS",
    "DIAMETER_MM",
    "DT",
    "DURATION",
    "ERROR_BOUND",
    "METRICS",
    "PAPER_TABLE",
    "PAYLOAD_SEED",
    "R",
    "SCENARIOS",
    "SUMMARY_COLUMNS",
    "T_C",
    "TUNED",
    "controller_name",
]

#: Delay scenarios (the paper's Section III): name -> delay profile.
SCENARIOS: dict[str, DelayProfile] = {
    "S1": AbsSineDelay.S1(),
    "S2": AbsSineDelay.S2(),
    "S3": ConstantDelay.S3(),
    "S4": ConstantDelay.S4(),
}
#: Contact time constants (s) of the robot with real wheels: MuJoCo's default, then a stiffer
#: contact, to show how much the contacts' softness matters.
CONTACT_TIME_CONSTANTS = (0.02, 0.005)
#: One payload seed for every reported run (the tuning uses another, tuning.TUNING_SEED).
PAYLOAD_SEED = 2024
#: Seconds per run, plant step ``dt`` and controller period ``T_c`` (s; none is in the paper).
DURATION, DT, T_C = 60.0, 1e-3, 0.01
#: %AE scale: the circle's diameter in mm (the paper's).
DIAMETER_MM = 2500.0
#: The "left the path" rule, the engine's (``simulate(error_bound=...)``): a run stops with
#: status ``left the path`` at the first controller tick where its x or y error exceeds 10 m
#: (the loop is unstable although the state stayed finite); heading and wheel angles are
#: unbounded. The path is 2.5 m across; the literal path's compromise motions stay below 5 m.
ERROR_BOUND = (10.0, 10.0, math.inf, math.inf, math.inf)
SUMMARY_COLUMNS = [
    "scenario",
    "controller",
    "ae_x_mm",
    "ae_y_mm",
    "pct_ae_x",
    "pct_ae_y",
    "tv_Nm",
    "rms_x_mm",
    "rms_y_mm",
    "max_x_mm",
    "max_y_mm",
]
#: The metric columns of :data:`SUMMARY_COLUMNS`.
METRICS = SUMMARY_COLUMNS[2:]
#: The paper's Tables I–III (real robot): (scenario, controller) -> (AE-x, %AE-x, AE-y, %AE-y, TV).
PAPER_TABLE: dict[tuple[str, str], tuple[float, float, float, float, float]] = {
    ("S1", "PCON"): (58.30, 2.33, 53.09, 2.12, 5.45),
    ("S1", "AROLC"): (23.33, 0.93, 22.92, 0.92, 0.42),
    ("S2", "PCON"): (78.46, 3.14, 81.37, 3.25, 6.39),
    ("S2", "AROLC"): (36.42, 1.46, 39.66, 1.59, 0.55),
    ("S3", "PCONf"): (99.63, 3.99, 85.79, 3.43, 8.74),
    ("S3", "AROLC"): (45.66, 1.82, 51.84, 2.07, 2.23),
    ("S4", "PCONf"): (136.91, 5.48, 102.19, 4.79, 10.73),
    ("S4", "AROLC"): (82.29, 3.29, 69.05, 2.76, 3.36),
}
#: The tuned AROLC's kind and controller name (``summary_tuned_arolc.csv``).
TUNED = "AROLC-tuned"


def controller_name(scenario: str, kind: str) -> str:
    """``AROLC``, ``OuterLoop``, or the scenario's baseline (``PCON`` / ``PCONf``)."""
    return BASELINE[scenario] if kind == "baseline" else kind
