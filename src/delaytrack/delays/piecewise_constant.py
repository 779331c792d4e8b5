"""A delay that jumps between constant values (for example a network that changes route)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from delaytrack.delays import _kernel
from delaytrack.delays.base import DelayProfile
from delaytrack.delays.knots import checked_knots, pack_knots

__all__ = ["PiecewiseConstantDelay"]


@dataclass(frozen=True, eq=False)
class PiecewiseConstantDelay(DelayProfile):
    """``h(t) = values[i]`` for ``times[i] <= t < times[i+1]``; ``values[0]`` before ``times[0]``.

    Parameters
    ----------
    times : array_like, shape (m,)
        Switching instants in seconds, strictly increasing.
    values : array_like, shape (m,)
        Delays in seconds, ``>= 0``.
    """

    times: np.ndarray
    values: np.ndarray
    _params: np.ndarray = field(init=False, repr=False)
    type_name: ClassVar[str] = "piecewise-constant"

    def __post_init__(self) -> None:
        times, values = checked_knots(self.times, self.values)
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "values", values)
        object.__setattr__(self, "_params", pack_knots(times, values))

    @property
    def kind(self) -> int:
        return _kernel.PIECEWISE_CONSTANT

    @property
    def params(self) -> np.ndarray:
        return self._params

    @property
    def h_max(self) -> float:
        return float(np.max(self.values))

    def to_spec(self) -> dict[str, Any]:
        return {
            "type": self.type_name,
            "times": self.times.tolist(),
            "values": self.values.tolist(),
        }
