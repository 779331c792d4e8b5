"""Say so before code is compiled for a new component (it takes seconds to a minute).

numba compiles :func:`~delaytrack.sim.engine.run_batch_compiled` once, and each plant's
integrator, reference, controller step and delay kernel once for itself (the engine calls them
through their address, :mod:`delaytrack._compile.native_parts`), and keeps them on disk; later
calls load them in well under a second. :func:`code_ready` tells which case a call is, so that
the first one can be announced instead of looking like a hang.
"""

from __future__ import annotations

import contextlib
import contextvars
import sys
from collections.abc import Callable, Iterator
from typing import Any

__all__ = [
    "after_first_compile",
    "announce_compile",
    "announce_compiled",
    "code_is_ready",
    "code_ready",
]


#: Keys of the signatures found ready in this process (typing the engine's arguments again costs
#: 0.25 ms).
_READY: set[object] = set()


def code_ready(dispatcher: Any, key: object, signature: tuple | Callable[[], tuple]) -> bool:
    """Whether ``dispatcher`` has code for ``signature`` in memory or in its disk cache.

    ``signature``: the argument types, or a function that gives them (called only when ``key``,
    which names them, has not been found ready before in this process). Uses numba's cache index
    (not a public interface); when it cannot be read, the answer is False (the notice is then
    shown once too often).
    """
    if (dispatcher, key) in _READY:
        return True
    try:
        types = signature() if callable(signature) else signature
        if types in dispatcher.overloads:
            _READY.add((dispatcher, key))
            return True
        cache = dispatcher._cache
        index = cache._index_key(types, dispatcher.targetctx.codegen())
        return index in cache._cache_file._load_index()
    except Exception:  # noqa: BLE001 - numba internals changed: assume a compile
        return False


def _listed(parts: list[str]) -> str:
    """``a``, ``a and b``, ``a, b and c``."""
    return parts[0] if len(parts) == 1 else f"{', '.join(parts[:-1])} and {parts[-1]}"


def announce_compile(parts: list[str], helped: bool = False) -> None:
    """One line on standard error before a first compile of ``parts`` (what is compiled, such as
    ``"the engine"`` or ``"AROLC's step on NominalRobot"``); ``helped``: a helper process
    compiles some of them (:mod:`delaytrack._compile.helper_process`)."""
    listed = _listed(parts)
    where = " in two processes" if helped else ""
    print(
        f"delaytrack: compiling {listed} (once{where}; from seconds to a minute, then kept on "
        "disk)",
        file=sys.stderr,
        flush=True,
    )


def announce_compiled(parts: list[str], seconds: float, helped: bool = False) -> None:
    """One line on standard error as a first compile of :func:`announce_compile` goes on: which
    ``parts`` are compiled (``helped``: by the helper process), ``seconds`` after it began."""
    listed = _listed(parts)
    where = " by the helper process" if helped else ""
    print(
        f"delaytrack: compiled {listed}{where} ({seconds:.1f} s into the compile)",
        file=sys.stderr,
        flush=True,
    )


#: What the :func:`after_first_compile` blocks around wait for: one list each, holding its call
#: until it is made.
_AFTER: contextvars.ContextVar[tuple[list[Callable[[], None]], ...]] = contextvars.ContextVar(
    "after_first_compile", default=()
)


@contextlib.contextmanager
def after_first_compile(callback: Callable[[], None]) -> Iterator[None]:
    """Within the block, ``callback()`` is called once, when the next compiled run has its code
    (compiled, here and by a helper, or loaded from numba's cache; :func:`code_is_ready`),
    before that run starts; never if no compiled run comes. For work that would compete with a
    first compile for the cores, such as a second process's imports."""
    pending = [callback]
    token = _AFTER.set((*_AFTER.get(), pending))
    try:
        yield
    finally:
        _AFTER.reset(token)


def code_is_ready() -> None:
    """Make the calls of the :func:`after_first_compile` blocks around that wait (each once)."""
    for pending in _AFTER.get():
        if pending:
            pending.pop()()
