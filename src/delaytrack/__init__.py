"""delaytrack: control of Euler-Lagrange systems under unknown input delay.

The curated public API. Everything here is also importable from its subpackage
(:mod:`delaytrack.plants`, :mod:`delaytrack.delays`, :mod:`delaytrack.controllers`,
:mod:`delaytrack.analysis`, :mod:`delaytrack.sim`, :mod:`delaytrack.metrics`,
:mod:`delaytrack.scenario`, :mod:`delaytrack.experiments`); figures and HTML reports live in
:mod:`delaytrack.report`.

Examples
--------
>>> import numpy as np
>>> import delaytrack as dt
>>> round(dt.razumikhin_bound(1.0, 1.0, 1.0, beta=1.0, r=1.1).h_m, 5)
0.12487
"""

# First: choose numba's cache folder before any kernel is decorated (see _compile.disk_cache).
from delaytrack._compile import disk_cache  # noqa: F401  isort: skip

from delaytrack._version import __version__
from delaytrack.analysis import (
    ExactDelayMargin,
    GainDesign,
    RazumikhinBound,
    UltimateBounds,
    design_gains,
    exact_delay_margin,
    razumikhin_bound,
    ultimate_bounds,
)
from delaytrack.controllers import AROLC, Controller, OuterLoop, controller_from_spec
from delaytrack.delays import (
    AbsSineDelay,
    CompiledDelay,
    ConstantDelay,
    DelayProfile,
    PiecewiseConstantDelay,
    RandomDelay,
    TraceDelay,
    delay_from_spec,
)
from delaytrack.experiments import EmpiricalMargin, empirical_margin, run_to_folder
from delaytrack.metrics import (
    max_abs_error,
    mean_absolute_error,
    metrics_table,
    percent_of,
    rms_error,
    total_variation,
)
from delaytrack.plants import (
    CallablePlant,
    CompiledPlant,
    ELPlant,
    LinearPlant,
    MujocoPlant,
    MujocoWheeledRobot,
    TwoLinkArm,
    plant_from_spec,
)
from delaytrack.references import Reference, SinusoidalReference, SplineReference
from delaytrack.scenario import Scenario, ScenarioError, load_builtin
from delaytrack.sim import MeasurementNoise, PacketLoss, SimResult, simulate

__all__ = [
    "AROLC",
    "AbsSineDelay",
    "CompiledDelay",
    "CallablePlant",
    "CompiledPlant",
    "ConstantDelay",
    "Controller",
    "DelayProfile",
    "ELPlant",
    "EmpiricalMargin",
    "ExactDelayMargin",
    "GainDesign",
    "LinearPlant",
    "MujocoPlant",
    "MujocoWheeledRobot",
    "OuterLoop",
    "PiecewiseConstantDelay",
    "RandomDelay",
    "RazumikhinBound",
    "Reference",
    "Scenario",
    "ScenarioError",
    "MeasurementNoise",
    "PacketLoss",
    "SimResult",
    "SinusoidalReference",
    "SplineReference",
    "TraceDelay",
    "TwoLinkArm",
    "UltimateBounds",
    "__version__",
    "controller_from_spec",
    "delay_from_spec",
    "design_gains",
    "empirical_margin",
    "exact_delay_margin",
    "load_builtin",
    "max_abs_error",
    "mean_absolute_error",
    "metrics_table",
    "percent_of",
    "plant_from_spec",
    "razumikhin_bound",
    "rms_error",
    "run_to_folder",
    "simulate",
    "total_variation",
    "ultimate_bounds",
]
