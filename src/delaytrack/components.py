"""The component protocol: how the engine calls a plant, model, controller or reference kernel.

Every component of a closed loop is a *kernel* (a function with a fixed signature, compiled with
``numba.njit`` or plain Python) plus a parameter vector it reads. The engine is handed each
component's :class:`Kernel` and calls it through one of the functions below:

===============================  ===========================================================
:func:`call_terms`               plant or nominal model: ``terms(t, q, qdot, params, M, N, G)``
:func:`call_command_map`         nominal model: actuator command realising a force ``τ``
:func:`has_identity_mass`        plant: ``M(q) = I`` always (no solve for ``q̈``)
:func:`plant_sizes`              plant: its ``n`` and ``m``, constants when compiled
:func:`has_stepper`              plant: stepped by an integrator of its own
:func:`call_stepper`             such a plant: one step ``stepper(t, x, u, dt, params, first)``
:func:`call_step`                controller: one tick (see :mod:`delaytrack.controllers.base`)
:func:`call_reference`           reference: ``q_d, q̇_d, q̈_d`` at ``t``
:func:`call_delay`               delay profile of your own: ``h(t)``
===============================  ===========================================================

The built-in components use this protocol exactly as a user's do; adding one is one file with
its kernel and its class.

In compiled code a :class:`Kernel` has a numba type of its own, named by :attr:`Kernel.key`:
the function's module and name and, for a function outside this package, a hash of its code
(and of the functions and constants it reaches). numba compiles the code that calls a kernel
(its part of the engine, :mod:`delaytrack.sim.native_parts`) once for each kernel and caches
it on disk under this name, so a user's compiled plant is compiled once, not once per process,
and an edit to its code compiles it again. The code
of this package is covered by the cache folder instead (:mod:`delaytrack._numba_cache`).
"""

from __future__ import annotations

import contextlib
import dis
import enum
import hashlib
import math
import types as python_types
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property, lru_cache
from typing import Any

import numpy as np
from llvmlite import ir
from numba import types
from numba.core.datamodel import default_manager
from numba.core.dispatcher import Dispatcher
from numba.core.errors import TypingError
from numba.extending import (
    NativeValue,
    models,
    overload,
    register_model,
    typeof_impl,
    unbox,
)

from delaytrack._jit import inline_kernel, tick_kernel
from delaytrack._native_call import NativeFunctionType, call_native
from delaytrack._small_linalg import solve_in_place

__all__ = [
    "Kernel",
    "KernelType",
    "call_command_map",
    "call_delay",
    "call_reference",
    "call_step",
    "call_stepper",
    "call_terms",
    "evaluate_reference",
    "evaluate_step",
    "code_fingerprint",
    "compiled_functions_reached",
    "has_identity_mass",
    "has_stepper",
    "is_compiled",
    "plant_sizes",
    "refuse_changed_globals",
    "refuse_random_draws",
    "solve_input_map",
]

_PACKAGE = __name__.partition(".")[0]
#: Modules whose functions are numba's or the interpreter's, never walked for a fingerprint.
_LIBRARIES = frozenset({"numba", "numpy", "math", "cmath", "builtins", "llvmlite", "scipy"})


def is_compiled(function: object) -> bool:
    """Whether ``function`` is a numba-compiled function (``@numba.njit``)."""
    return isinstance(function, Dispatcher)


def _python_function(function: object) -> python_types.FunctionType | None:
    """The Python function behind ``function`` (its ``py_func`` when compiled), if any."""
    inner = getattr(function, "py_func", function)
    return inner if isinstance(inner, python_types.FunctionType) else None


def _qualified_name(function: object) -> str:
    inner = _python_function(function) or function
    module = getattr(inner, "__module__", None) or "?"
    return f"{module}:{getattr(inner, '__qualname__', type(inner).__name__)}"


def _code_names(code: python_types.CodeType) -> set[str]:
    """Global names read by ``code`` and by the functions defined inside it."""
    names = set(code.co_names)
    for constant in code.co_consts:
        if isinstance(constant, python_types.CodeType):
            names |= _code_names(constant)
    return names


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
    return bool(top) and top != _PACKAGE and top not in _LIBRARIES


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
    if _python_function(value) is not None:
        walk.append(value)
        return _qualified_name(value)
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


#: numba's defaults of the options that a function compiled inside another function's compile
#: takes from that function when it sets none itself (numba's ``CPUTargetOptions.finalize``).
#: ``_nrt`` is numba's runtime, which frees the arrays a function makes.
_OWN_DEFAULTS = {"error_model": "python", "fastmath": False, "_nrt": True}


def _options_text(function: object, root: bool = False) -> str:
    """The numba options of a compiled ``function`` (none for a plain one), in a stable order.
    For the ``root`` of a walk (a kernel itself), an option set to its default in
    ``_OWN_DEFAULTS`` reads as not set: a kernel compiles with those defaults either way
    (:func:`_keep_own_options`); a function it calls takes its options from it instead."""
    options = getattr(function, "targetoptions", None) or {}
    return ";".join(
        f"{name}={sorted(map(str, value)) if isinstance(value, set | frozenset) else value!r}"
        for name, value in sorted(options.items())
        if not (root and name in _OWN_DEFAULTS and _OWN_DEFAULTS[name] == value)
    )


def _keep_own_options(function: Any) -> None:
    """Give a kernel of the user's, ``function`` (compiled), numba's defaults for the options it
    does not set (``_OWN_DEFAULTS``), so that it keeps them when it is first compiled inside the
    engine's compile, whose kernels use ``error_model="numpy"``: numba would otherwise compile it
    with the caller's options, and a division by zero that should raise would give ``inf``. The
    functions it calls keep taking their options from it, as when you call it yourself.

    The options are a new dictionary, given to the dispatcher and to the compiler it holds
    (numba's own reference), so that functions made by one decorator, which share theirs, are
    not changed with it. Parts of numba's dispatcher that are not a public interface: if they
    change, nothing is done."""
    options = {**_OWN_DEFAULTS, **function.targetoptions}
    if options != function.targetoptions:
        with contextlib.suppress(AttributeError):
            function._compiler.targetoptions = options
            function.targetoptions = options


def _refuse_managed_result(function: Any, argument_types: tuple, role: str, returns: str) -> None:
    """At the typing of a call of ``function`` (a compiled kernel of the user's, the ``role`` of a
    component) with ``argument_types``: refuse a result that holds an array, which a kernel
    compiled with numba's runtime hands to the engine's parts, compiled without it, that
    would never free it (a leak at every call). ``returns`` is what the kernel may return."""
    if not _users_compiled(function):
        return
    _, _, arguments, _ = function.get_call_template(tuple(argument_types), {})
    compiled = function.overloads.get(tuple(arguments))
    if compiled is None:  # numba converts the arguments to a signature given in advance
        return
    result = compiled.signature.return_type
    if default_manager.lookup(result).contains_nrt_meminfo():
        into = " (write its results into the arrays it is given)" if returns == "nothing" else ""
        raise TypingError(
            f"the {role} kernel {_qualified_name(function)} returns {result}; it must return "
            f"{returns}{into}"
        )


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


@lru_cache(maxsize=1024)
def _walk(
    function: Callable[..., Any],
) -> tuple[str, tuple[Any, ...], tuple[_Frozen, ...], tuple[tuple[str, str], ...]]:
    """:func:`code_fingerprint` of ``function``, :func:`compiled_functions_reached`, the
    module globals their compiled code reads as constants, with their values now (taken once
    per process, as numba compiles them once: :func:`refuse_changed_globals`), and the
    functions that draw random numbers, with the random module each reads
    (:func:`refuse_random_draws`)."""
    digest = hashlib.sha256()
    reached: list[Any] = []
    frozen: list[_Frozen] = []
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
        inner = _python_function(current)
        if inner is None:
            continue
        module = (inner.__module__ or "").partition(".")[0]
        if module in _LIBRARIES or (module == _PACKAGE and current is not function):
            continue
        if inner.__code__.co_filename == "<string>" and current is not function:
            continue  # generated by the library that made it (a dataclass's __init__, __eq__)
        if is_compiled(current) and module != _PACKAGE:
            reached.append(current)
        digest.update(_qualified_name(inner).encode())
        digest.update(_code_text(inner.__code__))
        digest.update(_options_text(current, root=current is function).encode())
        names = _code_names(inner.__code__)
        names_read |= names
        source = _random_module_read(inner.__code__, inner.__globals__)
        if source is not None:
            draws.append((_qualified_name(inner), source, members.get(id(current))))
        for name in sorted(names):
            if name in inner.__globals__:
                value = inner.__globals__[name]
                text = _value_text(value, walk)
                if text is not None:
                    digest.update(f"{name}={text}".encode())
                if is_compiled(current) and isinstance(value, _FROZEN):
                    frozen.append(
                        _Frozen(
                            _qualified_name(inner), inner.__globals__, name, text, _shown(value)
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
                frozen.append(_Frozen(module.__name__, vars(module), key, text, _shown(value)))
    # A member of a module or class that the code never names (a factory beside the kernel)
    # is not called by it: its draws are not the kernel's.
    called = tuple((owner, source) for owner, source, name in draws if name in (None, *names_read))
    return digest.hexdigest()[:16], tuple(reached), tuple(frozen), called


#: Modules whose functions draw random numbers from a generator that no run seeds.
_RANDOM_MODULES = ("random", "numpy.random")


def _random_module(value: object) -> str | None:
    """The module of :data:`_RANDOM_MODULES` that ``value`` is, or whose function it is (a
    function or bound method such as ``random.gauss`` or ``numpy.random.normal``), or None."""
    if isinstance(value, python_types.ModuleType):
        module = value.__name__
    else:
        owner = getattr(value, "__self__", None)
        module = getattr(value, "__module__", None) or type(owner).__module__
    if not isinstance(module, str):
        return None
    return next(
        (name for name in _RANDOM_MODULES if module == name or module.startswith(f"{name}.")),
        None,
    )


def _random_module_read(code: python_types.CodeType, namespace: dict) -> str | None:
    """The random module of :data:`_RANDOM_MODULES` that ``code`` (or a function defined in it)
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
            source = _random_module_read(constant, namespace)
            if source is not None:
                return source
    return None


#: Values of module globals that numba compiles into a function as constants.
_FROZEN = (*_CONSTANTS, np.ndarray, tuple)


@dataclass(frozen=True)
class _Frozen:
    """A module global ``name`` in ``namespace`` that compiled code of ``owner`` reads, the
    text of its value (:func:`_value_text`) when the code's fingerprint was taken, and that
    value ``shown`` in a message."""

    owner: str
    namespace: dict
    name: str
    text: str | None
    shown: str

    def changed(self) -> bool:
        return _value_text(self.namespace.get(self.name), []) != self.text


def refuse_changed_globals(kernel: Kernel) -> None:
    """Raise a ValueError when a module global that compiled code of ``kernel`` reads (a number,
    an array, a tuple, or a constant of a module it reads as an attribute) has another value
    than when the kernel was first named in this process (its fingerprint, :attr:`Kernel.key`).

    numba compiles such a value into the code once; a later change (a factory's keyword that
    sets a module global, a notebook cell) would reach neither the run nor the kernel's name, so
    runs with different values would give the same numbers under the same name.
    """
    for root in (kernel.function, kernel.command_map, kernel.stepper):
        if not _users_compiled(root):
            continue
        for frozen in _walk(root)[2]:
            if frozen.changed():
                name = _qualified_name(root)
                where = "" if frozen.owner == name else f" (in {frozen.owner})"
                now = _shown(frozen.namespace.get(frozen.name))
                raise ValueError(
                    f"your kernel {name} reads the module global {frozen.name}{where}, which "
                    f"was {frozen.shown} when the kernel was first used in this process and "
                    f"is {now} now: numba compiled {frozen.shown} into the kernel, so the run "
                    "would not see the change; pass the value in the kernel's parameter vector "
                    "(through your factory's parameters), not in a module global"
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
    for root in (kernel.function, kernel.command_map, kernel.stepper):
        if root is None or _in_package(root) or _python_function(root) is None:
            continue
        draws = _walk(root)[3]
        if draws:
            (owner, source), name = draws[0], _qualified_name(root)
            where = "" if owner == name else f" (in {owner})"
            raise ValueError(
                f"your kernel {name} draws random numbers: it reads {source}{where}, whose "
                "generator no run seeds, so every run would give other numbers; draw them in "
                "your factory from a seeded generator (numpy.random.default_rng(seed)) and pass "
                "them in the kernel's parameter vector"
            )


def _shown(value: object) -> str:
    """A short text of ``value`` for a message."""
    text = repr(value)
    return text if len(text) <= 40 else f"{text[:37]}..."


#: Every Kernel numba has typed in this process (:attr:`Kernel.numba_type`), by key: the
#: compiled engine finds its functions here.
_KERNELS: dict[str, Kernel] = {}


@dataclass(frozen=True)
class Kernel:
    """A component's kernel as the engine calls it.

    Parameters
    ----------
    function : callable
        The kernel, ``@numba.njit``-compiled or plain Python (then the engine runs as Python).
    command_map : callable, optional
        For a nominal model: ``command_map(q, params, tau, command)`` writing the actuator
        ``command`` (m,) that realises the generalised force ``τ`` (n,); by default
        :func:`solve_input_map`, ``Ĝ(q) command = τ``.
    identity_mass : bool
        For a plant whose terms kernel always fills ``M(q) = I`` (integrated as
        ``q̈ = G(q) u - N(q, q̇)`` without a solve).
    sizes : (int, int), optional
        For a plant: its numbers of coordinates ``n`` and inputs ``m``. The engine's loops
        over them are then compiled for these sizes (unrolled), once per size.
    stepper : callable, optional
        For a plant stepped by an integrator of its own (a MuJoCo model):
        ``stepper(t, x, u, dt, params, first)`` advances the state ``x = [q, q̇]`` in place over
        one step of ``dt`` from ``t`` with the input ``u`` held (``first``: the first step of a
        run, where it resets any state of its own). The engine then calls it once per step
        instead of its RK4 on the terms.
    """

    function: Callable[..., Any]
    command_map: Callable[..., Any] | None = None
    identity_mass: bool = False
    sizes: tuple[int, int] | None = None
    stepper: Callable[..., Any] | None = None

    def __post_init__(self) -> None:
        for name in ("function", "command_map", "stepper"):
            value = getattr(self, name)
            if not (callable(value) or (name != "function" and value is None)):
                raise TypeError(f"{name} must be callable; got {type(value).__name__}")
        if self.sizes is not None:
            sizes = tuple(self.sizes)
            if len(sizes) != 2 or not all(
                isinstance(size, int | np.integer) and not isinstance(size, bool) and size >= 1
                for size in sizes
            ):
                raise ValueError(f"sizes must be two integers n, m >= 1; got {self.sizes!r}")
            object.__setattr__(self, "sizes", (int(sizes[0]), int(sizes[1])))

    @cached_property
    def key(self) -> str:
        """Name of this kernel's numba type, and of the engine compiled for it on disk."""
        parts = [_name_with_code(self.function)]
        if self.command_map is not None:
            parts.append(f"command_map={_name_with_code(self.command_map)}")
        if self.identity_mass:
            parts.append("identity_mass")
        if self.sizes is not None:
            parts.append("sizes={}x{}".format(*self.sizes))
        if self.stepper is not None:
            parts.append(f"stepper={_name_with_code(self.stepper)}")
        return ",".join(parts)

    @property
    def callable_names(self) -> tuple[str, ...]:
        """``module:name`` of the kernel's function, and of its command map and stepper when it
        has them (for messages)."""
        parts = (self.function, self.command_map, self.stepper)
        return tuple(_qualified_name(part) for part in parts if part is not None)

    @property
    def built_in(self) -> bool:
        """Whether the kernel is one of this package's (its code is covered by the cache folder,
        :mod:`delaytrack._numba_cache`, not by a fingerprint)."""
        return _in_package(self.function)

    @property
    def runs_as_python(self) -> bool:
        """Whether the engine's helpers handed this kernel run as plain Python."""
        return not self.compiled

    @property
    def compiled(self) -> bool:
        """Whether the kernel (and its command map and stepper) are numba-compiled."""
        return _all_compiled(self.function, self.command_map, self.stepper)

    @classmethod
    def of(
        cls,
        function: Callable[..., Any],
        command_map: Callable[..., Any] | None = None,
        identity_mass: bool = False,
        sizes: tuple[int, int] | None = None,
        stepper: Callable[..., Any] | None = None,
    ) -> Kernel:
        """The Kernel of these functions; for compiled ones made once (its key and numba type
        are then computed once, not at every call of a component's ``engine_kernel``). Python
        kernels are made anew, so that a cache never keeps a user's closures alive."""
        if _all_compiled(
            function, command_map, stepper
        ):  # a hashable key for the cache; the Kernel checks the sizes themselves
            key = None if sizes is None else tuple(sizes)
            return _kernel_of(cls, function, command_map, identity_mass, key, stepper)
        return cls(function, command_map, identity_mass, sizes, stepper)

    @cached_property
    def numba_type(self) -> KernelType:
        """This kernel's numba type (:class:`KernelType`). The user's compiled kernel (and
        command map and stepper) keep their own numba options when the engine compiles them
        (:func:`_keep_own_options`)."""
        for root in (self.function, self.command_map, self.stepper):
            if _users_compiled(root):
                _keep_own_options(root)
        _KERNELS.setdefault(self.key, self)
        return KernelType(self.key)

    def __call__(self, *args: Any) -> Any:
        """Run the kernel from Python (compiled if it is)."""
        return self.function(*args)

    def as_python(self) -> Kernel:
        """The same kernel run as plain Python (its ``py_func``; the helpers it calls and the
        command map stay compiled), for the plain-Python engine."""
        return Kernel(
            getattr(self.function, "py_func", self.function),
            self.command_map,
            self.identity_mass,
            self.sizes,
            getattr(self.stepper, "py_func", self.stepper),
        )


def _all_compiled(function: object, *extras: object) -> bool:
    """Whether ``function`` and each of ``extras`` that is given are numba-compiled."""
    return is_compiled(function) and all(extra is None or is_compiled(extra) for extra in extras)


@lru_cache(maxsize=4096)
def _kernel_of(
    cls: type, function: Any, command_map: Any, identity_mass: bool, sizes: Any, stepper: Any
) -> Kernel:
    return cls(function, command_map, identity_mass, sizes, stepper)


def _users_compiled(function: object) -> bool:
    """Whether ``function`` is numba-compiled and not one of this package's."""
    return is_compiled(function) and not _in_package(function)


def _in_package(function: Callable[..., Any]) -> bool:
    """Whether ``function`` is one of this package's."""
    return _qualified_name(function).partition(".")[0] == _PACKAGE


def _name_with_code(function: Callable[..., Any]) -> str:
    name = _qualified_name(function)
    if _in_package(function):
        return name
    return f"{name}#{code_fingerprint(function)}"


class KernelType(types.Type):
    """numba type of a :class:`Kernel`: no runtime data, the kernel is known when compiling."""

    #: A call through an address may fill it in (:mod:`delaytrack._native_call`).
    carries_no_data = True

    def __init__(self, kernel_key: str) -> None:
        self.kernel_key = kernel_key
        super().__init__(name=f"Kernel({kernel_key})")

    def kernel(self) -> Kernel:
        try:
            return _KERNELS[self.kernel_key]
        except KeyError:
            raise RuntimeError(f"no Kernel {self.kernel_key!r} was made in this process") from None


register_model(KernelType)(models.OpaqueModel)


@typeof_impl.register(Kernel)
def _typeof_kernel(value: Kernel, context: Any) -> KernelType:
    return value.numba_type


@unbox(KernelType)
def _unbox_kernel(typ: KernelType, obj: Any, c: Any) -> NativeValue:
    return NativeValue(ir.Constant(c.context.get_value_type(typ), None))


# ---- the calls ---------------------------------------------------------------------------------


def call_terms(terms, t, q, qdot, params, mass, nonlinear, input_map):
    """Fill ``M, N, G`` of a plant or nominal model with its :class:`Kernel` ``terms``."""
    terms(t, q, qdot, params, mass, nonlinear, input_map)


@overload(call_terms, inline="always")
def _call_terms_compiled(terms, t, q, qdot, params, mass, nonlinear, input_map):
    if isinstance(terms, KernelType):
        function = terms.kernel().function
        arguments = (t, q, qdot, params, mass, nonlinear, input_map)
        _refuse_managed_result(function, arguments, "terms", "nothing")

        def impl(terms, t, q, qdot, params, mass, nonlinear, input_map):
            function(t, q, qdot, params, mass, nonlinear, input_map)

        return impl
    return None


def has_identity_mass(terms):
    """Whether the plant :class:`Kernel` ``terms`` always fills ``M(q) = I``."""
    return terms.identity_mass


@overload(has_identity_mass, inline="always")
def _has_identity_mass_compiled(terms):
    if isinstance(terms, KernelType):
        value = terms.kernel().identity_mass

        def impl(terms):
            return value

        return impl
    return None


def has_stepper(terms):
    """Whether the plant :class:`Kernel` ``terms`` is stepped by an integrator of its own."""
    return terms.stepper is not None


@overload(has_stepper, inline="always")
def _has_stepper_compiled(terms):
    if isinstance(terms, KernelType):
        value = terms.kernel().stepper is not None
        return lambda terms: value
    return None


def call_stepper(terms, t, x, u, dt, params, first):
    """Advance ``x`` over one step with the plant's own integrator (:attr:`Kernel.stepper`)."""
    terms.stepper(t, x, u, dt, params, first)


@overload(call_stepper, inline="always")
def _call_stepper_compiled(terms, t, x, u, dt, params, first):
    if isinstance(terms, KernelType):
        stepper = terms.kernel().stepper
        if stepper is None:
            return lambda terms, t, x, u, dt, params, first: None
        _refuse_managed_result(stepper, (t, x, u, dt, params, first), "stepper", "nothing")

        def impl(terms, t, x, u, dt, params, first):
            stepper(t, x, u, dt, params, first)

        return impl
    return None


def plant_sizes(terms, q, u):
    """``(n, m)`` of the plant :class:`Kernel` ``terms``: its :attr:`~Kernel.sizes` when it has
    them (compile-time constants in compiled code), else the lengths of ``q`` and ``u``."""
    if terms.sizes is not None:
        return terms.sizes
    return q.shape[0], u.shape[0]


@overload(plant_sizes, inline="always")
def _plant_sizes_compiled(terms, q, u):
    if isinstance(terms, KernelType):
        sizes = terms.kernel().sizes
        if sizes is None:
            return lambda terms, q, u: (q.shape[0], u.shape[0])
        n, m = sizes

        def impl(terms, q, u):
            return n, m

        return impl
    return None


@inline_kernel
def solve_input_map(input_map, tau, command):
    """The default command map: solve ``G(q) command = τ`` (a fully actuated model).

    ``input_map`` is scratch (the model's ``Ĝ`` of this tick): it is factorised in place, so
    that nothing is allocated.
    """
    for i in range(command.shape[0]):
        command[i] = tau[i]
    if not solve_in_place(input_map, command):  # Ĝ need not be symmetric: partial pivoting
        command[:] = math.nan


def call_command_map(model, q, params, input_map, tau, command):
    """Actuator ``command`` that realises the generalised force ``τ`` on the nominal ``model``
    (``input_map``, the model's ``Ĝ(q)``, may be overwritten).

    The model's own command map when its :class:`Kernel` has one (the wheeled robot's
    ``command = S(q)ᵀ τ``, the paper's Section III), else :func:`solve_input_map`.
    """
    if model.command_map is not None:
        model.command_map(q, params, tau, command)
    else:
        solve_input_map(input_map, tau, command)


@overload(call_command_map)
def _call_command_map_compiled(model, q, params, input_map, tau, command):
    if isinstance(model, KernelType):
        command_map = model.kernel().command_map
        if command_map is None:

            def solve(model, q, params, input_map, tau, command):
                solve_input_map(input_map, tau, command)

            return solve
        _refuse_managed_result(command_map, (q, params, tau, command), "command map", "nothing")

        def own(model, q, params, input_map, tau, command):
            command_map(q, params, tau, command)

        return own
    return None


def call_step(
    step, t, q, qdot, qd, qd_dot, qd_ddot, T_c, h, params, state, model, model_params, command, work
):
    """Run one controller tick with the controller's :class:`Kernel` ``step`` (in the compiled
    engine, its :class:`~delaytrack._native_call.NativeFunction`); the other arguments are those
    of the step kernel (:mod:`delaytrack.controllers.base`)."""
    step(t, q, qdot, qd, qd_dot, qd_ddot, T_c, h, params, state, model, model_params, command, work)


@overload(call_step, inline="always")
def _call_step_compiled(
    step, t, q, qdot, qd, qd_dot, qd_ddot, T_c, h, params, state, model, mp, u, work
):
    # Inlined, so that the tick calls the step itself (a call level cost about 0.13 µs a tick;
    # numba's inliner does not take *arguments): through its address (in the compiled engine,
    # delaytrack.sim.native_parts) or linked into the caller (evaluate_step).
    if isinstance(step, NativeFunctionType):  # native_parts.controller_step_part: kernels bound

        def native(
            step, t, q, qdot, qd, qd_dot, qd_ddot, T_c, h, params, state, model, mp, u, work
        ):
            arguments = (t, q, qdot, qd, qd_dot, qd_ddot, T_c, h, params, state, mp, u, work)
            call_native(step, arguments)

        return native
    if isinstance(step, KernelType):
        function = step.kernel().function
        arguments = (t, q, qdot, qd, qd_dot, qd_ddot, T_c, h, params, state, model, mp, u, work)
        _refuse_managed_result(function, arguments, "controller step", "nothing")

        def impl(step, t, q, qdot, qd, qd_dot, qd_ddot, T_c, h, params, state, model, mp, u, work):
            function(t, q, qdot, qd, qd_dot, qd_ddot, T_c, h, params, state, model, mp, u, work)

        return impl
    return None


def call_reference(reference, t, params, qd, qd_dot, qd_ddot):
    """Evaluate the reference :class:`Kernel` ``reference``: ``q_d, q̇_d, q̈_d`` at ``t``."""
    reference(t, params, qd, qd_dot, qd_ddot)


@overload(call_reference)
def _call_reference_compiled(reference, t, params, qd, qd_dot, qd_ddot):
    if isinstance(reference, NativeFunctionType):  # evaluate_reference, the kernel bound

        def native(reference, t, params, qd, qd_dot, qd_ddot):
            call_native(reference, (t, params, qd, qd_dot, qd_ddot))

        return native
    if isinstance(reference, KernelType):
        function = reference.kernel().function
        arguments = (t, params, qd, qd_dot, qd_ddot)
        _refuse_managed_result(function, arguments, "reference", "nothing")

        def impl(reference, t, params, qd, qd_dot, qd_ddot):
            function(t, params, qd, qd_dot, qd_ddot)

        return impl
    return None


@tick_kernel
def evaluate_step(
    step, t, q, qdot, qd, qd_dot, qd_ddot, T_c, h, params, state, model, model_params, command, work
):
    """:func:`call_step`, compiled on its own for each controller step and nominal model: the
    compiled engine calls it through its address (:mod:`delaytrack.sim.native_parts`)."""
    call_step(
        step,
        t,
        q,
        qdot,
        qd,
        qd_dot,
        qd_ddot,
        T_c,
        h,
        params,
        state,
        model,
        model_params,
        command,
        work,
    )


@tick_kernel
def evaluate_reference(reference, t, params, qd, qd_dot, qd_ddot):
    """:func:`call_reference`, compiled on its own for each reference kernel: the compiled engine
    calls it through its address (:mod:`delaytrack.sim.native_parts`)."""
    call_reference(reference, t, params, qd, qd_dot, qd_ddot)


def call_delay(delay, t, params):
    """Evaluate the delay-profile :class:`Kernel` ``delay``: ``h(t)`` in seconds."""
    return delay(t, params)


@overload(call_delay, inline="always")
def _call_delay_compiled(delay, t, params):
    if isinstance(delay, KernelType):
        function = delay.kernel().function
        _refuse_managed_result(function, (t, params), "delay profile", "a number")

        def impl(delay, t, params):
            return float(function(t, params))

        return impl
    return None
