"""What this machine offers a run: its cores and its memory."""

from __future__ import annotations

import math
import os

__all__ = ["WORKERS_PER_CORE", "available_cores", "physical_memory"]

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
