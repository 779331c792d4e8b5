"""The functions the compiled engine calls through their address, each compiled for one component.

numba compiles a call of one ``njit`` function from another by linking the callee into the
caller, so an engine that called the plant's, the reference's, the controller's and the delay's
code directly would be compiled again, tick loop and all, for every combination of them. The
engine instead calls four functions through the address of their compiled code
(:mod:`delaytrack._compile.native_call`), each compiled once for the component it serves and
kept on disk (:func:`engine_parts`):

* the plant's tick, :func:`~delaytrack.sim.integrator.integrate_tick` compiled for the plant's
  kernel and the batch's delay kernel;
* the reference, :func:`.native_entries.evaluate_reference` compiled for its kernel;
* the controller's step: one of this package's compiled for the nominal model's kernel, one of
  the user's in :func:`.native_entries.evaluate_step` compiled for the step's kernel
  and the model's;
* the delay at a tick, :func:`~delaytrack.delays._kernel.evaluate_profile` compiled for the
  batch's delay kernel (a profile of the user's, or none).

The components' kernels are *bound* (they carry no data: their numba types name the code), so
the engine's own numba type names none of them, and one compiled engine serves every
combination (two variants: one for this package's controller steps, one for the user's). A
part is keyed on disk by its kernels' numba types, which for a kernel of the user's include a
fingerprint of all the code it reaches (:mod:`delaytrack._compile.fingerprint`), so an edit to
that code compiles its part again.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numba import typeof, types

from delaytrack._compile.first_compile import code_ready
from delaytrack._compile.helper_process import CompileJob
from delaytrack._compile.native_call import NativeFunction
from delaytrack._compile.native_entries import evaluate_reference, evaluate_step
from delaytrack.components import Kernel
from delaytrack.controllers.base import step_workspace
from delaytrack.delays._kernel import evaluate_profile
from delaytrack.sim.integrator import TickArguments, plant_integrator

if TYPE_CHECKING:
    from delaytrack.sim._plan import Plan

__all__ = [
    "NativePart",
    "controller_step_name",
    "controller_step_part",
    "delay_part",
    "engine_parts",
    "plant_integrator_name",
    "plant_tick_part",
    "reference_part",
]

#: Position of the nominal model's kernel among a step kernel's arguments.
_MODEL = 10
#: Rough seconds of a first compile of each part, from an empty cache
#: (``benchmarks/compile_profile.py``, 2026-12-04: a step 1.2 s, a reference 0.4 s, the delay
#: profiles 0.05 s, a kernel of the user's for the delay more).
_STEP_COST, _REFERENCE_COST, _DELAY_COST = 1.5, 0.5, 0.3


def _integrator_cost(n: int) -> float:
    """Rough seconds of a first compile of a plant's integrator, ``3 + 0.8 n``.

    The plant's dynamics are compiled into the integrator, so its cost grows with the plant:
    measured, a pendulum 3.6–4.4 s (the formula 3.8), the wheeled robot's five coordinates
    6.6–7.4 s in their constrained form (7.0) and 5.4 s in their reduced form
    (:func:`~delaytrack.sim.integrator.integrate_reduced_tick`), and the two-link arm 3.3 s:
    the formula overestimates the last two.

    Parameters
    ----------
    n : int
        The plant's number of coordinates.

    Returns
    -------
    float
        The cost, in the units of the parts' costs (seconds).
    """
    return 3.0 + 0.8 * n


#: What :func:`~delaytrack.sim.integrator.integrate_tick` returns: ``(outcome, t_stop,
#: first_slot)``.
_TICK_OUTCOME = types.Tuple((types.int64, types.float64, types.int64))


@dataclass(frozen=True)
class NativePart:
    """One function the compiled engine calls through its address, for one component.

    Parameters
    ----------
    function : numba dispatcher
        The function, compiled on its own.
    signature : tuple of numba types
        Its argument types, the component's kernel among them.
    bound : tuple of int
        Positions of the arguments the call fills in (the component's kernel).
    returns : numba type
        What it returns.
    cost : float
        Rough seconds its first compile takes, relative to the others' (to share first
        compiles between two processes, :mod:`delaytrack._compile.helper_process`).
    """

    function: Any
    signature: tuple
    bound: tuple
    returns: types.Type
    cost: float

    def ready(self) -> bool:
        """Whether its compiled code is in memory or in the disk cache (nothing to compile)."""
        if not self.__dict__.get("_ready"):
            self.__dict__["_ready"] = code_ready(self.function, self.signature, self.signature)
        return self.__dict__["_ready"]

    def probe(self) -> NativeFunction:
        """A stand-in with the same numba type, to type the engine's arguments before the
        function is compiled (its address is 0: it must not be called)."""
        return NativeFunction(self.function, self.signature, 0, self.bound, self.returns)

    def compile_job(self) -> CompileJob:
        """Its compile, for :func:`delaytrack._compile.helper_process.start`."""
        kernels = tuple(self.signature[position].kernel() for position in self.bound)
        return CompileJob(self.function, self.signature, kernels, self.cost)

    def native(self) -> NativeFunction:
        """The function compiled (or loaded from the disk cache) and its address, found once per
        process (a part is made once for its types): numba keeps the code it compiled first for
        the life of the process."""
        found = self.__dict__.get("_native")
        if found is None:
            found = self.__dict__["_native"] = NativeFunction.of(
                self.function, self.signature, self.bound, self.returns
            )
        return found


@functools.cache
def _vector(n: int) -> types.Type:
    return typeof(np.empty(n))


def plant_tick_part(plant: Kernel, delay: Kernel, n: int, m: int) -> NativePart:
    """:func:`~delaytrack.sim.integrator.integrate_tick` (or its twin for a plant with a reduced
    form, :func:`~delaytrack.sim.integrator.plant_integrator`) for the kernel ``plant`` with ``n``
    coordinates and ``m`` inputs, and the delay kernel ``delay`` (the batch's, or
    :data:`~delaytrack.delays._kernel.NO_KERNEL`)."""
    return _plant_tick_part(plant.numba_type, delay.numba_type, n, m, plant_integrator(plant))


@functools.cache
def _plant_tick_part(
    plant: types.Type, delay: types.Type, n: int, m: int, integrator: Any
) -> NativePart:
    signature = (plant, delay, *typeof(TickArguments.sample(n, m)).types)
    return NativePart(integrator, signature, (0, 1), _TICK_OUTCOME, _integrator_cost(n))


def reference_part(reference: Kernel, n: int) -> NativePart:
    """:func:`.native_entries.evaluate_reference` for the reference kernel ``reference``
    of ``n`` coordinates."""
    return _reference_part(reference.numba_type, n)


@functools.cache
def _reference_part(reference: types.Type, n: int) -> NativePart:
    vector = _vector(n)
    signature = (reference, types.float64, vector, vector, vector, vector)
    return NativePart(evaluate_reference, signature, (0,), types.none, _REFERENCE_COST)


def controller_step_part(step: Kernel, model: Kernel, n: int, m: int) -> NativePart:
    """The controller's step kernel ``step`` on the nominal ``model`` with ``n`` coordinates and
    ``m`` inputs: one of this package's compiled for the model alone, the model bound; one of
    the user's in :func:`.native_entries.evaluate_step`, compiled for both, both bound.

    Either way the engine passes the same arguments; only the bound positions differ, so the
    engine has one variant for this package's steps and one for the user's. A step of this
    package's is not wrapped: the wrapper, compiled with the step linked into it, cost about
    4 s more per controller in a cold cache (the paper job's three controllers).
    """
    if step.built_in:
        return _builtin_step_part(step.function, model.numba_type, n, m)
    return _users_step_part(step.numba_type, model.numba_type, n, m)


def plant_integrator_name(plant: Any) -> str:
    """How the first-compile notice names the integrator part of ``plant``."""
    return f"{type(plant).__name__}'s integrator"


def controller_step_name(controller: Any) -> str:
    """How the first-compile notice names the step part of ``controller``."""
    return f"{type(controller).__name__}'s step on {type(controller.model).__name__}"


def _step_arguments(model: types.Type, n: int, m: int) -> tuple:
    """The types of a step kernel's arguments (:mod:`delaytrack.controllers.base`)."""
    vector = _vector(n)
    return (
        types.float64,  # t
        *(vector,) * 5,  # q, q̇, q_d, q̇_d, q̈_d
        types.float64,  # T_c
        types.float64,  # h
        vector,  # params
        vector,  # state
        model,
        vector,  # the model's params
        vector,  # command
        typeof(step_workspace(n, m)),
    )


@functools.cache
def _builtin_step_part(step: Any, model: types.Type, n: int, m: int) -> NativePart:
    return NativePart(step, _step_arguments(model, n, m), (_MODEL,), types.none, _STEP_COST)


@functools.cache
def _users_step_part(step: types.Type, model: types.Type, n: int, m: int) -> NativePart:
    signature = (step, *_step_arguments(model, n, m))
    return NativePart(evaluate_step, signature, (0, _MODEL + 1), types.none, _STEP_COST)


def delay_part(delay: Kernel) -> NativePart:
    """:func:`~delaytrack.delays._kernel.evaluate_profile` for the batch's delay kernel
    ``delay`` (:data:`~delaytrack.delays._kernel.NO_KERNEL` when it has none)."""
    return _delay_part(delay.numba_type)


@functools.cache
def _delay_part(delay: types.Type) -> NativePart:
    signature = (delay, types.int64, _vector(1), types.float64)
    return NativePart(evaluate_profile, signature, (0,), types.float64, _DELAY_COST)


def engine_parts(plan: Plan) -> tuple[tuple[str, ...], tuple[NativePart, ...]]:
    """The parts the compiled engine calls for ``plan``, in the order of its
    :class:`~delaytrack.sim.engine.Kernels`: its plant's tick, its reference, its controller's
    step and its delay; and how the first-compile notice and compile errors name each."""
    plant, controller, reference = plan.plants[0], plan.controllers[0], plan.reference
    names = (
        plant_integrator_name(plant),
        type(reference).__name__,
        controller_step_name(controller),
        f"the delay kernel {plan.delay_kernel.callable_names[0]}"
        if plan.own_delays
        else "the delay profiles",
    )
    parts = (
        plant_tick_part(plant.engine_kernel, plan.delay_kernel, plan.n, plan.m),
        reference_part(reference.engine_kernel, plan.n),
        controller_step_part(
            controller.engine_kernel, controller.model.engine_kernel, plan.n, plan.m
        ),
        delay_part(plan.delay_kernel),
    )
    return names, parts
