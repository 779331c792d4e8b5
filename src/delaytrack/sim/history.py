"""The command history: which controller command is applied at time ``t``.

Controller ticks are at ``t_k = t0 + (k * steps_per_tick) * dt`` — computed, never accumulated.
The input applied to the plant at time ``t`` is the command of the latest tick
``t_k <= t - h(t)``; before the first command exists it is ``u_init``. Commands live in a ring
buffer of ``capacity`` slots (tick ``k`` in slot ``k % capacity``), sized from the profile's
``h_max`` by :func:`history_capacity`.
"""

from __future__ import annotations

import math

from delaytrack._compile.jit import shared_kernel

__all__ = ["history_capacity", "latest_tick_index", "latest_tick_index_from", "tick_time"]


def history_capacity(h_max: float, T_c: float, n_ticks: int) -> int:
    """Ring-buffer slots needed when the delay never exceeds ``h_max`` in a run of ``n_ticks``.

    Over one controller period starting at tick ``k`` (the newest command) the oldest command
    needed is that of tick ``k - ceil(h_max / T_c)``: ``ceil(h_max / T_c) + 1`` slots. A run
    never issues more than ``n_ticks + 1`` commands, so a delay longer than the run needs no
    more than that (its commands never arrive and the plant keeps ``u_init``): memory is bounded
    by the run's length whatever ``h_max`` is, even infinite. Two more slots absorb rounding at
    tick boundaries.
    """
    ticks = h_max / T_c
    needed = n_ticks if not ticks < n_ticks else int(math.ceil(ticks))
    return needed + 3


@shared_kernel
def tick_time(k, t0, dt, steps_per_tick):
    """Time of controller tick ``k``: ``t0 + (k * steps_per_tick) * dt``."""
    return t0 + (k * steps_per_tick) * dt


@shared_kernel
def latest_tick_index(g, t0, dt, steps_per_tick):
    """Largest ``k`` with ``tick_time(k) <= g`` (``-1`` when ``g < t0``)."""
    if g < t0:
        return -1
    estimate = int(math.floor((g - t0) / (steps_per_tick * dt)))
    return latest_tick_index_from(g, estimate, t0, dt, steps_per_tick)


@shared_kernel
def latest_tick_index_from(g, hint, t0, dt, steps_per_tick):
    """:func:`latest_tick_index` found by walking from the tick index ``hint``.

    The same number: for the end of a plant step, whose tick index is a tick or two from that of
    the step's start, a walk of ``|result - hint|`` comparisons instead of a division.
    """
    if g < t0:
        return -1
    k = max(hint, 0)
    while tick_time(k + 1, t0, dt, steps_per_tick) <= g:
        k += 1
    while k >= 0 and tick_time(k, t0, dt, steps_per_tick) > g:
        k -= 1
    return k
