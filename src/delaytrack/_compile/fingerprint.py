"""The fingerprint of a kernel of the user's: a hash of all the code that compiling it depends on.

numba keys a function's compiled code on its own file only, and the engine's parts are compiled
once for each kernel they call and kept on disk (:mod:`delaytrack._compile.native_parts`). A
kernel's numba type is therefore named by its function's module and name and, for a function
outside this package, by :func:`code_fingerprint`: a hash of its code and of every function,
constant and numba option it reaches, so that an edit to any of them compiles its parts again.
The code of this package is covered by the cache folder instead
(:mod:`delaytrack._compile.disk_cache`).

The walk that takes the fingerprint also finds what the guards check
(:mod:`delaytrack._compile.guards`): the module globals that numba compiles into the code as
constants (:func:`frozen_globals`) and the functions that draw random numbers
(:func:`random_draws`).
"""

from __future__ import annotations

import enum
import hashlib
import types as python_types
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

from delaytrack._compile.functions import (
    PACKAGE,
    global_names,
    in_package,
    is_compiled,
    python_function,
    qualified_name,
)
from delaytrack._compile.own_options import options_text
from delaytrack._compile.random_reads import random_module_read

__all__ = [
    "FrozenGlobal",
    "code_fingerprint",
    "compiled_functions_reached",
    "frozen_globals",
    "name_with_code",
    "random_draws",
]

#: Modules whose functions are numba's or the interpreter's, never walked for a fingerprint.
_LIBRARIES = frozenset({"numba", "numpy", "math", "cmath", "builtins", "llvmlite", "scipy"})


def _code_text(code: python_types.CodeType) -> bytes:
    """What ``code`` does: its bytecode, names and constants, nested functions included (not
    its file or line numbers, nor how it was loaded: ``marshal`` gives other bytes for the same
    code read from a ``.pyc``)."""
    parts = [
        code.co_code,
        repr((code.co_names, code.co_varnames, code.co_freevars, code.co_cellvars)).encode(),
        repr((code.co_argcount, code.co_kwonlyargcount, code.co_flags)).encode(),
    ]
    for constant in code.co_consts:
        if isinstance(constant, python_types.CodeType):
            parts.append(_code_text(constant))
        else:
            parts.append(repr(constant).encode())
    return b"\x1f".join(parts)


def _is_users(module: str | None) -> bool:
    """Whether ``module`` is a user's (not this package, numba, NumPy or the interpreter's)."""
    top = (module or "").partition(".")[0]
    return bool(top) and top != PACKAGE and top not in _LIBRARIES


def _members(container: object) -> list[object]:
    """The functions a user's class (its methods, properties, a jitclass's methods) or module
    (the functions and classes defined in it) holds, for the walk."""
    if isinstance(container, python_types.ModuleType):
        return [
            value
            for value in vars(container).values()
            if getattr(value, "__module__", None) == container.__name__
        ]
    members: list[object] = []
    for value in vars(container).values():
        if isinstance(value, property):
            members += [value.fget, value.fset]
        elif isinstance(value, staticmethod | classmethod):
            members.append(value.__func__)
        else:
            members.append(value)
    class_type = getattr(container, "class_type", None)  # a numba jitclass
    members += list(getattr(class_type, "methods", {}).values())
    return members


#: Values whose text is their ``repr``.
_CONSTANTS = (enum.Enum, np.generic, bool, int, float, complex, str, bytes)


def _value_text(value: object, walk: list[object], depth: int = 0) -> str | None:
    """How a global or closure value enters a fingerprint; functions, and the members of a
    user's classes and modules, are queued in ``walk``."""
    if python_function(value) is not None:
        walk.append(value)
        return qualified_name(value)
    if isinstance(value, python_types.ModuleType | type):
        if _is_users(getattr(value, "__module__", None) or getattr(value, "__name__", None)):
            walk.append(value)
        name = getattr(value, "__qualname__", value.__name__)
        return f"{getattr(value, '__module__', '')}:{name}"
    if isinstance(value, np.ndarray):
        return f"array{value.dtype}{value.shape}:{hashlib.sha256(value.tobytes()).hexdigest()}"
    if isinstance(value, _CONSTANTS):
        return f"{type(value).__name__}:{value!r}"
    if value is None:
        return "None"
    if isinstance(value, python_types.BuiltinFunctionType | np.ufunc):
        return f"builtin {getattr(value, '__module__', None)}.{value.__name__}"
    if isinstance(value, set | frozenset) and depth < 4:
        return f"set({','.join(sorted(str(_value_text(item, walk, depth + 1)) for item in value))})"
    if isinstance(value, list | tuple | dict) and depth < 4:
        items = sorted(value.items(), key=repr) if isinstance(value, dict) else enumerate(value)
        inner = [f"{key!r}={_value_text(item, walk, depth + 1)}" for key, item in items]
        return f"{type(value).__name__}({','.join(inner)})"
    return f"object@{id(value)}"  # known only in this process: compiled again in the next


def code_fingerprint(function: Callable[..., Any]) -> str:
    """Hash (16 hex digits) of the code that compiling ``function`` depends on, outside delaytrack.

    It covers the code as loaded (bytecode, constants and names, not the file on disk, which may
    have changed since) of ``function`` and of every function it reaches through its globals and
    closure, through the user modules and classes it names (their functions, methods,
    properties and jitclass methods; a class's public constants; the constants of a module that
    the code reads as attributes, such as ``config.GAIN``, which numba compiles in), the values
    of the constants they read, and the numba options each compiled one was decorated with
    (``fastmath``, ``error_model``...). Functions of this package are covered by the cache
    folder and not walked. A value with no stable text (an arbitrary object) is taken by
    identity: the key then holds in this process only.
    """
    return _walk(function)[0]


def compiled_functions_reached(function: Callable[..., Any]) -> tuple[Any, ...]:
    """The numba-compiled functions of the user's that :func:`code_fingerprint` walks from
    ``function`` (``function`` itself among them when it is compiled and not this package's)."""
    return _walk(function)[1]


def frozen_globals(function: object) -> tuple[FrozenGlobal, ...]:
    """The module globals that the compiled code :func:`code_fingerprint` walks from
    ``function`` reads as constants, with their values when it was first walked in this process
    (:func:`~delaytrack._compile.guards.refuse_changed_globals`)."""
    return _walk(function)[2]


def random_draws(function: object) -> tuple[tuple[str, str], ...]:
    """``(function, random module)`` of each function that :func:`code_fingerprint` walks from
    ``function`` and that reads a random module
    (:func:`~delaytrack._compile.guards.refuse_random_draws`)."""
    return _walk(function)[3]


def name_with_code(function: Callable[..., Any]) -> str:
    """``module:name`` of ``function`` and, for one outside this package, ``#`` and its
    :func:`code_fingerprint`: the name of a kernel in its numba type."""
    name = qualified_name(function)
    if in_package(function):
        return name
    return f"{name}#{code_fingerprint(function)}"


@lru_cache(maxsize=1024)
def _walk(
    function: Callable[..., Any],
) -> tuple[str, tuple[Any, ...], tuple[FrozenGlobal, ...], tuple[tuple[str, str], ...]]:
    """:func:`code_fingerprint` of ``function``, :func:`compiled_functions_reached`, the
    module globals their compiled code reads as constants, with their values now (taken once
    per process, as numba compiles them once: :func:`frozen_globals`), and the functions
    that draw random numbers, with the random module each reads (:func:`random_draws`)."""
    digest = hashlib.sha256()
    reached: list[Any] = []
    frozen: list[FrozenGlobal] = []
    draws: list[tuple[str, str, str | None]] = []  # function, random module, member name
    walk: list[object] = [function]
    seen: set[int] = set()
    modules: list[python_types.ModuleType] = []
    names_read: set[str] = set()
    members: dict[int, str] = {}  # functions met as members of a module or class: their names
    while walk:
        current = walk.pop()
        if id(current) in seen:
            continue
        seen.add(id(current))
        if isinstance(current, python_types.ModuleType | type):
            found = _members(current)
            members.update((id(item), getattr(item, "__name__", "")) for item in found)
            walk += found
            if isinstance(current, type):  # class constants, enum members
                for key, value in sorted(vars(current).items()):
                    if not key.startswith("_") and isinstance(value, _CONSTANTS):
                        digest.update(f"{key}={_value_text(value, walk)}".encode())
            else:
                modules.append(current)
            continue
        inner = python_function(current)
        if inner is None:
            continue
        top_package = (inner.__module__ or "").partition(".")[0]
        if top_package in _LIBRARIES or (top_package == PACKAGE and current is not function):
            continue
        if inner.__code__.co_filename == "<string>" and current is not function:
            continue  # generated by the library that made it (a dataclass's __init__, __eq__)
        if is_compiled(current) and top_package != PACKAGE:
            reached.append(current)
        digest.update(qualified_name(inner).encode())
        digest.update(_code_text(inner.__code__))
        digest.update(options_text(current, root=current is function).encode())
        names = global_names(inner.__code__)
        names_read |= names
        source = random_module_read(inner.__code__, inner.__globals__)
        if source is not None:
            draws.append((qualified_name(inner), source, members.get(id(current))))
        for name in sorted(names):
            if name in inner.__globals__:
                value = inner.__globals__[name]
                text = _value_text(value, walk)
                if text is not None:
                    digest.update(f"{name}={text}".encode())
                if is_compiled(current) and isinstance(value, _FROZEN):
                    frozen.append(
                        FrozenGlobal(
                            qualified_name(inner), inner.__globals__, name, text, _shown(value)
                        )
                    )
        for cell in inner.__closure__ or ():
            text = _value_text(cell.cell_contents, walk)
            if text is not None:
                digest.update(text.encode())
    # The constants of a user's module that the code reads as attributes (``config.GAIN``):
    # numba compiles their values in.
    for module in modules:
        for key, value in sorted(vars(module).items()):
            if key in names_read and isinstance(value, (*_CONSTANTS, np.ndarray)):
                text = _value_text(value, [])
                digest.update(f"{module.__name__}.{key}={text}".encode())
                frozen.append(FrozenGlobal(module.__name__, vars(module), key, text, _shown(value)))
    # A member of a module or class that the code never names (a factory beside the kernel)
    # is not called by it: its draws are not the kernel's.
    called = tuple((owner, source) for owner, source, name in draws if name in (None, *names_read))
    return digest.hexdigest()[:16], tuple(reached), tuple(frozen), called


#: Values of module globals that numba compiles into a function as constants.
_FROZEN = (*_CONSTANTS, np.ndarray, tuple)


@dataclass(frozen=True)
class FrozenGlobal:
    """A module global ``name`` in ``namespace`` that compiled code of ``owner`` reads, the
    text of its value (:func:`_value_text`) when the code's fingerprint was taken, and that
    value ``shown`` in a message."""

    owner: str
    namespace: dict
    name: str
    text: str | None
    shown: str

    def changed(self) -> bool:
        """Whether the global's value now differs from the one the fingerprint took."""
        return _value_text(self.namespace.get(self.name), []) != self.text

    def shown_now(self) -> str:
        """The global's value now, shown in a message."""
        return _shown(self.namespace.get(self.name))


def _shown(value: object) -> str:
    """A short text of ``value`` for a message."""
    text = repr(value)
    return text if len(text) <= 40 else f"{text[:37]}..."
