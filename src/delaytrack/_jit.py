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
callers at the numba IR level (``inline="always"``). They are for the functions on the plant's
right-hand side, evaluated four times per RK4 step: a numba call passes arrays by reference
count (an atomic increment and decrement per array argument and call), which cost more than the
arithmetic of the robot's right-hand side; inlined, the counts cancel at compile time.
"""

from __future__ import annotations

from numba import njit
from numba.extending import register_jitable

__all__ = ["KERNEL_OPTIONS", "hot_inline_kernel", "hot_kernel", "inline_kernel", "kernel"]

#: numba options of every compiled kernel.
KERNEL_OPTIONS = {"cache": True, "error_model": "numpy"}

kernel = njit(**KERNEL_OPTIONS)
inline_kernel = register_jitable(error_model=KERNEL_OPTIONS["error_model"])
hot_kernel = njit(**KERNEL_OPTIONS, inline="always")
hot_inline_kernel = register_jitable(error_model=KERNEL_OPTIONS["error_model"], inline="always")
