"""The arguments the engine passes to each kind of kernel, checked before anything is compiled.

A kernel of yours with a parameter too many or too few would otherwise fail only when numba
compiles the engine for it, seconds later and with a long message about types; this check says
at once which kernel, what it takes and what it must take.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from functools import lru_cache
from typing import Any

__all__ = ["KERNEL_ARGUMENTS", "check_kernel_arguments"]

#: The arguments of each kind of kernel, in the order the engine passes them
#: (:mod:`delaytrack.components`).
KERNEL_ARGUMENTS: dict[str, tuple[str, ...]] = {
    "terms": ("t", "q", "qdot", "params", "M", "N", "G"),
    "command_map": ("q", "params", "tau", "command"),
    "stepper": ("t", "x", "u", "dt", "params", "first"),
    "step": (
        "t",
        "q",
        "qdot",
        "qd",
        "qd_dot",
        "qd_ddot",
        "T_c",
        "h",
        "params",
        "state",
        "model",
        "model_params",
        "command",
        "work",
    ),
    "reference": ("t", "params", "qd", "qd_dot", "qd_ddot"),
    "delay": ("t", "params"),
}


def check_kernel_arguments(owner: str, kind: str, function: Callable[..., Any]) -> None:
    """Raise a ValueError when ``function`` cannot be called with the arguments the engine
    passes a kernel of ``kind`` (a key of :data:`KERNEL_ARGUMENTS`); ``owner`` names the
    component in the message (``"plant"``, ``"controller"``)."""
    problem = _argument_problem(kind, getattr(function, "py_func", function))
    if problem:
        raise ValueError(f"{owner}: {problem}")


@lru_cache(maxsize=1024)
def _argument_problem(kind: str, function: Callable[..., Any]) -> str | None:
    """What is wrong with the parameters of ``function`` as a ``kind`` kernel, or None (also
    when Python cannot read its signature: numba then says what it finds)."""
    expected = KERNEL_ARGUMENTS[kind]
    try:
        signature = inspect.signature(function)
    except (TypeError, ValueError):  # no signature to read (a function written in C)
        return None
    try:
        signature.bind(*expected)
    except TypeError:
        name = getattr(function, "__qualname__", repr(function))
        return (
            f"its {kind} kernel must take the {len(expected)} arguments "
            f"({', '.join(expected)}); {name} takes {signature}"
        )
    return None
