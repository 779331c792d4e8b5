"""The rectified-sine delay ``h(t) = offset + amplitude |sin(omega t + phase)|`` (S1, S2)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

import delaytrack.delays._kernel as _kernel
from delaytrack._validation import ArgumentError, check_phase, finite_scalar, positive_scalar
from delaytrack.delays.base import DelayProfile

__all__ = ["AbsSineDelay"]


@dataclass(frozen=True)
class AbsSineDelay(DelayProfile):
    """``h(t) = offset + amplitude |sin(frequency t + phase)|`` seconds.

    Parameters
    ----------
    offset, amplitude : float
        Seconds, both ``>= 0``.
    frequency : float
        Angular frequency in rad/s, ``> 0``.
    phase : float
        Radians.
    """

    offset: float
    amplitude: float
    frequency: float
    phase: float = 0.0
    type_name: ClassVar[str] = "abs-sine"

    def __post_init__(self) -> None:
        object.__setattr__(self, "offset", positive_scalar("offset", self.offset, strictly=False))
        object.__setattr__(
            self, "amplitude", positive_scalar("amplitude", self.amplitude, strictly=False)
        )
        object.__setattr__(self, "frequency", positive_scalar("frequency", self.frequency))
        object.__setattr__(self, "phase", finite_scalar("phase", self.phase))
        check_phase("phase", self.phase)
        if not math.isfinite(self.offset + self.amplitude):
            raise ArgumentError(
                "amplitude",
                f"+ offset must be a finite delay; got {self.amplitude:g} + {self.offset:g} s",
            )

    @classmethod
    def S1(cls) -> AbsSineDelay:
        """The paper's S1: ``h(t) = 20 + 80 |sin(t)|`` ms."""
        return cls(offset=0.020, amplitude=0.080, frequency=1.0)

    @classmethod
    def S2(cls) -> AbsSineDelay:
        """The paper's S2: ``h(t) = 5 + 120 |sin(0.1 t)|`` ms."""
        return cls(offset=0.005, amplitude=0.120, frequency=0.1)

    @property
    def kind(self) -> int:
        return _kernel.ABS_SINE

    @property
    def params(self) -> np.ndarray:
        return np.array([self.offset, self.amplitude, self.frequency, self.phase])

    @property
    def h_max(self) -> float:
        return self.offset + self.amplitude

    @property
    def h_min(self) -> float:
        return self.offset

    def to_spec(self) -> dict[str, Any]:
        return {
            "type": self.type_name,
            "offset": self.offset,
            "amplitude": self.amplitude,
            "frequency": self.frequency,
            "phase": self.phase,
        }
