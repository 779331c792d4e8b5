"""A report drawn in a second process while this one runs the next study.

Drawing a report's figures (matplotlib, in one thread) takes one core for seconds while the other
cores wait. :meth:`SecondProcess.run` hands such a call to a second Python process when a core
is idle (measured as for the compile helper,
:func:`~delaytrack._compile.helper_process.idle_cpus`) and returns at once; this process goes on
with the next study. The files are the same: the call is the same function of the same values,
pickled.

Whatever the second process does not deliver (it could not start, failed or died) this process
runs itself when the block of :func:`second_process` ends, so that a failure reads as it would
without it; on Ctrl-C (which both processes receive) the second process is stopped, and on
another error its call is finished before the error goes on (a study already run is not lost).
"""

from __future__ import annotations

import contextlib
import io
import pickle
import subprocess
import sys
from collections.abc import Callable, Iterator
from typing import Any

from delaytrack._compile.helper_process import IDLE_NEEDED, bootstrap, idle_cpus

__all__ = ["SecondProcess", "main", "second_process"]

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

    def finish(self, *, again_here: bool = True) -> None:
        """Wait for the second process; run its call here when it did not complete it (and
        ``again_here``)."""
        process, call = self._process, self._call
        self._process = self._call = None
        if process is not None and call is not None and process.wait() != 0 and again_here:
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
    idle = idle_cpus()
    if idle is None or idle < IDLE_NEEDED or getattr(sys, "frozen", False):
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
        )
        assert process.stdin is not None  # opened with stdin=PIPE
        process.stdin.write(payload)
        process.stdin.close()
    except Exception:  # noqa: BLE001 - no second process: run here
        if process is not None:
            _end(process)
        return None
    return process


@contextlib.contextmanager
def second_process() -> Iterator[SecondProcess]:
    """A :class:`SecondProcess` for the block: its call is finished (or run here) when the block
    ends; on Ctrl-C it is stopped, on another error its call is finished before the error goes
    on."""
    second = SecondProcess()
    try:
        yield second
    except KeyboardInterrupt:
        second.stop()
        raise
    except BaseException:
        second.finish(again_here=False)
        raise
    second.finish()


def main(payload: io.BytesIO) -> int:
    """The second process: run the call pickled in ``payload``. Returns 0 when it returned, 1
    when it raised (the first process then runs it again and reports the error)."""
    try:
        function, args, kwargs = pickle.load(payload)
        function(*args, **kwargs)
    except Exception:  # noqa: BLE001 - run again by the first process, which reports it
        return 1
    return 0
