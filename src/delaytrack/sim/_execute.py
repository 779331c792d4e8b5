"""Run a built engine over its batch: the batch cut into chunks, run on a thread pool, with a
progress bar and Ctrl-C."""

from __future__ import annotations

import contextlib
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
from tqdm.auto import tqdm

from delaytrack.delays._kernel import NO_KERNEL
from delaytrack.plants.base import ELPlant
from delaytrack.sim._broadcast import stack_padded
from delaytrack.sim._build import Build
from delaytrack.sim._kernel_errors import could_not_compile, raised_during_the_run
from delaytrack.sim.engine import Records, Run, Settings
from delaytrack.sim.interruptible import run_interruptibly

__all__ = ["Chunks", "cut", "execute"]

#: What a run without ``progress`` updates instead of a progress bar.
_NO_PROGRESS_BAR = SimpleNamespace(update=lambda done: None)
#: Chunks per worker thread: enough for load balance and a moving progress bar, few enough
#: that the per-call overhead stays negligible.
_CHUNKS_PER_WORKER = 8


@dataclass(frozen=True)
class Chunks:
    """A batch cut into chunks, one engine call each, and the arrays the engine takes.

    Parameters
    ----------
    build : Build
        The engine.
    runs, settings, records : Run, Settings, Records
        The engine's arrays for the whole batch (:mod:`delaytrack.sim.engine`).
    status, t_stop : numpy.ndarray
        ``(B,)``: each run's outcome and when it stopped, written by the engine.
    indices : list of numpy.ndarray
        The batch elements of each chunk.
    in_parallel : bool
        Whether the chunks run on a thread pool.
    """

    build: Build
    runs: Run
    settings: Settings
    records: Records
    status: np.ndarray
    t_stop: np.ndarray
    indices: list[np.ndarray]
    in_parallel: bool

    def first(self, natives: tuple) -> tuple:
        """The engine's arguments for the first chunk (:meth:`arguments`)."""
        return self.arguments(0, natives)

    def arguments(self, index: int, natives: tuple) -> tuple:
        """The engine's arguments for chunk ``index``, its kernels compiled as ``natives``."""
        chunk = self.indices[index]
        part = slice(chunk[0], chunk[-1] + 1)
        runs = Run(*(array[part] for array in self.runs))
        plan = self.build.plan
        if self.in_parallel and plan.own_memory and index > 0:  # copies of plants and models
            runs = runs._replace(
                plant_params=stack_padded([plan.plants[b].for_worker(index).params for b in chunk]),
                model_params=stack_padded(
                    [plan.controllers[b].model.for_worker(index).params for b in chunk]
                ),
            )
        return (
            self.build.handles(int(chunk[0]), natives),
            runs,
            self.settings,
            Records(*(array[part] for array in self.records)),
            self.status[part],
            self.t_stop[part],
        )


def cut(build: Build, runs: Run, settings: Settings, records: Records, progress: bool) -> Chunks:
    """The batch of ``build`` in chunks: compiled kernels are shared by the whole batch and
    release the GIL, so chunks run on ``workers`` threads; Python callables may differ per
    element and hold the GIL, so the plain-Python engine runs one element at a time."""
    plan = build.plan
    batch, workers = plan.batch, plan.workers
    if build.compiled:
        per_worker = 1 if plan.own_memory else _CHUNKS_PER_WORKER
        pieces = min(batch, workers * per_worker if (progress or workers > 1) else 1)
    else:
        pieces = batch
    indices = [np.arange(batch)] if pieces == 1 else np.array_split(np.arange(batch), pieces)
    return Chunks(
        build=build,
        runs=runs,
        settings=settings,
        records=records,
        status=np.zeros(batch, dtype=np.int64),
        t_stop=np.zeros(batch),
        indices=indices,
        in_parallel=build.compiled and workers > 1 and len(indices) > 1,
    )


def _components(build: Build) -> list[ELPlant]:
    """The plant and the controller's model of each kind in the batch (one of each kind holds
    what its kind asks for while it runs: :meth:`ELPlant.while_running
    <delaytrack.plants.base.ELPlant.while_running>`)."""
    plan = build.plan
    kinds: dict[type, ELPlant] = {}
    for component in (*plan.plants, *(controller.model for controller in plan.controllers)):
        kinds.setdefault(type(component), component)
    return list(kinds.values())


def execute(chunks: Chunks, natives: tuple, progress: bool) -> None:
    """Run every chunk, its kernels compiled as ``natives``; a kernel of the user's that raised,
    or numba failing on the engine, ends the batch with a ValueError of one line."""
    build = chunks.build
    interrupted = threading.Event()  # Ctrl-C: the chunks not yet started are left

    def run_chunk(index: int) -> int:
        if interrupted.is_set():
            return 0
        try:
            build.runner(*chunks.arguments(index, natives))
        except Exception as error:
            yours = [k for k in build.kernels(0) if not k.built_in and k is not NO_KERNEL]
            if build.compiled and yours and not type(error).__module__.startswith("numba"):
                # Raised by a kernel of the user's as it ran (ours do not raise there; the
                # engine was compiled before the first chunk).
                raise ValueError(raised_during_the_run(error, yours)) from error
            raise
        return chunks.indices[index].size

    try:
        bar_context = (
            tqdm(total=build.plan.batch, desc="simulate", unit="run")
            if progress
            else contextlib.nullcontext(_NO_PROGRESS_BAR)  # a disabled tqdm costs ~0.1 ms
        )
        with contextlib.ExitStack() as held, bar_context as bar:
            # What the plant and the model ask for while they run; the bar is closed here, on
            # a new line, when Ctrl-C leaves the run.
            for component in _components(build):
                held.enter_context(component.while_running())

            def run_chunks() -> None:
                if chunks.in_parallel:
                    with ThreadPoolExecutor(max_workers=build.plan.workers) as pool:
                        for done in pool.map(run_chunk, range(len(chunks.indices))):
                            bar.update(done)
                else:
                    for index in range(len(chunks.indices)):
                        bar.update(run_chunk(index))

            if build.compiled:  # compiled code holds off Ctrl-C until it returns
                plan = build.plan
                try:
                    run_interruptibly(
                        run_chunks, size=plan.batch * plan.n_ticks * plan.steps_per_tick * plan.n
                    )
                except KeyboardInterrupt:
                    interrupted.set()
                    raise
            else:
                run_chunks()
    except Exception as error:
        if build.compiled and type(error).__module__.startswith("numba"):
            # numba could not compile a kernel of the user's into the engine (loaded from the
            # cache, or compiled, at the first chunk's call): their error, in one line.
            raise could_not_compile(error, "the engine", build.kernels(0)) from None
        raise
