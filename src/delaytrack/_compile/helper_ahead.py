"""A compile helper started ahead of the first compile that will need it.

A helper process (:mod:`delaytrack._compile.helper_process`) spends about a second starting:
Python, numba and the package imported, numba's compiler set up. Started when a first compile
begins, that second is lost to the compile's sharing. A job that compiles for certain (numba's
cache holds no engine yet for this version of the package: the first job on this machine, or
after an update) starts it ahead instead (:func:`helper_ahead`), while this process is still
importing and building what it will run; the first compile worth a helper then hands it its
jobs (:func:`take`; a compile that shares nothing leaves it to the next). In the paper job
from an empty cache, that is the time this process spends on its imports and the study's
set-up.
"""

from __future__ import annotations

import contextlib
import subprocess
import sys
import threading
from collections.abc import Iterator

from delaytrack._compile.helper_process import Helper, spare_core, spawn

__all__ = ["helper_ahead", "take"]

#: Helpers started ahead and not taken yet, innermost block last.
_WAITING: list[_Ahead] = []


class _Ahead:
    """One helper started ahead, by a thread (deciding takes a tenth of a second and more:
    :func:`_engine_compiled`, :func:`~delaytrack._compile.helper_process.spare_core`)."""

    def __init__(self) -> None:
        self.process: subprocess.Popen | None = None
        self.path = list(sys.path)
        self.taken = False
        self.lock = threading.Lock()
        self.thread = threading.Thread(target=self._start, name="compile helper ahead")
        self.thread.daemon = True

    def _start(self) -> None:
        if _engine_compiled() or not spare_core():
            return
        with self.lock:  # the block may have ended meanwhile: then no helper
            if self.taken:
                return
            # a process that could not start: no helper ahead (one is started when needed)
            with contextlib.suppress(OSError, ValueError):
                self.process = spawn(path=self.path)  # the path take() compares

    def take(self) -> subprocess.Popen | None:
        """The helper, once (None when there is none, or the module search path changed)."""
        self.thread.join()
        with self.lock:
            process, self.process, self.taken = self.process, None, True
        if process is not None and sys.path != self.path:
            Helper(process, 0.0).stop()  # it would import other modules than this process
            return None
        return process

    def stop(self) -> None:
        """Stop the helper if no compile took it (once the thread that starts it is done: no
        helper outlives the block)."""
        with self.lock:
            process, self.process, self.taken = self.process, None, True
        self.thread.join()
        if process is not None:
            Helper(process, 0.0).stop()


def _engine_compiled() -> bool:
    """Whether numba's cache holds the engine compiled (for any combination) for this version
    of the package, installation and Python: numba's own index of it, as
    :func:`~delaytrack._compile.first_compile.code_ready` reads it (not a public interface;
    when it cannot be read, the answer is False)."""
    from delaytrack.sim.engine import run_batch_compiled

    try:
        return bool(run_batch_compiled._cache._cache_file._load_index())
    except Exception:  # noqa: BLE001 - numba internals changed: a helper ahead does no harm
        return False


@contextlib.contextmanager
def helper_ahead() -> Iterator[None]:
    """Within this block, when numba's cache holds no engine yet for this version of the
    package (a compile is certain) and a core is spare, a helper is started at once, in the
    background, and the block's first compile worth a helper hands it its jobs
    (:func:`take`). A helper that no compile took is stopped when the block ends. (Whether the
    engine is in the cache is read by the thread that starts the helper, which imports the
    engine for it.)"""
    ahead = _Ahead()
    ahead.thread.start()
    _WAITING.append(ahead)
    try:
        yield
    finally:
        _WAITING.remove(ahead)
        ahead.stop()


def take() -> subprocess.Popen | None:
    """A helper started ahead by the innermost :func:`helper_ahead` block, once; None when
    there is none (outside such blocks, already taken, or none could start)."""
    if not _WAITING:
        return None
    return _WAITING[-1].take()
