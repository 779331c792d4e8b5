"""Compile what a built engine needs that is neither in memory nor on disk: the engine and its
parts, shared with a helper process when there are two or more (its first run only)."""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

from delaytrack.delays._kernel import NO_KERNEL
from delaytrack.sim._build import Build
from delaytrack.sim._kernel_errors import could_not_compile
from delaytrack.sim.compile_helper import CompileJob, parts_ahead
from delaytrack.sim.compile_helper import start as start_helper
from delaytrack.sim.first_compile import announce_compile, code_ready
from delaytrack.sim.stale_caches import compile_from_source

__all__ = ["compile_parts"]

#: Rough seconds of the engine's first compile, in the units of the parts' costs
#: (:mod:`delaytrack.sim.native_parts`), to share first compiles between two processes.
_ENGINE_COST = 9.0


def _compiled_if_it_can(part: Any) -> Any:
    """How a part compiled ahead for a later run is compiled here: an error is left to that
    run, which compiles the part again and reports it with its own kernels."""

    def compile_it() -> None:
        try:
            part.native()
        except Exception:  # noqa: BLE001, S110 - reported by the run that needs the part
            pass

    return compile_it


def _waiting(build: Build, first_chunk: Callable[[tuple], tuple]) -> list[tuple[str, Any, Any]]:
    """``(name, job, how this process compiles it or loads it from the cache)`` of what is not
    ready yet: the engine (typed on ``first_chunk``'s arguments) and the parts, and with a first
    compile the parts a caller asked for ahead."""
    runner, parts = build.runner, build.parts

    @functools.cache
    def engine_signature() -> tuple:
        """The engine's argument types: those of the compiled parts' stand-ins, which have
        an address of 0 and give the types without compiling."""
        probes = tuple(part.probe() for part in parts)
        return tuple(runner.typeof_pyval(item) for item in first_chunk(probes))

    engine_ready = code_ready(
        runner,
        ("the engine", parts[2].bound),  # one variant for built-in steps, one for the user's
        engine_signature,
    )
    waiting = [
        (name, part.compile_job(), part.native)
        for name, part in zip(build.names, parts, strict=True)
        if not part.ready()
    ]
    if not engine_ready:
        engine_job = CompileJob(runner, engine_signature(), (NO_KERNEL,), _ENGINE_COST)
        waiting.insert(0, ("the engine", engine_job, lambda: runner.compile(engine_signature())))
    if waiting:  # a first compile: with the parts the caller will need next, if any
        for name, part in parts_ahead():
            if part not in parts and not part.ready():
                waiting.append((name, part.compile_job(), _compiled_if_it_can(part)))
    return waiting


def compile_parts(build: Build, first_chunk: Callable[[tuple], tuple]) -> tuple:
    """The compiled ``build``'s parts, compiled or loaded from the disk cache, as the engine
    calls them (:class:`~delaytrack._native_call.NativeFunction`); the engine itself too, here,
    so that a chunk's error is a run's. ``first_chunk(natives)``: the engine's arguments for
    the first chunk. numba failing on a kernel of the user's is a ValueError of one line."""
    waiting = _waiting(build, first_chunk)
    natives: tuple = ()
    helper = None
    compiling = "the engine"  # what the message of a compile error names
    try:
        # Your functions' own disk caches may hold code older than the kernels' names.
        compile_from_source(kernel for _, job, _ in waiting for kernel in job.kernels)
        # Two or more to compile: a helper process compiles some of them on another core.
        helper, handed = start_helper([job for _, job, _ in waiting])
        if waiting:
            announce_compile([name for name, _, _ in waiting], helped=helper is not None)
        # This process's share first, the engine included, then the helper's (loaded from the
        # cache it wrote, or compiled here if it did not deliver).
        for position, (name, _, make) in enumerate(waiting):
            if position not in handed:
                compiling = name
                make()
        if helper is not None:
            helper.wait()
        for name, _, make in waiting:
            compiling = name
            make()
        for name, part in zip(build.names, build.parts, strict=True):
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
    return natives
