"""Your functions' own numba disk caches, kept from serving old code to a first compile.

``numba.njit(cache=True)`` keeps a function's compiled code on disk, checked against the
function's own file only: after an edit to a function it calls in *another* file, numba still
loads the old code (a limit numba documents), and links it into whatever calls the function.
The engine's parts are compiled for a kernel named by a hash of all the code it reaches
(:func:`~delaytrack.components.code_fingerprint`), so a part compiled for an edited kernel must
not take that old code, nor keep it on disk under the new name.

Before a first compile, :func:`compile_from_source` empties the disk cache of each of your
compiled functions that the kernels reach and that has one, drops the code this process loaded
from it, and saves again what this process compiled from the source (numba saves the rest as it
compiles it). A call of a function whose code was dropped compiles it once more, from its
source.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterable
from typing import Any

from numba.core.compiler_lock import global_compiler_lock

from delaytrack.components import Kernel, compiled_functions_reached

__all__ = ["compile_from_source"]


def compile_from_source(kernels: Iterable[Kernel]) -> None:
    """Empty the numba disk caches of the user's compiled functions that ``kernels`` reach (their
    functions, command maps and steppers, and what those call), and forget the code this process
    loaded from them, so that the compile that follows uses their source as it is now."""
    functions = {
        id(function): function
        for kernel in kernels
        if not kernel.built_in
        for part in (kernel.function, kernel.command_map, kernel.stepper)
        if part is not None
        for function in compiled_functions_reached(part)
    }
    with global_compiler_lock:  # not while another thread compiles
        for function in functions.values():
            _from_source(function)


def _from_source(function: Any) -> None:
    """Empty ``function``'s disk cache (a no-op without one) and drop the code this process
    loaded from it (numba compiles it again when it is next needed); code this process compiled
    from the source is saved again, so that the next process loads it. Parts of numba's
    dispatcher that are not a public interface: if they change, nothing is done."""
    with contextlib.suppress(AttributeError):
        function._cache.flush()
        if function.stats.cache_hits:
            function._make_finalizer()()  # as numba's Dispatcher.recompile does, not compiling
            function._reset_overloads()
            function._cache_hits.clear()
        for signature, compiled in function.overloads.items():
            function._cache.save_overload(signature, compiled)
