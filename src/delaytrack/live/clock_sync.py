"""One session clock for nodes on different machines: the robot node's monotonic clock.

Every stamp of the live loop is session time, ``clock() − t0``, where ``clock`` is the process's
monotonic clock and ``t0`` the session start the robot node announces on *its* clock at the
handshake. On one machine (the same Linux boot, told by ``/proc/sys/kernel/random/boot_id``)
every process reads the same ``CLOCK_MONOTONIC``, so ``t0`` is used as it is: the offset is 0
exactly. On another machine the clocks are unrelated; a node there estimates the offset
``θ = clock_robot − clock_own`` by round trips to the robot node's clock (a Zenoh query,
answered with the robot's clock reading ``r``), the classic estimate of NTP and of Cristian's
algorithm: for a round trip sent at ``a`` and answered at ``b`` on the node's clock,

    θ̂ = r − (a + b) / 2,   |θ̂ − θ| ≤ (b − a) / 2,

because ``r`` was read somewhere between ``a + θ`` and ``b + θ``. Of several round trips the
shortest is kept, and its half-length is the bound written in the node's summary
(``clock_offset_bound_s``). The node then starts at ``t0 − θ̂`` on its own clock, and its stamps
are session time up to that bound. Drift between the two clocks during a session (a few
microseconds per second for ordinary oscillators, more without NTP discipline) is not
corrected; a session of minutes across machines should run with the machines' clocks
disciplined (chrony/NTP), which keeps drift well under a millisecond.
"""

from __future__ import annotations

import struct
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

__all__ = ["SAME_CLOCK", "ClockOffset", "boot_id", "estimate_clock_offset", "serve_clock"]

_BOOT_ID = Path("/proc/sys/kernel/random/boot_id")
_READING = struct.Struct("<d")


def boot_id() -> str | None:
    """This machine's boot identifier (Linux), or None where there is none: processes with the
    same one read the same monotonic clock."""
    try:
        return _BOOT_ID.read_text().strip() or None
    except OSError:
        return None


@dataclass(frozen=True)
class ClockOffset:
    """The robot node's clock minus this node's, and how it was found (module docstring).

    Attributes
    ----------
    offset_s : float
        ``θ̂``, seconds.
    bound_s : float
        ``|θ̂ − θ|`` is at most this (0 on the same machine).
    round_trips : int
        Round trips measured (0 on the same machine).
    """

    offset_s: float
    bound_s: float
    round_trips: int

    def summary(self) -> dict[str, Any]:
        return {
            "clock_offset_s": self.offset_s,
            "clock_offset_bound_s": self.bound_s,
            "clock_round_trips": self.round_trips,
        }


SAME_CLOCK = ClockOffset(0.0, 0.0, 0)


def serve_clock(session: Any, key: str, clock: Any = time.monotonic) -> Any:
    """Answer every query on ``key`` with a reading of ``clock`` (the robot node's); return the
    Zenoh queryable."""

    def answer(query: Any) -> None:
        query.reply(query.key_expr, _READING.pack(clock()))

    return session.declare_queryable(key, answer)


def estimate_clock_offset(
    session: Any, key: str, clock: Any = time.monotonic, rounds: int = 16, timeout: float = 2.0
) -> ClockOffset:
    """Estimate the offset of the clock served on ``key`` from ``clock`` by ``rounds`` answered
    round trips, keeping the shortest (module docstring). A query that finds no answer (the
    robot's queryable not yet known on this side) is tried again after 10 ms.

    Raises
    ------
    TimeoutError
        When ``rounds`` round trips were not answered within ``timeout`` seconds.
    """
    best: tuple[float, float] | None = None
    answered_trips = 0
    deadline = time.monotonic() + timeout
    while answered_trips < rounds and time.monotonic() < deadline:
        sent = clock()
        replies = list(session.get(key, timeout=max(deadline - time.monotonic(), 1e-3)))
        answered = clock()
        readings = [_reading(reply) for reply in replies]
        readings = [r for r in readings if r is not None]
        if not readings:
            time.sleep(0.01)
            continue
        answered_trips += 1
        trip = answered - sent
        if best is None or trip < best[0]:
            best = (trip, readings[0] - (sent + answered) / 2)
    if best is None or answered_trips < rounds:
        raise TimeoutError(
            f"the robot node's clock answered {answered_trips} of {rounds} round trips on {key} "
            f"within {timeout:g} s"
        )
    return ClockOffset(best[1], best[0] / 2, rounds)


def _reading(reply: Any) -> float | None:
    """The clock reading in a reply, or None for an error or a malformed one."""
    if reply.ok is None:
        return None
    try:
        return _READING.unpack(reply.ok.payload.to_bytes())[0]
    except struct.error:
        return None
