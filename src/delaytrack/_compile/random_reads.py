"""Which random module a function's code reads: Python's ``random`` or ``numpy.random``, whose
generators no run seeds (:func:`~delaytrack._compile.guards.refuse_random_draws`)."""

from __future__ import annotations

import dis
import types as python_types

import numpy as np

__all__ = ["RANDOM_MODULES", "random_module_read"]

#: Modules whose functions draw random numbers from a generator that no run seeds.
RANDOM_MODULES = ("random", "numpy.random")


def _random_module(value: object) -> str | None:
    """The module of :data:`RANDOM_MODULES` that ``value`` is, or whose function it is (a
    function or bound method such as ``random.gauss`` or ``numpy.random.normal``), or None."""
    if isinstance(value, python_types.ModuleType):
        module = value.__name__
    else:
        owner = getattr(value, "__self__", None)
        module = getattr(value, "__module__", None) or type(owner).__module__
    if not isinstance(module, str):
        return None
    return next(
        (name for name in RANDOM_MODULES if module == name or module.startswith(f"{name}.")),
        None,
    )


def random_module_read(code: python_types.CodeType, namespace: dict) -> str | None:
    """The random module of :data:`RANDOM_MODULES` that ``code`` (or a function defined in it)
    reads: through a global that is that module or one of its functions, or as the attribute
    ``random`` of a global that is NumPy (``np.random.random()``); None if none."""
    previous = None
    for instruction in dis.get_instructions(code):
        if instruction.opname in ("LOAD_GLOBAL", "LOAD_NAME"):
            source = _random_module(namespace.get(instruction.argval))
            if source is not None:
                return source
        elif (
            instruction.opname in ("LOAD_ATTR", "LOAD_METHOD")
            and instruction.argval == "random"
            and previous is not None
            and previous.opname in ("LOAD_GLOBAL", "LOAD_NAME")
            and namespace.get(previous.argval) is np
        ):
            return "numpy.random"
        previous = instruction
    for constant in code.co_consts:
        if isinstance(constant, python_types.CodeType):
            source = random_module_read(constant, namespace)
            if source is not None:
                return source
    return None
