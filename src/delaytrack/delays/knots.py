"""Delay profiles defined by knots ``(t_i, h_i)``: their validation and compiled packing."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from delaytrack._validation import ArgumentError, finite_array
from delaytrack.delays.base import DelayProfile

__all__ = ["KnotDelay", "checked_knots", "pack_knots"]


def checked_knots(times: object, values: object) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(times, values)`` as read-only float arrays after checking them.

    Times must be finite and strictly increasing; delays finite and ``>= 0``; both 1-D of the
    same length ``>= 1``.
    """
    t = finite_array("times", times, ndim=1)
    h = finite_array("values", values, ndim=1)
    if t.size == 0:
        raise ArgumentError("times", "must contain at least one knot; got none")
    if t.shape != h.shape:
        raise ArgumentError(
            "values", f"must have one entry per time; got {h.size} values for {t.size} times"
        )
    steps = np.diff(t)
    if np.any(steps <= 0.0):
        i = int(np.argmax(steps <= 0.0))
        raise ArgumentError(
            "times",
            f"must be strictly increasing; times[{i}] = {t[i]:g} is followed by "
            f"times[{i + 1}] = {t[i + 1]:g}",
        )
    if np.any(h < 0.0):
        i = int(np.argmax(h < 0.0))
        raise ArgumentError(
            "values", f"must be >= 0 (delays); values[{i}] = {h[i]:g} at t = {t[i]:g}"
        )
    t.flags.writeable = False
    h.flags.writeable = False
    return t, h


def pack_knots(times: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Compiled parameter vector ``[m, t_0 .. t_{m-1}, h_0 .. h_{m-1}]``."""
    return np.concatenate(([float(times.size)], times, values))


@dataclass(frozen=True, eq=False)
class KnotDelay(DelayProfile):
    """Base of the profiles given by knots; subclasses fix how ``h`` runs between them.

    Parameters
    ----------
    times : array_like, shape (m,)
        Seconds, strictly increasing.
    values : array_like, shape (m,)
        Delays in seconds, ``>= 0``.
    """

    times: np.ndarray
    values: np.ndarray
    _params: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        times, values = checked_knots(self.times, self.values)
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "values", values)
        object.__setattr__(self, "_params", pack_knots(times, values))

    @property
    def params(self) -> np.ndarray:
        return self._params

    @property
    def h_max(self) -> float:
        return float(np.max(self.values))

    @property
    def h_min(self) -> float:
        return float(np.min(self.values))

    def to_spec(self) -> dict[str, Any]:
        return {
            "type": self.type_name,
            "times": self.times.tolist(),
            "values": self.values.tolist(),
        }
