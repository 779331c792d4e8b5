"""A component's :class:`~delaytrack.components.Kernel` in compiled code: a numba type of its own.

The type is named by :attr:`Kernel.key <delaytrack.components.Kernel.key>` (the function's module
and name and, for a function of the user's, its fingerprint,
:func:`~delaytrack._compile.fingerprint.code_fingerprint`) and carries no data: compiled code that
takes a kernel knows its functions when it is compiled, and numba compiles that code (its part
of the engine, :mod:`delaytrack._compile.native_parts`) once for each kernel and caches it on
disk under this name. A user's compiled plant is so compiled once, not once per process, and an
edit to its code compiles it again.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from llvmlite import ir
from numba import types
from numba.extending import NativeValue, models, register_model, typeof_impl, unbox

from delaytrack._compile.functions import users_compiled
from delaytrack._compile.own_options import keep_own_options

if TYPE_CHECKING:
    from delaytrack.components import Kernel

__all__ = ["KernelType", "known_to_numba", "numba_type_of"]

#: Every Kernel numba has typed in this process (:func:`numba_type_of`), by key: the compiled
#: engine finds its functions here.
_KERNELS: dict[str, Kernel] = {}


class KernelType(types.Type):
    """numba type of a :class:`~delaytrack.components.Kernel`: no runtime data, the kernel is
    known when compiling."""

    #: A call through an address may fill it in (:mod:`delaytrack._compile.native_call`).
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


@unbox(KernelType)
def _unbox_kernel(typ: KernelType, obj: Any, c: Any) -> NativeValue:
    return NativeValue(ir.Constant(c.context.get_value_type(typ), None))


def numba_type_of(kernel: Kernel) -> KernelType:
    """The numba type of ``kernel``, which is registered under its key for the compiler. The
    user's compiled kernel (and command map and stepper) keep their own numba options when the
    engine compiles them (:func:`~delaytrack._compile.own_options.keep_own_options`)."""
    for root in kernel.roots:
        if users_compiled(root):
            keep_own_options(root)
    _KERNELS.setdefault(kernel.key, kernel)
    return KernelType(kernel.key)


def known_to_numba(kernel_class: type) -> type:
    """Have numba type an object of ``kernel_class`` (:class:`~delaytrack.components.Kernel`)
    passed to compiled code as its ``numba_type``; returns the class (a class decorator)."""

    @typeof_impl.register(kernel_class)
    def _typeof_kernel(value: Kernel, context: Any) -> KernelType:
        return value.numba_type

    return kernel_class
