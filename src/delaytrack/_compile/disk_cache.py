"""Where numba keeps delaytrack's compiled kernels: a folder keyed by the compiled source.

numba validates a cached function against its own source file only. The compiled engine inlines
kernels from many files (plants, controllers, delays, references), so after an edit to one of
them numba would load a stale engine. Imported first by :mod:`delaytrack`, this module points
``numba.config.CACHE_DIR`` (read when each kernel is decorated) at
``<cache root>/<hash of the package's compiled code>``, so an edit to a kernel recompiles the
engine once. The hash covers only the files that hold compiled code (:func:`kernel_files`: the
ones importing numba or :mod:`delaytrack._compile.jit`, and those that decide how a user's kernel
compiles and under which name its code is kept); an edit to a report, the command line or a
study recompiles nothing. A user's kernels are covered by their numba type instead
(:mod:`delaytrack._compile.kernel_type`). The cache root is ``$NUMBA_CACHE_DIR`` when the user
sets it, else ``$XDG_CACHE_HOME/delaytrack/numba`` (``~/.cache/delaytrack/numba``).

Processes share that folder (pytest or dask workers, a notebook beside a sweep), so every
compiled kernel of the package writes its entries under a file lock (:func:`locked_cache`).
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

from delaytrack._compile.numba_settings import import_numba
from delaytrack._file_lock import LOCKS, exclusive

numba = import_numba()  # first: no settings from the working folder (numba_settings)

from numba.core.caching import IndexDataCacheFile  # noqa: E402

__all__ = [
    "cache_directory",
    "kernel_files",
    "locked_cache",
    "locks_cache",
    "source_hash",
]

#: The folder of the package delaytrack.
_PACKAGE = Path(__file__).resolve().parents[1]
#: Text that marks a file holding compiled code.
_MARKERS = (b"from delaytrack._compile.jit import", b"import numba", b"from numba")
#: Files without compiled code that decide how a kernel of the user's compiles (the numba options
#: it keeps) and the name its compiled code is kept under (its fingerprint).
_DECIDING = ("_compile/own_options.py", "_compile/fingerprint.py")


#: Changed when the entries that an earlier version wrote must not be read: numba's cached kernel
#: refers to its module by name, and a user's file named in a scenario is now imported under its
#: own name (it was ``<stem>_<hash>``, which a session importing the file could not find).
_LAYOUT = b"user files under their own name"


def kernel_files() -> list[Path]:
    """The package's Python files that hold compiled code (or decide how a kernel of the user's
    compiles and is named, :data:`_DECIDING`), sorted."""
    return [
        path
        for path in sorted(_PACKAGE.rglob("*.py"))
        if any(marker in path.read_bytes() for marker in _MARKERS)
        or path.relative_to(_PACKAGE).as_posix() in _DECIDING
    ]


def source_hash() -> str:
    """SHA-256 (16 hex digits) of numba's version, the cache's layout and the paths and
    contents of :func:`kernel_files`."""
    digest = hashlib.sha256(numba.__version__.encode() + _LAYOUT)
    for path in kernel_files():
        digest.update(str(path.relative_to(_PACKAGE)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def cache_directory() -> Path:
    """The folder for this exact compiled source; created on demand by numba."""
    root = os.environ.get("NUMBA_CACHE_DIR")
    if root:
        return Path(root) / "delaytrack" / source_hash()
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "delaytrack" / "numba" / source_hash()


def locks_cache() -> bool:
    """Whether entries are saved under a file lock (not on Windows, which has no ``fcntl``:
    numba's own writes, unlocked)."""
    return LOCKS


class _LockedIndexDataCacheFile(IndexDataCacheFile):
    """numba's index and data files of one kernel, each entry saved under a file lock.

    numba saves a compiled overload by reading the kernel's index, adding the entry and writing
    the index back. Two processes that compile different overloads of one kernel at once (the
    engine for two plants, say) each write back the index they read, so one entry is lost and
    compiled again by the next process, and both may number their data file alike. Under the
    lock each process reads the index the other wrote.
    """

    def save(self, key, data):
        with exclusive(self._index_path + ".lock"):
            super().save(key, data)


def locked_cache(dispatcher):
    """Have the cached numba ``dispatcher`` save its entries under a file lock; return it."""
    dispatcher._cache._cache_file.__class__ = _LockedIndexDataCacheFile
    return dispatcher


# numba.config sets its settings from the environment at run time: its typing lists none of them
numba.config.CACHE_DIR = str(cache_directory())
