"""A delay profile of its own: a network link with periodic congestion bursts.

The delay rests at ``base`` seconds and, once every ``period`` seconds, rises and falls back
along a raised cosine of height ``burst`` and width ``width`` (a queue filling and draining)::

    h(t) = base + burst * (1 - cos(2 pi s / width)) / 2   for s = (t - start) mod period < width
    h(t) = base                                          otherwise

It rises at most at ``pi burst / width`` seconds per second; the factory refuses parameters
that make that 1 or more (``t - h(t)`` would then run backwards and re-apply older commands,
which :class:`delaytrack.CompiledDelay` does not resolve inside a step).
"""

from __future__ import annotations

import math

import numba

import delaytrack as dt


@numba.njit(error_model="numpy")
def congested_link_delay(t, params):
    """``h(t)`` of the module docstring; ``params = [base, burst, width, period, start]``."""
    base, burst, width, period, start = params[0], params[1], params[2], params[3], params[4]
    if t < start:
        return base
    phase = (t - start) % period
    if phase >= width:
        return base
    return base + burst * 0.5 * (1.0 - math.cos(2.0 * math.pi * phase / width))


def make_congested_link(
    base: float = 0.02,
    burst: float = 0.1,
    width: float = 0.6,
    period: float = 2.0,
    start: float = 0.5,
) -> dt.CompiledDelay:
    """The congested link as a :class:`delaytrack.CompiledDelay` (times in seconds)."""
    for name, value in (("base", base), ("burst", burst), ("start", start)):
        if not (isinstance(value, int | float) and 0.0 <= value < math.inf):
            raise ValueError(f"{name} must be a number >= 0 (seconds); got {value!r}")
    for name, value in (("width", width), ("period", period)):
        if not (isinstance(value, int | float) and 0.0 < value < math.inf):
            raise ValueError(f"{name} must be a number > 0 (seconds); got {value!r}")
    if width > period:
        raise ValueError(f"width must be at most period = {period:g} s; got {width!r}")
    if math.pi * burst / width >= 1.0:
        raise ValueError(
            f"burst / width must stay below 1/pi = {1.0 / math.pi:.4f}: the delay would then "
            f"rise faster than time passes (got pi * {burst:g} / {width:g} = "
            f"{math.pi * burst / width:.3g})"
        )
    return dt.CompiledDelay(
        congested_link_delay,
        [base, burst, width, period, start],
        h_max=base + burst,
        name="congested link",
    )
