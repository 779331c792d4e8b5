"""The decorators of every compiled kernel, so that all of them share one set of numba options.

* ``cache=True``: compiled code is kept on disk (see :mod:`delaytrack._numba_cache`).
* ``error_model="numpy"``: a floating-point division by zero gives ``inf``/``NaN`` as in NumPy
  instead of raising. The simulator turns non-finite values into a ``diverged`` status for that
  run alone, whereas an exception would end the whole batch; it also drops a branch per division
  from the inner loop (about a third of the wheeled robot's right-hand side).

:data:`kernel` compiles a function on its own (callable from Python, compiled);
:data:`inline_kernel` registers a plain Python function that compiles into the kernels that call
it and stays plain Python otherwise (the path of user plants given as Python callables).

:data:`hot_kernel` and :data:`hot_inline_kernel` are the same, but inlined into their compiled
callers at the numba IR level (``inline="always"``). They are for the innermost loop: the RK4
sub-step, the plant's right-hand side (evaluated four times per step) and the controller's model.
A numba call passes arrays by reference count (an atomic increment and decrement per array
argument and call), which cost more than the arithmetic of the robot's right-hand side; inlined,
the counts cancel at compile time. The delay kernels stay out-of-line: inlined (numba 0.68) they
broke the applied-input test of the two-link arm.

:data:`borrowing_kernel` is :data:`inline_kernel` compiled without numba's runtime
(``_nrt=False``): no reference counts at all, so it may neither allocate nor return an array
(numba refuses to compile it if it does), only work in arrays its caller owns. Inlining does not
remove every count: a loop over sub-steps kept about 30 atomic operations per RK4 step, a third of
the step's time, in the plant's step; :func:`delaytrack.sim.integrator.integrate_tick` is
therefore one.
"""

from __future__ import annotations

from numba import njit
from numba.extending import register_jitable

__all__ = [
    "KERNEL_OPTIONS",
    "borrowing_kernel",
    "hot_inline_kernel",
    "hot_kernel",
    "inline_kernel",
    "kernel",
]

#: numba options of every compiled kernel.
KERNEL_OPTIONS = {"cache": True, "error_model": "numpy"}

kernel = njit(**KERNEL_OPTIONS)
inline_kernel = register_jitable(error_model=KERNEL_OPTIONS["error_model"])
hot_kernel = njit(**KERNEL_OPTIONS, inline="always")
borrowing_kernel = register_jitable(error_model=KERNEL_OPTIONS["error_model"], _nrt=False)


def hot_inline_kernel(function):
    """:data:`inline_kernel`, inlined into its compiled callers.

    A fresh decorator per function: ``register_jitable`` pops ``inline`` from its options on first
    use, so a shared one would inline only the first function it decorates.
    """
    return register_jitable(error_model=KERNEL_OPTIONS["error_model"], inline="always")(function)
