"""Calling a compiled function through its address, so that its caller is compiled without it.

numba compiles a call of one ``njit`` function from another by linking the callee's code into
the caller's and optimising the two together. The engine calls the plant's integrator, the
reference, the controller's step and the delay profile once a tick, so compiled that way it
would be compiled again, tick loop and all, for every combination of them. Called through the
address of their compiled code (:class:`NativeFunction`), the engine is compiled once, and each
of them once for its own component (its own entry in numba's disk cache, keyed by the
component's kernel: :mod:`delaytrack._compile.native_parts`).

The call uses numba's own calling convention (the callee's compiled code, not a C wrapper), so
arrays, tuples and kernels pass as they would in a linked call; the callee's argument types are
part of the numba type of a :class:`NativeFunction` and must equal those of the call, which
compiling the caller checks.

An argument that carries no data at run time (a component's kernel, whose numba type names the
code it calls, marked ``carries_no_data``) can be *bound*: the caller does not pass it, the call
fills it in, and its type is not part of the :class:`NativeFunction`'s numba type, so that one
compiled caller calls the code compiled for any component.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.errors import TypingError
from numba.extending import (
    NativeValue,
    intrinsic,
    models,
    overload,
    register_model,
    typeof_impl,
    unbox,
)

__all__ = ["NativeFunction", "NativeFunctionType", "call_native"]


@dataclass(frozen=True)
class NativeFunction:
    """A ``numba.njit`` function compiled for ``signature`` (its argument types), known to
    compiled code by the address of that compiled code.

    Parameters
    ----------
    function : numba dispatcher
        The compiled function.
    signature : tuple of numba types
        The types of its arguments.
    address : int
        Where its compiled code is, in this process.
    bound : tuple of int
        Positions of the arguments that carry no data (an opaque numba type, such as a
        component's kernel): the caller leaves them out and the call fills them in.
    returns : numba type
        What it returns (``none`` for nothing).
    """

    function: Any
    signature: tuple
    address: int
    bound: tuple = ()
    returns: types.Type = types.none

    @classmethod
    def of(
        cls, function: Any, signature: tuple, bound: tuple = (), returns: types.Type = types.none
    ) -> NativeFunction:
        """``function`` compiled (or loaded from numba's disk cache) for ``signature``, returning
        ``returns``, with the arguments at the positions ``bound`` filled in by the call.

        Its compiled code is looked up at every call of this method: numba keeps every compiled
        version of a function for the life of the process, so the address stays valid, and a
        recompiled function gives its new code's. (The simulator keeps the first one it finds
        for each function and signature,
        :meth:`delaytrack._compile.native_parts.NativePart.native`: this package's functions are
        not recompiled.)
        """
        signature = tuple(signature)
        bound = _check_bound(signature, bound)
        result = function.overloads.get(signature)
        if result is None:
            function.compile(signature)
            result = function.overloads[signature]
        if result.objectmode:
            raise TypeError(
                f"{function.__name__} is compiled in object mode; the engine calls only "
                "nopython code (numba.njit)"
            )
        if result.signature.return_type != returns:
            raise TypeError(
                f"{function.__name__} returns {result.signature.return_type}, not {returns}"
            )
        address = result.library.get_pointer_to_function(result.fndesc.llvm_func_name)
        if not address:
            raise RuntimeError(f"numba gave no address for the compiled {function.__name__}")
        return cls(function, signature, address, bound, returns)

    @property
    def runs_as_python(self) -> bool:
        """Never: the function is compiled (see :mod:`delaytrack._compile.jit`)."""
        return False

    @cached_property
    def numba_type(self) -> NativeFunctionType:
        """Its numba type, made once (numba types it at every call of the engine)."""
        free = tuple(t for i, t in enumerate(self.signature) if i not in self.bound)
        return NativeFunctionType(free, self.bound, self.returns)


def _check_bound(signature: tuple, bound: tuple) -> tuple:
    """The positions ``bound`` in increasing order; refuse one that is out of range or whose
    type does not declare that it carries no data (``carries_no_data``: a null is passed)."""
    positions = tuple(sorted(set(bound)))
    for position in positions:
        if not 0 <= position < len(signature):
            raise ValueError(f"bound position {position} is outside the {len(signature)} arguments")
        if not getattr(signature[position], "carries_no_data", False):
            raise TypeError(
                f"argument {position} ({signature[position]}) may carry data: it cannot be bound"
            )
    return positions


class NativeFunctionType(types.Type):
    """numba type of a :class:`NativeFunction`: the types of the arguments its callers pass, the
    positions of those it fills in and what it returns, not which function it is (the address
    is a run-time value), so one caller serves every function of that signature."""

    def __init__(
        self, signature: tuple, bound: tuple = (), returns: types.Type = types.none
    ) -> None:
        self.signature = tuple(signature)
        self.bound = tuple(bound)
        self.returns = returns
        arguments = ", ".join(map(str, self.signature))
        filled = f"; bound {list(self.bound)}" if self.bound else ""
        super().__init__(name=f"NativeFunction({arguments}{filled}) -> {returns}")

    @property
    def key(self) -> tuple:
        """The types themselves (not their text) identify the type."""
        return self.signature, self.bound, self.returns

    def __hash__(self) -> int:
        """The key's hash, computed once in this process: numba hashes the engine's argument
        types at every call, and hashing the signature anew cost 20 µs a call."""
        value = self.__dict__.get("_hash")
        if value is None:
            value = self.__dict__["_hash"] = hash(self.key)
        return value

    def __getstate__(self) -> dict:
        """Pickled (numba's disk cache) without the hash, which differs between processes."""
        return {name: value for name, value in self.__dict__.items() if name != "_hash"}


@register_model(NativeFunctionType)
class _NativeFunctionModel(models.PrimitiveModel):
    def __init__(self, dmm: Any, fe_type: NativeFunctionType) -> None:
        super().__init__(dmm, fe_type, ir.IntType(64))


@typeof_impl.register(NativeFunction)
def _typeof_native_function(value: NativeFunction, context: Any) -> NativeFunctionType:
    return value.numba_type


@unbox(NativeFunctionType)
def _unbox_native_function(typ: NativeFunctionType, obj: Any, c: Any) -> NativeValue:
    address = c.pyapi.object_getattr_string(obj, "address")
    value = c.pyapi.long_as_longlong(address)
    c.pyapi.decref(address)
    return NativeValue(value, is_error=c.pyapi.c_api_error())


def call_native(function, arguments):
    """Call the :class:`NativeFunction` ``function`` with the tuple ``arguments`` (those it does
    not bind) and return what it returns. From Python, a bound argument is the object its type
    names (``type.kernel()``)."""
    full = list(arguments)
    for position in function.bound:
        full.insert(position, function.signature[position].kernel())
    return function.function(*full)


@intrinsic
def _call_at(typingctx: Any, function: NativeFunctionType, arguments: types.BaseTuple) -> Any:
    # every tuple type of numba has ``types``; its typing declares it on the subclasses only
    argument_types = tuple(arguments.types)  # type: ignore[attr-defined]
    if argument_types != function.signature:
        raise TypingError(
            f"a native function compiled for ({', '.join(map(str, function.signature))}) is "
            f"called with ({', '.join(map(str, argument_types))})"
        )
    # A bound argument's type is opaque: any opaque type has its data model (one null pointer).
    full_types = list(argument_types)
    for position in function.bound:
        full_types.insert(position, types.voidptr)
    returns = function.returns

    def codegen(context: Any, builder: Any, signature: Any, values: Any) -> Any:
        address, packed = values
        full = [builder.extract_value(packed, i) for i in range(len(argument_types))]
        for position in function.bound:
            full.insert(position, context.get_constant_null(types.voidptr))
        function_type = context.call_conv.get_function_type(returns, full_types)
        callee = builder.inttoptr(address, function_type.as_pointer())
        status, value = context.call_conv.call_function(builder, callee, returns, full_types, full)
        with cgutils.if_unlikely(builder, status.is_error):
            context.call_conv.return_status_propagate(builder, status)
        return value if returns != types.none else context.get_dummy_value()

    return returns(function, arguments), codegen


@overload(call_native, inline="always")
def _call_native_compiled(function, arguments):
    if isinstance(function, NativeFunctionType):

        def impl(function, arguments):
            return _call_at(function, arguments)

        return impl
    return None
