"""The delay-profile interface: ``h(t)`` with a known upper bound ``h_max``."""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from typing import Any, ClassVar

import numpy as np

import delaytrack.delays._kernel as _kernel
from delaytrack._compile.functions import at_few_points
from delaytrack.components import Kernel

__all__ = ["DelayProfile"]


class DelayProfile(ABC):
    """An input delay ``h(t) >= 0`` in seconds, known to the simulator and never to AROLC.

    Subclasses are frozen dataclasses. Each states ``h_max``, an upper bound used to size the
    simulator's command history, and reduces to a compiled ``(kind, params)`` pair (see
    :mod:`delaytrack.delays._kernel`), which is the single definition of ``h(t)``.
    """

    #: Name used in scenario files (``[delay] type = ...``).
    type_name: ClassVar[str]

    @property
    @abstractmethod
    def kind(self) -> int:
        """Compiled profile family (a constant of :mod:`delaytrack.delays._kernel`)."""

    @property
    @abstractmethod
    def params(self) -> np.ndarray:
        """Compiled parameter vector, float64, 1-D."""

    @property
    def engine_kernel(self) -> Kernel:
        """The delay :class:`~delaytrack.components.Kernel` the simulator calls for this
        profile: none for the built-in kinds (:data:`~delaytrack.delays._kernel.NO_KERNEL`)."""
        return _kernel.NO_KERNEL

    @property
    @abstractmethod
    def h_max(self) -> float:
        """Upper bound of ``h(t)`` over all ``t`` (seconds)."""

    @property
    def h_min(self) -> float:
        """A lower bound of ``h(t)`` over all ``t`` (seconds): 0 unless the profile knows a
        larger one. A run no longer than it delivers no command to the plant."""
        return 0.0

    @property
    def start(self) -> float:
        """First time (s) from which the profile's data define ``h`` (``-inf``: always).

        A measured trace starts at its first sample; :func:`~delaytrack.sim.simulate` refuses a
        run that starts before it (never extends the data silently).
        """
        return -math.inf

    @property
    def horizon(self) -> float:
        """Last time (s) up to which the profile's data define ``h`` (``inf``: always).

        A measured trace or a seeded random walk covers a finite time; after it ``h`` would
        only hold the last value. :func:`~delaytrack.sim.simulate` refuses a run beyond the
        horizon unless the profile was built with ``beyond = "hold"``.
        """
        return math.inf

    def check_run(self, t0: float, dt: float, steps: int) -> None:  # noqa: B027 - a default
        """Refuse a run of ``steps`` plant steps of ``dt`` from ``t0`` that this profile cannot
        serve (a kernel of the user's out of ``[0, h_max]``); the built-in profiles are checked
        when they are made."""

    def switch_bound(self, t0: float, t1: float, T_c: float) -> float:
        """Upper bound on the command switches in a run over ``[t0, t1]``
        (:func:`~delaytrack.delays._kernel.switch_bound`); the simulator refuses a profile that
        would split steps without end."""
        return _kernel.switch_bound(self.kind, self.params, t0, t1, T_c)

    @abstractmethod
    def to_spec(self) -> dict[str, Any]:
        """Plain-data description, the inverse of :func:`delaytrack.delays.delay_from_spec`."""

    def h(self, t: float | np.ndarray) -> np.ndarray:
        """Delay ``h(t)`` in seconds at the time(s) ``t`` (any shape)."""
        times = np.asarray(t, dtype=float)
        # contiguous and writable, as compile_ahead compiles it
        flat = np.require(times.ravel(), requirements=("C", "W"))
        function, arguments = self.compiled_values(flat)
        # a few points as Python while the profile's code is not compiled
        values = at_few_points(function, times.size, lambda values_at: values_at(*arguments))
        return values.reshape(times.shape)

    def compiled_values(self, times: np.ndarray) -> tuple[Any, tuple]:
        """The compiled function :meth:`h` calls for its values at ``times`` (1-D, contiguous)
        and its arguments: :func:`~delaytrack.delays._kernel.profile_values`. Named so that
        a job can have it compiled ahead (:func:`~delaytrack.sim.compile_ahead`)."""
        return _kernel.profile_values, (self.engine_kernel, self.kind, self.params, times)
