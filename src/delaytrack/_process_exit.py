"""The end of a process that the toolkit runs as a whole: its commands (``delaytrack``,
``python -m delaytrack.live``) and the second processes it starts (the compile helper, a
report's process, a live session's nodes).

When Python ends, it clears its modules and collects garbage over every object still alive. In a
process that compiled or loaded numba's kernels and drew with matplotlib that is hundreds of
thousands of objects: ``delaytrack reproduce --no-contact --no-robustness`` spent 0.49 s between
its last exit handler and its end, 0.13 s with the objects frozen first (measured 2026-12-05).
:func:`exit_process` moves every object alive to the garbage collector's permanent generation
(:func:`gc.freeze`), which those last collections skip, and exits. Everything else of an exit
happens as before: exit handlers and weak-reference finalizers run (a temporary folder's
cleanup among them), objects are freed as their last reference goes, and the standard streams
are flushed. Objects that only a reference cycle keeps alive at the end are not finalized: their
``__del__`` does not run, and a file among them that is still open is neither flushed nor
closed. The toolkit closes every file it writes before it ends (in ``with`` blocks or
``finally`` clauses); a module of yours that a command imports (a scenario's factory) runs in
such a process too, so close the files it writes.

Never for a function of the library: freezing would change the collector of the user's process.
"""

from __future__ import annotations

import gc
import sys
from typing import NoReturn

__all__ = ["exit_process"]


def exit_process(code: int | None) -> NoReturn:
    """End this process with exit status ``code`` (:func:`sys.exit`), after freezing the objects
    alive (:func:`gc.freeze`) so that Python's collections at exit skip them."""
    gc.freeze()
    sys.exit(code)
