"""The reference interface: a desired trajectory ``q_d(t)`` with ``q̇_d(t)`` and ``q̈_d(t)``.

A reference is defined by a kernel ``reference(t, params, qd, qd_dot, qd_ddot)`` that fills the
three arrays (n,) at time ``t`` from its parameter vector. The controller reads them at every
tick (the paper's ``q^d``, ``q̇^d``, ``q̈^d`` in eq. (aux)); the simulator calls the kernel through
:func:`delaytrack.components.call_reference`, compiled when the kernel is ``numba.njit``-compiled.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import Any

import numpy as np

from delaytrack._compile.functions import at_few_points
from delaytrack.components import Kernel

__all__ = ["Reference", "by_time"]


class Reference(ABC):
    """A desired trajectory for ``n`` coordinates.

    Subclasses provide :attr:`n`, :attr:`params`, :attr:`reference_kernel` and :meth:`to_spec`.
    """

    @property
    @abstractmethod
    def n(self) -> int:
        """Number of coordinates."""

    @property
    @abstractmethod
    def params(self) -> np.ndarray:
        """Parameter vector passed to the kernel (float64, 1-D)."""

    @property
    @abstractmethod
    def reference_kernel(self) -> Callable[..., None]:
        """``reference(t, params, qd, qd_dot, qd_ddot)``: fill ``q_d, q̇_d, q̈_d`` (n,) at ``t``."""

    @abstractmethod
    def to_spec(self) -> dict[str, Any]:
        """Plain-data description (type name and parameters) for scenario files and reports."""

    @property
    def start(self) -> float:
        """First time (s) at which the reference is defined (``-inf``: always)."""
        return -math.inf

    @property
    def horizon(self) -> float:
        """Last time (s) up to which the reference is defined (``inf``: always); a longer run
        is refused."""
        return math.inf

    @property
    def engine_kernel(self) -> Kernel:
        """The :class:`~delaytrack.components.Kernel` the simulator calls."""
        return Kernel.of(self.reference_kernel)

    @property
    def compiled(self) -> bool:
        """Whether the kernel is numba-compiled (else the simulator runs as Python)."""
        return self.engine_kernel.compiled

    def evaluate(self, t: float | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``q_d, q̇_d, q̈_d`` at times ``t``, each of shape ``(*t.shape, n)``. One of the
        package's kernels runs as plain Python at a few times while its compiled code is not in
        the process (:func:`~delaytrack._compile.functions.at_few_points`): the same numbers,
        without a compile."""
        times = np.asarray(t, dtype=float)
        params, n = self.params, self.n
        function, _ = self.compiled_values(times.ravel())

        def each_time(kernel: Callable[..., None]) -> np.ndarray:
            out = np.empty((3, times.size, n))
            for i, time in enumerate(times.ravel()):
                kernel(float(time), params, out[0, i], out[1, i], out[2, i])
            return out

        return by_time(at_few_points(function, times.size, each_time), times.shape)

    def compiled_values(self, times: np.ndarray) -> tuple[Any, tuple]:
        """The compiled function :meth:`evaluate` calls for its values at ``times`` (1-D) and
        arguments of the types it passes: the reference's kernel, once a time (a time and
        three rows of its output). Named so that a job can have it compiled ahead
        (:func:`~delaytrack.sim.compile_ahead`)."""
        return self.reference_kernel, (0.0, self.params, *np.empty((3, self.n)))


def by_time(out: np.ndarray, shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``q_d, q̇_d, q̈_d`` from ``out (3, points, n)`` at times of ``shape``: each
    ``(*shape, n)``."""
    return tuple(out[j].reshape(*shape, out.shape[2]) for j in range(3))
