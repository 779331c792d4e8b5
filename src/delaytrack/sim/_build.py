"""Build the engine for a :class:`~delaytrack.sim._plan.Plan`: compiled or plain Python. The
compiled engine's parts are compiled by the compile stage (:mod:`delaytrack._compile`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from delaytrack._compile.jit import as_python
from delaytrack.sim._plan import Plan
from delaytrack.sim.engine import Kernels, run_batch, run_batch_compiled
from delaytrack.sim.fallback import PythonFallbackWarning, python_kernel, stepped_until

__all__ = ["ENGINES", "Build", "build"]

#: Values of ``simulate(engine=...)``.
ENGINES = ("auto", "compiled", "python")


@dataclass(frozen=True)
class Build:
    """The engine that runs a plan.

    Parameters
    ----------
    plan : Plan
        What it runs.
    compiled : bool
        Whether it runs compiled (else as plain Python).
    deadline : float
        As plain Python, the :func:`time.perf_counter` time after which no plant step or
        controller tick starts (:class:`~delaytrack.sim.fallback.OutOfTime` is raised instead);
        none by default.
    """

    plan: Plan
    compiled: bool
    deadline: float = math.inf

    @property
    def runner(self) -> Any:
        """The engine: :func:`~delaytrack.sim.engine.run_batch`, compiled or as Python; run
        first as Python (a deadline), with every function of this package as plain Python
        (:func:`~delaytrack._compile.jit.as_python`), so that it compiles nothing."""
        if self.compiled:
            return run_batch_compiled
        return run_batch if self.deadline == math.inf else _run_batch_as_python

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

    def handles(self, b: int, natives: Kernels | tuple) -> Kernels:
        """Element ``b``'s kernels as the engine takes them: as plain Python, or compiled, the
        batch's ``natives`` (:func:`delaytrack._compile.compile_engine`)."""
        if not self.compiled:
            kernels = Kernels(*(python_kernel(kernel) for kernel in self.kernels(b)))
            if self.deadline < math.inf:
                kernels = kernels._replace(
                    plant_step=stepped_until(kernels.plant_step, self.deadline),
                    controller_step=stepped_until(kernels.controller_step, self.deadline),
                )
            return kernels
        return Kernels(*natives)


def _run_batch_as_python(*arguments: Any) -> None:
    """:func:`~delaytrack.sim.engine.run_batch` with this package's functions as plain
    Python."""
    with as_python():
        run_batch(*arguments)


def build(plan: Plan, engine: str) -> Build:
    """The engine ``engine`` (one of :data:`ENGINES`) for ``plan``: compiled when every kernel
    is (else a :class:`~delaytrack.sim.fallback.PythonFallbackWarning`)."""
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
    return Build(plan, compiled)
