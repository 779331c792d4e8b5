"""Adaptive-Robust Outer Loop Control (AROLC), Roy & Kar (decisions left open: docs/decisions.md).

Continuous law (paper eqs. (input), (control input), (aux), (delta u), (ATRC)):

    τ  = M̂ u + N̂,   u = û + Δu,   û = q̈_d + K2 ė1 + K1 e1
    s  = Bᵀ P e,    B = [0; I],    AᵀP + PA = -Q,   A = [[0, I], [-K1, -K2]]
    Δu = α ĉ s / ‖s‖  if ‖s‖ >= ε,   α ĉ s / ε  otherwise
    ĉ' = ‖s‖ if ĉ > γ and sᵀṡ > 0;   -‖s‖ if ĉ > γ and sᵀṡ <= 0;   γ if ĉ <= γ

Decisions where the paper is silent (see docs/decisions.md):

* the law runs at a fixed period ``T_c`` with zero-order hold; ĉ is integrated by forward Euler,
  ``ĉ_{k+1} = ĉ_k + T_c ĉ'_k``, and Δu at tick k uses ĉ_k;
* ṡ is not measured: the sign of ``sᵀṡ`` is that of ``s_kᵀ (s_k - s_{k-1})``; at the first tick
  (no previous s) it is taken as ``<= 0``;
* ``ĉ(0) = γ`` unless ``c_hat0`` is given;
* a decreasing Euler step stops at γ: ``ĉ_{k+1} = max(ĉ_k - T_c ‖s_k‖, γ)``. In continuous time
  ĉ cannot pass below γ (at ĉ = γ the law switches to ĉ' = γ > 0 and ĉ slides along γ); plain
  forward Euler would overshoot, even below zero, which flips the sign of Δu.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from delaytrack._compile.jit import hot_kernel, tick_kernel
from delaytrack._small_linalg import matvec
from delaytrack._validation import ArgumentError, as_spd_matrix, positive_scalar
from delaytrack.analysis.razumikhin import (
    _WHOLE_P,
    _check_coupled,
    error_dynamics_matrices,
    lyapunov_matrix,
)
from delaytrack.components import plant_sizes
from delaytrack.controllers.base import (
    Controller,
    auxiliary_input,
    computed_torque_command,
    step_memory,
    tracking_errors,
)
from delaytrack.plants.base import ELPlant

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

__all__ = ["AROLC", "arolc_step", "adaptive_gain_rate"]

# Layout of the state vector: [c_hat, has_previous_s, s_previous (n)].
_C_HAT = 0
_HAS_PREVIOUS = 1
_S_PREVIOUS = 2


@hot_kernel
def adaptive_gain_rate(c_hat, s, s_previous, has_previous, gamma, norm_s=None):
    """``ĉ'`` of the adaptive law (ATRC) with ``sᵀṡ`` replaced by ``sᵀ(s - s_previous)``;
    ``norm_s`` is ``‖s‖`` when the caller has it already (computed here otherwise)."""
    if c_hat <= gamma:
        return gamma
    n = s.shape[0]
    norm_s = math.sqrt(_dot(n, s, s)) if norm_s is None else norm_s
    increasing = 0.0
    for i in range(n):
        increasing += s[i] * (s[i] - s_previous[i])
    if has_previous and increasing > 0.0:
        return norm_s
    return -norm_s


@hot_kernel
def _dot(n, a, b):
    """``aᵀb``, summed in index order."""
    total = 0.0
    for i in range(n):
        total += a[i] * b[i]
    return total


@tick_kernel
def arolc_step(
    t, q, qdot, qd, qd_dot, qd_ddot, T_c, h, params, state, model_terms, model_params, command, work
):
    """One AROLC tick (see the module docstring).

    ``params = [K1, K2, BᵀP, α, ε, γ]`` (matrices flattened row-major, ``BᵀP`` is (n, 2n));
    ``state = [ĉ, has_previous_s, s_previous]`` is advanced in place; ``work`` is
    :func:`~delaytrack.controllers.base.step_workspace` scratch.
    """
    n, m = plant_sizes(model_terms, q, command)
    alpha = params[4 * n * n]
    epsilon = params[4 * n * n + 1]
    gamma = params[4 * n * n + 2]
    memory = step_memory(model_terms, work)  # one set of arrays for the whole step
    vectors = memory[3]
    error = vectors[: 2 * n]
    s = vectors[2 * n : 3 * n]
    u = vectors[3 * n : 4 * n]
    tracking_errors(q, qdot, qd, qd_dot, error, n)
    matvec(params, 2 * n * n, n, 2 * n, error, s)  # s = BᵀP e
    norm_s = math.sqrt(_dot(n, s, s))
    c_hat = state[_C_HAT]
    # u = û + Δu with Δu = α ĉ s / max(‖s‖, ε)  (paper eqs. (control input), (delta u)).
    auxiliary_input(params, error, qd_ddot, u, n)
    gain = alpha * c_hat / max(norm_s, epsilon)
    for i in range(n):
        u[i] += gain * s[i]
    computed_torque_command(model_terms, model_params, t, q, qdot, u, command, memory)
    rate = adaptive_gain_rate(
        c_hat, s, state[_S_PREVIOUS:], state[_HAS_PREVIOUS] != 0.0, gamma, norm_s
    )
    c_next = c_hat + T_c * rate
    state[_C_HAT] = gamma if rate < 0.0 and c_next < gamma else c_next
    state[_HAS_PREVIOUS] = 1.0
    for i in range(n):  # a loop: an array-to-slice copy needs numba's runtime
        state[_S_PREVIOUS + i] = s[i]


#: alpha, gamma, c_hat0 <= _LAW_RANGE and epsilon >= 1 / _LAW_RANGE: the products in
#: Δu = α ĉ s/ε stay far from the double-precision limits.
_LAW_RANGE = 1e100


@dataclass(frozen=True, eq=False)
class AROLC(Controller):
    """AROLC for an ``n``-coordinate Euler–Lagrange plant.

    Parameters
    ----------
    model : ELPlant
        Nominal plant ``M̂, N̂`` (no knowledge of the delay or of uncertainty bounds is needed).
    K1, K2 : array_like
        Symmetric positive definite (n, n); a scalar means a multiple of I, 1-D a diagonal.
    Q : array_like
        Symmetric positive definite (2n, 2n) defining ``P`` by ``AᵀP + PA = -Q``.
    alpha, epsilon, gamma : float
        Switching gain ``α > 0``, boundary layer ``ε > 0`` and floor ``γ > 0`` of ĉ.
    c_hat0 : float, optional
        Initial ĉ, ``> 0``; ``γ`` by default.

    Notes
    -----
    The paper's robot gains are ``K1 = K2 = Q = I``, ``α = 2``, ``ε = 0.1``, ``γ = 0.001``.
    """

    model: ELPlant
    K1: np.ndarray
    K2: np.ndarray
    Q: np.ndarray
    alpha: float
    epsilon: float
    gamma: float
    c_hat0: float | None = None
    P: np.ndarray = field(init=False, repr=False)
    _params: np.ndarray = field(init=False, repr=False)
    type_name: ClassVar[str] = "arolc"

    if TYPE_CHECKING:
        # The generated __init__ takes any array_like gain; __post_init__ makes it a matrix.
        def __init__(
            self,
            model: ELPlant,
            K1: ArrayLike,
            K2: ArrayLike,
            Q: ArrayLike,
            alpha: float,
            epsilon: float,
            gamma: float,
            c_hat0: float | None = None,
        ) -> None: ...

    def __post_init__(self) -> None:
        self._check_model()
        n = self.model.n
        _check_coupled(n, _WHOLE_P)  # before Q's check
        object.__setattr__(self, "K1", as_spd_matrix("K1", self.K1, n))
        object.__setattr__(self, "K2", as_spd_matrix("K2", self.K2, n))
        object.__setattr__(self, "Q", as_spd_matrix("Q", self.Q, 2 * n))
        for name in ("alpha", "epsilon", "gamma"):
            object.__setattr__(self, name, positive_scalar(name, getattr(self, name)))
        c_hat0 = self.gamma if self.c_hat0 is None else positive_scalar("c_hat0", self.c_hat0)
        object.__setattr__(self, "c_hat0", c_hat0)
        # The law multiplies alpha c_hat ||s|| / epsilon: large factors or a tiny divisor
        # overflow double precision.
        for name in ("alpha", "gamma", "c_hat0", "epsilon"):
            value = getattr(self, name)
            inverse = name == "epsilon"
            if (1.0 / value if inverse else value) > _LAW_RANGE:
                bound = f">= {1.0 / _LAW_RANGE:g}" if inverse else f"<= {_LAW_RANGE:g}"
                raise ArgumentError(
                    name,
                    f"must be {bound} (the law multiplies alpha c_hat ||s|| / epsilon; beyond "
                    f"that the command overflows double precision); got {value:g}",
                )
        P = lyapunov_matrix(self.K1, self.K2, self.Q)
        input_matrix = error_dynamics_matrices(self.K1, self.K2)[3]
        sliding_gain = input_matrix.T @ P
        largest = float(np.max(np.abs(sliding_gain)))
        if not largest <= _LAW_RANGE:  # NaN too
            raise ArgumentError(
                "Q",
                f"with K1 and K2 gives s = B^T P e a gain of {largest:g} (P solves A^T P + P A "
                f"= -Q); it must be <= {_LAW_RANGE:g}, as alpha, c_hat0 and gamma must (the "
                "law multiplies them all: a command beyond double precision is a diverged run)",
            )
        object.__setattr__(self, "P", P)
        packed = [self.K1.ravel(), self.K2.ravel(), sliding_gain.ravel()]
        object.__setattr__(
            self, "_params", np.concatenate([*packed, [self.alpha, self.epsilon, self.gamma]])
        )

    @property
    def params(self) -> np.ndarray:
        return self._params

    @property
    def step_kernel(self):
        return arolc_step

    @property
    def state_names(self) -> tuple[str, ...]:
        return ("c_hat", "has_previous_s", *(f"s_previous_{i}" for i in range(self.n)))

    @property
    def reported_state_names(self) -> tuple[str, ...]:
        """``ĉ`` only: the previous ``s`` is the adaptive law's bookkeeping."""
        return ("c_hat",)

    def initial_state(self) -> np.ndarray:
        state = np.zeros(2 + self.n)
        state[_C_HAT] = self.c_hat0
        return state

    def to_spec(self) -> dict[str, Any]:
        return {
            "type": self.type_name,
            "K1": self.K1.tolist(),
            "K2": self.K2.tolist(),
            "Q": self.Q.tolist(),
            "alpha": self.alpha,
            "epsilon": self.epsilon,
            "gamma": self.gamma,
            "c_hat0": self.c_hat0,
        }
