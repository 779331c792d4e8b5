"""A bound on the memory one short read may take: for files whose own sizes cannot be trusted.

A file of a format that compresses (Parquet) says in its footer how large its values are, and
the reader allocates what each page's header says; someone who forges the footer can make a
file of a few kilobytes that passes every check of the footer and asks for gigabytes when it is
read. :func:`allocation_budget` caps, for the time of such a read, the data segment of the
process (``RLIMIT_DATA``, which on Linux counts every private writable mapping, so every
``malloc``) at what it holds now plus a budget: an allocation beyond it fails at once with a
:class:`MemoryError` (``pyarrow.ArrowMemoryError`` is one), which the caller turns into a
refusal, instead of the process growing until the system kills it. The cap is the process's,
so other threads' allocations count against the same budget while it is set: it is meant for
short reads on the main thread, with a budget far above what the read should need. Where the
process's data segment cannot be read (no ``/proc``, or no ``resource`` module: Windows) the
cap is not set and the read is bounded only by the checks before it.
"""

from __future__ import annotations

import contextlib
import re
from collections.abc import Iterator

__all__ = ["allocation_budget"]

_VM_DATA = re.compile(r"^VmData:\s+(\d+)\s+kB$", re.MULTILINE)


def _data_segment() -> int | None:
    """The process's data segment in bytes (``VmData``), or None where it cannot be read."""
    try:
        with open("/proc/self/status", encoding="ascii", errors="replace") as handle:
            found = _VM_DATA.search(handle.read())
    except OSError:
        return None
    return int(found.group(1)) * 1024 if found else None


@contextlib.contextmanager
def allocation_budget(budget: int) -> Iterator[bool]:
    """Within the block, allocations beyond ``budget`` more bytes than the process holds now
    fail with :class:`MemoryError` (module docstring); yields whether the cap is set.

    Parameters
    ----------
    budget : int
        Bytes the block may allocate, in all threads together; a positive number.
    """
    if budget <= 0:
        raise ValueError(f"budget must be a positive number of bytes; got {budget!r}")
    try:
        import resource
    except ImportError:  # Windows
        yield False
        return
    held = _data_segment()
    if held is None:
        yield False
        return
    soft, hard = resource.getrlimit(resource.RLIMIT_DATA)
    cap = held + budget
    if hard != resource.RLIM_INFINITY:
        cap = min(cap, hard)
    if soft != resource.RLIM_INFINITY and soft <= cap:  # already as low: nothing to add
        yield True
        return
    resource.setrlimit(resource.RLIMIT_DATA, (cap, hard))
    try:
        yield True
    finally:
        resource.setrlimit(resource.RLIMIT_DATA, (soft, hard))
