"""A report drawn in a second process while this one runs the next study.

Drawing a report's figures (matplotlib, in one thread) takes one core for seconds while the other
cores wait. :func:`second_process` starts a second Python process where the compile helper
would start (:func:`~delaytrack._compile.helper_process.spare_core`: a core is idle);
it imports the modules it is told to at once, while this process goes on, and then waits. A
job that compiles first starts it when that compile is done
(:func:`~delaytrack._compile.first_compile.after_first_compile`), not beside it: a first
compile takes both cores, and the second process's imports then only slowed it down.
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
module patched at run time, a warnings filter) does not reach the second process, whose
warnings and output are not shown. Matplotlib's settings do
(through :data:`matplotlib.rcParams`), so a call is run here once they differ from those a new
process reads. ``DELAYTRACK_COMPILE_HELPER=0`` runs everything in one process, ``1`` starts the
second process whatever the load, as for the compile helper.
"""

from __future__ import annotations

import contextlib
import importlib
import io
import pickle
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from delaytrack._compile import first_compile
from delaytrack._compile.helper_process import forget_own, spare_core, spawn

__all__ = ["PATIENCE", "SecondProcess", "main", "second_process"]

#: Seconds the end of the block waits for the second process, then this process runs its call.
PATIENCE = 600.0

#: Seconds a stopped second process's writing thread is waited for.
_WRITER_GRACE = 5.0

#: A call: the function, its positional and its keyword arguments.
Call = tuple[Callable[..., Any], tuple, dict]


class SecondProcess:
    """Runs one call in a second process, every other call here (made by
    :func:`second_process`).

    Parameters
    ----------
    process : subprocess.Popen or None
        The second process, waiting for its call; None to run every call here, or until
        :meth:`start` starts one.
    modules : sequence of str, optional
        The modules a second process started by the first call imports when none was started
        before (:meth:`start`); None: that call runs here.
    """

    def __init__(
        self, process: subprocess.Popen | None, modules: Sequence[str] | None = None
    ) -> None:
        self._process = process
        self._modules = modules
        self._call: Call | None = None
        self._writer: threading.Thread | None = None
        self._starter: threading.Thread | None = None
        self._stopped = False
        self._lock = threading.Lock()

    def start(self) -> None:
        """Start the second process, importing its modules, from a thread (deciding takes a
        tenth of a second: :func:`~delaytrack._compile.helper_process.spare_core`); nothing
        when one was started, the block ended, or it was given no modules."""
        with self._lock:
            if self._starter is not None or self._stopped or self._modules is None:
                return
            self._starter = threading.Thread(
                target=self._start,
                args=(self._modules,),
                name="delaytrack-second-start",
                daemon=True,
            )
            self._starter.start()

    def _start(self, modules: Sequence[str]) -> None:
        process = _start(modules)
        with self._lock:
            if not self._stopped:
                self._process = process
                return
        if process is not None:  # the block ended meanwhile
            SecondProcess(process).stop()

    def _started(self) -> None:
        """Wait for the thread that starts the second process, if one does."""
        if self._starter is not None:
            self._starter.join()

    def run(self, function: Callable[..., Any], *args: Any, **kwargs: Any) -> None:
        """Call ``function(*args, **kwargs)``: in the second process when it has no call yet
        (returning at once: a thread writes the call while the second process reads it), here
        otherwise (or when a value does not pickle or matplotlib's settings changed)."""
        call = (function, args, kwargs)
        self.start()  # unless one was started
        self._started()
        process = self._process
        if process is not None and self._call is None and _fresh_style():
            try:
                payload = pickle.dumps(call)
            except Exception:  # noqa: BLE001 - a value that does not pickle: run here
                pass
            else:
                writer = threading.Thread(
                    target=_write,
                    args=(process, payload),
                    name="delaytrack-second-process",
                    daemon=True,
                )
                writer.start()
                self._call, self._writer = call, writer
                return
        function(*args, **kwargs)

    def finish(self) -> None:
        """Wait for the second process (at most :data:`PATIENCE` seconds); run its call here
        when it did not complete it."""
        self._started()
        process, call = self._process, self._call
        if process is None:
            return
        deadline = time.monotonic() + PATIENCE
        if self._writer is not None:
            self._writer.join(timeout=PATIENCE)  # it reads the call after its imports
        else:
            _write(process, b"")  # without a call, the end of its input ends it
        try:
            completed = process.wait(timeout=max(0.0, deadline - time.monotonic())) == 0
        except subprocess.TimeoutExpired:
            completed = False
        self.stop()
        if call is not None and not completed:
            function, args, kwargs = call
            function(*args, **kwargs)

    def stop(self) -> None:
        """End the second process, whatever it is doing (once the thread that starts it is
        done: no second process outlives the block)."""
        with self._lock:
            self._stopped = True
        self._started()
        process, self._process, self._call = self._process, None, None
        if process is not None:
            if process.poll() is None:
                process.kill()
                process.wait()
            if process.stdin is not None:  # a process never given its call
                with contextlib.suppress(OSError):
                    process.stdin.close()
            forget_own(process.pid)
        if self._writer is not None:
            # Its pipe broke with the process, so it ends at once (unless a process the second
            # one started still holds the pipe: then it is left, a daemon, to the exit).
            self._writer.join(timeout=_WRITER_GRACE)
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
    """A second process importing ``modules``, then waiting for its call, when a core is spare
    (:func:`~delaytrack._compile.helper_process.spare_core`); None otherwise, or when it cannot
    start."""
    if not spare_core():
        return None
    process = None
    try:  # Ctrl-C included: a process started must not outlive this function's failure
        process = spawn(__name__)
        assert process.stdin is not None  # opened with stdin=PIPE
        process.stdin.write(pickle.dumps(tuple(modules)))
        process.stdin.flush()
    except BaseException as error:
        if process is not None:
            SecondProcess(process).stop()
        if not isinstance(error, OSError | ValueError):  # a process or pipe that failed
            raise
        return None  # no second process: everything runs here
    return process


def _fresh_style() -> bool:
    """Whether matplotlib's settings are those a new process reads (or it is not loaded); the
    backend aside, which figures drawn without pyplot do not use."""
    matplotlib = sys.modules.get("matplotlib")
    if matplotlib is None:
        return True
    now, fresh = dict(matplotlib.rcParams), dict(matplotlib.rcParamsOrig)
    now.pop("backend", None)
    fresh.pop("backend", None)
    return now == fresh


@contextlib.contextmanager
def second_process(
    modules: Sequence[str] = (), *, after_first_compile: bool = False
) -> Iterator[SecondProcess]:
    """A :class:`SecondProcess` for the block, with a process that imports ``modules`` when a
    core is idle: at once, or (``after_first_compile``) when the block's first compiled run
    has its code, or at the first call if that comes first (a first compile takes both cores,
    and a process importing beside it slowed it down by half a second in the paper job). Its
    call is finished (or run here) when the block ends; on Ctrl-C, in the block or while it
    waits, the second process is stopped; on another error its call is finished (here if need
    be; an error of that is noted on the first) before the first error goes on."""
    second = SecondProcess(None, modules)
    try:
        try:
            if after_first_compile:
                with first_compile.after_first_compile(second.start):
                    yield second
            else:
                second.start()
                second._started()
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


def main(stream: io.BufferedReader) -> int:
    """The second process: import the modules named in ``stream`` (its input, as
    :func:`~delaytrack._compile.helper_process.bootstrap` gives it), then run
    the call pickled after them (none when the input ends first). Returns 0 when it returned (or
    there was none), 1 when it raised (the first process then runs it again and reports the
    error)."""
    try:
        for module in pickle.load(stream):
            importlib.import_module(module)
        if stream.peek(1) == b"":  # waits for the call, or the end of the input
            return 0  # given no call
        function, args, kwargs = pickle.load(stream)
    except Exception:  # noqa: BLE001 - a module or a call that does not load: run there
        return 1
    try:
        function(*args, **kwargs)
    except Exception:  # noqa: BLE001 - run again by the first process, which reports it
        return 1
    return 0
