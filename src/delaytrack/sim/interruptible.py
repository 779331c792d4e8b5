"""Compiled runs that Ctrl-C interrupts.

Python runs a signal handler only in the main thread, between two of its bytecodes: while the main
thread is inside compiled code (a run of millions of steps, or a kernel of the user's that never
returns) Ctrl-C does nothing until the code returns. :func:`run_interruptibly` therefore runs
a long computation on a thread of its own (the compiled engine releases the GIL) while the main
thread waits for it in short, interruptible waits: Ctrl-C raises ``KeyboardInterrupt`` at once.
A short one runs on the calling thread, as handing it to a thread costs 0.1 to 1 ms; the command
line hands every one (:func:`every_run_interruptible`), since a kernel of the user's that never
returns makes any run long.

The computation itself cannot be stopped (compiled code does not look at signals): it goes on to
its end on its thread, its results thrown away. The command line, which has nothing more to do,
ends the process at once when :func:`work_left_running` says so (``os._exit``, after flushing
what it printed); a Python session that goes on has one busy core until the run ends.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable, Iterator
from typing import TypeVar

__all__ = ["LONG_WORK", "every_run_interruptible", "run_interruptibly", "work_left_running"]

_T = TypeVar("_T")

#: Size of a computation (for a run: plant steps times coordinates, over the batch) from which
#: it runs on a thread of its own: about a second of computing for a two-link arm, 0.15 s for
#: the wheeled robot, against the thread's cost of 0.1 to 1 ms.
LONG_WORK = 10**6

#: Seconds between two looks at Ctrl-C while the main thread waits (Windows does not interrupt
#: a wait without a timeout).
_POLL = 0.1

#: The end of each computation that Ctrl-C left running, set when it ends.
_LEFT_RUNNING: list[threading.Event] = []
#: Whether every computation, long or short, runs on a thread of its own.
_every_run = False


@contextlib.contextmanager
def every_run_interruptible() -> Iterator[None]:
    """Within it, :func:`run_interruptibly` hands every computation to a thread of its own,
    whatever its size (for the command line)."""
    global _every_run
    before, _every_run = _every_run, True
    try:
        yield
    finally:
        _every_run = before


def run_interruptibly(work: Callable[[], _T], size: float) -> _T:
    """``work()``, of ``size`` (:data:`LONG_WORK`), raising what it raises; a long one (or any,
    within :func:`every_run_interruptible`) called from the main thread computes on a thread of
    its own while the main thread waits for it, so that Ctrl-C interrupts the wait at once with
    ``KeyboardInterrupt``. (No signal reaches another thread, where ``work`` runs as called.)"""
    if threading.current_thread() is not threading.main_thread() or not (
        _every_run or size > LONG_WORK
    ):
        return work()
    outcome: list = []
    # An event of its own, not the thread's: an interrupted Thread.join leaves is_alive() False
    # while the thread runs on (Python 3.11).
    ended = threading.Event()

    def compute() -> None:
        try:
            outcome.append((True, work()))
        except BaseException as error:  # noqa: BLE001 - handed to the waiting thread
            outcome.append((False, error))
        finally:
            ended.set()

    threading.Thread(target=compute, name="delaytrack run", daemon=True).start()
    try:
        while not ended.wait(_POLL):
            pass
    except KeyboardInterrupt:
        _LEFT_RUNNING.append(ended)
        raise
    finished, value = outcome.pop()
    if not finished:
        raise value
    return value


def work_left_running() -> bool:
    """Whether a computation interrupted by Ctrl-C (:func:`run_interruptibly`) still runs."""
    _LEFT_RUNNING[:] = [ended for ended in _LEFT_RUNNING if not ended.is_set()]
    return bool(_LEFT_RUNNING)
