"""Stability analysis of AROLC: Theorem 1's delay bound, Theorem 2's ultimate bounds, the exact
delay margin of the nominal error dynamics, its error loop as python-control systems and a gain
design for the certified bound."""

from delaytrack.analysis.control_export import (
    error_loop,
    error_loop_frequency_response,
    error_loop_sampled,
)
from delaytrack.analysis.exact_margin import (
    MAX_SCANNED_JOINTS,
    ExactDelayMargin,
    exact_delay_margin,
)
from delaytrack.analysis.gain_design import GainDesign, design_gains
from delaytrack.analysis.razumikhin import (
    MAX_COUPLED_JOINTS,
    MAX_JOINTS,
    RazumikhinBound,
    error_dynamics_matrices,
    lyapunov_matrix,
    razumikhin_bound,
)
from delaytrack.analysis.ultimate_bounds import UltimateBounds, psi_min, ultimate_bounds

__all__ = [
    "MAX_COUPLED_JOINTS",
    "MAX_JOINTS",
    "MAX_SCANNED_JOINTS",
    "ExactDelayMargin",
    "GainDesign",
    "RazumikhinBound",
    "UltimateBounds",
    "design_gains",
    "error_dynamics_matrices",
    "error_loop",
    "error_loop_frequency_response",
    "error_loop_sampled",
    "exact_delay_margin",
    "lyapunov_matrix",
    "psi_min",
    "razumikhin_bound",
    "ultimate_bounds",
]
