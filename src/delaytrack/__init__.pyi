"""Names of the package root, imported when first used (see ``__init__.py``)."""

from ._version import __version__
from .analysis import (
    ExactDelayMargin,
    GainDesign,
    RazumikhinBound,
    UltimateBounds,
    design_gains,
    error_loop,
    error_loop_frequency_response,
    error_loop_sampled,
    exact_delay_margin,
    razumikhin_bound,
    ultimate_bounds,
)
from .controllers import AROLC, Controller, OuterLoop, controller_from_spec
from .delays import (
    AbsSineDelay,
    CompiledDelay,
    ConstantDelay,
    DelayProfile,
    PiecewiseConstantDelay,
    RandomDelay,
    TraceDelay,
    delay_from_spec,
)
from .experiments import EmpiricalMargin, empirical_margin
from .jobs.scenario_run import run_to_folder
from .metrics import (
    max_abs_error,
    mean_absolute_error,
    metrics_table,
    percent_of,
    rms_error,
    total_variation,
)
from .plants import (
    CallablePlant,
    CompiledPlant,
    ELPlant,
    LinearPlant,
    MujocoPlant,
    MujocoWheeledRobot,
    TwoLinkArm,
    plant_from_spec,
)
from .references import Reference, SinusoidalReference, SplineReference
from .scenario import Scenario, ScenarioError, load_builtin
from .sim import MeasurementNoise, PacketLoss, SimResult, simulate
