"""Build the engine for a :class:`~delaytrack.sim._plan.Plan`: compiled or plain Python, and
the parts the compiled engine calls through their address (:mod:`delaytrack.sim.native_parts`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from delaytrack.components import refuse_changed_globals
from delaytrack.delays._kernel import NO_KERNEL
from delaytrack.sim._plan import Plan
from delaytrack.sim.engine import Kernels, run_batch, run_batch_compiled
from delaytrack.sim.fallback import PythonFallbackWarning, python_kernel
from delaytrack.sim.native_parts import (
    NativePart,
    controller_step_name,
    controller_step_part,
    delay_part,
    plant_tick_part,
    reference_part,
)

__all__ = ["ENGINES", "Build", "build"]

#: Values of ``simulate(engine=...)``.
ENGINES = ("auto", "compiled", "python")


@dataclass(frozen=True)
class Build:
    """The engine that runs a plan, and what it calls.

    Parameters
    ----------
    plan : Plan
        What it runs.
    compiled : bool
        Whether it runs compiled (else as plain Python).
    parts : tuple of NativePart
        Compiled: the plant's tick, the reference, the controller's step and the delay, each
        compiled for its component (empty otherwise).
    names : tuple of str
        How the first-compile notice and compile errors name each part.
    """

    plan: Plan
    compiled: bool
    parts: tuple[NativePart, ...]
    names: tuple[str, ...]

    @property
    def runner(self) -> Any:
        """The engine: :func:`~delaytrack.sim.engine.run_batch`, compiled or as Python."""
        return run_batch_compiled if self.compiled else run_batch

    def kernels(self, b: int) -> Kernels:
        """Element ``b``'s kernels (:class:`~delaytrack.components.Kernel`)."""
        plan = self.plan
        return Kernels(
            plant_step=plan.plants[b].engine_kernel,
            model_terms=plan.controllers[b].model.engine_kernel,
            reference=plan.reference.engine_kernel,
            controller_step=plan.controllers[b].engine_kernel,
            delay=plan.delay_kernel,
        )

    def handles(self, b: int, natives: tuple) -> Kernels:
        """Element ``b``'s kernels as the engine takes them: as plain Python, or compiled, the
        :class:`~delaytrack._native_call.NativeFunction` objects ``natives`` of :attr:`parts`."""
        if not self.compiled:
            return Kernels(*(python_kernel(kernel) for kernel in self.kernels(b)))
        plant_step, reference, step, delay = natives
        return Kernels(plant_step, NO_KERNEL, reference, step, delay)


def build(plan: Plan, engine: str) -> Build:
    """The engine ``engine`` (one of :data:`ENGINES`) for ``plan``: compiled when every kernel
    is (else a :class:`~delaytrack.sim.fallback.PythonFallbackWarning`), and its parts."""
    plant, controller, reference = plan.plants[0], plan.controllers[0], plan.reference
    compiled = plant.compiled and controller.compiled and reference.compiled
    if engine not in ENGINES:
        raise ValueError(f"engine must be one of {list(ENGINES)}; got {engine!r}")
    if engine == "compiled" and not compiled:
        raise ValueError(
            "engine='compiled' needs compiled kernels; "
            + str(PythonFallbackWarning.describe(plant, controller, reference))
        )
    if engine == "python":
        compiled = False
    elif not compiled:
        PythonFallbackWarning.warn(plant, controller, reference)
    names = (
        f"{type(plant).__name__}'s integrator",
        type(reference).__name__,
        controller_step_name(controller),
        f"the delay kernel {plan.delay_kernel.callable_names[0]}"
        if plan.own_delays
        else "the delay profiles",
    )
    if not compiled:
        return Build(plan, compiled, (), names)
    # The plant's step, the reference, the controller's step and the delay are called through
    # their address, each compiled for its component alone: one engine serves every combination.
    for component in (plant, controller.model, controller, reference):
        refuse_changed_globals(component.engine_kernel)
    refuse_changed_globals(plan.delay_kernel)
    parts = (
        plant_tick_part(plant.engine_kernel, plan.delay_kernel, plan.n, plan.m),
        reference_part(reference.engine_kernel, plan.n),
        controller_step_part(
            controller.engine_kernel, controller.model.engine_kernel, plan.n, plan.m
        ),
        delay_part(plan.delay_kernel),
    )
    return Build(plan, compiled, parts, names)
