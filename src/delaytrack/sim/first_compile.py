"""Say so before the engine is compiled for a new set of kernels (it takes seconds to a minute).

numba compiles :func:`~delaytrack.sim.engine.run_batch_compiled` once for each set of kernels
(plant, nominal model, controller, reference, a delay kernel of the user's) and keeps it on
disk; later calls load it in well
under a second. :func:`engine_ready` tells which case a call is, so that the first one can be
announced instead of looking like a hang.
"""

from __future__ import annotations

import sys
from typing import Any

__all__ = ["announce_compile", "engine_ready"]


#: Keys of the argument sets found ready in this process (typing them again costs 0.25 ms).
_READY: set[object] = set()


def engine_ready(dispatcher: Any, arguments: tuple, key: object) -> bool:
    """Whether ``dispatcher`` has code for ``arguments``' types in memory or in its disk cache.

    ``key`` names the argument types (the kernels' keys; the arrays' types are the same in
    every call of :func:`~delaytrack.sim.simulate`): once found ready, the answer is remembered.
    Uses numba's cache index (not a public interface); when it cannot be read, the answer is
    False (the notice is then shown once too often).
    """
    if key in _READY:
        return True
    try:
        signature = tuple(dispatcher.typeof_pyval(argument) for argument in arguments)
        if signature in dispatcher.overloads:
            _READY.add(key)
            return True
        cache = dispatcher._cache
        index = cache._index_key(signature, dispatcher.targetctx.codegen())
        return index in cache._cache_file._load_index()
    except Exception:  # noqa: BLE001 - numba internals changed: assume a compile
        return False


def announce_compile(plant: Any, controller: Any, reference: Any, delay: Any = None) -> None:
    """One line on standard error before a first compile (``delay``: a profile of the user's
    kernel, when the batch has one)."""
    own_delay = f" + {type(delay).__name__} {delay.name!r}" if delay is not None else ""
    print(
        f"delaytrack: compiling the engine for {type(plant).__name__} + "
        f"{type(controller).__name__} on {type(controller.model).__name__} + "
        f"{type(reference).__name__}{own_delay} (once; from seconds to a minute, then kept on "
        "disk)",
        file=sys.stderr,
        flush=True,
    )
