"""Where a sweep's work units run: this process on every local core, or a Dask cluster.

An executor takes the units still to do and yields ``(unit, results frame)`` as each finishes, in
any order, or ``(unit, exception)`` for a unit that failed (the others go on); the caller
(:func:`delaytrack.sweeps.run_sweep`) writes each part as it arrives, so an interruption loses
only the units in flight.

- :class:`LocalExecutor` (the default): one unit after another in this process, each unit's runs
  batched by :func:`~delaytrack.sim.simulate` on a thread pool over all cores. Nothing to start.
- :class:`DaskExecutor`: every unit is a ``dask.distributed`` task on an existing cluster
  (``tcp://host:port``) or on a :class:`distributed.LocalCluster` it starts (``local-cluster``).
  Units travel as plain data (:meth:`Unit.to_payload`) and are checked on the worker (same
  package version, same hash); results come back to this process, which alone writes the parts,
  so workers need no shared file system. A task whose worker dies is rescheduled by the Dask
  scheduler (its ``allowed-failures``); a task that raises is retried ``retries`` times.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import os
import re
import sys
from collections.abc import Iterator, Mapping, Sequence
from typing import Any, Protocol

import pandas as pd

from delaytrack._validation import ArgumentError, is_integer_at_least
from delaytrack.sim._machine import WORKERS_PER_CORE, workers_problem
from delaytrack.sim.simulate import available_cores
from delaytrack.sweeps.parts import run_unit
from delaytrack.sweeps.spec import SweepError, Unit

__all__ = [
    "DaskExecutor",
    "Executor",
    "LocalExecutor",
    "UnitOutcome",
    "WORKERS_PER_CORE",
    "checked_workers",
    "compute_part",
    "make_executor",
]

#: ``--scheduler`` value that starts a local Dask cluster.
LOCAL_CLUSTER = "local-cluster"
_ADDRESS = re.compile(r"^(tcp|tls|ucx|ws|wss|inproc)://\S+$")


#: What an executor yields per unit: its :func:`run_unit` frame, or the exception it raised.
UnitOutcome = tuple[Unit, pd.DataFrame | Exception]


class Executor(Protocol):
    """Runs units and yields each :data:`UnitOutcome` as it finishes; :meth:`close` frees it."""

    #: One line for logs and the report (``"local: 2 threads"``, ``"dask: tcp://..."``).
    description: str

    def results(self, units: Sequence[Unit]) -> Iterator[UnitOutcome]:
        """Yield every unit of ``units`` once, with its frame or its exception, as it ends."""
        ...

    def close(self) -> None:
        """Stop what is still running and release workers (idempotent)."""
        ...


class _WorkersError(SweepError, ArgumentError):
    """A :class:`SweepError` about ``workers``, carrying the argument (``argument``)."""

    #: Always given (``ArgumentError.__init__``), unlike a ``SweepError``'s.
    problem: str


def checked_workers(workers: int | None) -> int | None:
    """``workers`` (threads or local worker processes) checked: None, or 1 to
    :data:`WORKERS_PER_CORE` per available core
    (:func:`~delaytrack.sim._machine.workers_problem`)."""
    problem = workers_problem(workers)
    if problem is not None:
        raise _WorkersError("workers", problem)
    return workers


class LocalExecutor:
    """Units one after another in this process; each unit's batch on ``workers`` threads.

    Parameters
    ----------
    workers : int, optional
        Threads of :func:`~delaytrack.sim.simulate` (all cores by default).
    """

    def __init__(self, workers: int | None = None) -> None:
        self.workers = checked_workers(workers)
        self.description = f"local: {workers or available_cores()} threads"

    def results(self, units: Sequence[Unit]) -> Iterator[UnitOutcome]:
        for unit in units:
            try:
                frame = run_unit(unit, workers=self.workers)
            except Exception as error:  # one unit's failure must not cost the others
                yield unit, error
            else:
                yield unit, frame

    def close(self) -> None:
        """Nothing to release."""


def compute_part(payload: Mapping[str, Any]) -> pd.DataFrame:
    """The Dask task: rebuild a unit from :meth:`Unit.to_payload` here and run it on one thread
    (a Dask worker's threads are the parallelism)."""
    return run_unit(Unit.from_payload(payload), workers=1)


def _check_scheduler(distributed: Any, scheduler: str, timeout: float) -> None:
    """Connect to ``scheduler`` and exchange Dask's handshake, all within ``timeout`` seconds,
    before a ``Client`` does: its handshake waits without end for a server that answers
    nothing (an HTTP server), and reads another server's first bytes as a frame length (3 EiB
    to allocate, a ``MemoryError``). Raises ``OSError`` when nothing answers,
    :class:`SweepError` when what answers is not Dask."""

    # Dask's connect gives up at ``timeout`` on a connection refused or not made, with an
    # OSError; past it, with a second more, only a handshake not answered holds it.
    limit = timeout + 1.0

    async def handshake() -> None:
        connect = distributed.comm.connect(scheduler, timeout=timeout)
        comm = await asyncio.wait_for(connect, limit)
        await comm.close()

    with concurrent.futures.ThreadPoolExecutor(1) as thread:  # a caller's loop may be running
        try:
            thread.submit(asyncio.run, handshake()).result()
        except TimeoutError:  # connected, and then no handshake (before OSError: a subclass)
            raise SweepError(
                f"--scheduler {scheduler!r}: a server accepted the connection but sent no Dask "
                f"handshake within {limit:g} s: it is not a Dask scheduler, or not one that "
                "answers; check the address and port (the scheduler's, 8786 by default, not its "
                "dashboard's)"
            ) from None
        except OSError:  # refused, or no connection within the time: Dask's own message
            raise
        except Exception as error:  # noqa: BLE001 - whatever the bytes of another server give
            raise SweepError(
                f"--scheduler {scheduler!r}: what answered there is not a Dask scheduler (its "
                f"first message is not Dask's handshake: {type(error).__name__}); check the "
                "address and port (the scheduler's, 8786 by default, not its dashboard's)"
            ) from None


def _distributed() -> Any:
    try:
        import distributed
    except ImportError:
        raise SweepError(
            "--scheduler needs dask.distributed, which is not installed: "
            "pip install -e '.[dask]' (from a clone of delaytrack)"
        ) from None
    return distributed


def checked_scheduler(scheduler: str | None, workers: int | None = None) -> str | None:
    """``scheduler`` checked: None, ``"local-cluster"`` or a Dask address that suits ``workers``.

    Raises
    ------
    SweepError
        Naming ``--scheduler`` (or ``--workers``) and what would be valid.
    """
    if scheduler is None:
        checked_workers(workers)
        return None
    if not isinstance(scheduler, str) or not (
        scheduler == LOCAL_CLUSTER or _ADDRESS.match(scheduler)
    ):
        raise SweepError(
            f"--scheduler must be '{LOCAL_CLUSTER}' or a Dask scheduler address such as "
            f"'tcp://10.0.0.5:8786'; got {scheduler!r}"
        )
    if checked_workers(workers) is not None and scheduler != LOCAL_CLUSTER:
        raise SweepError(
            f"--workers {workers} applies to the local executor and to --scheduler "
            f"{LOCAL_CLUSTER}; a running cluster ({scheduler}) has the workers it has"
        )
    return scheduler


class DaskExecutor:
    """Units as ``dask.distributed`` tasks; results gathered here as they complete.

    Parameters
    ----------
    scheduler : str
        ``tcp://host:port`` (any ``dask.distributed`` address: ``tcp``, ``tls``, ``ucx``,
        ``ws``, ``wss``, ``inproc``) of a running scheduler, or ``"local-cluster"``.
    workers : int, optional
        With ``"local-cluster"``: worker processes (one thread each), all cores by default.
    retries : int
        Extra attempts of a task that raises (a task whose worker dies is rescheduled anyway).
    timeout : float
        Seconds to wait for the scheduler to answer.
    progress : bool
        Say on standard error which scheduler is waited for, and for how long at most, before
        connecting to a running one (a scheduler that refuses the connection is retried until
        ``timeout``).
    """

    def __init__(
        self,
        scheduler: str,
        *,
        workers: int | None = None,
        retries: int = 2,
        timeout: float = 30.0,
        progress: bool = False,
    ) -> None:
        checked_scheduler(scheduler, workers)
        if not is_integer_at_least(retries, 0):
            raise SweepError(f"retries must be an integer >= 0; got {retries!r}")
        distributed = _distributed()
        self._cluster = None
        self._while_cluster_runs = contextlib.ExitStack()
        self.retries = retries
        self._futures: set[Any] = set()
        if scheduler == LOCAL_CLUSTER:
            count = workers or available_cores()
            self._while_cluster_runs.enter_context(_workers_without_the_working_folder())
            try:
                # ":0": any free port for the scheduler's HTTP server (two clusters coexist).
                self._cluster = distributed.LocalCluster(
                    n_workers=count, threads_per_worker=1, processes=True, dashboard_address=":0"
                )
            except BaseException as error:  # Ctrl-C too: the environment given back first
                self.close()
                if not isinstance(error, RuntimeError | OSError | TimeoutError):
                    raise
                cause = f" ({error.__cause__})" if error.__cause__ is not None else ""
                raise SweepError(
                    f"--scheduler {scheduler!r}: the local Dask cluster did not start: "
                    f"{error}{cause}"
                ) from None
            address = self._cluster.scheduler_address
            self.description = (
                f"dask: local cluster of {count} worker processes ({address}, dashboard "
                f"{self._cluster.dashboard_link})"
            )
        else:
            address = scheduler
            self.description = f"dask: {scheduler}"
            if progress:
                print(
                    f"delaytrack: connecting to the Dask scheduler at {scheduler} "
                    f"(waiting up to {timeout:g} s)",
                    file=sys.stderr,
                    flush=True,
                )
        try:
            if self._cluster is None:
                _check_scheduler(distributed, scheduler, timeout)
            self.client = distributed.Client(address, timeout=timeout)
        except (OSError, TimeoutError) as error:
            self.close()
            raise SweepError(
                f"--scheduler {scheduler!r}: no Dask scheduler answered within {timeout:g} s "
                f"({error}); start one (dask scheduler) or check the address"
            ) from None

    def results(self, units: Sequence[Unit]) -> Iterator[UnitOutcome]:
        distributed = _distributed()
        owner = {}
        for unit in units:
            future = self.client.submit(
                compute_part,
                unit.to_payload(),
                key=f"delaytrack-unit-{unit.index:05d}-{unit.hash[:16]}",
                retries=self.retries,
                pure=False,
            )
            owner[future.key] = unit
            self._futures.add(future)
        for future in distributed.as_completed(list(self._futures)):
            self._futures.discard(future)
            try:
                outcome = future.result()
            except Exception as error:  # retries spent, or the task's workers kept dying
                outcome = error
            future.release()
            yield owner[future.key], outcome

    def close(self) -> None:
        """Cancel unfinished tasks, then close the client and any cluster this executor started."""
        client = getattr(self, "client", None)
        if client is not None:
            if self._futures:
                client.cancel(list(self._futures))
                self._futures = set()
            client.close()
            self.client = None
        if self._cluster is not None:
            self._cluster.close()
            self._cluster = None
        self._while_cluster_runs.close()


@contextlib.contextmanager
def _workers_without_the_working_folder() -> Iterator[None]:
    """``PYTHONSAFEPATH=1`` in this process's environment while a local cluster runs, for the
    worker processes it starts (``python -c``, which would put the working folder first on
    their module search path, where a file named like a module they import at start, a
    ``multiprocessing.py`` sent with a sweep, would run instead)."""
    before = os.environ.get("PYTHONSAFEPATH")
    os.environ["PYTHONSAFEPATH"] = "1"
    try:
        yield
    finally:
        if before is None:
            os.environ.pop("PYTHONSAFEPATH", None)
        else:
            os.environ["PYTHONSAFEPATH"] = before


def make_executor(
    scheduler: str | None = None, *, workers: int | None = None, progress: bool = False
) -> Executor:
    """:class:`LocalExecutor` for ``scheduler=None``, else :class:`DaskExecutor` (``progress``:
    say which scheduler is waited for)."""
    if scheduler is None:
        return LocalExecutor(workers)
    return DaskExecutor(scheduler, workers=workers, progress=progress)
