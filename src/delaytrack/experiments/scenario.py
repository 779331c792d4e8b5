"""Scenarios: one closed-loop experiment as a frozen, serialisable spec (a TOML file).

A scenario file names the true plant, the nominal model the controller believes in, the
controller and its gains, the delay profile, the reference, and the numerical settings::

    name = "two_link_S1"        # folder name of the results: letters, digits, '.', '_', '-'
    duration = 30.0             # simulated seconds, from t = 0
    dt = 0.001                  # plant RK4 step (s)
    T_c = 0.002                 # controller period (s), an integer multiple of dt
    seed = 1                    # optional; see below
    x0 = [0.0, 0.0, 0.0, 0.0]   # optional [q, qdot] at t = 0; zeros by default
    record_every = 1            # optional; record every k-th controller tick
    error_bound = 10.0          # optional "left the path" rule: |e1_j| beyond it stops the run
    input_limits = [5.0, 2.0]   # optional actuator saturation: |u_j| applied at most this
    measurement_noise = { quantization = 0.0015, velocity = 0.01, seed = 3 }   # optional
    packet_loss = { probability = 0.05, seed = 3 }   # optional: lost command packets

    [plant]                     # the truth: type and parameters
    type = "two-link-arm"
    [model]                     # the nominal plant M̂, N̂ used by the controller
    type = "two-link-arm"
    fd1 = 0.0
    [controller]
    type = "arolc"
    K1 = 1.0                    # a number means K1 * I, a list a diagonal, a list of lists a matrix
    ...
    [delay]
    type = "S1"                 # or "constant", "abs-sine", "piecewise-constant", "trace", "random"
    [reference]                 # q_d(t) = offset + slope t + Σ amplitude sin(frequency t + phase)
    offset = [0.0, 0.0]         # (type = "sinusoidal" by default; "spline": waypoints)
    amplitude = [0.8, 0.5]
    frequency = [0.5, 0.7]

Every key is checked: an unknown key anywhere, a missing required key or a value of the wrong type
raises :class:`ScenarioError` naming the key in dotted form (``controller.alpha``) and what is
valid. The valid keys of each table depend on its ``type``; they are listed in the error message.

**Components of your own.** Any table's ``type`` may be ``"python:<file.py>:<function>"`` or
``"python:<module>:<function>"``: the function is called with the table's other keys as keyword
arguments (a controller's also with ``model=``) and returns the plant, controller, reference or
delay profile.

**A factory is code.** It runs with your rights when the file is loaded, and a file you were
sent could name any function (``python:os:remove``). So :meth:`Scenario.from_toml` (and every
command that reads a scenario or sweep file) allows a factory only from a ``.py`` file in the
scenario file's folder or below it, after resolving ``..`` and symbolic links, or from what you
trust: ``--trust NAME`` on the command line, ``trust=[NAME, ...]`` in Python, where NAME is a
module name (``mylab.robots``: it and its submodules) or a path with a ``/`` or ending in ``.py``
(``./robots``, ``~/lab/arm.py``: that file, or every file below that folder). No module is
trusted by default, not even this package's. Anything else is refused, naming the key, before
anything is imported. A dict given to :meth:`Scenario.from_dict` is your own code and is not
checked. The scenario as run that ``delaytrack simulate`` saves names factory files by absolute
path: loading it again from another folder needs ``--trust`` for them (the error says which).

**Seed.** ``seed`` is the scenario's random seed. Every random element without a seed of its own
takes it: today that is a ``[delay]`` of type ``"random"`` without ``seed``. Such a delay also
takes the scenario's ``duration`` when it has none. A random delay with neither its own seed nor a
scenario seed is refused (results must be reproducible). :meth:`Scenario.resolved` returns the
scenario with these defaults written in, which is what ``delaytrack simulate`` saves as
"the scenario as run".

**Paths.** A table's ``path`` (a trace or waypoint CSV file) and the file of a
``"python:<file.py>:..."`` type, in a file loaded by :meth:`Scenario.from_toml`, are taken
relative to the scenario file and stored absolute.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import json
import math
import re
import tomllib
from collections import OrderedDict
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from types import MappingProxyType
from typing import Any, TypeVar

import numpy as np

from delaytrack._io import regular_file, write_frame, write_text
from delaytrack._output import check_output_folder, claim_output_folder, record_outputs
from delaytrack._spec import (
    PYTHON_TYPE,
    check_table,
    factory_parts,
    fail,
    integer,
    number,
    string,
    vector,
)
from delaytrack._spec import SpecError as ScenarioError
from delaytrack._trust import Trust, check_factory
from delaytrack._validation import integer_multiple
from delaytrack.controllers import CONTROLLER_SPECS, Controller, controller_from_spec
from delaytrack.delays import DELAY_SPECS, DelayProfile, delay_from_spec
from delaytrack.plants import PLANT_SPECS, ELPlant, plant_from_spec
from delaytrack.references import REFERENCE_SPECS, Reference, reference_from_spec
from delaytrack.sim import MeasurementNoise, PacketLoss, SimResult, simulate
from delaytrack.sim.simulate import MAX_STEPS, physical_memory

__all__ = [
    "BuiltScenario",
    "RunOutput",
    "Scenario",
    "ScenarioError",
    "builtin_scenario_names",
    "builtin_scenario_path",
    "load_builtin",
    "run_batched",
    "run_to_folder",
    "dumps_toml",
]


_TOP_LEVEL_SCALARS: dict[str, Callable[[object], str | None]] = {
    "name": string,
    "duration": number,
    "dt": number,
    "T_c": number,
    "seed": integer,
    "x0": vector,
    "record_every": integer,
    "error_bound": lambda v: _error_bound_phrase(v),
    "input_limits": lambda v: _input_limits_phrase(v),
    "measurement_noise": lambda v: _measurement_noise_phrase(v),
    "packet_loss": lambda v: _packet_loss_phrase(v),
}
_TABLES = ("plant", "model", "controller", "delay", "reference")
_REQUIRED = ("name", "duration", "dt", "T_c", *_TABLES)
_TOP_LEVEL_KEYS = (*_TOP_LEVEL_SCALARS, *_TABLES)
_TABLE_TYPES = MappingProxyType(
    {
        "plant": PLANT_SPECS,
        "model": PLANT_SPECS,
        "controller": CONTROLLER_SPECS,
        "delay": DELAY_SPECS,
        "reference": REFERENCE_SPECS,
    }
)
_TABLE_PURPOSE = {
    "plant": "the true plant",
    "model": "the nominal plant the controller uses; copy [plant] for a perfect model",
    "controller": "the controller and its gains",
    "delay": "the input delay profile",
    "reference": "the desired trajectory q_d(t)",
}
_NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]*")


def _error_bound_phrase(value: object) -> str | None:
    """Check an ``error_bound``: a number or a list of numbers, each > 0 (``inf`` allowed)."""
    values = value if isinstance(value, list) else [value]
    valid = values and all(
        isinstance(v, int | float) and not isinstance(v, bool) and v > 0 for v in values
    )
    if valid:
        return None
    return (
        "must be a number > 0 or a list of them, one per coordinate (inf: no bound for that "
        "coordinate)"
    )


def _input_limits_phrase(value: object) -> str | None:
    """Check ``input_limits``: a number or a list of numbers, each > 0 (``inf`` allowed)."""
    if _error_bound_phrase(value) is None:
        return None
    return "must be a number > 0 or a list of them, one per input (inf: no limit for that input)"


_NOISE_KEYS = ("quantization", "position", "velocity", "seed")


def _measurement_noise_phrase(value: object) -> str | None:
    """Check ``measurement_noise``: a table of :class:`MeasurementNoise`'s keys."""
    if isinstance(value, dict) and set(value) <= set(_NOISE_KEYS):
        try:
            MeasurementNoise(**value)
        except (TypeError, ValueError) as error:
            return f"is refused: {error}"
        return None
    return f"must be a table with keys among {list(_NOISE_KEYS)}"


def _packet_loss_phrase(value: object) -> str | None:
    """Check ``packet_loss``: a table of :class:`PacketLoss`'s keys."""
    if isinstance(value, dict) and set(value) <= {"probability", "seed"}:
        try:
            PacketLoss(**value)
        except (TypeError, ValueError) as error:
            return f"is refused: {error}"
        return None
    return "must be a table with keys among ['probability', 'seed']"


#: Exact types whose values :func:`_plain` returns as they are (a NumPy scalar, a subclass of
#: float or int, is converted).
_IMMUTABLE = frozenset({str, int, float, bool, type(None)})


def _check_value(key: str, value: object, check: Callable[[object], str | None]) -> None:
    phrase = check(value)
    if phrase is not None:
        raise fail(key, phrase, value)


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


# --------------------------------------------------------------------------------------------
# TOML output. The standard library reads TOML but does not write it; scenarios only hold
# strings, integers, floats, booleans, (nested) lists of those and one level of tables, which
# this small writer covers with one-line arrays (readable matrices).

_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


def _toml_key(key: str) -> str:
    return key if _BARE_KEY.fullmatch(key) else json.dumps(key)


def _toml_value(value: Any, key: str) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        text = repr(value)
        return text if any(c in text for c in ".en") else f"{text}.0"
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(item, key) for item in value) + "]"
    raise ScenarioError(f"scenario key {key!r} cannot be written to TOML; got {value!r}")


def dumps_toml(data: Mapping[str, Any]) -> str:
    """Render scenario data (scalars, lists, one level of tables) as TOML text."""
    lines = [
        f"{_toml_key(key)} = {_toml_value(value, key)}"
        for key, value in data.items()
        if not isinstance(value, Mapping)
    ]
    for table, content in data.items():
        if not isinstance(content, Mapping):
            continue
        lines += ["", f"[{_toml_key(table)}]"]
        for key, value in content.items():
            if isinstance(value, Mapping):
                raise ScenarioError(f"scenario key '{table}.{key}' cannot be a nested table")
            lines.append(f"{_toml_key(key)} = {_toml_value(value, f'{table}.{key}')}")
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BuiltScenario:
    """The objects a scenario describes, ready for :func:`delaytrack.sim.simulate`."""

    plant: ELPlant
    model: ELPlant
    controller: Controller
    delay: DelayProfile
    reference: Reference
    x0: np.ndarray


@dataclass(frozen=True)
class Scenario:
    """One closed-loop experiment: plant, nominal model, controller, delay, reference, settings.

    Construct with :meth:`from_toml` or :meth:`from_dict` (or directly with the same fields);
    every field is validated on construction (see the module docstring for the file format).

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
        Default seed of random elements (a random delay without its own seed).
    x0 : tuple of float or None
        Initial state ``[q, q̇]`` (2n); zeros when None.
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
    x0: tuple[float, ...] | None = None
    record_every: int = 1
    error_bound: float | tuple[float, ...] | None = None
    input_limits: float | tuple[float, ...] | None = None
    measurement_noise: Mapping[str, Any] | None = None
    packet_loss: Mapping[str, Any] | None = None

    def __post_init__(self) -> None:
        _check_value("name", self.name, string)
        if not _NAME_PATTERN.fullmatch(self.name):
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
        if self.x0 is not None:
            x0 = _plain(self.x0)
            _check_value("x0", x0, vector)
            _check_value(
                "x0", x0, lambda v: None if all(map(math.isfinite, v)) else "must be finite"
            )
            object.__setattr__(self, "x0", tuple(float(v) for v in x0))
        _check_value("record_every", self.record_every, integer)
        if self.record_every < 1:
            raise fail("record_every", "must be >= 1", self.record_every)
        for key, phrase in (
            ("error_bound", _error_bound_phrase),
            ("input_limits", _input_limits_phrase),
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
            ("measurement_noise", _measurement_noise_phrase),
            ("packet_loss", _packet_loss_phrase),
        ):
            if getattr(self, key) is not None:
                table = _plain(getattr(self, key))
                _check_value(key, table, phrase)
                object.__setattr__(self, key, MappingProxyType(table))
        for table in _TABLES:
            content = _plain(getattr(self, table))
            if isinstance(content, dict):  # anything else is refused by its check below
                content = MappingProxyType(content)
            object.__setattr__(self, table, content)
        for table, types in _TABLE_TYPES.items():
            check = functools.partial(check_table, table, self._checked_form(table), types)
            _remembered(check, "checked", self, table)

    # ---- reading and writing -----------------------------------------------------------------

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Scenario:
        """Build from a dict with the layout of a scenario file (see the module docstring).

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
        for key in data:
            if key not in _TOP_LEVEL_KEYS:
                raise ScenarioError(
                    f"unknown key {key!r} in scenario; valid keys are {sorted(_TOP_LEVEL_KEYS)}"
                )
        for key in _REQUIRED:
            if key not in data:
                what = (
                    f"table [{key}] ({_TABLE_PURPOSE[key]})" if key in _TABLES else f"key {key!r}"
                )
                raise ScenarioError(f"scenario is missing the required {what}")
        # Tables are copied once, by the constructor.
        return cls(**{k: v if isinstance(v, Mapping) else _plain(v) for k, v in data.items()})

    @classmethod
    def from_toml(cls, path: str | Path, *, trust: Sequence[str] = ()) -> Scenario:
        """Read a scenario file. Relative paths (traces, factory files) are taken relative to
        its folder.

        A factory (``type = "python:..."``) is Python code: it is allowed only from a ``.py``
        file in the scenario file's folder or below it (after resolving ``..`` and links), or
        when ``trust`` names it (see the module docstring). Nothing is imported before.

        Parameters
        ----------
        path : path
        trust : sequence of str
            What you trust beyond the file's folder: module names (``"mylab.robots"``: it and
            its submodules) and paths with a ``/`` or ending in ``.py`` (``"./robots"``,
            ``"~/lab/arm.py"``: that file, or every file below that folder). The command
            line's ``--trust``.

        Raises
        ------
        ScenarioError
            If the file is missing, is not TOML, names a factory it may not, or is not a valid
            scenario; the message starts with the file name.
        ValueError
            If ``trust`` holds a name that is neither a module name nor an existing ``.py`` file
            or folder.
        """
        trusted = Trust.of(trust)
        source = Path(path)
        data = read_toml_file(source, "scenario file", ScenarioError)
        try:
            for table in _TABLES:
                resolve_file_keys(source, table, data.get(table), trusted)
            return cls.from_dict(data)
        except ScenarioError as error:
            raise ScenarioError(f"{source}: {error}") from None

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
            data["x0"] = list(self.x0)
        data["record_every"] = self.record_every
        for key in ("error_bound", "input_limits"):
            value = getattr(self, key)
            if value is not None:
                data[key] = list(value) if isinstance(value, tuple) else value
        for key in ("measurement_noise", "packet_loss"):
            if getattr(self, key) is not None:
                data[key] = _plain(getattr(self, key))
        for table in _TABLES:
            data[table] = _plain(getattr(self, table))
        return data

    def to_toml(self, path: str | Path | None = None) -> str:
        """The scenario as TOML text; also written (atomically) to ``path`` when given."""
        text = dumps_toml(self.to_dict())
        if path is not None:
            write_text(path, text)
        return text

    def replace(self, **changes: Any) -> Scenario:
        """A copy with some fields changed (validated again), e.g. ``replace(dt=5e-4)``."""
        return dataclasses.replace(self, **changes)

    # ---- building and running ----------------------------------------------------------------

    def _delay_spec(self) -> dict[str, Any]:
        return _with_delay_defaults(_plain(self.delay), self.seed, self.duration)

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
        """How :func:`remembered_tables` tells each table apart: its checked form
        (:meth:`_checked_form`) as JSON text with sorted keys, None when it is not JSON data."""
        identities = {}
        for table in _TABLES:
            form = self._checked_form(table)
            try:
                identities[table] = _identity_text(
                    dict(form) if isinstance(form, Mapping) else form
                )
            except (TypeError, ValueError):  # not JSON data (a date): never taken for another
                identities[table] = None
        return identities

    def build(self) -> BuiltScenario:
        """Construct plant, model, controller, delay, reference and ``x0``.

        Raises
        ------
        ScenarioError
            If a table's values are refused by its constructor (for example a gain that is not
            positive definite) or the dimensions disagree; the message names the table.
        """
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
        delay = self._built(lambda: delay_from_spec(self._delay_spec()), "delay")
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
        if self.x0 is None:
            x0 = np.zeros(2 * plant.n)
        else:
            x0 = np.array(self.x0)
            if x0.shape != (2 * plant.n,):
                raise fail("x0", f"must have 2n = {2 * plant.n} entries [q, qdot]", list(self.x0))
        return BuiltScenario(plant, model, controller, delay, reference, x0)

    def _built(self, make: Callable[[], _T], *tables: str) -> _T:
        """The component ``make`` builds from ``tables``, remembered (:func:`remembered_tables`)
        unless one of them names a factory of yours: a factory is called every time."""
        for table in tables:
            kind = getattr(self, table).get("type")
            if isinstance(kind, str) and kind.startswith(PYTHON_TYPE):
                return make()
        return _remembered(make, "built", self, *tables)

    def resolved(self) -> Scenario:
        """The scenario with its defaults written in: ``x0``, and a random delay's seed/duration.

        Running the resolved scenario gives the same result; it is what gets saved as the
        scenario "as run".
        """
        return self.resolved_and_built()[0]

    def resolved_and_built(self) -> tuple[Scenario, BuiltScenario]:
        """:meth:`resolved` and :meth:`build` from one construction (sweeps check every run)."""
        built = self.build()
        x0, delay = tuple(built.x0.tolist()), self._delay_spec()
        if x0 == self.x0 and delay == self.delay:  # resolved already: nothing to check again
            return self, built
        return self.replace(x0=x0, delay=delay), built

    @property
    def simulated_error_bound(self) -> float | tuple[float, ...]:
        """``error_bound`` as :func:`~delaytrack.sim.simulate` takes it (``inf``: none set)."""
        return math.inf if self.error_bound is None else self.error_bound

    @property
    def simulated_measurement_noise(self) -> MeasurementNoise | None:
        """``measurement_noise`` as :func:`~delaytrack.sim.simulate` takes it."""
        if self.measurement_noise is None:
            return None
        return MeasurementNoise(**_plain(self.measurement_noise))

    @property
    def simulated_packet_loss(self) -> PacketLoss | None:
        """``packet_loss`` as :func:`~delaytrack.sim.simulate` takes it."""
        return None if self.packet_loss is None else PacketLoss(**_plain(self.packet_loss))

    @property
    def simulated_input_limits(self) -> float | tuple[float, ...]:
        """``input_limits`` as :func:`~delaytrack.sim.simulate` takes it (``inf``: none set)."""
        return math.inf if self.input_limits is None else self.input_limits

    def run(self, *, progress: bool = False) -> SimResult:
        """Simulate the scenario (batch of one); see :func:`delaytrack.sim.simulate`."""
        built = self.build()
        return _simulate(self, built.plant, built.controller, built.delay, built, progress)


# --------------------------------------------------------------------------------------------
# Tables met again (a sweep's runs share a few distinct tables): checked and built once.

_T = TypeVar("_T")

#: Most checked tables and built components a :func:`remembered_tables` block keeps, the least
#: recently used dropped first: a sweep's runs share a few distinct values per key, and a table
#: drawn anew for every run is not met again. A check is remembered as a name; a component may
#: hold a model file's arrays, so fewer of them are kept.
_REMEMBERED_TABLES = MappingProxyType({"checked": 4096, "built": 256})
_REMEMBERED: ContextVar[dict[str, OrderedDict[tuple[str, ...], Any]] | None] = ContextVar(
    "_REMEMBERED", default=None
)
#: The text that identifies tables: JSON with sorted keys (a float's exact digits; 1, 1.0 and
#: true apart).
_identity_text = json.JSONEncoder(sort_keys=True, separators=(",", ":")).encode


@contextmanager
def remembered_tables() -> Iterator[None]:
    """Within the block, a scenario table met again is neither checked nor built again.

    Tables are the same when their name and content are (compared as JSON text with sorted
    keys); a ``[delay]`` is compared with the defaults it takes from the scenario written in, a
    ``[controller]`` with its ``[model]``. The rest of every scenario is checked every time. A
    table whose type is a factory of yours is checked once but its factory is called for every
    scenario (it may depend on more than its arguments). A file a table names is read when the
    table is first built: the block is for one load (a sweep's expansion), not for a session.
    """
    token = _REMEMBERED.set({kind: OrderedDict() for kind in _REMEMBERED_TABLES})
    try:
        yield
    finally:
        _REMEMBERED.reset(token)


def _remembered(make: Callable[[], _T], kind: str, scenario: Scenario, *tables: str) -> _T:
    """``make()``, or what it returned earlier in the :func:`remembered_tables` block for the
    same ``tables`` (names and contents) of a scenario, among the ``kind`` ("checked", "built")
    it keeps; a refusal is never remembered."""
    memories = _REMEMBERED.get()
    if memories is None:
        return make()
    identities = scenario._identities
    key = (*tables, *(identities[table] for table in tables))
    if None in key:
        return make()
    memory = memories[kind]
    if key in memory:
        memory.move_to_end(key)
        return memory[key]
    value = memory[key] = make()
    if len(memory) > _REMEMBERED_TABLES[kind]:
        memory.popitem(last=False)
    return value


def _construct(table: str, make: Callable[[], Any], keys: Iterable[str] = ()) -> Any:
    """Call a constructor; re-raise its refusal naming the table (and the key when it names one).

    The library's messages start with the offending argument's name (``"K1 must be symmetric
    positive definite; ..."``); when that name is a key of the table the message becomes
    ``"scenario key 'controller.K1' must be ..."``.
    """
    try:
        return make()
    except ScenarioError:
        raise
    except (ValueError, TypeError, FileNotFoundError) as error:
        message = str(error)
        for key in keys:
            if message.startswith(f"{key} "):
                raise ScenarioError(
                    f"scenario key '{table}.{key}' {message[len(key) + 1 :]}"
                ) from None
        raise ScenarioError(f"scenario table [{table}]: {message}") from None


def read_toml_file(source: Path, what: str, error: type[ScenarioError]) -> dict[str, Any]:
    """The TOML data of the file ``source`` (a regular file of bounded size, a byte-order mark
    allowed), or ``error`` naming ``what`` (``"scenario file"``) and the file."""
    try:
        regular_file(source, what, error)
        text = source.read_text(encoding="utf-8-sig")  # a byte-order mark is not TOML
    except FileNotFoundError:
        raise error(f"{what} {str(source)!r} does not exist") from None
    except (OSError, UnicodeDecodeError) as problem:
        raise error(f"cannot read {what} {str(source)!r}: {problem}") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as problem:
        raise error(f"{source}: not valid TOML: {problem}") from None


def resolve_file_keys(source: Path, table: str, value: object, trust: Trust) -> None:
    """Make the files a table names (``path``, and the file of a ``"python:<file.py>:..."``
    type) absolute, relative to the file ``source`` that holds it, in place; refuse a factory
    that is neither beside ``source`` (or below) nor trusted (:mod:`delaytrack._trust`), before
    anything is imported."""
    if not isinstance(value, dict):
        return
    kind = value.get("type")
    if isinstance(kind, str) and kind.startswith(PYTHON_TYPE):
        location, name = factory_parts(f"{table}.type", kind)
        if location.endswith(".py"):
            location = _absolute(source, f"{table}.type", location)
            value["type"] = f"{PYTHON_TYPE}{location}:{name}"
        check_factory(f"{table}.type", kind, location, source, trust)
    if isinstance(value.get("path"), str):
        value["path"] = _absolute(source, f"{table}.path", value["path"])


def _absolute(source: Path, key: str, text: str) -> str:
    try:
        path = Path(text).expanduser()
        return str(path if path.is_absolute() else (source.parent / path).resolve())
    except (OSError, RuntimeError) as error:  # "~user" of no such user, a link loop
        raise ScenarioError(f"scenario key {key!r}: {error}") from None


def _with_reference_type(reference: object) -> object:
    """``[reference]`` with its default type, ``"sinusoidal"``, written in (a copy)."""
    if not isinstance(reference, Mapping) or "type" in reference:
        return reference
    return {"type": "sinusoidal", **reference}


def _with_delay_defaults(delay: object, seed: int | None, duration: float) -> object:
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


def _simulate(
    scenario: Scenario,
    plant: ELPlant,
    controller: Controller,
    delay: DelayProfile | list[DelayProfile],
    built: BuiltScenario,
    progress: bool,
) -> SimResult:
    try:
        return simulate(
            plant,
            controller,
            delay,
            built.x0,
            reference=built.reference,
            t1=scenario.duration,
            dt=scenario.dt,
            T_c=scenario.T_c,
            record_every=scenario.record_every,
            error_bound=scenario.simulated_error_bound,
            input_limits=scenario.simulated_input_limits,
            measurement_noise=scenario.simulated_measurement_noise,
            packet_loss=scenario.simulated_packet_loss,
            progress=progress,
        )
    except ValueError as error:
        # simulate()'s refusals of its input; anything else is a bug and keeps its traceback.
        raise ScenarioError(f"scenario {scenario.name!r}: {error}") from None


def run_batched(scenarios: Sequence[Scenario], *, progress: bool = False) -> SimResult:
    """Run scenarios that differ only in name, delay and seed as one batched simulation.

    Batch element ``i`` is ``scenarios[i]``; the result equals running each scenario alone.

    Raises
    ------
    ScenarioError
        If the list is empty or the scenarios differ in anything else than name, delay and seed.
    """
    if not scenarios:
        raise ScenarioError("run_batched needs at least one scenario")
    first = scenarios[0]
    shared = _shared_part(first)
    for other in scenarios[1:]:
        if _shared_part(other) != shared:
            different = sorted(k for k in shared if _shared_part(other).get(k) != shared.get(k))
            raise ScenarioError(
                f"scenarios {first.name!r} and {other.name!r} differ in {different}; only name, "
                "delay and seed may differ within a batch"
            )
    built = first.build()
    delays = [delay_from_spec(scenario._delay_spec()) for scenario in scenarios]
    return _simulate(first, built.plant, built.controller, delays, built, progress)


def _shared_part(scenario: Scenario) -> dict[str, Any]:
    data = scenario.to_dict()
    for key in ("name", "delay", "seed"):
        data.pop(key, None)
    return data


# --------------------------------------------------------------------------------------------
# Scenarios shipped with the package (src/delaytrack/scenarios/*.toml).


def builtin_scenario_names() -> list[str]:
    """Names (file stems) of the scenario files shipped with the package."""
    folder = resources.files("delaytrack").joinpath("scenarios")
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def builtin_scenario_path(name: str) -> Path:
    """Path of a shipped scenario file, e.g. ``builtin_scenario_path("two_link_S1")``."""
    names = builtin_scenario_names()
    if name not in names:
        raise ScenarioError(f"no built-in scenario {name!r}; the built-in scenarios are {names}")
    return Path(str(resources.files("delaytrack").joinpath("scenarios", f"{name}.toml")))


def load_builtin(name: str) -> Scenario:
    """Load a shipped scenario by name (see :func:`builtin_scenario_names`)."""
    return Scenario.from_toml(builtin_scenario_path(name))


# --------------------------------------------------------------------------------------------
# One scenario to a results folder (what `delaytrack simulate` does).

TRAJECTORY_FORMATS = ("parquet", "csv")
#: Peak memory of writing a results folder over the recorded arrays alone (measured: the frame,
#: its Parquet/CSV writers and the figures hold copies).
_WRITE_OVERHEAD = 10


@dataclass(frozen=True)
class RunOutput:
    """What :func:`run_to_folder` produced: the result and the files written."""

    scenario: Scenario
    result: SimResult
    folder: Path
    files: tuple[Path, ...]


def run_to_folder(
    scenario: Scenario,
    folder: str | Path,
    *,
    formats: Sequence[str] = ("parquet",),
    figure_formats: Sequence[str] = ("png", "svg"),
    progress: bool = False,
) -> RunOutput:
    """Run a scenario and write its results folder.

    Files (each written atomically):

    - ``scenario.toml``: the scenario as run (:meth:`Scenario.resolved`; loads back unchanged);
    - ``metrics.csv``: :func:`delaytrack.metrics.metrics_table` (AE, RMS, max error, TV);
    - ``trajectories.parquet`` and/or ``trajectories.csv``: :meth:`SimResult.to_frame`;
    - ``figures/{tracking,error,commands,delay[,c_hat]}.{png,svg}``.

    Parameters
    ----------
    scenario : Scenario
    folder : path
        Created if missing. It must be new, empty or a results folder of an earlier run (whose
        files are replaced; those this run does not write again are removed), and it is checked
        before anything is computed.
    formats : sequence of {"parquet", "csv"}
        Trajectory file formats.
    figure_formats : sequence of str
        Figure file formats (matplotlib names).
    progress : bool
        Show the simulator's progress bar.
    """
    from delaytrack.metrics import metrics_table
    from delaytrack.report.figures import write_run_figures

    unknown = sorted(set(formats) - set(TRAJECTORY_FORMATS))
    if unknown or not formats:
        raise ValueError(
            f"formats must be a non-empty subset of {list(TRAJECTORY_FORMATS)}; got {list(formats)}"
        )
    folder = check_output_folder(folder)
    resolved, built = scenario.resolved_and_built()
    records = int(resolved.duration / resolved.T_c) // resolved.record_every + 1
    columns = 4 * built.plant.n + 2 * built.plant.m + 3 + built.controller.state_size
    needed = _WRITE_OVERHEAD * records * columns * 8
    if needed > physical_memory():
        raise ScenarioError(
            f"scenario {resolved.name!r}: writing {records} records of every tick needs about "
            f"{needed / 2**30:.3g} GiB while its tables and figures are built, more than this "
            "machine's memory; raise 'record_every' or shorten 'duration'"
        )
    text = resolved.to_toml()
    try:
        text.encode("utf-8")
    except UnicodeEncodeError as error:
        raise ScenarioError(
            f"scenario {resolved.name!r} names a file whose path is not UTF-8 text "
            f"({error.object[max(0, error.start - 40) : error.end + 10]!r}); scenario.toml, which "
            "records the scenario as run, could not hold it: rename the folder or file"
        ) from None
    result = _simulate(resolved, built.plant, built.controller, built.delay, built, progress)
    claim_output_folder(folder)  # first: a run interrupted while writing leaves a folder of ours
    files = [folder / "scenario.toml"]
    write_text(files[0], text)
    # The metrics first: they are the result a user waits for; trajectories and figures follow.
    names = built.plant.coordinate_names
    table = metrics_table(result, coordinate_names=names, label=resolved.name)
    files.append(write_frame(table, folder / "metrics.csv"))
    frame = result.to_frame()
    for fmt in formats:
        files.append(write_frame(frame, folder / f"trajectories.{fmt}"))
    files += write_run_figures(
        result, folder / "figures", formats=figure_formats, label=resolved.name
    )
    record_outputs(folder, files)
    return RunOutput(resolved, result, folder, tuple(files))
