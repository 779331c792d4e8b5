"""Stability analysis of AROLC: Theorem 1's delay bound and Theorem 2's ultimate bounds."""

from delaytrack.analysis.razumikhin import (
    RazumikhinBound,
    error_dynamics_matrices,
    lyapunov_matrix,
    razumikhin_bound,
)
from delaytrack.analysis.ultimate_bounds import UltimateBounds, psi_min, ultimate_bounds

__all__ = [
    "RazumikhinBound",
    "UltimateBounds",
    "error_dynamics_matrices",
    "lyapunov_matrix",
    "psi_min",
    "razumikhin_bound",
    "ultimate_bounds",
]
