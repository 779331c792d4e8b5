"""What a kernel of the user's must not do to be compiled into the engine, refused in a message
that names it: read a module global that has changed since numba compiled it in, draw random
numbers from a generator no run seeds, or return an array that the engine would never free."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from numba import types
from numba.core.datamodel import default_manager
from numba.core.errors import TypingError

from delaytrack._compile.fingerprint import frozen_globals, random_draws
from delaytrack._compile.functions import (
    in_package,
    python_function,
    qualified_name,
    users_compiled,
)

if TYPE_CHECKING:
    from delaytrack.components import Kernel

__all__ = [
    "holds_managed_memory",
    "refuse_changed_globals",
    "refuse_managed_result",
    "refuse_random_draws",
]


def refuse_changed_globals(kernel: Kernel) -> None:
    """Raise a ValueError when a module global that compiled code of ``kernel`` reads (a number,
    an array, a tuple, or a constant of a module it reads as an attribute) has another value
    than when the kernel was first named in this process (its fingerprint, :attr:`Kernel.key`).

    numba compiles such a value into the code once; a later change (a factory's keyword that
    sets a module global, a notebook cell) would reach neither the run nor the kernel's name, so
    runs with different values would give the same numbers under the same name.
    """
    for root in kernel.roots:
        if not users_compiled(root):
            continue
        for frozen in frozen_globals(root):
            if frozen.changed():
                name = qualified_name(root)
                where = "" if frozen.owner == name else f" (in {frozen.owner})"
                raise ValueError(
                    f"your kernel {name} reads the module global {frozen.name}{where}, which "
                    f"was {frozen.shown} when the kernel was first used in this process and "
                    f"is {frozen.shown_now()} now: numba compiled {frozen.shown} into the "
                    "kernel, so the run would not see the change; pass the value in the "
                    "kernel's parameter vector (through your factory's parameters), not in a "
                    "module global"
                )


def refuse_random_draws(kernel: Kernel) -> None:
    """Raise a ValueError when code of the user's ``kernel`` (its function, command map or
    stepper, or a function they reach) reads Python's ``random`` or ``numpy.random``.

    Compiled, these draw from numba's generator, seeded differently in every process and
    thread and never by the run, so that two runs of one experiment give different numbers
    under the same name (plain Python's differ the same way). Random numbers belong in the
    parameter vector, drawn by the factory from a seeded generator, as the built-in
    :class:`~delaytrack.delays.RandomDelay` draws its knots.
    """
    for root in kernel.roots:
        if root is None or in_package(root) or python_function(root) is None:
            continue
        draws = random_draws(root)
        if draws:
            (owner, source), name = draws[0], qualified_name(root)
            where = "" if owner == name else f" (in {owner})"
            raise ValueError(
                f"your kernel {name} draws random numbers: it reads {source}{where}, whose "
                "generator no run seeds, so every run would give other numbers; draw them in "
                "your factory from a seeded generator (numpy.random.default_rng(seed)) and pass "
                "them in the kernel's parameter vector"
            )


def holds_managed_memory(value_type: Any) -> bool:
    """Whether a value of the numba type ``value_type`` holds memory of numba's runtime (an
    array, or a tuple with one): a result that compiled code without the runtime cannot free."""
    return bool(default_manager.lookup(value_type).contains_nrt_meminfo())


def refuse_managed_result(function: Any, argument_types: tuple, role: str, returns: str) -> None:
    """At the typing of a call of ``function`` (a compiled kernel of the user's, the ``role`` of a
    component) with ``argument_types``: refuse a result that holds an array, which a kernel
    compiled with numba's runtime hands to the engine's parts, compiled without it, that
    would never free it (a leak at every call). ``returns`` is what the kernel may return."""
    if not users_compiled(function):
        return
    # The signature numba calls, compiled for these arguments or, for a kernel compiled for
    # signatures given in advance, the one it converts them to.
    called = function.typingctx.resolve_function_type(
        types.Dispatcher(function), tuple(argument_types), {}
    )
    if called is None:  # no signature takes them: numba's own error follows
        return
    result = called.return_type
    if holds_managed_memory(result):
        into = " (write its results into the arrays it is given)" if returns == "nothing" else ""
        raise TypingError(
            f"the {role} kernel {qualified_name(function)} returns {result}; it must return "
            f"{returns}{into}"
        )
