"""Your functions' own numba disk caches, kept from serving old code to a first compile.

``numba.njit(cache=True)`` keeps a function's compiled code on disk, checked against the
function's own file only: after an edit to a function it calls in *another* file, numba still
loads the old code (a limit numba documents), and links it into whatever calls the function,
also into code compiled from the source in this process. The engine's parts are compiled for a
kernel named by a hash of all the code it reaches
(:func:`~delaytrack._compile.fingerprint.code_fingerprint`), so a part compiled for an edited
kernel must not take that old code, nor keep it on disk under the new name.

Before the first compile of a process that involves a compiled function of yours that a kernel
reaches, :func:`compile_from_source` empties that function's disk cache (if it has one), drops
every compiled version of it this process holds, and compiles those versions again from the
source, as numba's ``Dispatcher.recompile`` does; numba fills the caches again as it compiles.
"""

from __future__ import annotations

import contextlib
import weakref
from collections.abc import Iterable
from typing import Any

from numba.core.compiler_lock import global_compiler_lock

from delaytrack._compile.fingerprint import compiled_functions_reached
from delaytrack.components import Kernel

__all__ = ["compile_from_source"]

#: The functions whose code this process has dropped once (later versions are its own
#: compiles, from the source as it was loaded); a module imported again gives new functions.
_DROPPED: weakref.WeakSet = weakref.WeakSet()


def compile_from_source(kernels: Iterable[Kernel]) -> None:
    """Empty the numba disk caches of the user's compiled functions that ``kernels`` reach (their
    functions, command maps and steppers, and what those call) and compile the code this process
    holds for them again from the source, once per process and function, so that the compile
    that follows uses their source as it is now."""
    reached = {
        id(function): function
        for kernel in kernels
        for root in kernel.roots
        if root is not None
        for function in compiled_functions_reached(root)
    }
    with global_compiler_lock:  # not while another thread compiles
        new = [function for function in reached.values() if function not in _DROPPED]
        held = [(function, list(function.overloads)) for function in new if function.overloads]
        # All are dropped before any is compiled again (a compile links the others' code), and
        # compiled again here, kernels first, as they were: a function compiled inside the
        # engine's compile would take its options (numba's error_model, fastmath, runtime) from it.
        for function in new:
            _drop(function)
        for function, signatures in held:
            _compile_again(function, signatures)


def _drop(function: Any) -> None:
    """Empty ``function``'s disk cache (or, where it cannot be written, stop reading it) and drop
    its compiled code. Parts of numba's dispatcher that are not a public interface: if they
    change, nothing is done."""
    with contextlib.suppress(AttributeError):
        try:
            function._cache.flush()
        except OSError:  # the cache folder is gone or read-only: its old code must not load
            function._cache.disable()
        function._make_finalizer()()  # as numba's Dispatcher.recompile does, not compiling
        function._reset_overloads()
        function._cache_hits.clear()
        function._cache_misses.clear()
    _DROPPED.add(function)


def _compile_again(function: Any, signatures: list) -> None:
    """Compile ``function`` for ``signatures`` (the argument types it held code for, from its
    source: its cache is empty), also when it is closed to new compiles (explicit
    signatures), as numba's Dispatcher.recompile does."""
    previous = function._can_compile
    function._can_compile = True
    try:
        for signature in signatures:
            function.compile(signature)
    finally:
        function._can_compile = previous
