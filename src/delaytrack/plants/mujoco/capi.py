"""MuJoCo's C functions called from compiled kernels, by addresses given at run time.

A kernel receives the addresses of MuJoCo's ``mjModel``, ``mjData``, of the arrays inside
``mjData`` and of the C functions it calls as numbers in its parameter vector, reads and
writes those arrays through :func:`read_at` and :func:`write_at` (no array object is made, so
they also work in kernels compiled without numba's runtime) and calls the functions through
:func:`call_void2` and :func:`call_void4`. Nothing in the compiled code depends on where the
library or the model were loaded in this process, so numba caches it on disk like any other
kernel. An address (below 2**47 in a user process on x86-64 and AArch64 Linux) is exact in a
float64. All four functions also run as plain Python (through :mod:`ctypes`), for the
plain-Python engine.
"""

from __future__ import annotations

import ctypes
import glob
import os
from functools import cache
from typing import Any

import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic, overload

__all__ = [
    "call_void2",
    "call_void4",
    "function_address",
    "mujoco_library",
    "read_at",
    "write_at",
]

_VOID2 = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_void_p)
_VOID4 = ctypes.CFUNCTYPE(None, *[ctypes.c_void_p] * 4)


@cache
def mujoco_library(folder: str) -> ctypes.CDLL:
    """MuJoCo's shared library in ``folder`` (the ``mujoco`` package's), loaded once."""
    candidates = sorted(glob.glob(os.path.join(folder, "libmujoco.so*"))) or sorted(
        glob.glob(os.path.join(folder, "libmujoco*.dylib"))
    )
    if not candidates:
        raise ImportError(f"MuJoCo's shared library was not found in {folder}")
    return ctypes.CDLL(candidates[0])


def function_address(mujoco: Any, name: str) -> int:
    """Address of MuJoCo's C function ``name`` (of the library its package ``mujoco`` loaded)."""
    function = getattr(mujoco_library(os.path.dirname(mujoco.__file__)), name)
    address = ctypes.cast(function, ctypes.c_void_p).value
    if address is None:  # ctypes gives a null pointer's address as None
        raise ImportError(f"MuJoCo's C function {name} has a null address")
    return address


def call_void2(function, first, second):
    """Call the C function at address ``function`` with two pointers ``first``, ``second``
    (integer addresses); it returns nothing."""
    _VOID2(int(function))(int(first), int(second))


def call_void4(function, first, second, third, fourth):
    """As :func:`call_void2`, with four pointers."""
    _VOID4(int(function))(int(first), int(second), int(third), int(fourth))


def read_at(address, index):
    """Entry ``index`` of the float64 numbers at ``address``."""
    return ctypes.c_double.from_address(int(address) + 8 * int(index)).value


def write_at(address, index, value):
    """Set entry ``index`` of the float64 numbers at ``address`` to ``value``."""
    ctypes.c_double.from_address(int(address) + 8 * int(index)).value = float(value)


def _codegen(arity: int):
    """Code calling the C function at an integer address with ``arity`` pointer arguments
    (integer addresses), returning nothing."""

    def codegen(context, builder, signature, values):
        pointer = ir.IntType(8).as_pointer()
        function_type = ir.FunctionType(ir.VoidType(), [pointer] * arity)
        callee = builder.inttoptr(values[0], function_type.as_pointer())
        builder.call(callee, [builder.inttoptr(value, pointer) for value in values[1:]])
        return context.get_dummy_value()

    return codegen


@intrinsic
def _call_void2(typingctx, function, first, second):
    return types.void(*[types.int64] * 3), _codegen(2)


@intrinsic
def _call_void4(typingctx, function, first, second, third, fourth):
    return types.void(*[types.int64] * 5), _codegen(4)


@intrinsic
def _read(typingctx, address, index):
    def codegen(context, builder, signature, values):
        pointer = builder.inttoptr(values[0], ir.DoubleType().as_pointer())
        return builder.load(builder.gep(pointer, [values[1]]))

    return types.float64(types.int64, types.int64), codegen


@intrinsic
def _write(typingctx, address, index, value):
    def codegen(context, builder, signature, values):
        pointer = builder.inttoptr(values[0], ir.DoubleType().as_pointer())
        builder.store(values[2], builder.gep(pointer, [values[1]]))
        return context.get_dummy_value()

    return types.void(types.int64, types.int64, types.float64), codegen


@overload(call_void2, inline="always")
def _call_void2_compiled(function, first, second):
    def impl(function, first, second):
        _call_void2(np.int64(function), np.int64(first), np.int64(second))

    return impl


@overload(call_void4, inline="always")
def _call_void4_compiled(function, first, second, third, fourth):
    def impl(function, first, second, third, fourth):
        _call_void4(
            np.int64(function), np.int64(first), np.int64(second), np.int64(third), np.int64(fourth)
        )

    return impl


@overload(read_at, inline="always")
def _read_at_compiled(address, index):
    def impl(address, index):
        return _read(np.int64(address), np.int64(index))

    return impl


@overload(write_at, inline="always")
def _write_at_compiled(address, index, value):
    def impl(address, index, value):
        _write(np.int64(address), np.int64(index), np.float64(value))

    return impl
