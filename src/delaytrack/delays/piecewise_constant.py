"""A delay that jumps between constant values (for example a network that changes route)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import delaytrack.delays._kernel as _kernel
from delaytrack.delays.knots import KnotDelay

__all__ = ["PiecewiseConstantDelay"]


@dataclass(frozen=True, eq=False)
class PiecewiseConstantDelay(KnotDelay):
    """``h(t) = values[i]`` for ``times[i] <= t < times[i+1]``; ``values[0]`` before ``times[0]``.

    Parameters
    ----------
    times : array_like, shape (m,)
        Switching instants in seconds, strictly increasing.
    values : array_like, shape (m,)
        Delays in seconds, ``>= 0``.
    """

    type_name: ClassVar[str] = "piecewise-constant"

    @property
    def kind(self) -> int:
        return _kernel.PIECEWISE_CONSTANT
