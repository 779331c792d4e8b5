"""A controller's step for a real-time loop: checked once, then one tick per call.

A tick of a sampled-data law at ``t_k = k T_c`` computes the actuator command and the next state
of the law from the measured state and the reference at ``t_k``,

    command_k, state_{k+1} = step(t_k, q_k, q̇_k, q_d(t_k), q̇_d(t_k), q̈_d(t_k), T_c, h(t_k),
                                  state_k)

(for AROLC: ``τ = M̂(q) u + N̂(q, q̇)`` with ``u = û + Δu``, paper eqs. (input), (control input),
and ĉ advanced by the adaptive law (ATRC); see :mod:`delaytrack.controllers.arolc`).
A :class:`ControllerStepper`, made by
:meth:`Controller.stepper <delaytrack.controllers.base.Controller.stepper>`, checks what can be
checked once when it is made: the period with the law's ``check_run``; the arrays of the step
(the inputs, state, command and scratch memory) are its own, and the step's compiled code is
called through its entry point for these arrays (:func:`entry_point`), without numba's type
dispatch. A tick then only checks the delay ``h`` (and, called with arrays, copies them into its
own). :meth:`Controller.step <delaytrack.controllers.base.Controller.step>` keeps such a
stepper and copies the state in and out at each call.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from delaytrack._validation import positive_scalar

__all__ = ["ControllerStepper", "checked_vector", "entry_point"]

#: Names of the step's inputs, in the order of its arguments (for messages).
INPUT_NAMES = ("q", "qdot", "qd", "qd_dot", "qd_ddot")

#: A vector given to a stepper: an array, or a sequence of numbers.
Vector = np.ndarray | Sequence[float]


def checked_vector(name: str, value: Vector, size: int) -> np.ndarray:
    """``value`` as a float64 array of shape ``(size,)`` (``value`` itself when it is one), or
    a ValueError naming ``name``."""
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(
            f"{name} must be a vector of {size} numbers; got {type(value).__name__} {value!r:.60}"
        ) from None
    if array.shape != (size,):
        raise ValueError(f"{name} must have shape ({size},); got {array.shape}")
    return array


def entry_point(function: Callable[..., Any], arguments: Sequence[Any]) -> Callable[..., Any]:
    """The compiled code of ``function`` for the types of ``arguments``, callable without
    numba's type dispatch, or ``function`` itself (plain Python, or arguments numba cannot
    type).

    The entry point does not check its arguments' types: call it only with arguments of the
    same types (the same arrays, say). Compiled here if numba has not compiled (or loaded from
    its disk cache) ``function`` for these types yet.
    """
    typeof = getattr(function, "typeof_pyval", None)
    overloads = getattr(function, "overloads", None)
    compile_for = getattr(function, "compile", None)
    if typeof is None or overloads is None or compile_for is None:
        return function
    try:
        signature = tuple(typeof(argument) for argument in arguments)
    except Exception:  # noqa: BLE001 - an argument numba cannot type: keep the dispatcher
        return function
    found = overloads.get(signature)
    if found is not None:
        return found.entry_point
    if not getattr(function, "_can_compile", True):  # explicit signatures only: dispatch
        return function
    return compile_for(signature)


def _copy_checked(name: str, value: Vector, own: np.ndarray) -> None:
    """Copy ``value`` into the vector ``own``, or refuse it naming ``name``
    (:func:`checked_vector`)."""
    try:
        if len(value) == own.shape[0]:
            own[...] = value  # faster than own[:] = value
            return
    except (TypeError, ValueError):
        pass
    own[...] = checked_vector(name, value, own.shape[0])


def _read_only(array: np.ndarray) -> np.ndarray:
    """A read-only view of ``array``: it shows the array's values as they change."""
    view = array.view()
    view.flags.writeable = False
    return view


class ControllerStepper:
    """A controller's step with its own arrays, for one tick per call in a real-time loop.

    Made by :meth:`Controller.stepper <delaytrack.controllers.base.Controller.stepper>`, which
    has checked ``T_c`` and the delays up to :attr:`h_max` with the law's ``check_run``. Each
    tick computes ``command_k, state_{k+1} = step(t_k, q_k, q̇_k, q_d, q̇_d, q̈_d, T_c, h_k,
    state_k)`` (module docstring) with the same kernel, model and parameters as the simulator,
    so its commands and states are bit for bit those of
    :meth:`Controller.step <delaytrack.controllers.base.Controller.step>` and of
    :func:`delaytrack.sim.simulate`.

    Parameters
    ----------
    step : callable
        The step kernel (compiled, or its Python function).
    arguments : tuple
        Its fourteen arguments as :meth:`Controller.step_arguments
        <delaytrack.controllers.base.Controller.step_arguments>` makes them; the stepper owns
        their arrays from now on (``t`` and ``h`` are given at each tick).
    check_run : callable
        The law's ``check_run(T_c, h_max)``, called when a tick brings a delay above
        :attr:`h_max`.
    h_max : float
        The largest delay ``check_run`` has accepted at ``T_c``.
    needs_delay : bool
        Whether the law reads the true delay (then every tick needs ``h``).
    law : str
        The law's name, for messages.
    """

    def __init__(
        self,
        step: Callable[..., None],
        arguments: tuple,
        *,
        check_run: Callable[[float, float], None],
        h_max: float,
        needs_delay: bool,
        law: str,
    ) -> None:
        _, *inputs, T_c, _, _, state, _, _, command, _ = arguments
        self._inputs = tuple(inputs)
        self._size = len(inputs[0])
        # The step's arguments; a tick sets t (first) and h (eighth) in place.
        self._arguments = list(arguments)
        self._state = state
        self._initial_state = state.copy()
        self._state_view = _read_only(state)
        self._command_view = _read_only(command)
        self._check_run = check_run
        self._h_max = h_max
        self._needs_delay = needs_delay
        self._law = law
        self._T_c = T_c
        self._step = entry_point(step, arguments)

    @property
    def T_c(self) -> float:
        """The sampling period (s) the stepper runs at."""
        return self._T_c

    @property
    def h_max(self) -> float:
        """The largest delay (s) the law's ``check_run`` has accepted for this stepper: at its
        making, or at a tick that brought a larger one."""
        return self._h_max

    @property
    def inputs(self) -> tuple[np.ndarray, ...]:
        """The stepper's own input arrays ``(q, q̇, q_d, q̇_d, q̈_d)``, each (n,): write the
        measured state and the reference into them, then call :meth:`tick` (no copy)."""
        return self._inputs

    @property
    def state(self) -> np.ndarray:
        """The law's state for the next tick (a read-only view: each tick advances it)."""
        return self._state_view

    def reset(self, state: Vector | None = None) -> None:
        """Start again from ``state`` (copied), or from the law's initial state."""
        if state is None:
            self._state[...] = self._initial_state
        else:
            _copy_checked("state", state, self._state)

    def __call__(
        self,
        t: float,
        q: Vector,
        qdot: Vector,
        reference: tuple[Vector, Vector, Vector],
        h: float | None = None,
    ) -> np.ndarray:
        """One tick at ``t`` from the measured ``q, q̇`` and the reference ``(q_d, q̇_d, q̈_d)``
        at ``t`` (each copied into :attr:`inputs`): the command (m,), a read-only view that the
        next tick overwrites (:meth:`tick`).

        ``h`` is the true delay (s), required by laws that read it.
        """
        return self._tick_from(None, t, q, qdot, reference, h)

    def _step_from(
        self,
        state: Vector,
        t: float,
        q: Vector,
        qdot: Vector,
        reference: tuple[Vector, Vector, Vector],
        h: float | None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`reset` to ``state``, then one tick (:meth:`__call__`): new arrays ``(command
        (m,), next state)``, what :meth:`Controller.step
        <delaytrack.controllers.base.Controller.step>` returns."""
        command = self._tick_from(state, t, q, qdot, reference, h)
        return command.copy(), self._state.copy()

    def _tick_from(
        self,
        state: Vector | None,
        t: float,
        q: Vector,
        qdot: Vector,
        reference: tuple[Vector, Vector, Vector],
        h: float | None,
    ) -> np.ndarray:
        """One tick (:meth:`__call__`), from ``state`` (copied in) unless it is None.

        Written out in one function, as :meth:`tick` is: in a loop at a kilohertz, every call
        and every loop over the vectors is a tenth of a microsecond.
        """
        if not (isinstance(h, float) and 0.0 <= h <= self._h_max):  # else checked before
            h = self._delay(h)
        qd, qd_dot, qd_ddot = reference
        size = self._size
        own_q, own_qdot, own_qd, own_qd_dot, own_qd_ddot = self._inputs
        own_state = self._state
        try:
            copied = len(q) == len(qdot) == len(qd) == len(qd_dot) == len(qd_ddot) == size and (
                state is None or len(state) == own_state.shape[0]
            )
            if copied:
                own_q[...] = q  # faster than own_q[:] = q
                own_qdot[...] = qdot
                own_qd[...] = qd
                own_qd_dot[...] = qd_dot
                own_qd_ddot[...] = qd_ddot
                if state is not None:
                    own_state[...] = state
        except (TypeError, ValueError):
            copied = False
        if not copied:  # one by one, refusing the first that is not a vector of n numbers
            if state is not None:
                _copy_checked("state", state, own_state)
            for name, value, own in zip(
                INPUT_NAMES, (q, qdot, qd, qd_dot, qd_ddot), self._inputs, strict=True
            ):
                _copy_checked(name, value, own)
        arguments = self._arguments
        arguments[0] = float(t)
        arguments[7] = h
        self._step(*arguments)
        return self._command_view

    def tick(self, t: float, h: float | None = None) -> np.ndarray:
        """One tick at ``t`` from the values in :attr:`inputs`: the command (m,).

        The command is a read-only view of the stepper's own array, which the next tick
        overwrites: copy it (``command.copy()``) to keep it. ``h`` is the true delay (s),
        required by laws that read it.
        """
        if not (isinstance(h, float) and 0.0 <= h <= self._h_max):  # else checked before
            h = self._delay(h)
        arguments = self._arguments
        arguments[0] = float(t)
        arguments[7] = h
        self._step(*arguments)
        return self._command_view

    def _delay(self, h: float | None) -> float:
        """``h`` checked: a non-negative number, refused by the law's ``check_run`` only when
        larger than any it has accepted before (``0.0`` for None if the law does not read it)."""
        if h is None:
            if self._needs_delay:
                raise ValueError(f"{self._law} needs the true delay: pass h=... (seconds)")
            return 0.0
        if isinstance(h, float) and 0.0 <= h <= self._h_max:
            return h
        delay = positive_scalar("h", h, strictly=False)
        if delay > self._h_max:
            self._check_run(self._T_c, delay)
            self._h_max = delay
        return delay
