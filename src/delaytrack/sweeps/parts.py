"""Run a sweep's work units and keep their results as Parquet parts, one per finished unit.

A part is ``<folder>/part-<unit index>-<hash12>.parquet``, one row per run, written atomically
(temporary file in the same folder, fsync, :func:`os.replace`): a reader sees no part or a
complete one. Its Parquet metadata holds the unit's full hash, its run count and a sha256 of its
values (:func:`content_hash`), so :func:`finished_units` can tell a finished unit of *this* spec
from a stale, truncated, corrupt or altered file.
"""

from __future__ import annotations

import functools
import hashlib
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from delaytrack._io import atomic_path
from delaytrack._memory_budget import allocation_budget
from delaytrack.metrics import metrics_table
from delaytrack.scenario.table_memory import remembered_tables
from delaytrack.sim import MeasurementNoise, PacketLoss, simulate
from delaytrack.sim.certified_bound import stated_by_the_caller
from delaytrack.sweeps.spec import Run, SweepError, SweepSpec, Unit, canonical_json

__all__ = ["PartsScan", "finished_units", "run_unit", "value_column", "write_part"]

#: Parquet metadata keys of a part.
HASH_KEY = b"delaytrack.unit_hash"
RUNS_KEY = b"delaytrack.unit_runs"
CONTENT_KEY = b"delaytrack.content_sha256"


def content_hash(frame: pd.DataFrame) -> str:
    """sha256 of a part's column names and values (``pandas.util.hash_pandas_object`` rows)."""
    digest = hashlib.sha256("\x1f".join(frame.columns).encode("utf-8"))
    digest.update(pd.util.hash_pandas_object(frame, index=False).to_numpy().tobytes())
    return digest.hexdigest()


def _batch_key(run: Run) -> str:
    """Runs with equal keys can share one :func:`simulate` call."""
    scenario = run.scenario
    return canonical_json(
        {
            "kernels": list(run.kernels),  # a factory may give other kernels for other keys
            "plant": scenario.plant["type"],
            "model": scenario.model["type"],
            "controller": scenario.controller["type"],
            # Controller states of different sizes (a predictor's history, its space) cannot be
            # stacked into one batch.
            "state_size": run.state_size,
            "times": [scenario.duration, scenario.dt, scenario.T_c],
            "error_bound": scenario.error_bound,
            "u_init": scenario.u_init,  # one input before the first command per simulate call
            "reference": dict(scenario.reference),
        }
    )


def _simulate_batch(runs: list[Run], workers: int | None) -> pd.DataFrame:
    built = [run.scenario.build() for run in runs]
    # One batch shares the first run's settings but for those that may differ between its runs.
    settings = runs[0].scenario.simulation_settings() | {
        "input_limits": np.array(
            [
                np.broadcast_to(run.scenario.simulated_input_limits, (b.plant.m,))
                for run, b in zip(runs, built, strict=True)
            ]
        ),
        "measurement_noise": [
            run.scenario.simulated_measurement_noise or MeasurementNoise() for run in runs
        ],
        "packet_loss": [run.scenario.simulated_packet_loss or PacketLoss() for run in runs],
    }
    try:
        with stated_by_the_caller():  # a sweep runs beyond h_m on purpose
            result = simulate(
                [b.plant for b in built],
                [b.controller for b in built],
                [b.delay for b in built],
                np.stack([b.x0 for b in built]),
                reference=built[0].reference,
                trajectories=False,
                workers=workers,
                **settings,
            )
    except ValueError as error:
        indices = [run.index for run in runs]
        raise SweepError(f"runs {indices} cannot be simulated together: {error}") from None
    # TV received too, for every run: a sweep's tables have the same columns whether or not
    # its runs have actuator limits.
    frame = metrics_table(result, built[0].plant.coordinate_names, tv_applied=True)
    frame = frame.drop(columns="run")
    frame.insert(0, "h_max", [float(b.delay.h_max) for b in built])
    return frame


def _is_number(value: object) -> bool:
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(
        value, bool | np.bool_
    )


def value_column(values: Sequence[Any]) -> list[Any]:
    """How a swept key's values are stored: the same rule per unit and for the whole table.

    A column of numbers stays numbers; otherwise strings stay as they are and every other value
    (numbers among strings, booleans, lists, tables) becomes canonical JSON text, so a value is
    stored the same way whatever else its unit holds, and parts concatenate into one type.
    """
    if all(_is_number(value) for value in values):
        return list(values)
    return [value if isinstance(value, str) else canonical_json(_plain(value)) for value in values]


def _plain(value: Any) -> Any:
    return value.item() if isinstance(value, np.generic) else value


def run_unit(unit: Unit, *, workers: int | None = None) -> pd.DataFrame:
    """Simulate a unit's runs (metrics only) with the batched engine; one row per run.

    Runs with the same plant, model and controller types, times and reference share one
    :func:`~delaytrack.sim.simulate` call.

    Returns
    -------
    DataFrame
        Columns ``run`` (index in the sweep), one per swept key (numbers and strings as they
        are, lists and tables as canonical JSON), ``controller_type``, ``delay_type``, ``h_max``
        (the delay profile's bound, s), ``status``, ``t_stop``, ``ae_<c>``, ``rms_<c>``,
        ``max_<c>`` per coordinate ``c`` (the plant's ``coordinate_names``, else ``q1 .. qn``) and
        ``tv`` (NaN unless ``status`` is ``ok``), in run order.
    """
    groups: dict[str, list[Run]] = {}
    for run in unit.runs:
        groups.setdefault(_batch_key(run), []).append(run)
    metrics = {}
    # Equal tables of the unit's runs (a batch's controller, a robot drawn again) are built
    # once, not once a run: the same objects, so the same numbers.
    with remembered_tables():
        for batch in groups.values():
            frame = _simulate_batch(batch, workers)
            for run, (_, row) in zip(batch, frame.iterrows(), strict=True):
                metrics[run.index] = row
    runs = unit.runs
    columns: dict[str, Any] = {"run": [run.index for run in runs]}
    for key in runs[0].values:
        columns[key] = value_column([run.values[key] for run in runs])
    columns["controller_type"] = [run.scenario.controller["type"] for run in runs]
    columns["delay_type"] = [run.scenario.delay["type"] for run in runs]
    table = pd.DataFrame([metrics[run.index] for run in runs]).reset_index(drop=True)
    return pd.concat([pd.DataFrame(columns), table], axis=1)


def write_part(frame: pd.DataFrame, unit: Unit, folder: str | Path) -> Path:
    """Write a unit's results as its part, atomically and durably; return the path.

    The unit's hash and run count go into the Parquet metadata. The file is fsynced before it is
    renamed into place and the folder after, so a part that exists survives a crash.
    """
    if len(frame) != len(unit.runs):
        raise ValueError(
            f"frame has {len(frame)} rows; unit {unit.index} has {len(unit.runs)} runs"
        )
    table = pa.Table.from_pandas(frame, preserve_index=False)
    metadata = {
        **(table.schema.metadata or {}),
        HASH_KEY: unit.hash.encode("ascii"),
        RUNS_KEY: str(len(unit.runs)).encode("ascii"),
        CONTENT_KEY: content_hash(frame).encode("ascii"),
    }
    target = Path(folder) / unit.part_name
    with atomic_path(target) as temporary:
        pq.write_table(table.replace_schema_metadata(metadata), temporary)
        with open(temporary, "rb") as handle:
            os.fsync(handle.fileno())
    _fsync_folder(target.parent)
    return target


def _fsync_folder(folder: Path) -> None:
    """Make a rename in ``folder`` durable (POSIX; a no-op where folders cannot be opened)."""
    try:
        handle = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(handle)
    finally:
        os.close(handle)


@dataclass(frozen=True)
class PartsScan:
    """What :func:`finished_units` found in a results folder.

    Attributes
    ----------
    finished : frozenset of int
        Indices of units whose part is complete and made by this spec and package version.
    rejected : Mapping[str, str]
        Part file name -> why it does not count (truncated, corrupt, another spec or version,
        wrong row count); those units run again.
    """

    finished: frozenset[int]
    rejected: Mapping[str, str]


#: Largest uncompressed size of a part's values, per run of its unit (1 MiB: a run's row
#: holds its labels, drawn values and metrics, a few kB).
_LARGEST_PER_RUN = 2**20


class _Unbounded(Exception):
    """A part whose values would be read beyond its bound: the message says why."""


#: What reading a part may allocate: this many times the bytes of values it may hold (values,
#: the pages they are decoded from, the dictionaries of its texts), and this much more.
_READ_BUDGET_FACTOR = 4
_READ_BUDGET_SLACK = 64 * 2**20


def _read(source: Any, texts: Sequence[str]) -> pa.Table:
    """A part's table, its ``texts`` as dictionaries, read on this thread."""
    return pq.read_table(source, read_dictionary=texts, use_threads=False, pre_buffer=False)


@functools.cache
def _arrow_threads_started() -> None:
    """Read a tiny table once, before any capped read: Arrow starts the threads its reads use
    on the first one, and their stacks (8 MiB or more each) would count against the cap."""
    sink = pa.BufferOutputStream()
    pq.write_table(pa.table({"x": ["a"]}), sink)
    _read(pa.BufferReader(sink.getvalue()), ["x"])


def _read_bounded(path: Path, footer: pq.FileMetaData, largest: int) -> pa.Table:
    """The table of the part at ``path`` (its ``footer`` read), read within ``largest`` bytes
    of values or refused (:class:`_Unbounded`): a nested column (no part holds one, and it
    would be read whole) and a footer giving more bytes are refused before reading; text
    columns are read as dictionaries, so that a text repeated in every row is held once while
    its rows' size, counted from the dictionary's lengths, is checked. The read itself may
    allocate at most a few times ``largest`` (:func:`~delaytrack._memory_budget.allocation_budget`):
    a footer can be forged to give sizes smaller than its pages'."""
    schema = footer.schema.to_arrow_schema()
    nested = [field.name for field in schema if pa.types.is_nested(field.type)]
    if nested:  # a part holds numbers and texts only: a nested column would be read unbounded
        raise _Unbounded(f"nested columns {nested}, which no part of the toolkit holds")
    stored = sum(footer.row_group(i).total_byte_size for i in range(footer.num_row_groups))
    if stored > largest:  # what a column not read as a dictionary takes, read whole
        raise _Unbounded(f"{stored} bytes of values, more than {largest}")
    texts = [
        field.name
        for field in schema
        if pa.types.is_string(field.type)
        or pa.types.is_large_string(field.type)
        or pa.types.is_binary(field.type)
        or pa.types.is_large_binary(field.type)
    ]
    # The footer's sizes are the file's own word: a forged one passes the check above, so the
    # read itself is capped too (a few kB of pages can decompress to gigabytes). Through the
    # system's allocator, which maps each large block anew: Arrow's own keeps memory it mapped
    # before and hands it out again, which the cap cannot see.
    budget = _READ_BUDGET_FACTOR * largest + _READ_BUDGET_SLACK
    _arrow_threads_started()
    pool = pa.default_memory_pool()
    pa.set_memory_pool(pa.system_memory_pool())
    try:
        with allocation_budget(budget):  # on this thread: a pool's new stacks would count
            table = _read(path, texts)
    except MemoryError:
        raise _Unbounded(
            f"reading its values asked for more than {budget} bytes, where its footer gives "
            f"{stored} bytes of values (its pages are larger than its footer says)"
        ) from None
    finally:
        pa.set_memory_pool(pool)
    size = 0
    for column in table.columns:
        for chunk in column.chunks:
            if pa.types.is_dictionary(chunk.type):
                lengths = pc.binary_length(chunk.dictionary).fill_null(0)
                size += pc.sum(pc.take(lengths, chunk.indices)).as_py() or 0
            else:
                size += chunk.nbytes
        if size > largest:
            raise _Unbounded(f"{size} bytes of values, more than {largest}")
    return pa.table(
        [
            column.cast(column.type.value_type) if pa.types.is_dictionary(column.type) else column
            for column in table.columns
        ],
        schema=schema.with_metadata(table.schema.metadata),
    )


def _check_part(path: Path, unit: Unit) -> str | None:
    """Why the part at ``path`` does not finish ``unit``, or None when it does. Its footer is
    checked before its values are read (:func:`_read_bounded`): a part of a folder someone sent
    can hold a few hundred bytes that decompress to gigabytes."""
    try:
        footer = pq.read_metadata(path)
    except (OSError, pa.ArrowException) as error:
        return f"unreadable (truncated or corrupt): {error}"
    metadata = footer.metadata or {}
    stored = metadata.get(HASH_KEY, b"").decode("ascii", "replace")
    if stored != unit.hash:
        return f"unit hash {stored[:12] or 'missing'} != {unit.hash[:12]} of this spec"
    runs = len(unit.runs)
    if footer.num_rows != runs or metadata.get(RUNS_KEY) != str(runs).encode():
        return f"{footer.num_rows} rows; unit {unit.index} has {runs} runs"
    try:
        table = _read_bounded(path, footer, _LARGEST_PER_RUN * (runs + 1))
    except (OSError, pa.ArrowException) as error:
        return f"unreadable (truncated or corrupt): {error}"
    except _Unbounded as error:
        return (
            f"{error}; unit {unit.index} has {runs} runs of at most {_LARGEST_PER_RUN} bytes each"
        )
    if metadata.get(CONTENT_KEY) != content_hash(table.to_pandas()).encode("ascii"):
        return "its values do not match the content hash written with them (altered or corrupt)"
    return None


def finished_units(folder: str | Path, spec: SweepSpec) -> PartsScan:
    """Which units of ``spec`` already have a valid part in ``folder`` (a resume check).

    Every ``part-*.parquet`` is read in full: one of this spec's parts counts when its metadata
    hash equals the unit's, its row count the unit's run count and its values their content
    hash. Any other part file is listed in :attr:`PartsScan.rejected` with the reason; a
    missing folder means nothing is finished.
    """
    folder = Path(folder)
    units = {unit.part_name: unit for unit in spec.units()}
    finished: set[int] = set()
    rejected: dict[str, str] = {}
    for path in sorted(folder.glob("part-*.parquet")):
        unit = units.get(path.name)
        if unit is None:
            rejected[path.name] = "not a part of this spec (another spec or package version)"
            continue
        reason = _check_part(path, unit)
        if reason is None:
            finished.add(unit.index)
        else:
            rejected[path.name] = reason
    return PartsScan(frozenset(finished), MappingProxyType(rejected))
