"""A seeded random delay with bounded value and bounded rate of change."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

import delaytrack.delays._kernel as _kernel
from delaytrack._compile.jit import kernel
from delaytrack._validation import ArgumentError, beyond_choice, positive_scalar
from delaytrack.delays.base import DelayProfile
from delaytrack.delays.knots import pack_knots

__all__ = ["MAX_KNOTS", "RandomDelay", "reflected_walk"]

#: Largest ``max_rate``: numpy draws slopes in ``[-max_rate, max_rate]`` only while that
#: interval's width is a finite double.
MAX_RATE = 1e300
#: Most knots of one walk: 10^7 knots take under half a GB and a tenth of a second to draw.
MAX_KNOTS = 1e7


#: Most knots drawn as plain Python while :func:`reflected_walk` is not compiled in this process:
#: about 0.3 s of Python, what compiling it would cost.
PYTHON_KNOTS = 10**6


@kernel
def reflected_walk(values: np.ndarray, steps: np.ndarray, low: float, high: float) -> None:
    """Fill ``values[1:]`` with the walk from ``values[0]`` reflected at ``low`` and ``high``:
    ``h_{i+1} = fold(h_i + steps_i)``, where ``fold`` reflects a value outside ``[low, high]``
    at the bounds as often as needed, in closed form (a narrow band would take many
    reflections): ``low + r`` if ``r <= w``, else ``low + 2w - r``, with ``w = high - low`` and
    ``r = (h - low) mod 2w``; every value is ``low`` when ``w = 0``. Compiled, for walks of
    millions of knots; plain Python gives the same numbers (the same operations on IEEE doubles).
    """
    width = high - low
    for i in range(steps.shape[0]):
        value = values[i] + steps[i]
        if width == 0.0:
            value = low
        elif not low <= value <= high:
            folded = (value - low) % (2.0 * width)
            value = low + (folded if folded <= width else 2.0 * width - folded)
        values[i + 1] = value


@dataclass(frozen=True, eq=False)
class RandomDelay(DelayProfile):
    """A piecewise-linear random walk in ``[h_low, h_high]`` with ``|dh/dt| <= max_rate``.

    Knots are ``knot_spacing`` seconds apart over ``[0, duration]``; the first value is uniform in
    ``[h_low, h_high]``, each slope uniform in ``[-max_rate, max_rate]``, and the walk is reflected
    at the bounds (a reflected segment has a smaller slope, so ``|dh/dt| <= max_rate`` holds).
    The walk covers ``[0, duration]`` (its :attr:`horizon`); a simulation that runs longer is
    refused, unless ``beyond = "hold"``, which holds the last value after ``duration``.
    The same ``seed`` gives the same profile. ``max_rate > 1`` is allowed: where the delay then
    grows faster than time passes (``dh/dt > 1``), ``t - h(t)`` runs backwards and older
    commands are re-applied, as the physics says; where it shrinks faster (``dh/dt < -1``),
    commands are skipped.
    """

    h_low: float
    h_high: float
    max_rate: float
    duration: float
    seed: int
    knot_spacing: float = 0.01
    beyond: str = "refuse"
    _params: np.ndarray = field(init=False, repr=False)
    type_name: ClassVar[str] = "random"

    def __post_init__(self) -> None:
        low = positive_scalar("h_low", self.h_low, strictly=False)
        high = positive_scalar("h_high", self.h_high, strictly=False)
        if high < low:
            raise ArgumentError(
                "h_high", f"must be >= h_low; got h_low = {low:g}, h_high = {high:g}"
            )
        rate = positive_scalar("max_rate", self.max_rate, strictly=False)
        if rate > MAX_RATE:
            raise ArgumentError(
                "max_rate",
                f"must be at most {MAX_RATE:g} (s of delay per s; a faster walk only bounces "
                f"between h_low and h_high); got {rate:g}",
            )
        duration = positive_scalar("duration", self.duration)
        spacing = positive_scalar("knot_spacing", self.knot_spacing)
        if (
            isinstance(self.seed, bool)
            or not isinstance(self.seed, int | np.integer)
            or self.seed < 0
        ):
            raise ArgumentError("seed", f"must be a non-negative integer; got {self.seed!r}")
        for name, value in (("h_low", low), ("h_high", high), ("max_rate", rate)):
            object.__setattr__(self, name, value)
        object.__setattr__(self, "duration", duration)
        object.__setattr__(self, "knot_spacing", spacing)
        object.__setattr__(self, "beyond", beyond_choice(self.beyond))
        if self.duration / spacing > MAX_KNOTS:
            raise ArgumentError(
                "duration",
                f"must be at most {MAX_KNOTS:g} knot spacings (one knot each, held in memory); "
                f"got duration = {self.duration:g} s with knot_spacing = {spacing:g} s",
            )
        times, values = self._walk()
        object.__setattr__(self, "_params", pack_knots(times, values))

    def _walk(self) -> tuple[np.ndarray, np.ndarray]:
        rng = np.random.default_rng(int(self.seed))
        count = int(np.ceil(self.duration / self.knot_spacing)) + 1
        times = np.arange(count) * self.knot_spacing
        steps = rng.uniform(-self.max_rate, self.max_rate, size=count - 1) * self.knot_spacing
        values = np.empty(count)
        values[0] = rng.uniform(self.h_low, self.h_high)
        walk = (
            reflected_walk
            if count > PYTHON_KNOTS or reflected_walk.signatures
            else reflected_walk.py_func
        )
        walk(values, steps, self.h_low, self.h_high)
        return times, values

    @property
    def times(self) -> np.ndarray:
        """The walk's knot times ``t_i`` (read-only), seconds: ``0, knot_spacing, ...``, the
        last at or after ``duration``. The same attribute as a trace's
        (:class:`~delaytrack.delays.TraceDelay`)."""
        return self._knots(0)

    @property
    def values(self) -> np.ndarray:
        """The walk's delays ``h_i`` at :attr:`times` (read-only), seconds; ``h`` is linear
        between knots."""
        return self._knots(1)

    def _knots(self, which: int) -> np.ndarray:
        count = int(self._params[0])
        view = self._params[1 + which * count : 1 + (which + 1) * count].view()
        view.flags.writeable = False
        return view

    @property
    def kind(self) -> int:
        return _kernel.PIECEWISE_LINEAR

    @property
    def params(self) -> np.ndarray:
        return self._params

    @property
    def h_max(self) -> float:
        return self.h_high

    @property
    def h_min(self) -> float:
        return self.h_low

    @property
    def horizon(self) -> float:
        return math.inf if self.beyond == "hold" else self.duration

    def to_spec(self) -> dict[str, Any]:
        return {
            "type": self.type_name,
            "h_low": self.h_low,
            "h_high": self.h_high,
            "max_rate": self.max_rate,
            "duration": self.duration,
            "seed": int(self.seed),
            "knot_spacing": self.knot_spacing,
            **({"beyond": self.beyond} if self.beyond != "refuse" else {}),
        }
