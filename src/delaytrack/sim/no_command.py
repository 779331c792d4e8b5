"""A run whose delay outlasts it: no command reaches the plant, which receives ``u_init``
throughout (a delay in milliseconds given as seconds, say)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from delaytrack.warning import DelaytrackWarning

if TYPE_CHECKING:
    from delaytrack.delays import DelayProfile

__all__ = ["NoCommandArrivesWarning", "no_command_arrives"]


class NoCommandArrivesWarning(DelaytrackWarning):
    """A run's delay is never shorter than the run (its :attr:`~DelayProfile.h_min` at least
    ``t1 - t0``): no command reaches the plant, which receives ``u_init`` throughout."""


def no_command_arrives(
    delays: Sequence[DelayProfile], t0: float, t1: float
) -> NoCommandArrivesWarning | None:
    """The warning for the runs whose delay is never shorter than ``t1 - t0``, or None."""
    duration = t1 - t0
    never = [i for i, delay in enumerate(delays) if delay.h_min >= duration]
    if not never:
        return None
    shortest = min(delays[i].h_min for i in never)
    runs = "" if len(delays) == 1 else f" in {len(never)} of {len(delays)} runs"
    return NoCommandArrivesWarning(
        f"the delay is never shorter than {shortest:g} s, and the run lasts {duration:g} s"
        f"{runs}: no command reached the plant, which received u_init throughout (delays are "
        "in seconds)"
    )
