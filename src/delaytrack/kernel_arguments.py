"""The arguments the engine passes to each kind of kernel, checked before anything is compiled.

A kernel of yours with a parameter too many or too few would otherwise fail only when numba
compiles the code that calls it, seconds later and with a long message about types; this check says
at once which kernel, what it takes and what it must take.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from functools import lru_cache
from typing import Any

from delaytrack.components import (
    call_command_map,
    call_delay,
    call_reduced_dynamics,
    call_reference,
    call_step,
    call_stepper,
    call_terms,
    call_velocity_map,
)

__all__ = ["KERNEL_ARGUMENTS", "check_kernel_arguments"]


def _passed_on(call: Callable[..., Any], *kept: str) -> tuple[str, ...]:
    """The arguments a ``call_*`` function of :mod:`delaytrack.components` passes to the kernel
    it is given first: its own after the kernel, less those it keeps for itself (``kept``)."""
    names = list(inspect.signature(call).parameters)[1:]
    return tuple(name for name in names if name not in kept)


#: The arguments of each kind of kernel, in the order the engine passes them: those of the
#: component protocol's functions (:mod:`delaytrack.components`).
KERNEL_ARGUMENTS: dict[str, tuple[str, ...]] = {
    "terms": _passed_on(call_terms),
    "command_map": _passed_on(call_command_map, "input_map"),  # used only by the solve
    "stepper": _passed_on(call_stepper),
    "velocity_map": _passed_on(call_velocity_map),
    "reduced_dynamics": _passed_on(call_reduced_dynamics),
    "step": _passed_on(call_step),
    "reference": _passed_on(call_reference),
    "delay": _passed_on(call_delay),
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
