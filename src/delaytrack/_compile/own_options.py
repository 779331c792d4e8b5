"""The numba options of a compiled kernel of the user's: kept as its own when the engine's
compile is the first to compile it, and their text in the kernel's fingerprint.

A function that numba compiles inside another function's compile takes the options it does not
set itself from that function (numba's ``CPUTargetOptions.finalize``). The engine's kernels use
``error_model="numpy"``, so a kernel of yours first compiled there would give ``inf`` for a
division by zero that raises when you call it yourself: :func:`keep_own_options` gives it
numba's defaults instead, as it would have on its own.
"""

from __future__ import annotations

import contextlib
from typing import Any

__all__ = ["OWN_DEFAULTS", "keep_own_options", "options_text"]

#: numba's defaults of the options that a function compiled inside another function's compile
#: takes from that function when it sets none itself (numba's ``CPUTargetOptions.finalize``).
#: ``_nrt`` is numba's runtime, which frees the arrays a function makes.
OWN_DEFAULTS = {"error_model": "python", "fastmath": False, "_nrt": True}


def options_text(function: object, root: bool = False) -> str:
    """The numba options of a compiled ``function`` (none for a plain one), in a stable order.
    For the ``root`` of a walk (a kernel itself), an option set to its default in
    :data:`OWN_DEFAULTS` reads as not set: a kernel compiles with those defaults either way
    (:func:`keep_own_options`); a function it calls takes its options from it instead."""
    options = getattr(function, "targetoptions", None) or {}
    return ";".join(
        f"{name}={sorted(map(str, value)) if isinstance(value, set | frozenset) else value!r}"
        for name, value in sorted(options.items())
        if not (root and name in OWN_DEFAULTS and OWN_DEFAULTS[name] == value)
    )


def keep_own_options(function: Any) -> None:
    """Give a kernel of the user's, ``function`` (compiled), numba's defaults for the options it
    does not set (:data:`OWN_DEFAULTS`), so that it keeps them when it is first compiled inside
    the engine's compile, whose kernels use ``error_model="numpy"``: numba would otherwise
    compile it with the caller's options, and a division by zero that should raise would give
    ``inf``. The functions it calls keep taking their options from it, as when you call it
    yourself.

    The options are a new dictionary, given to the dispatcher and to the compiler it holds
    (numba's own reference), so that functions made by one decorator, which share theirs, are
    not changed with it. Parts of numba's dispatcher that are not a public interface: if they
    change, nothing is done."""
    options = {**OWN_DEFAULTS, **function.targetoptions}
    if options != function.targetoptions:
        with contextlib.suppress(AttributeError):
            function._compiler.targetoptions = options
            function.targetoptions = options
