"""Say so before the engine is compiled for a new set of kernels (it takes seconds to a minute).

numba compiles :func:`~delaytrack.sim.engine.run_batch_compiled` once for each set of kernels
(plant, nominal model, reference, a delay kernel of the user's), and each controller's step once
for itself (the engine calls it through its address, :mod:`delaytrack._native_call`), and
keeps them on disk; later calls load them in well under a second. :func:`code_ready` tells
which case a call is, so that the first one can be announced instead of looking like a hang.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import Any

__all__ = ["announce_compile", "code_ready"]


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


def announce_compile(
    plant: Any, controller: Any, reference: Any, delay: Any = None, engine: bool = True
) -> None:
    """One line on standard error before a first compile (``delay``: a profile of the user's
    kernel, when the batch has one; ``engine``: False when only the controller's step is to be
    compiled, the engine for the plant being ready)."""
    if not engine:
        print(
            f"delaytrack: compiling {type(controller).__name__}'s step on "
            f"{type(controller.model).__name__} (once; a few seconds, then kept on disk)",
            file=sys.stderr,
            flush=True,
        )
        return
    own_delay = f" + {type(delay).__name__} {delay.name!r}" if delay is not None else ""
    print(
        f"delaytrack: compiling the engine for {type(plant).__name__} + "
        f"{type(controller).__name__} on {type(controller.model).__name__} + "
        f"{type(reference).__name__}{own_delay} (once; from seconds to a minute, then kept on "
        "disk)",
        file=sys.stderr,
        flush=True,
    )
