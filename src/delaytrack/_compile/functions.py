"""What a function is to the compile machinery: numba-compiled or not, this package's or the
user's, and the name messages and kernel keys give it (``module:qualified name``)."""

from __future__ import annotations

import types as python_types

from numba.core.dispatcher import Dispatcher

__all__ = [
    "FEW_POINTS",
    "PACKAGE",
    "few_points_as_python",
    "in_package",
    "is_compiled",
    "python_function",
    "qualified_name",
    "users_compiled",
]

#: This package's name: a function of one of its modules is this package's, not the user's.
PACKAGE = __name__.partition(".")[0]


#: Points up to which an evaluation from Python (a reference's ``evaluate``) runs as plain
#: Python while the compiled code is not in this process: microseconds a point, against the
#: second that compiling (or tenths loading from the disk cache) would take.
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
