"""Working arrays on the stack of a compiled function, for the innermost loop.

:func:`stack_vector` and :func:`stack_matrix` give a float64 array whose shape is a compile-time
constant, placed in the stack frame of the compiled function that calls them (allocated once when
it is entered, whatever loop the call sits in) instead of on the heap. Memory that the compiler
sees whole is memory it can optimise: the RK4 stages of the plant's integrator
(:func:`delaytrack.sim.integrator.integrate_tick`) keep their slopes, their stage state and the
plant's ``M, N, G`` there, so that a terms kernel inlined into the stage no longer stores the
entries nobody reads (``M = I`` of a robot whose right-hand side skips the solve) and hands the
others to the right-hand side in registers (what that gains: ``docs/performance.md``).

The arrays hold no reference count (numba's runtime ignores them) and must not outlive the call
of the function that made them: they are working memory, never results. Their content starts
undefined, as that of ``np.empty``. Shapes are bounded by :data:`MOST_STACK_ENTRIES` in all, so
that a large model cannot overflow a thread's stack.
"""

from __future__ import annotations

import math

from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.core.errors import TypingError
from numba.extending import intrinsic
from numba.np.arrayobj import make_array, populate_array

__all__ = ["MOST_STACK_ENTRIES", "stack_matrix", "stack_terms", "stack_vector"]

#: Most float64 entries that a compiled function keeps on its stack through these arrays
#: (256 KiB, a small part of a thread's usual 8 MiB stack); callers fall back to heap arrays
#: beyond it.
MOST_STACK_ENTRIES = 32768

_ITEM_SIZE = 8  # float64


def _literal_extent(value: types.Type, name: str) -> int:
    if not isinstance(value, types.IntegerLiteral) or value.literal_value < 1:
        raise TypingError(f"{name} of a stack array must be a positive compile-time constant")
    return value.literal_value


def _stack_array(context, builder, shape: tuple[int, ...]):
    """A C-contiguous float64 array of ``shape`` in the entry block of the function being built."""
    double = context.get_value_type(types.float64)
    memory = cgutils.alloca_once(builder, ir.ArrayType(double, math.prod(shape)))
    strides = [_ITEM_SIZE * math.prod(shape[axis + 1 :]) for axis in range(len(shape))]
    intp = context.get_value_type(types.intp)
    array = make_array(types.Array(types.float64, len(shape), "C"))(context, builder)
    populate_array(
        array,
        data=builder.bitcast(memory, double.as_pointer()),
        shape=[ir.Constant(intp, extent) for extent in shape],
        strides=[ir.Constant(intp, stride) for stride in strides],
        itemsize=ir.Constant(intp, _ITEM_SIZE),
        meminfo=None,
    )
    return array._getvalue()


@intrinsic
def stack_vector(typingctx, length):
    """A float64 array of ``length`` entries (a compile-time constant) on the caller's stack."""
    shape = (_literal_extent(length, "the length"),)

    def codegen(context, builder, signature, arguments):
        return _stack_array(context, builder, shape)

    return types.Array(types.float64, 1, "C")(length), codegen


@intrinsic
def stack_matrix(typingctx, rows, columns):
    """A C-ordered float64 array ``(rows, columns)`` (compile-time constants) on the caller's
    stack."""
    shape = (_literal_extent(rows, "the rows"), _literal_extent(columns, "the columns"))

    def codegen(context, builder, signature, arguments):
        return _stack_array(context, builder, shape)

    return types.Array(types.float64, 2, "C")(rows, columns), codegen


@njit(inline="always")
def stack_terms(n, m):
    """A model's ``M (n, n), N (n,), G (n, m)`` (``n``, ``m`` compile-time constants) on the
    caller's stack, zeroed: an entry a terms kernel leaves unwritten is zero at every call, as
    in a workspace zeroed once a run. Only for compiled callers."""
    mass, nonlinear, input_map = stack_matrix(n, n), stack_vector(n), stack_matrix(n, m)
    for i in range(n):
        nonlinear[i] = 0.0
        for j in range(n):
            mass[i, j] = 0.0
        for j in range(m):
            input_map[i, j] = 0.0
    return mass, nonlinear, input_map
