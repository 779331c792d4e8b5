"""The robot node's plant step, compiled: one RK4 step of the simulator's own scheme.

:func:`live_plant_step` is the engine's RK4 sub-step
(:func:`delaytrack.sim.integrator._rk4_substep`, with the plant's right-hand side
:func:`~delaytrack.plants.base.el_rhs` inlined and the stages on the stack,
:func:`~delaytrack.sim.integrator.rk4_memory`), compiled on its own for each plant kernel (whose
numba type names the code, as for the engine's parts, :mod:`delaytrack._compile.native_parts`)
and kept in numba's disk cache. The robot node calls the compiled code through its entry point
(:func:`entry_point`): the argument types are fixed when it is compiled, so numba's type
dispatch, which costs about 8 µs for a kernel and a tuple of arrays (more than the step itself),
is skipped.

This file holds compiled code only, so that edits to the node do not invalidate the cache.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import typeof, types

from delaytrack._compile.jit import tick_kernel
from delaytrack.sim.integrator import _rk4_substep, reduced_twin, rk4_memory, rk4_workspace

__all__ = [
    "entry_point",
    "live_plant_step",
    "live_reduced_plant_step",
    "plant_step_function",
    "step_signature",
]

_VECTOR = typeof(np.empty(1))


@tick_kernel
def live_plant_step(plant_terms, plant_params, t, x, u, dt, work, bound):
    """Advance ``x = [q, q̇]`` in place by one RK4 step of ``dt`` from ``t`` with ``u`` held.

    Returns ``(outside, indefinite_at)`` as :func:`~delaytrack.sim.integrator._rk4_substep`:
    whether an entry of the new ``x`` is non-finite or beyond ``bound``, and the time of the
    first stage whose mass matrix was not positive definite (NaN if none).
    """
    memory = rk4_memory(plant_terms, work)
    return _rk4_substep(plant_terms, plant_params, t, x, u, dt, memory, bound)


#: :func:`live_plant_step` for the plants with a reduced form
#: (:func:`~delaytrack.sim.integrator.reduced_twin`).
live_reduced_plant_step = tick_kernel(
    reduced_twin(live_plant_step.py_func, "live_reduced_plant_step")
)


def plant_step_function(kernel: Any) -> Any:
    """:func:`live_plant_step`, or :data:`live_reduced_plant_step` for a plant :class:`Kernel`
    with a reduced form."""
    return live_reduced_plant_step if kernel.reduced is not None else live_plant_step


def step_signature(kernel: Any, n: int, m: int) -> tuple:
    """The argument types of :func:`live_plant_step` for the plant :class:`Kernel`
    ``kernel`` with ``n`` coordinates and ``m`` inputs (every vector float64, contiguous)."""
    work = typeof(rk4_workspace(np.empty(2 * n), m))
    vector, real = _VECTOR, types.float64
    return (kernel.numba_type, vector, real, vector, vector, real, work, real)


def entry_point(step: Any, signature: tuple) -> Any:
    """The compiled ``step`` (:func:`plant_step_function`) for ``signature`` (or loaded from the
    disk cache): its entry point, which takes arguments of exactly these types without checking
    them, or the dispatcher when numba does not give one."""
    step.compile(signature)
    found = step.overloads.get(signature)
    return getattr(found, "entry_point", None) or step
