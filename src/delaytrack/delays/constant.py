"""A constant input delay (the paper's S3 and S4)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

import delaytrack.delays._kernel as _kernel
from delaytrack._validation import positive_scalar
from delaytrack.delays.base import DelayProfile

__all__ = ["ConstantDelay"]


@dataclass(frozen=True)
class ConstantDelay(DelayProfile):
    """``h(t) = h`` seconds, ``h >= 0``."""

    value: float
    type_name: ClassVar[str] = "constant"

    def __post_init__(self) -> None:
        object.__setattr__(self, "value", positive_scalar("value", self.value, strictly=False))

    @classmethod
    def S3(cls) -> ConstantDelay:
        """The paper's S3: ``h = 60 ms``."""
        return cls(0.060)

    @classmethod
    def S4(cls) -> ConstantDelay:
        """The paper's S4: ``h = 120 ms``."""
        return cls(0.120)

    @property
    def kind(self) -> int:
        return _kernel.CONSTANT

    @property
    def params(self) -> np.ndarray:
        return np.array([self.value])

    @property
    def h_max(self) -> float:
        return self.value

    @property
    def h_min(self) -> float:
        return self.value

    def to_spec(self) -> dict[str, Any]:
        return {"type": self.type_name, "h": self.value}
