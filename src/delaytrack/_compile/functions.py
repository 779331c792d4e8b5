"""What a function is to the compile machinery: numba-compiled or not, this package's or the
user's, and the name messages and kernel keys give it (``module:qualified name``)."""

from __future__ import annotations

import types as python_types
from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np
from numba.core.dispatcher import Dispatcher

from delaytrack._compile.jit import as_python

__all__ = [
    "FEW_POINTS",
    "PACKAGE",
    "at_few_points",
    "few_points_as_python",
    "global_names",
    "in_package",
    "is_compiled",
    "python_function",
    "qualified_name",
    "users_compiled",
]

#: This package's name: a function of one of its modules is this package's, not the user's.
PACKAGE = __name__.partition(".")[0]


#: Points up to which an evaluation from Python (a reference's ``evaluate``, a plant's ``terms``)
#: runs as plain Python while the compiled code is not in this process: microseconds a point,
#: against the second that compiling (or tenths loading from the disk cache) would take.
FEW_POINTS = 64


def few_points_as_python(function: object, points: int) -> bool:
    """Whether an evaluation of this package's compiled ``function`` at ``points`` points from
    Python should run its plain Python function instead: few points (:data:`FEW_POINTS` or
    fewer), and no compiled code of it in this process yet. Both give the same numbers (the
    same operations on the same IEEE doubles, and the same ``math`` functions). A function of
    the user's always runs compiled: as Python it could differ (a division by zero raises
    there, and numba options such as ``fastmath`` change the compiled numbers)."""
    return (
        is_compiled(function)
        and in_package(function)
        and points <= FEW_POINTS
        and not function.signatures  # type: ignore[attr-defined]
    )


Result = TypeVar("Result")


def at_few_points(
    function: object, points: int, evaluate: Callable[[Callable[..., Any]], Result]
) -> Result:
    """``evaluate(function)``, run as plain Python (within
    :func:`~delaytrack._compile.jit.as_python`: this package's compiled functions, ``function``
    and those it calls, run their Python functions) when :func:`few_points_as_python` says so
    for ``points`` points (with NumPy's warnings off, as compiled code runs), else compiled. A
    value Python refuses where compiled code gives ``inf`` or NaN (a math domain error, an
    overflow, a division by zero) is computed compiled: ``evaluate`` runs again, so it must
    write all of its outputs afresh."""
    if few_points_as_python(function, points):
        try:
            with np.errstate(all="ignore"), as_python():
                return evaluate(function)  # type: ignore[arg-type]
        except (ArithmeticError, ValueError):
            pass
    return evaluate(function)  # type: ignore[arg-type]


def global_names(code: python_types.CodeType) -> set[str]:
    """Global names read by ``code`` and by the functions defined inside it."""
    names = set(code.co_names)
    for constant in code.co_consts:
        if isinstance(constant, python_types.CodeType):
            names |= global_names(constant)
    return names


def is_compiled(function: object) -> bool:
    """Whether ``function`` is a numba-compiled function (``@numba.njit``)."""
    return isinstance(function, Dispatcher)


def python_function(function: object) -> python_types.FunctionType | None:
    """The Python function behind ``function`` (its ``py_func`` when compiled), if any."""
    inner = getattr(function, "py_func", function)
    return inner if isinstance(inner, python_types.FunctionType) else None


def qualified_name(function: object) -> str:
    """``module:qualified name`` of ``function`` (of its Python function when compiled)."""
    inner = python_function(function) or function
    module = getattr(inner, "__module__", None) or "?"
    return f"{module}:{getattr(inner, '__qualname__', type(inner).__name__)}"


def in_package(function: object) -> bool:
    """Whether ``function`` is one of this package's."""
    return qualified_name(function).partition(".")[0] == PACKAGE


def users_compiled(function: object) -> bool:
    """Whether ``function`` is numba-compiled and not one of this package's."""
    return is_compiled(function) and not in_package(function)
