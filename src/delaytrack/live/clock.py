"""The session clock and absolute-deadline periodic waking.

All nodes of a session on one machine read the same ``time.monotonic`` (``CLOCK_MONOTONIC`` on
Linux is system-wide), so a time stamped by one process is comparable with a time read by
another. The session time is ``time.monotonic() - t0``, with ``t0`` agreed at the handshake.

A periodic loop sleeps to *absolute* deadlines ``t0 + phase + k·period``: a late wake-up does
not shift later deadlines (no drift). A wake-up later than the next deadline has missed the
ticks in between; they are counted and skipped, and the loop resumes at the next multiple of the
period (no burst of catch-up ticks).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

__all__ = ["Ticker", "Wake", "steps_until"]


@dataclass(frozen=True)
class Wake:
    """One wake-up of a :class:`Ticker`: tick index, its deadline (session time), the session
    time read on waking, and how many ticks were skipped just before it."""

    k: int
    deadline: float
    now: float
    skipped: int

    @property
    def lateness(self) -> float:
        """Seconds between the deadline and the wake-up (>= 0 up to clock reading)."""
        return self.now - self.deadline


class Ticker:
    """Wake at ``t0 + phase + k·period`` for ``k = first, first + 1, ...``.

    Parameters
    ----------
    t0 : float
        Session start, ``time.monotonic`` seconds.
    period : float
        Seconds.
    phase : float
        Offset of every deadline from the tick's model time (may be negative: wake before it).
    stop : callable
        Checked before each sleep; the iteration ends when it returns True.
    idle : callable, optional
        ``idle(limit)`` is called before each sleep with the monotonic time by which it must
        return (work that can wait, such as writing the log).
    until : float
        Last session time (model time) of a tick: ticks with ``k·period >= until`` are not run.
    """

    def __init__(
        self,
        t0: float,
        period: float,
        *,
        phase: float = 0.0,
        until: float = math.inf,
        stop: Callable[[], bool] = lambda: False,
        idle: Callable[[float], None] | None = None,
    ) -> None:
        self.t0, self.period, self.phase, self.until, self.stop = t0, period, phase, until, stop
        self.idle = idle
        self.missed = 0

    def now(self) -> float:
        return time.monotonic() - self.t0

    def __iter__(self):
        k = 0
        tolerance = 1e-9 * self.period
        while k * self.period < self.until - tolerance and not self.stop():
            deadline = k * self.period + self.phase
            if self.idle is not None:  # work that may wait (logging), until shortly before
                self.idle(self.t0 + deadline - min(2e-4, self.period / 4))
            while True:
                remaining = deadline - self.now()
                if remaining <= 0.0 or self.stop():
                    break
                # Sleep in slices of at most 50 ms so that a stop request is seen soon.
                time.sleep(min(remaining, 0.05))
            if self.stop():
                return
            now = self.now()
            skipped = 0
            behind = math.floor((now - self.phase) / self.period + 1e-9) - k
            if behind >= 1:  # the next deadline has passed too: skip to the latest one
                if (k + behind) * self.period >= self.until - tolerance:
                    # Only the ticks before the end were missed (the session ends here).
                    self.missed += steps_until(self.until, self.period) - k
                    return
                skipped = behind
                k += behind
                self.missed += behind
                deadline = k * self.period + self.phase
            yield Wake(k, deadline, now, skipped)
            k += 1


def steps_until(duration: float, dt: float) -> int:
    """How many robot steps ``j = 0, 1, ...`` have ``j·dt < duration`` (up to rounding, as the
    periodic loops count them, :class:`~delaytrack.live.clock.Ticker`)."""
    tolerance = 1e-9 * dt
    count = max(0, math.ceil(duration / dt) - 1)
    while count * dt < duration - tolerance:
        count += 1
    while count > 0 and (count - 1) * dt >= duration - tolerance:
        count -= 1
    return count
