"""Calling a compiled function through its address, so that its caller is compiled without it.

numba compiles a call of one ``njit`` function from another by linking the callee's code into
the caller's and optimising the two together. The engine calls a controller's step once a
tick, so compiled that way it would be compiled again, tick loop and all, for every controller.
Called through the address of the step's compiled code (:class:`NativeFunction`), the engine is
compiled once for a plant, model, reference and delay kernel, and each of this package's
controller steps once for itself (its own entry in numba's disk cache): the paper's second and
third controllers then compile in about a second each, not in the several seconds of a whole
engine. A step of the user's stays linked into the engine, whose disk cache is keyed by a
fingerprint of all the code the step reaches (:mod:`delaytrack.components`); numba's own cache
of a function checks only that function's file.

The call uses numba's own calling convention (the step's compiled code, not a C wrapper), so
arrays, tuples and kernels pass as they would in a linked call; the step's argument types are
part of the numba type of a :class:`NativeFunction` and must equal those of the call, which
compiling the caller checks.
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
    """A ``numba.njit`` function compiled for ``signature`` (its argument types, returning
    nothing), known to compiled code by the address of that compiled code.

    Parameters
    ----------
    function : numba dispatcher
        The compiled function.
    signature : tuple of numba types
        The types of its arguments.
    address : int
        Where its compiled code is, in this process.
    """

    function: Any
    signature: tuple
    address: int

    @classmethod
    def of(cls, function: Any, signature: tuple) -> NativeFunction:
        """``function`` compiled (or loaded from numba's disk cache) for ``signature``.

        Its compiled code is looked up at every call of this method: numba keeps every compiled
        version of a function for the life of the process, so the address stays valid, and a
        recompiled function gives its new code's. (The simulator keeps the first one it finds
        for each controller step, :func:`~delaytrack.sim.engine.native_controller_step`: this
        package's steps are not recompiled.)
        """
        signature = tuple(signature)
        result = function.overloads.get(signature)
        if result is None:
            function.compile(signature)
            result = function.overloads[signature]
        if result.objectmode:
            raise TypeError(
                f"{function.__name__} is compiled in object mode; the engine calls only "
                "nopython code (numba.njit)"
            )
        address = result.library.get_pointer_to_function(result.fndesc.llvm_func_name)
        if not address:
            raise RuntimeError(f"numba gave no address for the compiled {function.__name__}")
        return cls(function, signature, address)

    @property
    def runs_as_python(self) -> bool:
        """Never: the function is compiled (see :mod:`delaytrack._jit`)."""
        return False

    @cached_property
    def numba_type(self) -> NativeFunctionType:
        """Its numba type, made once (numba types it at every call of the engine)."""
        return NativeFunctionType(self.signature)


class NativeFunctionType(types.Type):
    """numba type of a :class:`NativeFunction`: its argument types, not which function it is
    (the address is a run-time value), so one caller serves every function of that signature."""

    def __init__(self, signature: tuple) -> None:
        self.signature = tuple(signature)
        super().__init__(name=f"NativeFunction({', '.join(map(str, self.signature))})")

    @property
    def key(self) -> tuple:
        """The argument types themselves (not their text) identify the type."""
        return self.signature

    def __hash__(self) -> int:
        """The signature's hash, computed once in this process: numba hashes the engine's
        argument types at every call, and hashing the signature anew cost 20 µs a call."""
        value = self.__dict__.get("_hash")
        if value is None:
            value = self.__dict__["_hash"] = hash(self.signature)
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
    """Call the :class:`NativeFunction` ``function`` with the tuple ``arguments``."""
    function.function(*arguments)


@intrinsic
def _call_at(typingctx: Any, function: NativeFunctionType, arguments: types.BaseTuple) -> Any:
    argument_types = tuple(arguments.types)
    if argument_types != function.signature:
        raise TypingError(
            f"a native function compiled for ({', '.join(map(str, function.signature))}) is "
            f"called with ({', '.join(map(str, argument_types))})"
        )

    def codegen(context: Any, builder: Any, signature: Any, values: Any) -> Any:
        address, packed = values
        unpacked = [builder.extract_value(packed, i) for i in range(len(argument_types))]
        function_type = context.call_conv.get_function_type(types.none, argument_types)
        callee = builder.inttoptr(address, function_type.as_pointer())
        status, _ = context.call_conv.call_function(
            builder, callee, types.none, argument_types, unpacked
        )
        with cgutils.if_unlikely(builder, status.is_error):
            context.call_conv.return_status_propagate(builder, status)
        return context.get_dummy_value()

    return types.none(function, arguments), codegen


@overload(call_native, inline="always")
def _call_native_compiled(function, arguments):
    if isinstance(function, NativeFunctionType):

        def impl(function, arguments):
            _call_at(function, arguments)

        return impl
    return None
