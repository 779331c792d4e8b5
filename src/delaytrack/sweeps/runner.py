"""Run a sweep into a results folder, resumably: the units not yet done, one part each.

Folder layout (``out``)::

    parts/part-<unit>-<hash12>.parquet   one per finished unit, written atomically
    .delaytrack-files.json               the toolkit's marker, written first (``_output``)
    runs.parquet, runs.csv               every run, in run order (when the sweep is complete)
    .lock                                held while a sweep or its report writes here

:func:`run_sweep` skips the units whose part is valid for this spec
(:func:`~delaytrack.sweeps.finished_units`), runs the others with an executor
(:mod:`delaytrack.sweeps.executors`) and writes each part as soon as its unit returns. Stopped
by Ctrl-C, it cancels what is in flight and raises :class:`SweepInterrupted`, which counts the
valid parts then in the folder; every part already written stays, and the same call resumes from
there.
"""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

import pandas as pd
import pyarrow.parquet as pq
from tqdm.auto import tqdm

from delaytrack._io import write_frame
from delaytrack._output import claim_output_folder
from delaytrack.sweeps.executors import Executor, LocalExecutor
from delaytrack.sweeps.parts import finished_units, value_column, write_part
from delaytrack.sweeps.spec import SweepError, SweepSpec

__all__ = ["SweepInterrupted", "SweepOutcome", "SweepUnitsFailed", "folder_lock", "run_sweep"]


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C stopped a sweep; ``done`` of ``total`` units have their part in ``folder``."""

    def __init__(self, folder: Path, done: int, total: int) -> None:
        super().__init__(
            f"sweep interrupted: {done} of {total} units done, their parts kept in {folder}; run "
            "the same command again to resume"
        )
        self.folder, self.done, self.total = folder, done, total


class SweepUnitsFailed(SweepError):
    """Some units raised; ``failures`` maps unit index -> error. Every other part was written."""

    def __init__(self, folder: Path, failures: Mapping[int, str], done: int, total: int) -> None:
        shown = "; ".join(f"unit {k}: {reason}" for k, reason in list(failures.items())[:5])
        more = f"; and {len(failures) - 5} more" if len(failures) > 5 else ""
        super().__init__(
            f"{len(failures)} of {total} units failed ({shown}{more}); the parts of the {done} "
            f"finished units are kept in {folder}: fix the cause and run the same command to "
            "compute the failed units"
        )
        self.folder, self.failures, self.done, self.total = folder, dict(failures), done, total


@dataclass(frozen=True)
class SweepOutcome:
    """What :func:`run_sweep` did.

    Attributes
    ----------
    spec : SweepSpec
    folder : Path
        The results folder.
    runs : DataFrame
        Every run (:func:`~delaytrack.sweeps.run_unit`'s columns), in run order.
    computed, resumed : int
        Units run by this call; units whose part was already there.
    rejected : Mapping[str, str]
        Part files found that did not count (file name -> reason): a corrupt or altered part
        of this spec was computed again; parts of another spec or code are ignored.
    seconds : float
        Wall time of this call.
    executor : str
        Where the units ran (:attr:`Executor.description`).
    """

    spec: SweepSpec
    folder: Path
    runs: pd.DataFrame
    computed: int
    resumed: int
    rejected: Mapping[str, str]
    seconds: float
    executor: str


@contextlib.contextmanager
def folder_lock(folder: Path) -> Iterator[None]:
    """Hold ``folder/.lock`` (POSIX ``flock``) so two sweeps never write the same folder.

    Raises
    ------
    SweepError
        When another process holds it.
    """
    try:
        import fcntl
    except ImportError:  # Windows: no advisory lock
        yield
        return
    with open(folder / ".lock", "w") as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise SweepError(
                f"another sweep is writing to {str(folder)!r}; wait for it or choose another "
                "output folder"
            ) from None
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def _remove_temporaries(parts: Path) -> None:
    """Delete half-written parts left by a killed process (``atomic_path``'s ``.part-*``)."""
    for path in parts.glob(".part-*"):
        with contextlib.suppress(FileNotFoundError):
            path.unlink()


def _read_runs(parts: Path, spec: SweepSpec) -> pd.DataFrame:
    frames = [pq.read_table(parts / unit.part_name).to_pandas() for unit in spec.units()]
    runs = pd.concat(frames, ignore_index=True).sort_values("run", kind="stable")
    for key in spec.runs[0].values:  # numbers in one unit, text in another: one rule for all
        if runs[key].dtype == object:
            runs[key] = value_column(list(runs[key]))
    return runs.reset_index(drop=True)


def _interrupted(folder: Path, spec: SweepSpec, executor: Executor) -> SweepInterrupted:
    """What Ctrl-C left: stop the units in flight, then count the valid parts on disk.

    Ctrl-C can land between a part's rename into place and any count kept beside it, so the
    count is taken from the folder itself. Only :func:`run_sweep`'s own loop writes parts, and it
    has stopped: the count stays true. A temporary file an interrupted write left behind is
    removed.
    """
    executor.close()
    parts = folder / "parts"
    _remove_temporaries(parts)
    done = len(finished_units(parts, spec).finished)
    return SweepInterrupted(folder, done, len(spec.units()))


def run_sweep(
    spec: SweepSpec,
    out: str | os.PathLike[str],
    *,
    executor: Executor | None = None,
    progress: bool = True,
) -> SweepOutcome:
    """Run every unit of ``spec`` that has no valid part in ``out/parts``; gather all runs.

    Parameters
    ----------
    spec : SweepSpec
    out : path
        Results folder (created if missing). A new or empty one gets the toolkit's marker
        before anything else, so that the command line resumes an interrupted sweep there; the
        command line checks the folder first (new, empty or marked), this function does not.
    executor : Executor, optional
        Where units run; :class:`~delaytrack.sweeps.executors.LocalExecutor` (all cores) by
        default. It is closed on return.
    progress : bool
        Show a progress bar (runs done, runs per second, ETA) on stderr.

    Returns
    -------
    SweepOutcome
        With every run; ``runs.parquet`` and ``runs.csv`` are written in ``out``.

    Raises
    ------
    SweepInterrupted
        On Ctrl-C, after cancelling the units in flight; finished parts stay, and its ``done``
        is the number of valid parts in ``out/parts`` at that moment.
    SweepUnitsFailed
        When units raised: after every other unit ran and was written.
    SweepError
        If another sweep holds the folder.
    """
    start = time.perf_counter()
    folder = Path(out)
    parts = folder / "parts"
    executor = executor if executor is not None else LocalExecutor()
    units = spec.units()
    try:
        claim_output_folder(folder)  # first: an interrupted sweep leaves a folder of ours
        parts.mkdir(exist_ok=True)
        with folder_lock(folder):
            _remove_temporaries(parts)
            scan = finished_units(parts, spec)
            pending = [unit for unit in units if unit.index not in scan.finished]
            done_runs = sum(len(unit.runs) for unit in units if unit.index in scan.finished)
            done = len(units) - len(pending)
            bar = tqdm(
                total=len(spec.runs),
                initial=done_runs,
                unit="run",
                desc="sweep",
                disable=not progress,
                dynamic_ncols=True,
            )
            failures: dict[int, str] = {}
            try:
                for unit, frame in executor.results(pending):
                    if isinstance(frame, Exception):
                        failures[unit.index] = f"{type(frame).__name__}: {frame}"
                        continue
                    write_part(frame, unit, parts)
                    done += 1
                    bar.update(len(unit.runs))
                    bar.set_postfix_str(f"units {done}/{len(units)}", refresh=False)
            except KeyboardInterrupt:
                raise _interrupted(folder, spec, executor) from None
            finally:
                bar.close()
            if failures:
                raise SweepUnitsFailed(folder, dict(sorted(failures.items())), done, len(units))
            runs = _read_runs(parts, spec)
            write_frame(runs, folder / "runs.parquet")
            write_frame(runs, folder / "runs.csv")
    finally:
        executor.close()
    return SweepOutcome(
        spec=spec,
        folder=folder,
        runs=runs,
        computed=len(pending),
        resumed=len(units) - len(pending),
        rejected=scan.rejected,
        seconds=time.perf_counter() - start,
        executor=executor.description,
    )
