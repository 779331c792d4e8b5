"""What this machine offers a run: its cores and its memory."""

from __future__ import annotations

import math
import os

from delaytrack._validation import is_integer_at_least

__all__ = ["WORKERS_PER_CORE", "available_cores", "physical_memory", "workers_problem"]

#: Most threads or local worker processes per available core: more only share the same cores
#: (and each worker process loads its own compiled engine, hundreds of MB).
WORKERS_PER_CORE = 4


def available_cores() -> int:
    """The cores this process may use (its CPU affinity where the OS has one, else all)."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return os.cpu_count() or 1


def physical_memory() -> float:
    """Bytes of physical memory (infinite where the platform does not say)."""
    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, ValueError, OSError):
        return math.inf


def workers_problem(workers: object) -> str | None:
    """What is wrong with ``workers`` (threads or local worker processes; None: the default),
    worded after the argument's name, or None: a positive integer up to
    :data:`WORKERS_PER_CORE` per available core."""
    if workers is None:
        return None
    if not is_integer_at_least(workers, 1):
        return f"must be a positive integer or None; got {workers!r}"
    most = WORKERS_PER_CORE * available_cores()
    if workers > most:
        return (
            f"must be at most {most} ({WORKERS_PER_CORE} per core of the {available_cores()} "
            f"this process may use: more only share them); got {workers}"
        )
    return None
