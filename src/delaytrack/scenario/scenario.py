"""A scenario, one closed-loop experiment as a frozen, serialisable spec, and the objects it
describes (:class:`BuiltScenario`); the file format is described in :mod:`delaytrack.scenario`."""

from __future__ import annotations

import copy
import dataclasses
import functools
import math
import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any, TypeVar

import numpy as np

from delaytrack._io import write_text
from delaytrack._spec import (
    PYTHON_TYPE,
    check_table,
    fail,
    integer,
    named_in_a_file,
    number,
    string,
    vector,
)
from delaytrack._spec import SpecError as ScenarioError
from delaytrack._trust import Trust
from delaytrack._validation import integer_multiple
from delaytrack.controllers import Controller, controller_from_spec
from delaytrack.delays import DelayProfile, delay_from_spec
from delaytrack.plants import ELPlant, plant_from_spec
from delaytrack.references import Reference, reference_from_spec
from delaytrack.scenario.files import read_toml_file, resolve_file_keys
from delaytrack.scenario.keys import (
    NAME_PATTERN,
    REQUIRED,
    SWEEP_KEYS,
    TABLE_PURPOSE,
    TABLE_TYPES,
    TABLES,
    TOP_LEVEL_KEYS,
    error_bound_phrase,
    input_limits_phrase,
    measurement_noise_phrase,
    packet_loss_phrase,
    x0_phrase,
)
from delaytrack.scenario.table_memory import remembered, table_identity
from delaytrack.scenario.toml_text import dumps_toml
from delaytrack.sim import MeasurementNoise, PacketLoss, SimResult, simulate
from delaytrack.sim._kernel_checks import velocities_on_constraints
from delaytrack.sim.certified_bound import stated_by_the_caller
from delaytrack.sim.measurement import MAX_SEED as MAX_NOISE_SEED
from delaytrack.sim.simulate import MAX_STEPS

_T = TypeVar("_T")

#: Exact types whose values :func:`_plain` returns as they are (a NumPy scalar, a subclass of
#: float or int, is converted).
_IMMUTABLE = frozenset({str, int, float, bool, type(None)})


def _check_value(key: str, value: object, check: Callable[[object], str | None]) -> None:
    phrase = check(value)
    if phrase is not None:
        raise fail(key, phrase, value)


def _all_finite(values: Any) -> str | None:
    """``None`` when every entry of ``values`` (a checked vector) is finite."""
    return None if all(number(value) is None for value in values) else "must be finite"


def _plain(value: Any) -> Any:
    """Deep copy of TOML-like data as plain dicts and lists (tuples become lists)."""
    if type(value) in _IMMUTABLE:  # the common case first: a copy would be the value itself
        return value
    if isinstance(value, Mapping):
        return {str(key): _plain(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(item) for item in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return copy.deepcopy(value)


@dataclass(frozen=True)
class BuiltScenario:
    """The objects a scenario describes, ready for :func:`delaytrack.sim.simulate`."""

    plant: ELPlant
    model: ELPlant
    controller: Controller
    delay: DelayProfile
    reference: Reference
    x0: np.ndarray


def _refuse_unknown_keys(keys: Iterable[str]) -> None:
    """Raise :class:`ScenarioError` naming the first of ``keys`` that is not a scenario's."""
    for key in keys:
        if key not in TOP_LEVEL_KEYS:
            kind = (
                "; this looks like a sweep file (run it with delaytrack sweep)"
                if key in SWEEP_KEYS
                else ""
            )
            raise ScenarioError(
                f"unknown key {key!r} in scenario; valid keys are {sorted(TOP_LEVEL_KEYS)}{kind}"
            )


@dataclass(frozen=True)
class Scenario:
    """One closed-loop experiment: plant, nominal model, controller, delay, reference, settings.

    Construct with :meth:`from_toml` or :meth:`from_dict` (or directly with the same fields);
    every field is validated on construction (see :mod:`delaytrack.scenario` for the file format).

    Attributes
    ----------
    name : str
        Identifier, also the default results folder name.
    plant, model, controller, delay, reference : Mapping
        The ``[plant]`` (truth), ``[model]`` (nominal plant), ``[controller]``, ``[delay]`` and
        ``[reference]`` tables, read-only.
    duration, dt, T_c : float
        Simulated time from ``t = 0``, plant step and controller period, in seconds. ``T_c`` must
        be an integer multiple of ``dt`` and ``duration`` of ``T_c``.
    seed : int or None
        Default seed of random elements: a random delay, ``measurement_noise`` and
        ``packet_loss`` without a seed of their own.
    x0 : tuple of float, "reference" or None
        Initial state ``[q, q̇]`` (2n); zeros when None. ``"reference"``: on the reference at
        ``t = 0``, ``q = q_d(0)`` and ``q̇ = q̇_d(0)``, or, for a plant with a reduced form
        (velocity constraints), ``q̇ = S(q) η`` with ``η`` the last ``r`` entries of
        ``q̇_d(0)``: on the constraints of the plant the run has, whatever its dimensions (a
        sweep over a robot's wheel radius starts each run on its own constraints).
    record_every : int
        Record every ``record_every``-th controller tick.
    error_bound : float or tuple of float or None
        The "left the path" rule: a run stops with status ``left the path`` at the first
        controller tick where a tracking error ``|e1_j|`` exceeds it (one number for every
        coordinate, or one per coordinate, ``inf`` for none); no bound when None. Its metrics
        are then NaN and a sweep counts it in the divergence rate.
    input_limits : float or tuple of float or None
        Actuator saturation: each command is applied as ``clip(u_j, -limit_j, limit_j)`` (one
        number for every input, or one per input, ``inf`` for none); no limit when None.
    measurement_noise : mapping or None
        What the controller reads: ``{quantization, position, velocity, seed}``
        (:class:`~delaytrack.sim.measurement.MeasurementNoise`); the true state when None.
    packet_loss : mapping or None
        Lost command packets: ``{probability, seed}``
        (:class:`~delaytrack.sim.packet_loss.PacketLoss`); none lost when None.
    u_init : tuple of float or None
        The input ``u_init`` (m entries, in the inputs' units) the plant receives before the
        first command arrives, i.e. over ``[0, h(0))``; zeros when None. It must lie within
        ``input_limits``.
    source : Path or None
        The file it was read from (:meth:`from_toml`), which its refusals name; not a key of
        the file, and not compared.
    """

    name: str
    plant: Mapping[str, Any]
    model: Mapping[str, Any]
    controller: Mapping[str, Any]
    delay: Mapping[str, Any]
    reference: Mapping[str, Any]
    duration: float
    dt: float
    T_c: float
    seed: int | None = None
    x0: tuple[float, ...] | str | None = None
    record_every: int = 1
    error_bound: float | tuple[float, ...] | None = None
    input_limits: float | tuple[float, ...] | None = None
    measurement_noise: Mapping[str, Any] | None = None
    packet_loss: Mapping[str, Any] | None = None
    u_init: tuple[float, ...] | None = None
    source: Path | None = field(default=None, compare=False, repr=False, kw_only=True)

    def __post_init__(self) -> None:
        _check_value("name", self.name, string)
        if not NAME_PATTERN.fullmatch(self.name):
            raise fail(
                "name",
                "must start with a letter or digit and contain only letters, digits, '.', '_' "
                "and '-' (it names the results folder)",
                self.name,
            )
        for key in ("duration", "dt", "T_c"):
            value = getattr(self, key)
            _check_value(key, value, number)
            if value <= 0:
                raise fail(key, "must be > 0 (seconds)", value)
            object.__setattr__(self, key, float(value))
        if self.duration / self.dt > MAX_STEPS:
            raise fail(
                "duration",
                f"must be at most {MAX_STEPS:.0e} plant steps of 'dt' = {self.dt:g} s "
                f"({MAX_STEPS * self.dt:g} s; about a minute of computing for one run)",
                self.duration,
            )
        _check_ratio("T_c", self.T_c, "dt", self.dt)
        _check_ratio("duration", self.duration, "T_c", self.T_c)
        if self.seed is not None:
            _check_value("seed", self.seed, integer)
            if self.seed < 0:
                raise fail("seed", "must be >= 0", self.seed)
        if isinstance(self.x0, str):
            _check_value("x0", self.x0, x0_phrase)
        elif self.x0 is not None:
            x0 = _plain(self.x0)
            _check_value("x0", x0, vector)
            _check_value("x0", x0, _all_finite)
            object.__setattr__(self, "x0", tuple(float(v) for v in x0))
        if self.u_init is not None:
            u_init = _plain(self.u_init)
            _check_value("u_init", u_init, vector)
            _check_value("u_init", u_init, _all_finite)
            object.__setattr__(self, "u_init", tuple(float(v) for v in u_init))
        _check_value("record_every", self.record_every, integer)
        if self.record_every < 1:
            raise fail("record_every", "must be >= 1", self.record_every)
        for key, phrase in (
            ("error_bound", error_bound_phrase),
            ("input_limits", input_limits_phrase),
        ):
            if getattr(self, key) is not None:
                value = _plain(getattr(self, key))
                _check_value(key, value, phrase)
                object.__setattr__(
                    self,
                    key,
                    tuple(map(float, value)) if isinstance(value, list) else float(value),
                )
        for key, phrase in (
            ("measurement_noise", measurement_noise_phrase),
            ("packet_loss", packet_loss_phrase),
        ):
            if getattr(self, key) is not None:
                table = _plain(getattr(self, key))
                _check_value(key, table, phrase)
                object.__setattr__(self, key, MappingProxyType(table))
                if "seed" not in table and (self.seed or 0) > MAX_NOISE_SEED:
                    raise fail(
                        "seed",
                        f"must be at most {MAX_NOISE_SEED} (2**32 - 1): it seeds {key}, which "
                        "has no seed of its own",
                        self.seed,
                    )
        for table in TABLES:
            content = _plain(getattr(self, table))
            if isinstance(content, dict):  # anything else is refused by its check below
                content = MappingProxyType(content)
            object.__setattr__(self, table, content)
        for table, types in TABLE_TYPES.items():
            check = functools.partial(check_table, table, self._checked_form(table), types)
            remembered(check, "checked", lambda: self._identities, table)

    # ---- reading and writing -----------------------------------------------------------------

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Scenario:
        """Build from a dict with the layout of a scenario file (see :mod:`delaytrack.scenario`).

        The dict is your own code: its factories (``"python:..."`` types) are imported without
        the check of :meth:`from_toml`, and a ``"python:<file.py>:..."`` file is taken relative
        to the working folder.

        Raises
        ------
        ScenarioError
            For an unknown, missing or ill-typed key; the message names it.
        """
        if not isinstance(data, Mapping):
            raise ScenarioError(f"a scenario must be a table of keys; got {type(data).__name__}")
        _refuse_unknown_keys(data)
        for key in REQUIRED:
            if key not in data:
                what = f"table [{key}] ({TABLE_PURPOSE[key]})" if key in TABLES else f"key {key!r}"
                raise ScenarioError(f"scenario is missing the required {what}")
        # Tables are copied once, by the constructor.
        fields: dict[str, Any] = {
            k: v if isinstance(v, Mapping) else _plain(v) for k, v in data.items()
        }
        return cls(**fields)

    @classmethod
    def from_toml(
        cls, path: str | Path, *, trust: Sequence[str] = (), trust_its_folder: bool = True
    ) -> Scenario:
        """Read a scenario file. Relative paths (traces, factory files) are taken relative to
        its folder.

        A factory (``type = "python:..."``) is Python code: it is allowed only from a ``.py``
        file in the scenario file's folder or below it (after resolving ``..`` and links), or
        when ``trust`` names it (see :mod:`delaytrack.scenario`). Nothing is imported before.

        Parameters
        ----------
        path : path
        trust : sequence of str
            What you trust beyond the file's folder: module names (``"mylab.robots"``: it and
            its submodules) and paths with a ``/`` or ending in ``.py`` (``"./robots"``,
            ``"~/lab/arm.py"``: that file, or every file below that folder). The command
            line's ``--trust``.
        trust_its_folder : bool
            False for a file you did not write and only open (a live session folder's
            ``scenario.toml``): a factory beside it is then allowed only when ``trust`` names
            it.

        Raises
        ------
        ScenarioError
            If the file is missing, is not TOML, names a factory it may not, or is not a valid
            scenario; the message starts with the file name.
        ValueError
            If ``trust`` holds a name that is neither a module name nor an existing ``.py`` file
            or folder.
        """
        trusted = dataclasses.replace(Trust.of(trust), own_folder=bool(trust_its_folder))
        if not isinstance(path, str | os.PathLike) or isinstance(path, bytes):
            raise TypeError(
                f"path must be a file name (str or pathlib.Path); got {type(path).__name__} "
                f"{path!r:.80}"
            )
        if not str(path):
            raise ScenarioError("the scenario file's name is empty; give the path of a .toml file")
        source = Path(path)
        data = read_toml_file(source, "scenario file", ScenarioError)
        try:
            for table in TABLES:
                resolve_file_keys(source, table, data.get(table), trusted)
            with named_in_a_file():
                scenario = cls.from_dict(data)
        except ScenarioError as error:
            raise error.in_file(source) from None
        object.__setattr__(scenario, "source", source)  # not a key: set after the checks
        return scenario

    def to_dict(self) -> dict[str, Any]:
        """Plain data in the file layout (a deep copy); ``None`` fields are left out."""
        data: dict[str, Any] = {
            "name": self.name,
            "duration": self.duration,
            "dt": self.dt,
            "T_c": self.T_c,
        }
        if self.seed is not None:
            data["seed"] = self.seed
        if self.x0 is not None:
            data["x0"] = self.x0 if isinstance(self.x0, str) else list(self.x0)
        data["record_every"] = self.record_every
        for key in ("error_bound", "input_limits"):
            value = getattr(self, key)
            if value is not None:
                data[key] = list(value) if isinstance(value, tuple) else value
        for key in ("measurement_noise", "packet_loss"):
            if getattr(self, key) is not None:
                data[key] = _plain(getattr(self, key))
        if self.u_init is not None:
            data["u_init"] = list(self.u_init)
        for table in TABLES:
            data[table] = _plain(getattr(self, table))
        return data

    def to_toml(self, path: str | Path | None = None) -> str:
        """The scenario as TOML text; also written (atomically) to ``path`` when given."""
        text = dumps_toml(self.to_dict())
        if path is not None:
            write_text(path, text)
        return text

    def replace(self, **changes: Any) -> Scenario:
        """A copy with some fields changed (validated again), e.g. ``replace(dt=5e-4)``; the
        fields are the scenario file's top-level keys and tables. The copy is not the file's
        (its :attr:`source` is None): its refusals do not blame the file for a value changed."""
        _refuse_unknown_keys(changes)
        return dataclasses.replace(self, **changes, source=None)

    # ---- building and running ----------------------------------------------------------------

    def _checked_form(self, table: str) -> Any:
        """``[table]`` as it is checked and built: a delay with the defaults it takes from the
        scenario, a reference with its type."""
        if table == "delay":
            return _with_delay_defaults(self.delay, self.seed, self.duration)
        if table == "reference":
            return _with_reference_type(self.reference)
        return getattr(self, table)

    @functools.cached_property
    def _identities(self) -> Mapping[str, str | None]:
        """How :func:`~delaytrack.scenario.table_memory.remembered_tables` tells each table
        apart: the :func:`~delaytrack.scenario.table_memory.table_identity` of its checked form
        (:meth:`_checked_form`)."""
        return {table: table_identity(self._checked_form(table)) for table in TABLES}

    def build(self) -> BuiltScenario:
        """Construct plant, model, controller, delay, reference and ``x0``.

        Raises
        ------
        ScenarioError
            If a table's values are refused by its constructor (for example a gain that is not
            positive definite) or the dimensions disagree; the message names the table, and
            the file (:attr:`source`) of a scenario read from one.
        """
        try:
            return self._build()
        except ScenarioError as error:
            raise error if self.source is None else error.in_file(self.source) from None

    def _build(self) -> BuiltScenario:
        """:meth:`build`, its refusals not yet naming the file."""
        plant = self._built(lambda: plant_from_spec(_plain(self.plant)), "plant")
        model = self._built(lambda: plant_from_spec(_plain(self.model), table="model"), "model")
        if (model.n, model.m) != (plant.n, plant.m):
            raise ScenarioError(
                f"scenario table [model] has n = {model.n}, m = {model.m}; [plant] has "
                f"n = {plant.n}, m = {plant.m} (they must describe the same kind of system)"
            )
        controller = self._built(
            lambda: controller_from_spec(_plain(self.controller), model), "controller", "model"
        )
        delay = self._built(lambda: delay_from_spec(delay_as_run(self)), "delay")
        reference = self._built(lambda: reference_from_spec(_plain(self.reference)), "reference")
        if reference.n != plant.n:
            raise ScenarioError(
                f"scenario table [reference] gives n = {reference.n} coordinates; the plant has "
                f"n = {plant.n}"
            )
        if isinstance(self.error_bound, tuple) and len(self.error_bound) != plant.n:
            raise fail(
                "error_bound",
                f"must be one number or n = {plant.n} of them (one per coordinate)",
                list(self.error_bound),
            )
        if isinstance(self.input_limits, tuple) and len(self.input_limits) != plant.m:
            raise fail(
                "input_limits",
                f"must be one number or m = {plant.m} of them (one per input)",
                list(self.input_limits),
            )
        if self.u_init is not None and len(self.u_init) != plant.m:
            raise fail(
                "u_init", f"must have m = {plant.m} entries (one per input)", list(self.u_init)
            )
        limits = np.broadcast_to(self.simulated_input_limits, (plant.m,))
        if self.u_init is not None and np.any(np.abs(self.u_init) > limits):
            # the simulator refuses it too; checked here so that the live robot never applies it
            raise fail("u_init", "must lie within input_limits", list(self.u_init))
        if self.x0 is None:
            x0 = np.zeros(2 * plant.n)
        elif isinstance(self.x0, str):
            x0 = start_on_reference(plant, reference)
        else:
            x0 = np.array(self.x0)
            if x0.shape != (2 * plant.n,):
                raise fail("x0", f"must have 2n = {2 * plant.n} entries [q, qdot]", list(self.x0))
        return BuiltScenario(plant, model, controller, delay, reference, x0)

    def _built(self, make: Callable[[], _T], *tables: str) -> _T:
        """The component ``make`` builds from ``tables``, remembered
        (:func:`~delaytrack.scenario.table_memory.remembered_tables`) unless one of them names a
        factory of yours: a factory is called every time."""
        for table in tables:
            kind = getattr(self, table).get("type")
            if isinstance(kind, str) and kind.startswith(PYTHON_TYPE):
                return make()
        return remembered(make, "built", lambda: self._identities, *tables)

    def resolved(self) -> Scenario:
        """The scenario with its defaults written in: ``x0``, a random delay's seed/duration, and
        the seed of ``measurement_noise`` and ``packet_loss`` where they have none.

        Running the resolved scenario gives the same result; it is what gets saved as the
        scenario "as run".
        """
        return self.resolved_and_built()[0]

    def resolved_and_built(self) -> tuple[Scenario, BuiltScenario]:
        """:meth:`resolved` and :meth:`build` from one construction (sweeps check every run)."""
        built = self.build()
        as_run = {
            "x0": tuple(built.x0.tolist()),
            "delay": delay_as_run(self),
            "measurement_noise": _seeded(self.measurement_noise, self.seed),
            "packet_loss": _seeded(self.packet_loss, self.seed),
        }
        if all(value == getattr(self, key) for key, value in as_run.items()):
            return self, built  # resolved already: nothing to check again
        return self.replace(**as_run), built

    @property
    def simulated_error_bound(self) -> float | tuple[float, ...]:
        """``error_bound`` as :func:`~delaytrack.sim.simulate` takes it (``inf``: none set)."""
        return math.inf if self.error_bound is None else self.error_bound

    @property
    def simulated_measurement_noise(self) -> MeasurementNoise | None:
        """``measurement_noise`` as :func:`~delaytrack.sim.simulate` takes it."""
        noise = _seeded(self.measurement_noise, self.seed)
        return None if noise is None else MeasurementNoise(**noise)

    @property
    def simulated_packet_loss(self) -> PacketLoss | None:
        """``packet_loss`` as :func:`~delaytrack.sim.simulate` takes it."""
        loss = _seeded(self.packet_loss, self.seed)
        return None if loss is None else PacketLoss(**loss)

    @property
    def simulated_input_limits(self) -> float | tuple[float, ...]:
        """``input_limits`` as :func:`~delaytrack.sim.simulate` takes it (``inf``: none set)."""
        return math.inf if self.input_limits is None else self.input_limits

    @property
    def simulated_u_init(self) -> np.ndarray | None:
        """``u_init`` as :func:`~delaytrack.sim.simulate` takes it (None: zeros)."""
        return None if self.u_init is None else np.array(self.u_init)

    def simulation_settings(self) -> dict[str, Any]:
        """The scenario's keywords of :func:`~delaytrack.sim.simulate`: its times (``t1`` the
        duration, ``dt``, ``T_c``), error bound, input limits, measurement noise, packet loss
        and ``u_init``, each as ``simulate`` takes it (``record_every`` apart: a run without
        trajectories records nothing)."""
        return {
            "t1": self.duration,
            "dt": self.dt,
            "T_c": self.T_c,
            "error_bound": self.simulated_error_bound,
            "input_limits": self.simulated_input_limits,
            "measurement_noise": self.simulated_measurement_noise,
            "packet_loss": self.simulated_packet_loss,
            "u_init": self.simulated_u_init,
        }

    def run(self, *, progress: bool = False) -> SimResult:
        """Simulate the scenario (batch of one); see :func:`delaytrack.sim.simulate`."""
        built = self.build()
        return simulate_built(self, built, built.delay, progress=progress)


def _with_reference_type(reference: object) -> object:
    """``[reference]`` with its default type, ``"sinusoidal"``, written in (a copy)."""
    if not isinstance(reference, Mapping) or "type" in reference:
        return reference
    return {"type": "sinusoidal", **reference}


def _seeded(table: Mapping[str, Any] | None, seed: int | None) -> dict[str, Any] | None:
    """A ``measurement_noise`` or ``packet_loss`` table as it runs (a plain copy): without a
    seed of its own, with the scenario's ``seed``; with neither, it keeps its class's, 0."""
    if table is None:
        return None
    spec = _plain(table)
    if "seed" not in spec and seed is not None:
        spec["seed"] = seed
    return spec


def _with_delay_defaults(delay: Any, seed: int | None, duration: float) -> Any:
    """A random delay without its own seed or duration takes the scenario's (a copy)."""
    if not isinstance(delay, Mapping) or delay.get("type") != "random":
        return delay
    spec = dict(delay)
    if "seed" not in spec:
        if seed is None:
            raise ScenarioError(
                "scenario key 'delay.seed' is missing and the scenario has no 'seed'; a "
                "random delay needs one of them (results must be reproducible)"
            )
        spec["seed"] = seed
    spec.setdefault("duration", duration)
    return spec


def _check_ratio(name: str, value: float, unit_name: str, unit: float) -> None:
    ratio = value / unit
    if integer_multiple(value, unit) is None:
        raise ScenarioError.of_key(
            name,
            f"must be a positive integer multiple of {unit_name!r}; got {name} = {value:g}, "
            f"{unit_name} = {unit:g} ({name}/{unit_name} = {ratio:.12g})",
        )


def delay_as_run(scenario: Scenario) -> dict[str, Any]:
    """The scenario's ``[delay]`` as it runs: a random delay without its own seed or duration
    with the scenario's written in (a plain copy)."""
    return _with_delay_defaults(_plain(scenario.delay), scenario.seed, scenario.duration)


def simulate_built(
    scenario: Scenario,
    built: BuiltScenario,
    delay: DelayProfile | list[DelayProfile],
    *,
    progress: bool = False,
) -> SimResult:
    """Simulate ``scenario`` with the objects :meth:`Scenario.build` made of it.

    Parameters
    ----------
    scenario : Scenario
        Its times, ``record_every``, error bound, input limits, measurement noise, packet
        loss and ``u_init``.
    built : BuiltScenario
        ``scenario.build()``: the plant, controller, reference and ``x0`` simulated.
    delay : DelayProfile or list of DelayProfile
        ``built.delay``, or one delay per batch element (:func:`delaytrack.sim.simulate`).
    progress : bool
        Show the simulator's progress bar.

    Raises
    ------
    ScenarioError
        If :func:`delaytrack.sim.simulate` refuses its input; the message names the scenario.
    """
    try:
        with stated_by_the_caller():  # the command line states h_m beside the delays
            return simulate(
                built.plant,
                built.controller,
                delay,
                built.x0,
                reference=built.reference,
                record_every=scenario.record_every,
                progress=progress,
                **scenario.simulation_settings(),
            )
    except ValueError as error:
        # simulate()'s refusals of its input; anything else is a bug and keeps its traceback.
        raise ScenarioError(f"scenario {scenario.name!r}: {error}") from None


def start_on_reference(plant: ELPlant, reference: Reference) -> np.ndarray:
    """The start ``x0 = "reference"`` of a scenario: ``[q_d(0), q̇_d(0)]``, its velocities for a
    plant with a reduced form set on the plant's constraints, ``q̇ = S(q) η`` with ``η`` the last
    ``r`` entries of ``q̇_d(0)`` (:class:`~delaytrack.components.ReducedForm`); ``reference``
    of the plant's ``n`` coordinates (checked by :meth:`Scenario.build`)."""
    q_d, q_d_dot, _ = reference.evaluate(0.0)
    x0 = np.concatenate([q_d, q_d_dot])
    if plant.engine_kernel.reduced is not None:
        x0[plant.n :] = velocities_on_constraints(plant, x0)
    return x0
