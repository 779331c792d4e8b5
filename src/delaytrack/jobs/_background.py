"""A report drawn in a second process while this one runs the next study.

Drawing a report's figures (matplotlib, in one thread) takes one core for seconds while the other
cores wait. :func:`second_process` starts a second Python process when a core is idle
(measured as for the compile helper, :func:`~delaytrack._compile.helper_process.idle_cpus`);
it imports the modules it is told to at once, while this process goes on, and then waits.
:meth:`SecondProcess.run` hands it a call and returns at once; this process goes on with the
next study. The files are the same: the call is the same function of the same values, pickled.
The second process's CPU time counts as this process's own for the compile helper
(:func:`~delaytrack._compile.helper_process.count_as_own`), so that its imports, which fall in
the job's first compile, keep no helper off.

Whatever the second process does not deliver (it could not start, failed, died or took
:data:`PATIENCE` seconds more than this process) this process runs itself when the block of
:func:`second_process` ends, so that a failure reads as it would without it; on Ctrl-C the
second process is stopped, and on another error its call is finished (here if need be) before
the error goes on, so that a study already run is not lost.

The call must depend on its arguments and on files only: what else this process changed (a
module patched at run time) does not reach the second process. Matplotlib's settings do
(through :data:`matplotlib.rcParams`), so a call is run here once they differ from those a new
process reads. The idle core is measured from ``/proc``, so the second process starts on Linux
only; set ``DELAYTRACK_COMPILE_HELPER=0`` to run everything in one process, as the compile
helper does.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import pickle
import subprocess
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from typing import IO, Any

from delaytrack._compile.helper_process import (
    ENVIRONMENT,
    IDLE_NEEDED,
    bootstrap,
    count_as_own,
    forget_own,
    idle_cpus,
)

__all__ = ["PATIENCE", "SecondProcess", "main", "second_process"]

#: Seconds the end of the block waits for the second process, then this process runs its call.
PATIENCE = 600.0

#: A call: the function, its positional and its keyword arguments.
Call = tuple[Callable[..., Any], tuple, dict]


class SecondProcess:
    """Runs one call in a second process, every other call here (made by
    :func:`second_process`).

    Parameters
    ----------
    process : subprocess.Popen or None
        The second process, waiting for its call; None to run every call here.
    """

    def __init__(self, process: subprocess.Popen | None) -> None:
        self._process = process
        self._call: Call | None = None
        self._writer: threading.Thread | None = None

    def run(self, function: Callable[..., Any], *args: Any, **kwargs: Any) -> None:
        """Call ``function(*args, **kwargs)``: in the second process when it has no call yet
        (returning at once: a thread writes the call while the second process reads it), here
        otherwise (or when a value does not pickle or matplotlib's settings changed)."""
        call = (function, args, kwargs)
        process = self._process
        if process is not None and self._call is None and _fresh_style():
            try:
                payload = pickle.dumps(call)
            except Exception:  # noqa: BLE001 - a value that does not pickle: run here
                pass
            else:
                self._call = call
                self._writer = threading.Thread(
                    target=_write, args=(process, payload), name="delaytrack-second-process"
                )
                self._writer.start()
                return
        function(*args, **kwargs)

    def finish(self) -> None:
        """Wait for the second process (at most :data:`PATIENCE` seconds); run its call here
        when it did not complete it."""
        process, call = self._process, self._call
        if process is None:
            return
        if self._writer is not None:
            self._writer.join()
        else:
            _write(process, b"")  # without a call, the end of its input ends it
        try:
            completed = process.wait(timeout=PATIENCE) == 0
        except subprocess.TimeoutExpired:
            completed = False
        self.stop()
        if call is not None and not completed:
            function, args, kwargs = call
            function(*args, **kwargs)

    def stop(self) -> None:
        """End the second process, whatever it is doing."""
        process, self._process, self._call = self._process, None, None
        if process is not None:
            if process.poll() is None:
                process.kill()
                process.wait()
            forget_own(process.pid)
        if self._writer is not None:
            self._writer.join()  # its pipe broke with the process: it ends at once
            self._writer = None


def _write(process: subprocess.Popen, payload: bytes) -> None:
    """Write ``payload`` to ``process`` and close its input (nothing when it is gone: its exit
    status then says that it did not complete its call)."""
    assert process.stdin is not None  # started with stdin=PIPE
    with contextlib.suppress(OSError, ValueError):
        process.stdin.write(payload)
    with contextlib.suppress(OSError, ValueError):
        process.stdin.close()


def _start(modules: Sequence[str]) -> subprocess.Popen | None:
    """A second process importing ``modules``, then waiting for its call, when a core is idle;
    None otherwise, or when it cannot start."""
    if os.environ.get(ENVIRONMENT, "").strip() == "0" or getattr(sys, "frozen", False):
        return None
    idle = idle_cpus()
    if idle is None or idle < IDLE_NEEDED:
        return None
    process = None
    try:
        process = subprocess.Popen(
            bootstrap(__name__, streamed=True),
            stdin=subprocess.PIPE,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            env={**os.environ, ENVIRONMENT: "0"},  # it starts no helper of its own
        )
        count_as_own(process.pid)
        assert process.stdin is not None  # opened with stdin=PIPE
        process.stdin.write(pickle.dumps(list(sys.path)) + pickle.dumps(tuple(modules)))
        process.stdin.flush()
    except Exception:  # noqa: BLE001 - no second process: everything runs here
        if process is not None:
            SecondProcess(process).stop()
        return None
    return process


def _fresh_style() -> bool:
    """Whether matplotlib's settings are those a new process reads (or it is not loaded)."""
    matplotlib = sys.modules.get("matplotlib")
    return matplotlib is None or dict(matplotlib.rcParams) == dict(matplotlib.rcParamsOrig)


@contextlib.contextmanager
def second_process(modules: Sequence[str] = ()) -> Iterator[SecondProcess]:
    """A :class:`SecondProcess` for the block, with a process that imports ``modules`` at once
    when a core is idle: its call is finished (or run here) when the block ends; on Ctrl-C, in
    the block or while it waits, the second process is stopped; on another error its call is
    finished (here if need be; an error of that is noted on the first) before the first error
    goes on."""
    second = SecondProcess(_start(modules))
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


def main(stream: IO[bytes]) -> int:
    """The second process: import the modules named in ``stream``, then run the call pickled
    after them (none when the input ends first). Returns 0 when it returned (or there was none),
    1 when it raised (the first process then runs it again and reports the error)."""
    try:
        for module in pickle.load(stream):
            importlib.import_module(module)
        function, args, kwargs = pickle.load(stream)
    except EOFError:
        return 0
    except Exception:  # noqa: BLE001 - a module or the call that does not load: run there
        return 1
    try:
        function(*args, **kwargs)
    except Exception:  # noqa: BLE001 - run again by the first process, which reports it
        return 1
    return 0
