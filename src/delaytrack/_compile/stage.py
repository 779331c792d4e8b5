"""Compile what a built engine needs that is neither in memory nor on disk: the engine and its
parts, shared with a helper process when there are two or more (its first run only)."""

from __future__ import annotations

import functools
import time
from collections.abc import Callable
from typing import Any

from delaytrack._compile.ahead import parts_ahead
from delaytrack._compile.first_compile import (
    announce_compile,
    announce_compiled,
    code_is_ready,
    code_ready,
)
from delaytrack._compile.guards import refuse_changed_globals
from delaytrack._compile.helper_ahead import take as take_ahead
from delaytrack._compile.helper_process import CompileJob, order_here
from delaytrack._compile.helper_process import start as start_helper
from delaytrack._compile.native_parts import NativePart, engine_parts
from delaytrack._compile.stale_caches import compile_from_source
from delaytrack.delays._kernel import NO_KERNEL
from delaytrack.sim._build import Build
from delaytrack.sim._kernel_errors import could_not_compile
from delaytrack.sim.engine import Kernels

__all__ = ["compile_cost", "compile_engine", "refuse_changed_kernels"]

#: Rough seconds of the engine's first compile, in the units of the parts' costs
#: (:mod:`delaytrack._compile.native_parts`), to share first compiles between two processes
#: (measured from an empty cache: 4.7–5.3 s).
_ENGINE_COST = 5.0


def _compiled_if_it_can(part: Any) -> Any:
    """How a part compiled ahead for a later run is compiled here: an error is left to that
    run, which compiles the part again and reports it with its own kernels."""

    def compile_it() -> None:
        try:
            part.native()
        except Exception:  # noqa: BLE001, S110 - reported by the run that needs the part
            pass

    return compile_it


def _engine_kernels(plant_step: Any, reference: Any, controller_step: Any, delay: Any) -> Kernels:
    """The engine's kernels: its parts (compiled, or their stand-ins), in the order of
    :func:`~delaytrack._compile.native_parts.engine_parts`; the model's is not read."""
    return Kernels(plant_step, NO_KERNEL, reference, controller_step, delay)


def _waiting(
    names: tuple[str, ...],
    parts: tuple[NativePart, ...],
    runner: Any,
    first_chunk: Callable[[Kernels], tuple],
    ahead: bool = True,
) -> list[tuple[str, Any, Any]]:
    """``(name, job, how this process compiles it or loads it from the cache)`` of what is not
    ready yet: the engine ``runner`` (typed on ``first_chunk``'s arguments) and the ``parts``,
    and (``ahead``) with a first compile the parts a caller asked for ahead."""

    @functools.cache
    def engine_signature() -> tuple:
        """The engine's argument types: those of the compiled parts' stand-ins, which have
        an address of 0 and give the types without compiling."""
        probes = _engine_kernels(*(part.probe() for part in parts))
        return tuple(runner.typeof_pyval(item) for item in first_chunk(probes))

    engine_ready = code_ready(
        runner,
        ("the engine", parts[2].bound),  # one variant for built-in steps, one for the user's
        engine_signature,
    )
    waiting = [
        (name, part.compile_job(), part.native)
        for name, part in zip(names, parts, strict=True)
        if not part.ready()
    ]
    if not engine_ready:
        engine_job = CompileJob(runner, engine_signature(), (NO_KERNEL,), _ENGINE_COST)
        waiting.insert(0, ("the engine", engine_job, lambda: runner.compile(engine_signature())))
    if waiting and ahead:  # a first compile: with the parts the caller will need next, if any
        for name, part in parts_ahead():
            if part not in parts and not part.ready():
                waiting.append((name, part.compile_job(), _compiled_if_it_can(part)))
    return waiting


def refuse_changed_kernels(build: Build) -> None:
    """Refuse a kernel of ``build`` (a compiled engine's) that reads a module global of the
    user's changed since the kernel was first named in this process
    (:func:`~delaytrack._compile.guards.refuse_changed_globals`): compiled code would not see
    the change. A run interpreted first refuses it alike, so that the result does not depend on
    which engine ran it.

    Raises
    ------
    ValueError
        Naming the kernel and the global.
    """
    plan = build.plan
    plant, controller = plan.plants[0], plan.controllers[0]
    for component in (plant, controller.model, controller, plan.reference):
        refuse_changed_globals(component.engine_kernel)
    refuse_changed_globals(plan.delay_kernel)


def compile_cost(
    build: Build, first_chunk: Callable[[Kernels], tuple]
) -> tuple[tuple[NativePart, ...], float]:
    """The parts the compiled ``build`` runs, and the rough seconds of compiling what of them
    and of the engine is neither in memory nor on disk.

    Parameters
    ----------
    build : Build
        A compiled engine.
    first_chunk : callable
        The engine's arguments for the first chunk, as for :func:`compile_engine`.

    Returns
    -------
    parts : tuple of NativePart
        :func:`~delaytrack._compile.native_parts.engine_parts`'s.
    cost : float
        Seconds on one core, in the units of
        :class:`~delaytrack._compile.helper_process.CompileJob`'s cost; 0 when nothing is to
        compile.
    """
    names, parts = engine_parts(build.plan)
    waiting = _waiting(names, parts, build.runner, first_chunk, ahead=False)
    return parts, sum(job.cost for _, job, _ in waiting)


def compile_engine(build: Build, first_chunk: Callable[[Kernels], tuple]) -> Kernels:
    """The compiled ``build``'s kernels as the engine calls them: its parts, compiled or loaded
    from the disk cache (:class:`~delaytrack._compile.native_call.NativeFunction`); the engine
    itself too, here, so that a chunk's error is a run's. ``first_chunk(kernels)``: the
    engine's arguments for the first chunk. A module global that a kernel of the user's reads
    and numba compiled in is refused if it changed; numba failing on a kernel of the user's is
    a ValueError of one line. Once the parts are there, what waits for a first compile is
    called (:func:`~delaytrack._compile.first_compile.after_first_compile`)."""
    plan = build.plan
    refuse_changed_kernels(build)
    names, parts = engine_parts(plan)
    waiting = _waiting(names, parts, build.runner, first_chunk)
    natives: tuple = ()
    helper = None
    compiling = "the engine"  # what the message of a compile error names
    try:
        # Your functions' own disk caches may hold code older than the kernels' names.
        compile_from_source(kernel for _, job, _ in waiting for kernel in job.kernels)
        # Two or more to compile: a helper process compiles some of them on another core.
        jobs = [job for _, job, _ in waiting]
        helper, handed = start_helper(jobs, take_ahead)
        if waiting:
            announce_compile([name for name, _, _ in waiting], helped=helper is not None)
        start = time.perf_counter()
        # Each job the helper has not claimed (the engine included; those it cannot take
        # first), then the helper's (loaded from the cache it wrote, or compiled here if it did
        # not deliver).
        here = set()
        for position in order_here(jobs, handed):
            if helper is None or helper.claim(position):
                compiling, make = waiting[position][0], waiting[position][2]
                make()
                here.add(position)
                announce_compiled([compiling], time.perf_counter() - start)
        delivered = True
        if helper is not None:
            delivered = helper.wait()  # else what it left is compiled here, below
            helped = [name for i, (name, _, _) in enumerate(waiting) if i not in here]
            if delivered and helped:  # seen done now, when this process waited for it
                announce_compiled(helped, time.perf_counter() - start, helped=True)
        for position, (name, _, make) in enumerate(waiting):
            compiling = name
            make()
            if not delivered and position not in here:  # compiled here after all
                announce_compiled([name], time.perf_counter() - start)
        for name, part in zip(names, parts, strict=True):
            compiling = name
            natives += (part.native(),)
    except Exception as error:
        if type(error).__module__.startswith("numba"):
            # numba could not compile a kernel of the user's: their error, in one line.
            raise could_not_compile(error, compiling, build.kernels(0)) from None
        raise
    finally:
        if helper is not None:
            helper.stop()
    code_is_ready()  # what waited for the cores to be free of compiling
    return _engine_kernels(*natives)
