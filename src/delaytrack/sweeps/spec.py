"""Sweep specs: a base scenario, a grid and seeded random draws over its keys, cut into units.

A sweep file (TOML)::

    scenario = "two_link_S1"   # a shipped scenario name, or a scenario file (relative to this file)
    unit_size = 8              # runs per work unit (one Parquet part each)
    draws = 4                  # random draws, each paired with every grid point (with [random])
    seed = 7                   # seed of the draws (with [random])
    metrics = ["ae_q1", "tv"]  # optional: what the summary reports (every ae_* and tv by default)

    [grid]                     # Cartesian product, first key outermost, values in the listed order
    "controller.K1" = [0.5, 1.0, 2.0]
    delay = [{type = "S1"}, {type = "constant", h = 0.05}]   # a table name: whole tables

    [random]                   # key -> distribution
    "plant.fd1" = {dist = "loguniform", low = 1.0, high = 10.0}
    "controller.alpha" = {dist = "choice", values = [1.0, 2.0]}
    seed = {dist = "integers", low = 0, high = 1000}          # the scenario's seed; high inclusive

A key is a top-level scenario key (``duration``, ``seed``, ...), a table name (``delay``: the
value replaces the whole table) or a dotted ``table.key`` (``controller.K1``: the value replaces
one key of the table, after any whole-table replacement; also ``measurement_noise.seed`` and
``packet_loss.seed`` when the run has that table). Every run is validated as a
:class:`~delaytrack.scenario.Scenario` when the spec is loaded; a refusal names the sweep key
(``grid."controller.K9" = 1.0 (run 0): unknown key 'controller.K9' in scenario; ...``).

A table's ``type`` may name a factory of yours (``"python:<file.py>:<function>"``, the file
relative to the file that names it, or ``"python:<module>:<function>"``). A factory is Python code
that runs with your rights: one named in the sweep file must be a ``.py`` file in its folder or
below it, one named in the scenario file a ``.py`` file in that file's folder or below it, unless
you trust it (``--trust``, ``trust=``; see :mod:`delaytrack.scenario`).

Run ``i`` is grid point ``i // draws`` with draw ``i % draws`` (one draw without ``[random]``).
Draws of a key come from ``numpy.random.default_rng([seed, *key.encode()])``: they depend on the
seed, the key, its distribution and ``draws`` only, not on the other keys.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np
from tqdm.auto import tqdm

from delaytrack._compile.disk_cache import source_hash
from delaytrack._io import finite_numbers, regular_file
from delaytrack._spec import named_in_a_file, number
from delaytrack._trust import Trust
from delaytrack._validation import is_integer_at_least, quoted
from delaytrack._version import __version__
from delaytrack.metrics import COORDINATE_METRICS
from delaytrack.scenario import (
    BuiltScenario,
    Scenario,
    ScenarioError,
    builtin_scenario_names,
    builtin_scenario_path,
)
from delaytrack.scenario.files import read_toml_file, resolve_file_keys
from delaytrack.scenario.keys import SWEEP_KEYS, TOP_LEVEL_KEYS
from delaytrack.scenario.table_memory import remembered_tables
from delaytrack.units import default_names

__all__ = ["DISTRIBUTIONS", "MAX_RUNS", "Run", "SweepError", "SweepSpec", "Unit"]


class SweepError(ScenarioError):
    """A sweep spec is not valid; the message names the sweep key and what is valid."""


_INT64_MIN, _INT64_MAX = -(2**63), 2**63 - 1


def _check_storable(where: str, values: list[Any]) -> None:
    """Refuse a swept integer that a part's column of numbers cannot hold (beyond 64 bits):
    found after its unit ran, it lost the unit every time (an integer inside a table is
    stored as JSON text, whatever its size)."""
    for i, value in enumerate(values):
        if isinstance(value, int) and not isinstance(value, bool):
            if not _INT64_MIN <= value <= _INT64_MAX:
                raise SweepError(
                    f"{where}[{i}] = {value} is beyond what a sweep's tables store: a 64-bit "
                    f"integer, from {_INT64_MIN} to {_INT64_MAX}"
                )


#: Most runs of one sweep: loading checks every run (about 0.3 ms each on two busy cores, each
#: distinct table once, so 100 000 runs take about 30 to 50 s and a few hundred MB); larger
#: studies are several sweep files.
MAX_RUNS = 100_000
_TABLES = ("plant", "model", "controller", "delay", "reference")
#: Optional scenario tables whose keys a sweep may also set one by one (``measurement_noise.seed``).
_OPTIONAL_TABLES = ("measurement_noise", "packet_loss")
_SCALARS = (
    "name",
    "duration",
    "dt",
    "T_c",
    "seed",
    "x0",
    "record_every",
    "error_bound",
    "input_limits",
    "u_init",
    "measurement_noise",
    "packet_loss",
)

#: Distribution name -> its parameters, for ``[random]`` entries.
DISTRIBUTIONS: Mapping[str, tuple[str, ...]] = MappingProxyType(
    {
        "uniform": ("low", "high"),
        "loguniform": ("low", "high"),
        "choice": ("values",),
        "integers": ("low", "high"),
    }
)


@dataclass(frozen=True)
class Run:
    """One run of a sweep: its stable index, the swept values, the resolved scenario, what the
    engine receives for it (:func:`engine_inputs`: the kernels' keys and a hash of every
    parameter vector) and its controller's state size (runs of different sizes cannot share a
    batch)."""

    index: int
    values: Mapping[str, Any]
    scenario: Scenario
    kernels: tuple[str, ...]
    parameters: str
    state_size: int

    @classmethod
    def of(cls, index: int, values: Mapping[str, Any], scenario: Scenario, built: Any) -> Run:
        """The run of a scenario and its construction (:meth:`Scenario.build`)."""
        return cls(index, values, scenario, *engine_inputs(built), built.controller.state_size)

    def canonical(self) -> dict[str, Any]:
        """Plain data identifying the run (what unit hashes cover)."""
        return {
            "index": self.index,
            "values": dict(self.values),
            "scenario": self.scenario.to_dict(),
            "kernels": list(self.kernels),
            "parameters": self.parameters,
        }


def _resolve_swept_files(
    source: Path, section: str, key: str, values: object, trust: Trust
) -> None:
    """Make the files named by swept values absolute, relative to the sweep file ``source``, in
    place: whole tables (``controller = [{type = "python:pd.py:make", ...}]``) and the keys
    ``<table>.path`` and ``<table>.type``; refuse a factory that is neither beside the sweep
    file (or below) nor trusted, naming ``<section>."<key>"``."""
    if isinstance(values, dict):  # a "choice" draw
        values = values.get("values")
    if not isinstance(values, list):
        return
    table, _, field = key.partition(".")
    try:
        for i, value in enumerate(values):
            if key in _TABLES:
                resolve_file_keys(source, key, value, trust)
            elif table in _TABLES and field in ("path", "type") and isinstance(value, str):
                holder = {field: value}
                resolve_file_keys(source, table, holder, trust)
                values[i] = holder[field]
    except ScenarioError as error:
        raise SweepError(f'{section}."{key}": {error}') from None


def engine_inputs(built: BuiltScenario) -> tuple[tuple[str, ...], str]:
    """What the compiled engine receives for a run: the keys of its plant's, model's,
    controller's, reference's and delay's kernels (a user's with a hash of their code) and a
    sha256 of every parameter vector, the delay profile and ``x0``.

    A unit hash covers these rather than the Python code that made them, so that an edit of a
    factory, a default or a delay's definition that changes a run changes its hash, and one that
    does not (a docstring, a report) keeps finished parts.
    """
    controller = built.controller
    kernels = tuple(
        component.engine_kernel.key
        for component in (built.plant, controller.model, controller, built.reference, built.delay)
    )
    digest = hashlib.sha256()
    for array in (
        built.plant.run_identity,
        controller.model.run_identity,
        controller.params,
        controller.initial_state(),
        np.array([built.delay.kind], dtype=float),
        built.delay.params,
        built.reference.params,
        built.x0,
    ):
        values = np.ascontiguousarray(array, dtype=float)
        digest.update(str(values.shape).encode())
        digest.update(values.tobytes())
    return kernels, digest.hexdigest()


@dataclass(frozen=True)
class Unit:
    """A work unit: consecutive runs, written as one Parquet part.

    ``hash`` is the sha256 (hex) of the canonical JSON of the runs' :meth:`Run.canonical` and
    :func:`code_version` (package version and source hash): a part whose stored hash differs
    was made by another spec or another code.
    """

    index: int
    runs: tuple[Run, ...]
    hash: str

    @property
    def part_name(self) -> str:
        """The unit's part file: ``part-<unit index, 5 digits>-<hash, 12 hex>.parquet``."""
        return f"part-{self.index:05d}-{self.hash[:12]}.parquet"

    def to_payload(self) -> dict[str, Any]:
        """The unit as plain data (JSON types), to send to another process or machine."""
        runs = [run.canonical() for run in self.runs]
        version = code_version()
        return {"index": self.index, "hash": self.hash, "version": version, "runs": runs}

    @classmethod
    def from_payload(cls, payload: Mapping[str, Any]) -> Unit:
        """Rebuild a unit from :meth:`to_payload`, checking that it hashes the same here.

        The payload comes from a spec that was checked where it was loaded (its factories
        included, :meth:`SweepSpec.from_toml`); its factories are imported here unchecked.

        Raises
        ------
        SweepError
            When this process has another delaytrack version, or the rebuilt runs do not give the
            sender's hash (the scenarios would not run the same here).
        """
        index, version = payload["index"], payload["version"]
        if version != code_version():
            raise SweepError(
                f"unit {index} comes from delaytrack {version} (version+source hash); this "
                f"process has {code_version()}: install the same code on every Dask worker"
            )
        rebuilt: list[Run] = []
        with remembered_tables():
            for run in payload["runs"]:
                scenario = Scenario.from_dict(run["scenario"])
                values = MappingProxyType(run["values"])
                rebuilt.append(Run.of(run["index"], values, scenario, scenario.build()))
        runs = tuple(rebuilt)
        unit = cls(index, runs, _unit_hash(runs, version))
        if unit.hash != payload["hash"]:
            raise SweepError(
                f"unit {index} hashes to {unit.hash[:12]} here and {payload['hash'][:12]} where "
                "it was made: the scenarios differ between the two processes"
            )
        return unit


def _toml_text(value: float) -> str:
    """A non-finite float (an ``error_bound`` of ``inf``) as the text TOML uses."""
    return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf")


def canonical_json(data: Any) -> str:
    """Sorted keys, no spaces; a non-finite float as its TOML text: equal data give equal text."""
    try:  # most data is JSON as it is: the same text without a walk through it in Python
        return json.dumps(data, sort_keys=True, separators=(",", ":"), allow_nan=False)
    except (TypeError, ValueError):  # a non-finite float, a read-only mapping
        safe = finite_numbers(data, _toml_text)
        return json.dumps(safe, sort_keys=True, separators=(",", ":"), allow_nan=False)


#: Files without compiled code that still decide a sweep's numbers: how a run is set up for the
#: engine, how metrics are taken, how a part's rows are made.
RESULT_FILES = (
    "sim/simulate.py",
    "sim/_plan.py",
    "sim/_broadcast.py",
    "sim/_build.py",
    "sim/_arrays.py",
    "sim/_execute.py",
    "sim/_collect.py",
    "metrics.py",
    "sweeps/parts.py",
)


def code_version() -> str:
    """The package version, the hash of its compiled code
    (:func:`~delaytrack._compile.disk_cache.source_hash`) and of :data:`RESULT_FILES`; with
    :func:`engine_inputs`, what a part's numbers depend on."""
    digest = hashlib.sha256(source_hash().encode())
    package = Path(__file__).resolve().parents[1]
    for name in RESULT_FILES:
        digest.update((package / name).read_bytes())
    return f"{__version__}+{digest.hexdigest()[:16]}"


def _unit_hash(runs: Sequence[Run], version: str) -> str:
    payload = {"version": version, "runs": [run.canonical() for run in runs]}
    return hashlib.sha256(canonical_json(payload).encode("utf-8")).hexdigest()


def _check_key(source: str, key: object) -> str:
    if not isinstance(key, str):
        raise SweepError(f"{source} key {key!r} must be a string")
    table, dot, field = key.partition(".")
    if dot and table in (*_TABLES, *_OPTIONAL_TABLES) and field and "." not in field:
        return key
    if not dot and key in (*_TABLES, *_SCALARS):
        return key
    raise SweepError(
        f'{source}."{key}": unknown key; a sweep key is a top-level scenario key '
        f"{list(_SCALARS)}, a table name {list(_TABLES)} (its value replaces the table) or "
        "'table.key' such as 'controller.K1', 'delay.h' or 'measurement_noise.seed'"
    )


def _number(where: str, name: str, value: object) -> float:
    if number(value) is not None:  # not a number, or not finite as a float
        raise SweepError(f"{where}: '{name}' must be a finite number; got {quoted(value)}")
    return value  # type: ignore[return-value]  # checked a number by number()


def _draw(key: str, table: object, draws: int, seed: int) -> list[Any]:
    """``draws`` values of ``random."key"`` from its own seeded generator."""
    where = f'random."{key}"'
    if not isinstance(table, Mapping) or "dist" not in table:
        raise SweepError(
            f"{where} must be a table with 'dist', one of {list(DISTRIBUTIONS)}, and its "
            f"parameters; got {table!r}"
        )
    dist = table["dist"]
    if dist not in DISTRIBUTIONS:
        raise SweepError(f"{where}: 'dist' must be one of {list(DISTRIBUTIONS)}; got {dist!r}")
    expected = {"dist", *DISTRIBUTIONS[dist]}
    if set(table) != expected:
        raise SweepError(
            f"{where}: dist = {dist!r} takes exactly the keys {sorted(expected)}; got "
            f"{sorted(table)}"
        )
    rng = np.random.default_rng([seed, *key.encode("utf-8")])
    if dist == "choice":
        values = table["values"]
        if not isinstance(values, list) or not values:
            raise SweepError(f"{where}: 'values' must be a non-empty list; got {values!r}")
        _check_storable(f"{where}.values", values)
        return [copy.deepcopy(values[i]) for i in rng.integers(0, len(values), size=draws)]
    low = _number(where, "low", table["low"])
    high = _number(where, "high", table["high"])
    if dist == "integers":
        if not (isinstance(low, int) and isinstance(high, int) and low <= high):
            raise SweepError(
                f"{where}: dist = 'integers' needs integers low <= high (high inclusive); got "
                f"low = {low!r}, high = {high!r}"
            )
        if not (_INT64_MIN <= low and high < _INT64_MAX):
            raise SweepError(
                f"{where}: dist = 'integers' needs bounds within 64-bit integers "
                f"[{_INT64_MIN}, {_INT64_MAX - 1}]; got low = {low!r}, high = {high!r}"
            )
        return [int(v) for v in rng.integers(low, high, size=draws, endpoint=True)]
    if not (low < high and math.isfinite(high - low)):
        raise SweepError(
            f"{where}: needs low < high with a finite difference; got low = {low!r}, "
            f"high = {high!r}"
        )
    if dist == "uniform":
        return [float(v) for v in rng.uniform(low, high, size=draws)]
    if low <= 0:
        raise SweepError(f"{where}: dist = 'loguniform' needs low > 0; got low = {low!r}")
    return [float(v) for v in np.exp(rng.uniform(math.log(low), math.log(high), size=draws))]


def _apply(base: Mapping[str, Any], values: Mapping[str, Any]) -> dict[str, Any]:
    """The base scenario data with the run's values written in (whole tables first).

    Values and tables are shared with ``base`` and ``values`` (a :class:`Scenario` copies what
    it keeps), except a table a dotted key writes into: the run's own copy.
    """
    data = dict(base)
    for key, value in values.items():
        if "." not in key:
            data[key] = value
    own = set()
    for key, value in values.items():
        table, dot, field = key.partition(".")
        if dot:
            if not isinstance(data.get(table), dict):
                raise SweepError(
                    f'sweep key "{key}" needs a [{table}] table in the scenario or the sweep; '
                    f"got {data.get(table)!r}"
                )
            if table not in own:
                data[table] = dict(data[table])
                own.add(table)
            data[table][field] = value
    return data


def _metrics_list(value: object) -> tuple[str, ...] | None:
    if value is None:
        return None
    if not isinstance(value, list) or not value or not all(isinstance(v, str) for v in value):
        raise SweepError(
            f"sweep key 'metrics' must be a non-empty list of metric names such as "
            f'["ae_q1", "tv"]; got {value!r}'
        )
    return tuple(value)


def _positive_int(key: str, value: object) -> int:
    if not is_integer_at_least(value, 1):
        raise SweepError(f"sweep key {key!r} must be a positive integer; got {value!r}")
    return int(value)


@dataclass(frozen=True)
class SweepSpec:
    """A sweep: base scenario, grid, seeded random draws and unit size
    (:mod:`delaytrack.sweeps.spec`).

    Build with :meth:`from_toml` or :meth:`from_dict`; every run is expanded and validated on
    construction, so a spec that loads runs only valid scenarios.

    Attributes
    ----------
    base : Scenario
        The scenario every run starts from.
    grid : Mapping[str, tuple]
        Sweep key -> values (Cartesian product, first key outermost).
    random : Mapping[str, Mapping]
        Sweep key -> distribution table.
    draws, seed : int
        Number of random draws (1 without ``[random]``) and their seed.
    unit_size : int
        Runs per work unit.
    metrics : tuple of str or None
        Metric columns the summary reports (``ae_<c>``, ``rms_<c>``, ``max_<c>`` for the base
        plant's coordinates ``c``, ``tv``); None: every ``ae_*`` and ``tv``.
    progress : bool
        Show a progress bar while the runs are checked (not part of the sweep: specs that
        differ only in it are equal).
    """

    base: Scenario
    grid: Mapping[str, tuple[Any, ...]]
    random: Mapping[str, Mapping[str, Any]]
    draws: int
    seed: int
    unit_size: int
    metrics: tuple[str, ...] | None = None
    progress: bool = field(default=False, compare=False, repr=False)

    @classmethod
    def from_dict(
        cls,
        data: Mapping[str, Any],
        *,
        root: str | Path = ".",
        trust: Sequence[str] = (),
        progress: bool = False,
    ) -> SweepSpec:
        """Build from the layout of a sweep file; a relative ``scenario`` path is under ``root``.

        The dict is your own code: the factories its ``[grid]`` and ``[random]`` name are not
        checked. A scenario file it names is read by :meth:`Scenario.from_toml` with ``trust``.
        ``progress``: a progress bar while the runs are checked.

        Raises
        ------
        SweepError
            For an unknown, missing or ill-typed key, or a run that is not a valid scenario.
        """
        if not isinstance(data, Mapping):
            raise SweepError(f"a sweep spec must be a table of keys; got {type(data).__name__}")
        for key in data:
            if key not in SWEEP_KEYS:
                kind = (
                    "; this looks like a scenario file (run it with delaytrack simulate, or name "
                    "it in a sweep file's 'scenario' key)"
                    if key in TOP_LEVEL_KEYS
                    else ""
                )
                raise SweepError(
                    f"unknown sweep key {key!r}; valid keys are {list(SWEEP_KEYS)}{kind}"
                )
        for key in ("scenario", "unit_size"):
            if key not in data:
                raise SweepError(f"sweep spec is missing the required key {key!r}")
        if "grid" not in data and "random" not in data:
            raise SweepError("sweep spec needs a [grid] table, a [random] table or both")
        for table in ("grid", "random"):
            if table in data and isinstance(data[table], Mapping) and not data[table]:
                raise SweepError(
                    f"sweep table [{table}] is empty; give it at least one key or leave it out"
                )
        grid = data.get("grid", {})
        if not isinstance(grid, Mapping):
            raise SweepError(f"sweep key 'grid' must be a table; got {grid!r}")
        checked_grid = {}
        for key, values in grid.items():
            _check_key("grid", key)
            if not isinstance(values, list) or not values:
                raise SweepError(f'grid."{key}" must be a non-empty list of values; got {values!r}')
            _check_storable(f'grid."{key}"', values)
            checked_grid[key] = tuple(copy.deepcopy(values))
        random = data.get("random", {})
        if not isinstance(random, Mapping):
            raise SweepError(f"sweep key 'random' must be a table; got {random!r}")
        if random:
            missing = [key for key in ("draws", "seed") if key not in data]
            if missing:
                raise SweepError(
                    f"sweep spec has [random] and needs {' and '.join(map(repr, missing))} "
                    "(draws: how many draws, an integer >= 1; seed: their seed, an integer >= 0)"
                )
        else:
            for key in ("draws", "seed"):
                if key in data:
                    raise SweepError(f"sweep key {key!r} needs a [random] table to draw from")
        draws = _positive_int("draws", data.get("draws", 1))
        seed = data.get("seed", 0)
        if not is_integer_at_least(seed, 0):
            raise SweepError(f"sweep key 'seed' must be an integer >= 0; got {seed!r}")
        for key in random:
            _check_key("random", key)
            if key in checked_grid:
                raise SweepError(f'sweep key "{key}" is in both [grid] and [random]; keep one')
        return cls(
            base=_load_base(data["scenario"], Path(root), trust),
            grid=MappingProxyType(checked_grid),
            random=MappingProxyType(copy.deepcopy(dict(random))),
            draws=draws,
            seed=int(seed),
            unit_size=_positive_int("unit_size", data["unit_size"]),
            metrics=_metrics_list(data.get("metrics")),
            progress=progress,
        )

    @classmethod
    def from_toml(
        cls, path: str | Path, *, trust: Sequence[str] = (), progress: bool = False
    ) -> SweepSpec:
        """Read a sweep file; a relative ``scenario`` path is taken relative to the file.

        A factory a swept value names (``controller = [{type = "python:pd.py:make"}]``) is
        allowed only from a ``.py`` file in the sweep file's folder or below it, and one in the
        scenario file only from that file's folder or below, unless ``trust`` names it, as for
        :meth:`Scenario.from_toml`; nothing is imported before. ``progress``: a progress bar
        while the runs are checked.

        Raises
        ------
        SweepError
            If the file is missing, is not TOML, names a factory it may not, or is not a valid
            sweep; the message starts with the file name.
        ValueError
            If ``trust`` holds a name that is neither a module name nor an existing ``.py`` file
            or folder.
        """
        trusted = Trust.of(trust)
        source = Path(path)
        data = read_toml_file(source, "sweep file", SweepError)
        try:
            for section in ("grid", "random"):
                swept = data.get(section)
                for key, values in swept.items() if isinstance(swept, Mapping) else ():
                    _resolve_swept_files(source, section, key, values, trusted)
            with named_in_a_file():
                return cls.from_dict(data, root=source.parent, trust=trust, progress=progress)
        except ScenarioError as error:
            raise SweepError(f"{source}: {error}") from None

    def __post_init__(self) -> None:
        self.runs  # noqa: B018 -- expand and validate every run now, not at run time
        if self.metrics is not None:
            _check_metrics(self.metrics, self.base)

    @cached_property
    def runs(self) -> tuple[Run, ...]:
        """Every run, in index order."""
        count = math.prod(len(values) for values in self.grid.values()) * self.draws
        if count > MAX_RUNS:
            sizes = " x ".join(
                [f"{len(values)} ({key})" for key, values in self.grid.items()]
                + ([f"{self.draws} draws"] if self.random else [])
            )
            raise SweepError(
                f"the sweep expands to {count} runs ({sizes}); a sweep holds at most {MAX_RUNS} "
                "runs (each is validated and kept in memory when the file loads): split it into "
                "several sweep files"
            )
        drawn = {key: _draw(key, dist, self.draws, self.seed) for key, dist in self.random.items()}
        base = self.base.to_dict()
        runs: list[Run] = []
        bar = tqdm(
            total=count, desc="checking runs", unit="run", disable=not self.progress, delay=1
        )
        with remembered_tables(), bar:  # each distinct table checked and built once
            for point in itertools.product(*self.grid.values()):
                for d in range(self.draws):
                    values = dict(zip(self.grid, point, strict=True))
                    values.update({key: column[d] for key, column in drawn.items()})
                    runs.append(self._run(len(runs), values, base))
                    bar.update()
        return tuple(runs)

    def _run(self, index: int, values: dict[str, Any], base: Mapping[str, Any]) -> Run:
        try:
            scenario, built = Scenario.from_dict(_apply(base, values)).resolved_and_built()
            _check_runnable(scenario, built)
        except ScenarioError as error:
            message = str(error)
            named = [key for key in values if f"'{key}'" in message or f"[{key}]" in message]
            if named:
                key = named[0]
                source = "grid" if key in self.grid else "random"
                raise SweepError(
                    f'{source}."{key}" = {values[key]!r} (run {index}): {message}'
                ) from None
            shown = ", ".join(f"{key} = {value!r}" for key, value in values.items())
            raise SweepError(f"run {index} ({shown}): {message}") from None
        return Run.of(index, MappingProxyType(values), scenario, built)

    def units(self) -> tuple[Unit, ...]:
        """The runs cut into units of ``unit_size`` consecutive runs (the last may be shorter)."""
        return self._units

    @cached_property
    def _units(self) -> tuple[Unit, ...]:
        size, version = self.unit_size, code_version()
        chunks = [self.runs[i : i + size] for i in range(0, len(self.runs), size)]
        return tuple(Unit(k, chunk, _unit_hash(chunk, version)) for k, chunk in enumerate(chunks))

    def size_summary(self) -> str:
        """The work in one line: runs, units, plant steps per run and the base plant's
        coordinates (a sweep records metrics, not trajectories)."""
        steps = sorted({round(run.scenario.duration / run.scenario.dt) for run in self.runs})
        span = str(steps[0]) if len(steps) == 1 else f"{steps[0]} to {steps[-1]}"
        return (
            f"{len(self.runs)} runs in {len(self.units())} units of up to {self.unit_size}, "
            f"{span} plant steps each, n = {self.base.build().plant.n} coordinates (base "
            "scenario); metrics only, no trajectories recorded"
        )

    @property
    def label_keys(self) -> tuple[str, ...]:
        """Swept ``controller.*`` keys that name a controller in summaries: grid keys and
        ``choice`` draws (a continuous draw would make one group per run)."""
        return tuple(key for key in self._listed_keys if key.startswith("controller."))

    @property
    def delay_label_keys(self) -> tuple[str, ...] | None:
        """Swept delay keys (``delay``, ``delay.*``) that tell the summary's delay classes apart
        (:func:`~delaytrack.sweeps.summary.delay_classes`): grid keys and ``choice`` draws.
        None when a delay key is drawn from a continuous distribution: the classes are then
        bands of ``h_max``."""
        if any(_is_delay_key(key) for key in self.random if key not in self._listed_keys):
            return None
        return tuple(key for key in self._listed_keys if _is_delay_key(key))

    @property
    def _listed_keys(self) -> tuple[str, ...]:
        """The swept keys whose values come from lists: the grid's and ``choice`` draws."""
        chosen = [key for key, dist in self.random.items() if dist["dist"] == "choice"]
        return (*self.grid, *chosen)


def _is_delay_key(key: str) -> bool:
    return key == "delay" or key.startswith("delay.")


def _check_runnable(scenario: Scenario, built: BuiltScenario) -> None:
    """What :func:`~delaytrack.sim.simulate` checks before a run: the controller can run at
    ``T_c`` under delays up to ``h_max`` (a predictor's history)."""
    try:
        built.controller.check_run(scenario.T_c, float(built.delay.h_max))
    except ValueError as error:
        raise ScenarioError(
            f"scenario table [controller] cannot run with [delay]: {error}"
        ) from None


def _check_metrics(metrics: tuple[str, ...], base: Scenario) -> None:
    built = base.build()
    names = default_names(built.plant.coordinate_names, built.plant.n)
    valid = [f"{prefix}_{name}" for prefix in COORDINATE_METRICS for name in names]
    valid += ["tv", "tv_applied"]
    unknown = [metric for metric in metrics if metric not in valid]
    if unknown:
        raise SweepError(f"sweep key 'metrics': {unknown} unknown; valid metrics are {valid}")


def _load_base(source: object, root: Path, trust: Sequence[str]) -> Scenario:
    """A scenario file (relative to ``root``, read with ``trust``) or the name of a shipped
    scenario."""
    if not isinstance(source, str):
        raise SweepError(
            f"sweep key 'scenario' must be a scenario file or a shipped scenario name; got "
            f"{source!r}"
        )
    try:
        path = root / Path(source).expanduser()
    except RuntimeError as error:  # "~user" of no such user
        raise SweepError(f"sweep key 'scenario' = {source!r}: {error}") from None
    if path.is_file():
        return Scenario.from_toml(path, trust=trust)
    if source in builtin_scenario_names():
        return Scenario.from_toml(builtin_scenario_path(source))
    if path.exists():  # a folder, a device, a FIFO: named as such
        regular_file(path, "sweep key 'scenario' =", SweepError)
    raise SweepError(
        f"sweep key 'scenario' = {source!r} is neither a file (looked for {str(path)!r}) nor a "
        f"shipped scenario ({builtin_scenario_names()})"
    )
