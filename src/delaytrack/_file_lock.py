"""An exclusive lock between processes on one machine, held on a file (POSIX ``flock``).

On Windows, which has no ``fcntl``, there is no lock: :data:`LOCKS` is false and
:func:`exclusive` only runs its block.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from types import ModuleType

fcntl: ModuleType | None
try:
    import fcntl
except ImportError:  # Windows
    fcntl = None

__all__ = ["LOCKS", "exclusive"]

#: Whether :func:`exclusive` locks (not on Windows).
LOCKS = fcntl is not None


@contextlib.contextmanager
def exclusive(path: str, *, remove: bool = False) -> Iterator[None]:
    """Hold an exclusive lock on the file ``path`` (created if missing) while inside.

    With ``remove``, the file is deleted before the lock is given back, so that locks taken in
    a shared folder (the temporary files') leave nothing behind. A process that was waiting on
    the deleted file then finds that ``path`` is no longer the file it locked, and locks the
    file of that name anew (created by it, or by a process that came later and holds it), so
    that one process at a time is inside. Every user of a ``path`` must pass the same
    ``remove``: one that does not remove does not check, and could wake on a deleted file.
    """
    if fcntl is None:
        yield
        return
    while True:
        handle = open(path, "a")  # noqa: SIM115 - closed below, after the lock is given back
        try:
            fcntl.flock(handle, fcntl.LOCK_EX)
            if not remove or _is_the_file_at(handle, path):
                break
        except BaseException:
            handle.close()
            raise
        handle.close()  # the holder before removed it: lock the file now at path
    try:
        yield
    finally:
        try:
            if remove and _is_the_file_at(handle, path):
                os.unlink(path)  # still held: no process is inside with this file
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)
            handle.close()


def _is_the_file_at(handle, path: str) -> bool:
    """Whether the open file ``handle`` is the file at ``path`` (not deleted or replaced)."""
    try:
        at_path = os.stat(path)
    except FileNotFoundError:
        return False
    held = os.fstat(handle.fileno())
    return (held.st_dev, held.st_ino) == (at_path.st_dev, at_path.st_ino)
