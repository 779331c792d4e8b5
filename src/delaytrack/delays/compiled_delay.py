"""A delay profile of your own at compiled speed: ``h(t)`` written with ``numba.njit``."""

from __future__ import annotations

import weakref
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

import delaytrack.delays._kernel as _kernel
from delaytrack._compile.functions import is_compiled, qualified_name
from delaytrack._compile.stale_caches import compile_from_source
from delaytrack._validation import finite_array, positive_scalar
from delaytrack.components import Kernel
from delaytrack.delays.base import DelayProfile
from delaytrack.kernel_arguments import check_kernel_arguments

__all__ = ["CompiledDelay"]

#: The delay kernels compiled from their source in this process
#: (:meth:`CompiledDelay._from_source`), which a live controller's ``h`` asks at every tick. By
#: function, not by code: a module imported again, even with the code it had before an edit,
#: gives new functions, which numba's disk cache may serve the edited code.
_FROM_SOURCE: weakref.WeakSet = weakref.WeakSet()


@dataclass(frozen=True, eq=False)
class CompiledDelay(DelayProfile):
    """``h(t) = kernel(t, params)`` seconds, from a numba-compiled kernel of your own.

    Parameters
    ----------
    kernel : numba-compiled function
        ``kernel(t, params) -> h``, decorated with ``@numba.njit``. It is compiled into the
        simulator's loop like a built-in profile.
    parameters : array_like
        1-D float parameter vector passed to ``kernel`` as ``params`` (may be empty).
    h_max : float
        An upper bound of ``h(t)`` (seconds, finite, ``>= 0``): the simulator sizes the command
        history from it and refuses a run in which the kernel exceeds it.
    name : str
        Shown in results and reports.

    Notes
    -----
    The simulator evaluates ``h`` at the ends of every plant step and refuses, before running,
    a run in which one of these values is not a number in ``[0, h_max]`` (naming the time). The
    applied input switches where ``t - h(t)`` crosses a controller tick; the simulator finds
    each crossing between the ends of a step (regula falsi, to round-off) and splits the step
    there, so the integration keeps its order. It takes ``t - h(t)`` to be monotone between the
    ends of a step: true when ``h`` changes at a rate below one second per second, or jumps
    down. A rise of ``h`` faster than that, or a jump up, that takes ``t - h(t)`` back across a
    tick and forth again within one step (``dt``) is not resolved, so keep such events at
    least ``dt`` apart or give them as a :class:`PiecewiseConstantDelay` or
    :class:`TraceDelay`, whose breakpoints the simulator knows.

    Examples
    --------
    A delay that steps between two values with a smooth transition:

    >>> import math, numba
    >>> @numba.njit
    ... def smooth_step(t, params):
    ...     low, high, at, width = params[0], params[1], params[2], params[3]
    ...     return low + (high - low) * 0.5 * (1.0 + math.tanh((t - at) / width))
    >>> delay = CompiledDelay(smooth_step, [0.02, 0.08, 5.0, 0.5], h_max=0.08)
    >>> round(float(delay.h(5.0)), 3)
    0.05
    """

    kernel: Callable[..., float]
    parameters: np.ndarray = field(default_factory=lambda: np.zeros(0))
    h_max: float = 0.0
    name: str = "compiled"
    type_name: ClassVar[str] = "compiled"

    def __post_init__(self) -> None:
        if not is_compiled(self.kernel):
            raise TypeError(
                "kernel must be a numba-compiled function (decorate it with @numba.njit); got "
                f"{type(self.kernel).__name__}"
            )
        check_kernel_arguments("CompiledDelay", "delay", self.kernel)
        parameters = finite_array("parameters", self.parameters, ndim=1)
        object.__setattr__(self, "parameters", np.ascontiguousarray(parameters))
        object.__setattr__(self, "h_max", positive_scalar("h_max", self.h_max, strictly=False))
        if not isinstance(self.name, str):
            raise TypeError(f"name must be a string; got {self.name!r}")

    @property
    def kind(self) -> int:
        return _kernel.KERNEL

    @property
    def params(self) -> np.ndarray:
        return self.parameters

    @property
    def engine_kernel(self) -> Kernel:
        return Kernel.of(self.kernel)

    def switch_bound(self, t0: float, t1: float, T_c: float) -> float:
        """With ``t - h(t)`` monotone between step ends and ``0 <= h <= h_max``, it crosses at
        most ``(t1 - t0 + h_max) / T_c + 2`` ticks."""
        duration = t1 - t0
        return (duration + min(self.h_max, duration)) / T_c + 2.0

    def _from_source(self) -> None:
        """Before code is compiled for the kernel: the compiled functions it reaches compiled
        again from their source once in this process
        (:func:`~delaytrack._compile.stale_caches.compile_from_source`, as a simulation does),
        so that neither that code nor the engine's code compiled for the kernel's fingerprint
        (:func:`~delaytrack.delays._kernel.evaluate_profile`) takes an old version from numba's
        disk cache."""
        if self.kernel not in _FROM_SOURCE:
            compile_from_source([self.engine_kernel])
            _FROM_SOURCE.add(self.kernel)  # what it reaches is now this process's compiles

    def h(self, t: float | np.ndarray) -> np.ndarray:
        """Delay ``h(t)`` in seconds at the time(s) ``t`` (any shape), from the kernel's
        source as it is now."""
        self._from_source()
        return super().h(t)

    def check_run(self, t0: float, dt: float, steps: int) -> None:
        """Refuse a run whose step ends ``t0 + j dt`` (``j = 0 .. steps``) meet an ``h`` that is
        not a number in ``[0, h_max]``."""
        self._from_source()
        index, value = _kernel.first_invalid_step_end(
            self.engine_kernel, self.params, float(t0), float(dt), int(steps), self.h_max
        )
        if index >= 0:
            raise ValueError(
                f"CompiledDelay {self.name!r}: its kernel {qualified_name(self.kernel)} gives "
                f"h = {value:g} s at "
                f"t = {t0 + index * dt:.9g} s; it must be a number from 0 to h_max = "
                f"{self.h_max:g} s at every step of the run (raise h_max if the bound is wrong)"
            )

    def to_spec(self) -> dict[str, Any]:
        return {"type": self.type_name, "name": self.name, "h_max": self.h_max}
