"""The predictor baselines PCON (paper Ref 32) and PCONf (Ref 31); decisions: docs/decisions.md.

Continuous law (paper eqs. (filter), (int error) and ``τ = k_b ϱ``):

    ϱ   = ė1 + κ e1 − ϑ e_z,     e_z(t) = ∫_{t−h}^{t} τ(θ) dθ,     τ = k_b ϱ

with ``e1 = q_d − q``, ``κ > 0``, ``ϑ`` a constant symmetric positive definite estimate of
``M⁻¹`` and ``k_b`` the feedback gain. PCON (Fischer et al., time-varying delay) evaluates the
window with the true delay ``h = h(t_k)`` (its assumption: the delay is known), or with what
it is told of it (:mod:`~delaytrack.controllers.delay_knowledge`: a scaled, offset or noisy
``h(t_k)``); PCONf (Sharma et al. 2011, constant delay) with its constant ``h̄``. The
generalised force ``τ`` (n,) is mapped to the actuators by the nominal model's command map, as
for AROLC: ``Ĝ(q)⁻¹ τ`` for a fully actuated model, the model's own map (``S(q)ᵀ τ`` for the
wheeled robot) otherwise.

Decisions where the paper is silent (docs/decisions.md, D23):

* The law runs at the fixed period ``T_c`` with zero-order hold, ``τ(θ) = τ_j`` on
  ``[t_j, t_{j+1})``. ``e_z`` is then a finite sum, evaluated exactly (no quadrature): at tick
  ``k``, with ``H = h / T_c = w + f`` (``w`` whole ticks, ``0 <= f < 1``),

      e_z(t_k) = T_c (τ_{k−1} + … + τ_{k−w} + f τ_{k−w−1}).

  The weights are overlaps of ``[t_j, t_{j+1})`` with ``[t_k − h, t_k)`` measured in units of
  ``T_c`` from the current tick, never from absolute times (``t_k − h`` vs ``t_j`` would lose
  digits at large ``t``). The command being computed (``τ_k``) does not contribute.
* Before the first tick ``τ = 0`` (the simulator's default ``u_init``): ticks before the first
  contribute nothing.
* ``τ_j`` is the law's generalised force, stored before the command map.
* ``space="actuator"`` runs the same law on the actuator commands (for the wheeled robot the
  wheel-space law of the cited controllers, ``e_z = ∫ τ_w``, ``ϑ ≈ M_r⁻¹``): the error term is
  mapped to the actuators first, ``ϱ = B̂(q)(ė1 + κ e1) − ϑ e_z``, and the ring stores the
  commands themselves. The projected five-coordinate law (the default) integrates forces the
  robot never receives (``S(q)ᵀ`` discards three of five coordinates), so its ``e_z`` is not
  the integral of the delayed input; the actuator-space ``e_z`` is.
* The past ``τ_j`` live in the explicit state, in a ring of ``ceil(history / T_c) + 2`` ticks.
  The period ``T_c`` the ring is sized for is a constructor argument (the state size must be
  known before a run); a step called with another period, or asked for a window longer than
  ``history``, issues a NaN command, which the simulator reports as ``diverged``. The Python
  :meth:`~PredictorBaseline.step` raises instead.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from delaytrack._compile.jit import tick_kernel
from delaytrack._counter_noise import NOISE_BOUND
from delaytrack._small_linalg import matvec
from delaytrack._validation import (
    ArgumentError,
    as_spd_matrix,
    finite_scalar,
    is_integer_at_least,
    positive_scalar,
)
from delaytrack.components import call_command_map, call_terms
from delaytrack.controllers.base import Controller, terms_views
from delaytrack.controllers.delay_knowledge import told_delay
from delaytrack.plants.base import ELPlant

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

__all__ = ["PCON", "PCONf", "SPACES", "PredictorBaseline", "pcon_step", "ring_slots"]

# Layout of the parameter vector: [κ, T_c, history, fixed, h̄, slots, s, b, σ, seed, actuator,
# k_b (d²), ϑ (d²)] (s, b, σ, seed: what PCON is told of the delay; d = n, or m when the law runs
# in actuator space).
_KAPPA = 0
_PERIOD = 1
_HISTORY = 2
_FIXED = 3
_H_BAR = 4
_SLOTS = 5
_SCALE = 6
_OFFSET = 7
_NOISE = 8
_SEED = 9
_ACTUATOR = 10
_MATRICES = 11
#: The spaces the law can run in (:class:`PredictorBaseline`'s ``space``).
SPACES = ("generalised", "actuator")
#: Largest seed of the delay estimate's noise (it lives in the float parameter vector).
MAX_NOISE_SEED = 2**32 - 1

#: Relative tolerance between the step's ``T_c`` and the period the ring was sized for.
_PERIOD_RTOL = 1e-9


def ring_slots(history: float, T_c: float) -> int:
    """Ticks of ``τ`` kept by a controller whose window never exceeds ``history`` seconds.

    At tick ``k`` a window ``h = (w + f) T_c <= history`` reads ``τ_{k−1} … τ_{k−w}``, and
    ``τ_{k−w−1}`` only when ``f > 0``, so ``w + 1 <= ceil(history / T_c)``: that many ticks
    suffice. Two more are margin against rounding (as for the engine's history).
    """
    return int(math.ceil(history / T_c)) + 2


@tick_kernel
def pcon_step(
    t, q, qdot, qd, qd_dot, qd_ddot, T_c, h, params, state, model_terms, model_params, command, work
):
    """One PCON / PCONf tick (see the module docstring).

    ``params = [κ, T_c, history, fixed, h̄, slots, s, b, σ, seed, actuator, k_b, ϑ]`` (matrices
    flattened row-major); the window is ``h̄`` when ``fixed`` is non-zero (PCONf), else what PCON
    is told of the true delay ``h``: ``max(0, s h + b + σ ξ_k)`` (:func:`told_delay`). With
    ``actuator`` zero the law runs on generalised forces (``d = n``), else on actuator commands
    (``d = m``, ``ϱ = B̂(q)(ė1 + κ e1) − ϑ e_z``, ``B̂`` the nominal command map).
    ``state = [e_z (d), ϱ (d), count, ring (slots × d)]``: ``e_z`` and ``ϱ`` of the latest
    tick, the number of ticks taken, and the law's output of tick ``j`` in ring slot
    ``j % slots``. ``work`` is :func:`~delaytrack.controllers.base.step_workspace` scratch.
    """
    n = q.shape[0]
    m = command.shape[0]
    actuator = params[_ACTUATOR] != 0.0
    d = m if actuator else n
    period = params[_PERIOD]
    if params[_FIXED] != 0.0:
        window = params[_H_BAR]
    else:
        window = told_delay(
            h, t, period, params[_SCALE], params[_OFFSET], params[_NOISE], int(params[_SEED])
        )
    if not (abs(T_c - period) <= _PERIOD_RTOL * period and 0.0 <= window <= params[_HISTORY]):
        command[:] = np.nan  # the simulator stops the run as diverged
        return
    kappa = params[_KAPPA]
    slots = int(params[_SLOTS])
    # k_b (d, d) and ϑ (d, d) are read in place, row-major from these indices of params.
    k_b_at = _MATRICES
    vartheta_at = _MATRICES + d * d
    count = int(state[2 * d])
    ring = 2 * d + 1
    mass, nonlinear, input_map, vectors = terms_views(work, n, m)
    e_z = vectors[:d]
    predicted = vectors[n : n + d]
    rho = vectors[2 * n : 2 * n + d]
    tau = vectors[3 * n : 3 * n + d]
    # e_z(t_k) = T_c (τ_{k−1} + … + τ_{k−w} + f τ_{k−w−1}), H = h / T_c = w + f; ticks before
    # the first (j < 0) carry τ = 0.
    ticks = window / T_c
    whole = int(math.floor(ticks))
    fraction = ticks - whole
    e_z[:] = 0.0
    for i in range(1, min(whole, count) + 1):
        start = ring + ((count - i) % slots) * d
        e_z += state[start : start + d]
    if fraction > 0.0 and whole < count:
        start = ring + ((count - whole - 1) % slots) * d
        for j in range(d):
            e_z[j] += fraction * state[start + j]
    e_z *= T_c
    matvec(params, vartheta_at, d, d, e_z, predicted)
    call_terms(model_terms, t, q, qdot, model_params, mass, nonlinear, input_map)
    finite = True
    for i in range(n):
        for j in range(m):
            finite = finite and math.isfinite(input_map[i, j])
    if actuator:
        # ϱ = B̂(q)(ė1 + κ e1) − ϑ e_z: the error term mapped to the actuators first (tau holds
        # ė1 + κ e1 for the map, its first m entries then take the command).
        velocity_error = vectors[3 * n : 4 * n]
        for i in range(n):
            velocity_error[i] = (qd_dot[i] - qdot[i]) + kappa * (qd[i] - q[i])
        call_command_map(model_terms, q, model_params, input_map, velocity_error, command)
        for i in range(m):
            rho[i] = command[i] - predicted[i]
        matvec(params, k_b_at, d, d, rho, command)
        for i in range(m):
            tau[i] = command[i]
    else:
        for i in range(n):
            rho[i] = ((qd_dot[i] - qdot[i]) + kappa * (qd[i] - q[i])) - predicted[i]
        matvec(params, k_b_at, d, d, rho, tau)
    for i in range(d):
        finite = finite and math.isfinite(tau[i])
    if not finite:
        command[:] = np.nan
        return
    if not actuator:
        call_command_map(model_terms, q, model_params, input_map, tau, command)
    start = ring + (count % slots) * d
    for i in range(d):  # loops: an array-to-slice copy needs numba's runtime
        state[i] = e_z[i]
        state[d + i] = rho[i]
        state[start + i] = tau[i]
    state[2 * d] = count + 1


#: Most controller periods a predictor's history may hold (8 bytes per coordinate each, per run).
MAX_HISTORY_TICKS = 10**7


@dataclass(frozen=True, eq=False)
class PredictorBaseline(Controller):
    """The predictor law shared by :class:`PCON` and :class:`PCONf` (the paper's Refs 31–32).

    Parameters
    ----------
    model : ELPlant
        Nominal plant; only its command map is used (``τ`` to actuator commands).
    kappa : float
        ``κ > 0``, weight of ``e1`` in ``ϱ``.
    vartheta : array_like
        ``ϑ``, symmetric positive definite (n, n) estimate of ``M⁻¹``; a scalar means a multiple
        of I, 1-D a diagonal.
    k_b : array_like
        Feedback gain ``τ = k_b ϱ``: a scalar ``> 0`` as in the paper, or symmetric positive
        definite (n, n) (1-D a diagonal).
    history : float
        Seconds of ``τ`` kept, ``> 0``; must cover the longest window the law will be asked for.
    T_c : float
        Controller period the history is sized for (the simulator's ``T_c``), ``> 0``.
    space : {"generalised", "actuator"}, keyword only
        Where the law runs. ``"generalised"`` (default): on generalised forces, ``ϱ, τ, e_z`` of
        size ``n``, ``ϑ`` and ``k_b`` (n, n), the result mapped to the actuators by the
        nominal command map ``B̂(q)`` (``S(q)ᵀ`` for the wheeled robot). ``"actuator"``: on the
        actuator commands themselves,

            ϱ = B̂(q)(ė1 + κ e1) − ϑ e_z,   e_z(t) = ∫_{t−h}^{t} u(θ) dθ,   u = k_b ϱ,

        with ``ϑ`` and ``k_b`` (m, m) and ``e_z`` the integral of the commands actually sent
        (for the wheeled robot the wheel-space law, ``ϑ`` an estimate of the inverse of the
        reduced mass matrix ``M_r = SᵀMS``). Needs ``m <= n``. For scalar ``ϑ`` and ``k_b``
        both spaces give the same commands (the map commutes with scalars); with matrices they
        are different laws.
    """

    model: ELPlant
    kappa: float
    vartheta: np.ndarray
    k_b: np.ndarray
    history: float
    T_c: float
    space: str = field(default="generalised", kw_only=True)
    _params: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if type(self) is PredictorBaseline:
            raise TypeError("PredictorBaseline is the shared law; build a PCON or a PCONf")
        self._check_model()
        if not isinstance(self.space, str) or self.space not in SPACES:
            raise ArgumentError("space", f"must be one of {SPACES}; got {self.space!r}")
        if self.space == "actuator" and self.model.m > self.model.n:
            raise ArgumentError(
                "space",
                f"= 'actuator' needs at most as many inputs as coordinates; the model has "
                f"m = {self.model.m} inputs and n = {self.model.n} coordinates",
            )
        d = self.law_size
        object.__setattr__(self, "kappa", positive_scalar("kappa", self.kappa))
        object.__setattr__(self, "vartheta", as_spd_matrix("vartheta", self.vartheta, d))
        object.__setattr__(self, "k_b", as_spd_matrix("k_b", self.k_b, d))
        object.__setattr__(self, "history", positive_scalar("history", self.history))
        object.__setattr__(self, "T_c", positive_scalar("T_c", self.T_c))
        if self.history / self.T_c > MAX_HISTORY_TICKS:
            raise ArgumentError(
                "history",
                f"must be at most {MAX_HISTORY_TICKS:.0e} controller periods "
                f"({MAX_HISTORY_TICKS * self.T_c:g} s at T_c = {self.T_c:g} s): every run keeps "
                f"one command per period of it in its state; got history = {self.history:g} s",
            )
        scalars = [
            self.kappa,
            self.T_c,
            self.history,
            1.0 if self.fixed_delay is not None else 0.0,
            0.0 if self.fixed_delay is None else self.fixed_delay,
            float(ring_slots(self.history, self.T_c)),
            *self.delay_knowledge,
            1.0 if self.space == "actuator" else 0.0,
        ]
        packed = np.concatenate([scalars, self.k_b.ravel(), self.vartheta.ravel()])
        object.__setattr__(self, "_params", packed)

    @property
    def law_size(self) -> int:
        """``d``: the size of ``ϱ``, ``e_z`` and each stored output (``n``, or ``m`` in actuator
        space)."""
        return self.model.m if self.space == "actuator" else self.model.n

    @property
    def fixed_delay(self) -> float | None:
        """The constant window ``h̄`` (PCONf), or None when the law reads the true delay."""
        return None

    @property
    def delay_knowledge(self) -> tuple[float, float, float, float]:
        """``(s, b, σ, seed)`` of what the law is told of the delay (exact by default)."""
        return (1.0, 0.0, 0.0, 0.0)

    @property
    def slots(self) -> int:
        """Ticks of ``τ`` the state keeps: ``ceil(history / T_c) + 2``."""
        return ring_slots(self.history, self.T_c)

    @property
    def params(self) -> np.ndarray:
        return self._params

    @property
    def step_kernel(self):
        return pcon_step

    @property
    def state_names(self) -> tuple[str, ...]:
        """``e_z`` and ``ϱ`` of the latest tick: recorded at tick ``k`` they belong to ``k − 1``."""
        return (
            *(f"e_z_previous_{i}" for i in range(self.law_size)),
            *(f"rho_previous_{i}" for i in range(self.law_size)),
        )

    @property
    def state_size(self) -> int:
        """``2d`` recorded entries, the tick count, and the ring of ``slots × d`` past outputs."""
        return 2 * self.law_size + 1 + self.slots * self.law_size

    def initial_state(self) -> np.ndarray:
        return np.zeros(self.state_size)

    def check_run(self, T_c: float, h_max: float) -> None:
        """Raise unless the law runs at its own ``T_c`` under delays up to ``h_max`` seconds.

        The history ring is sized for the constructor's ``T_c``. PCON reads the true delay, so
        ``h_max`` must not exceed ``history``; PCONf never reads it (any ``h_max`` is fine).
        """
        T_c = positive_scalar("T_c", T_c)
        if abs(T_c - self.T_c) > _PERIOD_RTOL * self.T_c:
            raise ValueError(
                f"T_c = {T_c:g} s differs from the period {type(self).__name__} was built for "
                f"(T_c = {self.T_c:g} s): its history is sized for it"
            )
        h_max = positive_scalar("h_max", h_max, strictly=False)
        scale, offset, noise, _ = self.delay_knowledge
        told = scale * h_max + offset + NOISE_BOUND * noise
        if self.fixed_delay is None and told > self.history:
            raise ValueError(
                f"delay {h_max:g} s exceeds history = {self.history:g} s: {type(self).__name__} "
                "integrates tau over the true delay and keeps only history seconds of it"
                if told == h_max
                else f"the delay {type(self).__name__} may be told reaches "
                f"{scale:g} · {h_max:g} + {offset:g} + {NOISE_BOUND:g} · {noise:g} = {told:g} s "
                f"(delay_scale · h_max + delay_offset + {NOISE_BOUND:g} delay_noise), more than "
                f"history = {self.history:g} s: raise history to at least {told:g} s"
            )

    def to_spec(self) -> dict[str, Any]:
        spec = {
            "type": self.type_name,
            "kappa": self.kappa,
            "vartheta": self.vartheta.tolist(),
            "k_b": self.k_b.tolist(),
            "history": self.history,
            "T_c": self.T_c,
        }
        if self.space != "generalised":
            spec["space"] = self.space
        return spec


@dataclass(frozen=True, eq=False)
class PCON(PredictorBaseline):
    """PCON (paper Ref 32, time-varying delay): the window is the true delay ``h(t_k)``, or what
    the law is told of it.

    The law assumes the delay known, so the simulator passes it ``h(t_k)`` at every tick. See
    :class:`PredictorBaseline` for the other parameters.

    Parameters
    ----------
    delay_scale, delay_offset, delay_noise : float
        What the law is told (:mod:`~delaytrack.controllers.delay_knowledge`):
        ``ĥ_k = max(0, delay_scale · h(t_k) + delay_offset + delay_noise · ξ_k)``, with
        ``delay_scale >= 0``, ``delay_offset`` in s, ``delay_noise >= 0`` the standard deviation
        (s) of approximately normal noise bounded by 6 of them. The defaults ``1, 0, 0`` tell
        the true delay, the paper's assumption.
    noise_seed : int
        Seed of the noise, 0 to 2³² − 1.

    Notes
    -----
    ``history`` must hold the longest window the law can be told,
    ``delay_scale · h_max + delay_offset + 6 delay_noise``
    (:meth:`PredictorBaseline.check_run` refuses a run otherwise).
    """

    delay_scale: float = 1.0
    delay_offset: float = 0.0
    delay_noise: float = 0.0
    noise_seed: int = 0
    type_name: ClassVar[str] = "pcon"
    needs_delay: ClassVar[bool] = True

    if TYPE_CHECKING:
        # The generated __init__ takes any array_like gain; __post_init__ makes it a matrix.
        def __init__(
            self,
            model: ELPlant,
            kappa: float,
            vartheta: ArrayLike,
            k_b: ArrayLike,
            history: float,
            T_c: float,
            delay_scale: float = 1.0,
            delay_offset: float = 0.0,
            delay_noise: float = 0.0,
            noise_seed: int = 0,
            *,
            space: str = "generalised",
        ) -> None: ...

    def __post_init__(self) -> None:
        object.__setattr__(
            self, "delay_scale", positive_scalar("delay_scale", self.delay_scale, strictly=False)
        )
        object.__setattr__(self, "delay_offset", finite_scalar("delay_offset", self.delay_offset))
        object.__setattr__(
            self, "delay_noise", positive_scalar("delay_noise", self.delay_noise, strictly=False)
        )
        if not is_integer_at_least(self.noise_seed, 0) or self.noise_seed > MAX_NOISE_SEED:
            raise ArgumentError(
                "noise_seed",
                f"must be an integer from 0 to {MAX_NOISE_SEED}; got {self.noise_seed!r}",
            )
        super().__post_init__()

    @property
    def delay_knowledge(self) -> tuple[float, float, float, float]:
        return (self.delay_scale, self.delay_offset, self.delay_noise, float(self.noise_seed))

    def to_spec(self) -> dict[str, Any]:
        spec = super().to_spec()
        for key, default in (
            ("delay_scale", 1.0),
            ("delay_offset", 0.0),
            ("delay_noise", 0.0),
            ("noise_seed", 0),
        ):
            if getattr(self, key) != default:
                spec[key] = getattr(self, key)
        return spec


@dataclass(frozen=True, eq=False)
class PCONf(PredictorBaseline):
    """PCONf (paper Ref 31, constant known delay): the window is the constant ``h_bar``.

    Parameters are those of :class:`PredictorBaseline` and ``h_bar``, the delay the law assumes
    (seconds, ``0 <= h_bar <= history``). The true delay is never read.
    """

    h_bar: float
    type_name: ClassVar[str] = "pconf"
    needs_delay: ClassVar[bool] = False

    if TYPE_CHECKING:
        # The generated __init__ takes any array_like gain; __post_init__ makes it a matrix.
        def __init__(
            self,
            model: ELPlant,
            kappa: float,
            vartheta: ArrayLike,
            k_b: ArrayLike,
            history: float,
            T_c: float,
            h_bar: float,
            *,
            space: str = "generalised",
        ) -> None: ...

    def __post_init__(self) -> None:
        h_bar = positive_scalar("h_bar", self.h_bar, strictly=False)
        history = positive_scalar("history", self.history)
        if h_bar > history:
            raise ArgumentError(
                "h_bar",
                f"= {h_bar:g} s exceeds history = {history:g} s: the history must hold the whole "
                "window of tau",
            )
        object.__setattr__(self, "h_bar", h_bar)
        super().__post_init__()

    @property
    def fixed_delay(self) -> float | None:
        return self.h_bar

    def to_spec(self) -> dict[str, Any]:
        return {**super().to_spec(), "h_bar": self.h_bar}
