"""The controller interface: frozen parameters, explicit state, one compiled step.

A controller is sampled at ``T_c``. Its kernel

    step(t, q, qdot, qd, qd_dot, qd_ddot, T_c, h, params, state, model_terms, model_params,
         command, work)

reads the measured ``q, q̇`` and the reference ``q_d, q̇_d, q̈_d`` at the tick ``t``, writes the
actuator ``command`` (m,) and advances ``state`` in place to the next tick. ``model_terms`` is
the terms kernel of the nominal plant (``M̂, N̂, Ĝ``; see :mod:`delaytrack.plants.base`).
``work`` is scratch memory of :func:`step_workspace` (its contents on entry do not matter), so
that a tick allocates nothing: the simulator makes it once per run.

``h`` is the true delay ``h(t)``. AROLC and the outer loop never read it (they do not know the
delay); the predictor baselines need it by assumption (:attr:`Controller.needs_delay`).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import Any, ClassVar

import numpy as np
from numba.extending import overload

from delaytrack._compile.functions import is_compiled
from delaytrack._compile.jit import hot_inline_kernel, inline_kernel
from delaytrack._compile.stack_arrays import stack_terms, stack_vector
from delaytrack._validation import positive_scalar
from delaytrack.components import (
    Kernel,
    call_command_map,
    call_terms,
    plant_sizes,
    sizes_on_stack,
)
from delaytrack.controllers.stepper import INPUT_NAMES, ControllerStepper, checked_vector
from delaytrack.plants.base import ELPlant

__all__ = [
    "Controller",
    "auxiliary_input",
    "computed_torque_command",
    "step_memory",
    "step_workspace",
    "terms_views",
    "tracking_errors",
]


@inline_kernel
def step_workspace(n, m):
    """Scratch memory of a step kernel for ``n`` coordinates and ``m`` inputs.

    ``(M̂ (n, n), N̂ (n,), Ĝ (n, m), rest (4 n,))``: the nominal model's terms, then the law's
    vectors (:func:`terms_views`). Separate arrays rather than views of one: reshaping a view
    compiles numba's shape-error path into every step (about 2 s of a first compile). Zeroed
    (once a run): an entry a kernel leaves unwritten holds the same number in every run.
    """
    return np.zeros((n, n)), np.zeros(n), np.zeros((n, m)), np.zeros(4 * n)


@hot_inline_kernel
def terms_views(work, n, m):
    """``(M̂ (n, n), N̂ (n,), Ĝ (n, m), rest (4 n,))`` of a :func:`step_workspace` ``work``."""
    return work


@hot_inline_kernel
def tracking_errors(q, qdot, qd, qd_dot, error, n=None):
    """``e = [e1; ė1]`` with ``e1 = q_d - q`` (the paper's tracking error) into ``error`` (2n,).
    ``n`` (by default ``q``'s length) known when compiled unrolls the loop."""
    n = q.shape[0] if n is None else n
    for i in range(n):
        error[i] = qd[i] - q[i]
        error[n + i] = qd_dot[i] - qdot[i]


@hot_inline_kernel
def auxiliary_input(params, error, qd_ddot, u, n=None):
    """``û = q̈_d + K2 ė1 + K1 e1`` (paper eq. (aux)) into ``u`` (n,); ``params`` starts with K1,
    K2 (row-major). ``n`` (by default ``q̈_d``'s length) known when compiled unrolls the loops."""
    n = qd_ddot.shape[0] if n is None else n
    for i in range(n):
        damping = 0.0
        stiffness = 0.0
        for j in range(n):
            damping += params[n * n + i * n + j] * error[n + j]
            stiffness += params[i * n + j] * error[j]
        u[i] = qd_ddot[i] + damping + stiffness


def step_memory(model_terms, work):
    """The working memory of a step on the nominal model ``model_terms``: ``(M̂ (n, n), N̂ (n,),
    Ĝ (n, m), rest (4 n,))``, those of ``work`` (:func:`terms_views`), to be passed on to
    :func:`computed_torque_command` in place of ``work``.

    Compiled, for a model whose sizes ``(n, m)`` are known when compiling, arrays on the stack
    of the compiled step instead (:mod:`delaytrack._compile.stack_arrays`), zeroed at each call
    (a call inside a loop reuses the same memory): memory the compiler sees whole, whose entries
    it keeps in registers and which no other array can alias. An entry a kernel leaves
    unwritten is zero, as in the zeroed ``work``; a model kernel that writes every entry, as
    :class:`~delaytrack.plants.CompiledPlant`'s start-up check asks, sees no difference.
    Nothing written there outlasts the step: call it once a step, and keep in ``state`` what
    the next tick reads.
    """
    return work


@overload(step_memory, inline="always")
def _step_memory_compiled(model_terms, work):
    sizes = sizes_on_stack(model_terms, lambda n, m: n * n + n + n * m + 4 * n)
    if sizes is None:
        return lambda model_terms, work: work
    n, m = sizes
    width = 4 * n

    def on_stack(model_terms, work):
        mass, nonlinear, input_map = stack_terms(n, m)
        rest = stack_vector(width)
        for i in range(width):
            rest[i] = 0.0
        return mass, nonlinear, input_map, rest

    return on_stack


@hot_inline_kernel
def computed_torque_command(model_terms, model_params, t, q, qdot, u, command, work):
    """Actuator command realising ``τ = M̂(q) u + N̂(q, q̇)`` (paper eq. (input)).

    ``τ`` is mapped to the actuators by the model's command map
    (:func:`delaytrack.components.call_command_map`): ``Ĝ(q)⁻¹ τ`` for a fully actuated
    model, ``S(q)ᵀ τ`` for the wheeled robot. The model's terms go to the front of ``work``
    (:func:`terms_views`; a step may pass its :func:`step_memory` instead); ``u`` must not lie
    there. Afterwards ``N̂`` holds ``τ`` and ``Ĝ`` may hold its LU factors (the default command
    map factorises it in place): read neither again.
    """
    n, m = plant_sizes(model_terms, q, command)
    mass, nonlinear, input_map, _ = terms_views(work, n, m)
    call_terms(model_terms, t, q, qdot, model_params, mass, nonlinear, input_map)
    finite = True
    for i in range(n):
        total = 0.0
        for j in range(n):
            total += mass[i, j] * u[j]
        nonlinear[i] += total  # τ, in place of N̂
        finite = finite and math.isfinite(nonlinear[i])
        for j in range(m):
            finite = finite and math.isfinite(input_map[i, j])
    if not finite:
        command[:] = np.nan  # the simulator stops the run as diverged
        return
    call_command_map(model_terms, q, model_params, input_map, nonlinear, command)


#: Largest accepted condition number of the nominal input map at q = 0.
_MAX_INPUT_MAP_CONDITION = 1e12

#: Where :meth:`Controller.step` keeps the stepper of its last call (left out of pickles).
_STEP_STEPPER = "_step_stepper"


class Controller(ABC):
    """A sampled-data tracking controller for an ``n``-coordinate Euler–Lagrange plant.

    Attributes
    ----------
    model : ELPlant
        The nominal plant ``M̂, N̂, Ĝ`` the controller believes in.
    """

    model: ELPlant
    #: Name used in scenario files and result tables.
    type_name: ClassVar[str]
    #: Whether the law reads the true delay ``h(t)`` (the predictor baselines do; AROLC does not).
    needs_delay: ClassVar[bool] = False

    @property
    def n(self) -> int:
        return self.model.n

    @property
    def m(self) -> int:
        return self.model.m

    @property
    @abstractmethod
    def params(self) -> np.ndarray:
        """Parameter vector of the step kernel (float64, 1-D)."""

    @property
    @abstractmethod
    def step_kernel(self) -> Callable[..., None]:
        """The compiled step (:mod:`delaytrack.controllers.base` states its signature)."""

    @property
    @abstractmethod
    def state_names(self) -> tuple[str, ...]:
        """Names of the leading state entries that the simulator records (may be empty)."""

    @property
    def reported_state_names(self) -> tuple[str, ...]:
        """The recorded state entries worth a column in result files (``SimResult.to_frame``);
        all of :attr:`state_names` unless a controller keeps bookkeeping there."""
        return self.state_names

    @abstractmethod
    def initial_state(self) -> np.ndarray:
        """State at the first tick."""

    @abstractmethod
    def to_spec(self) -> dict[str, Any]:
        """Plain-data description: ``{"type": ..., gains...}``."""

    @property
    def state_size(self) -> int:
        """Length of the whole state vector; the entries past ``state_names`` (for example a
        history buffer) are working memory and are not recorded."""
        return len(self.state_names)

    @property
    def engine_kernel(self) -> Kernel:
        """The :class:`~delaytrack.components.Kernel` the simulator calls for this law."""
        return Kernel.of(self.step_kernel)

    @property
    def compiled(self) -> bool:
        """Whether the step runs compiled: the step and the nominal model's kernel both are."""
        return is_compiled(self.step_kernel) and self.model.compiled

    @property
    def step_callable(self) -> Callable[..., None]:
        """The step as a Python callable: compiled, or plain Python for a Python nominal model."""
        return (
            self.step_kernel
            if self.compiled
            else getattr(self.step_kernel, "py_func", self.step_kernel)
        )

    def step(
        self,
        t: float,
        q: np.ndarray,
        qdot: np.ndarray,
        reference: tuple[np.ndarray, np.ndarray, np.ndarray],
        state: np.ndarray,
        *,
        T_c: float,
        h: float | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """One controller tick for real-time use: ``(command (m,), next state)``.

        ``reference`` is ``(q_d, q̇_d, q̈_d)`` at ``t``; ``state`` is not modified. ``h`` is the
        true delay, required only by controllers with :attr:`needs_delay`.

        Every argument is checked at every call; the arrays and the compiled code of the last
        call's period are used again (a :class:`~delaytrack.controllers.stepper.ControllerStepper`
        kept by the controller). A loop of your own that keeps the state can call a
        :meth:`stepper` instead, which neither copies the state nor makes new arrays.

        The values are used as given: a NaN in a measurement gives a NaN command (checking
        every value would more than double the time of a call).
        """
        kept = getattr(self, "__dict__", {})
        stepper = kept.pop(_STEP_STEPPER, None)  # a call on another thread makes its own
        if stepper is None or not (isinstance(T_c, float) and T_c == stepper.T_c):
            sample = positive_scalar("T_c", T_c)
            if stepper is None or sample != stepper.T_c:
                stepper = self.stepper(T_c=sample)
        try:
            return stepper._step_from(state, t, q, qdot, reference, h)
        finally:
            kept[_STEP_STEPPER] = stepper

    def stepper(
        self, *, T_c: float, h_max: float | None = None, state: np.ndarray | None = None
    ) -> ControllerStepper:
        """This law's step at period ``T_c`` for a real-time loop of your own.

        The arguments are checked here once (``T_c`` and ``h_max`` with :meth:`check_run`);
        the stepper owns the step's arrays, calls its compiled code without numba's type
        dispatch and keeps the state from tick to tick (see
        :class:`~delaytrack.controllers.stepper.ControllerStepper`).

        Parameters
        ----------
        T_c : float
            Sampling period (s).
        h_max : float, optional
            The largest true delay (s) the loop will pass (0 by default); a tick with a larger
            one is checked with :meth:`check_run` when it comes.
        state : array_like, optional
            The state at the first tick; :meth:`initial_state` by default.
        """
        delay = 0.0 if h_max is None else positive_scalar("h_max", h_max, strictly=False)
        # Arrays of the stepper's own: step_arguments keeps these (already float64 and
        # contiguous) and copies the state.
        q, qdot, qd, qd_dot, qd_ddot = (np.zeros(self.n) for _ in INPUT_NAMES)
        arguments = self.step_arguments(
            0.0,
            q,
            qdot,
            (qd, qd_dot, qd_ddot),
            self.initial_state() if state is None else state,
            T_c=T_c,
            h=delay,
        )
        return ControllerStepper(
            self.step_callable,
            arguments,
            check_run=self.check_run,
            h_max=delay,
            needs_delay=self.needs_delay,
            law=type(self).__name__,
        )

    def step_arguments(
        self,
        t: float,
        q: np.ndarray,
        qdot: np.ndarray,
        reference: tuple[np.ndarray, np.ndarray, np.ndarray],
        state: np.ndarray,
        *,
        T_c: float,
        h: float | None = None,
    ) -> tuple:
        """The arguments of one call of the step kernel (checked, and of the sizes the
        simulator passes: a copy of ``state``, a new ``command`` and ``work``)."""
        sample = positive_scalar("T_c", T_c)
        if h is None and self.needs_delay:
            raise ValueError(f"{type(self).__name__} needs the true delay: pass h=... (seconds)")
        delay = 0.0 if h is None else positive_scalar("h", h, strictly=False)
        self.check_run(sample, delay)
        arrays = [
            np.ascontiguousarray(checked_vector(name, value, self.n))
            for name, value in zip(INPUT_NAMES, (q, qdot, *reference), strict=True)
        ]
        next_state = np.array(checked_vector("state", state, self.state_size))
        model = self.model.engine_kernel
        return (
            float(t),
            *arrays,
            sample,
            delay,
            self.params,
            next_state,
            model if self.compiled else model.as_python(),
            self.model.params,
            np.empty(self.m),
            step_workspace(self.n, self.m),
        )

    def __getstate__(self) -> object:
        """The pickled state, without the stepper :meth:`step` keeps (compiled code)."""
        state = super().__getstate__()
        if isinstance(state, dict) and _STEP_STEPPER in state:
            state = {key: value for key, value in state.items() if key != _STEP_STEPPER}
        return state

    def check_run(self, T_c: float, h_max: float) -> None:
        """Raise if the law cannot run at period ``T_c`` under delays up to ``h_max`` seconds.

        :func:`delaytrack.sim.simulate` calls it for every run, :meth:`stepper` for every
        stepper, and a stepper (so :meth:`step` too) at a tick whose delay is larger than any
        accepted before: accepting ``h_max`` accepts every smaller delay. Most laws accept
        anything.
        """
        return  # AROLC and the outer loop run at any period under any delay.

    def _check_model(self) -> None:
        if not isinstance(self.model, ELPlant):
            raise TypeError(
                f"model must be an ELPlant (the nominal plant); got {type(self.model).__name__}"
            )
        if self.model.stepper_kernel is not None:
            raise ValueError(
                f"{type(self).__name__}'s nominal model must be a plant form M q'' + N = G u; "
                f"{type(self.model).__name__} is stepped by an integrator of its own (a MuJoCo "
                "model with stepping='mujoco' is for the simulated plant only)"
            )
        if self.model.has_command_map:
            return
        if self.model.m != self.model.n:
            raise ValueError(
                f"{type(self).__name__} needs a fully actuated nominal model (m == n) or one "
                f"with its own command map; got n = {self.model.n}, m = {self.model.m}"
            )
        condition = np.linalg.cond(self.model.input_map(np.zeros(self.model.n))[0])
        if not condition < _MAX_INPUT_MAP_CONDITION:
            raise ValueError(
                f"{type(self).__name__} needs an invertible nominal input map G(q) to turn tau "
                f"into actuator commands; at q = 0 its condition number is {condition:.3g}"
            )
