"""A report drawn in a second process while this one runs the next study.

Drawing a report's figures (matplotlib, in one thread) takes one core for seconds while the other
cores wait. :meth:`SecondProcess.run` hands such a call to a second Python process when a core
is idle (measured as for the compile helper,
:func:`~delaytrack._compile.helper_process.idle_cpus`) and returns at once; this process goes on
with the next study. The files are the same: the call is the same function of the same values,
pickled.

Whatever the second process does not deliver (it could not start, failed, died or took
:data:`PATIENCE` seconds more than this process) this process runs itself when the block of
:func:`second_process` ends, so that a failure reads as it would without it; on Ctrl-C the
second process is stopped, and on another error its call is finished (here if need be) before
the error goes on, so that a study already run is not lost.

The call must depend on its arguments and on files only: what else this process changed (a
module patched at run time) does not reach the second process. Matplotlib's settings do
(through :data:`matplotlib.rcParams`), so a call is run here once they differ from those a new
process reads. The idle core is measured from ``/proc`` (:func:`idle_cpus`), so the second
process starts on Linux only; set ``DELAYTRACK_COMPILE_HELPER=0`` to run everything in one
process, as the compile helper does.
"""

from __future__ import annotations

import contextlib
import io
import os
import pickle
import subprocess
import sys
from collections.abc import Callable, Iterator
from typing import Any

from delaytrack._compile.helper_process import ENVIRONMENT, IDLE_NEEDED, bootstrap, idle_cpus

__all__ = ["PATIENCE", "SecondProcess", "main", "second_process"]

#: Seconds the end of the block waits for the second process, then this process runs its call.
PATIENCE = 600.0

#: A call: the function, its positional and its keyword arguments.
Call = tuple[Callable[..., Any], tuple, dict]


class SecondProcess:
    """Runs one call in a second process when a core is idle, every other call here (made by
    :func:`second_process`)."""

    def __init__(self) -> None:
        self._process: subprocess.Popen | None = None
        self._call: Call | None = None

    def run(self, function: Callable[..., Any], *args: Any, **kwargs: Any) -> None:
        """Call ``function(*args, **kwargs)``: in a second process when none runs yet and a core
        is idle (returning at once), here otherwise."""
        call = (function, args, kwargs)
        if self._call is None:
            self._process = _start(call)
            if self._process is not None:
                self._call = call
                return
        function(*args, **kwargs)

    def finish(self) -> None:
        """Wait for the second process (at most :data:`PATIENCE` seconds); run its call here
        when it did not complete it."""
        process, call = self._process, self._call
        if process is None or call is None:
            return
        try:
            completed = process.wait(timeout=PATIENCE) == 0
        except subprocess.TimeoutExpired:
            completed = False
        self.stop()
        if not completed:
            function, args, kwargs = call
            function(*args, **kwargs)

    def stop(self) -> None:
        """End the second process, whatever it is doing."""
        process, self._process, self._call = self._process, None, None
        if process is not None:
            _end(process)


def _end(process: subprocess.Popen) -> None:
    """Kill ``process`` if it still runs."""
    if process.poll() is None:
        process.kill()
        process.wait()


def _start(call: Call) -> subprocess.Popen | None:
    """A second process running ``call``, when a core is idle; None otherwise, or when it cannot
    start or a value of the call does not pickle."""
    if os.environ.get(ENVIRONMENT, "").strip() == "0" or getattr(sys, "frozen", False):
        return None
    if not _fresh_style():
        return None
    idle = idle_cpus()
    if idle is None or idle < IDLE_NEEDED:
        return None
    try:
        payload = pickle.dumps(list(sys.path)) + pickle.dumps(call)
    except Exception:  # noqa: BLE001 - a value that does not pickle: run here
        return None
    process = None
    try:
        process = subprocess.Popen(
            bootstrap(__name__),
            stdin=subprocess.PIPE,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            env={**os.environ, ENVIRONMENT: "0"},  # it starts no helper of its own
        )
        assert process.stdin is not None  # opened with stdin=PIPE
        process.stdin.write(payload)
        process.stdin.close()
    except Exception:  # noqa: BLE001 - no second process: run here
        if process is not None:
            _end(process)
        return None
    return process


def _fresh_style() -> bool:
    """Whether matplotlib's settings are those a new process reads (or it is not loaded)."""
    matplotlib = sys.modules.get("matplotlib")
    return matplotlib is None or dict(matplotlib.rcParams) == dict(matplotlib.rcParamsOrig)


@contextlib.contextmanager
def second_process() -> Iterator[SecondProcess]:
    """A :class:`SecondProcess` for the block: its call is finished (or run here) when the block
    ends; on Ctrl-C, in the block or while it waits, the second process is stopped; on another
    error its call is finished (here if need be; an error of that is noted on the first) before
    the first error goes on."""
    second = SecondProcess()
    try:
        try:
            yield second
        except KeyboardInterrupt:
            raise
        except BaseException as error:
            try:
                second.finish()
            except Exception as also:  # noqa: BLE001 - the first error is the one to report
                error.add_note(f"and then: {type(also).__name__}: {also}")
            raise
        second.finish()
    finally:
        second.stop()  # after a finish, nothing to stop


def main(payload: io.BytesIO) -> int:
    """The second process: run the call pickled in ``payload``. Returns 0 when it returned, 1
    when it raised (the first process then runs it again and reports the error)."""
    try:
        function, args, kwargs = pickle.load(payload)
        function(*args, **kwargs)
    except Exception:  # noqa: BLE001 - run again by the first process, which reports it
        return 1
    return 0
