"""Empirical delay margin: the largest delay at which the full closed loop still tracks.

:func:`empirical_margin` takes a :class:`~delaytrack.scenario.Scenario` (its true plant,
nominal model, reference, ``x0``, duration, ``dt`` and ``T_c``), replaces its delay by one member
of a one-parameter family and searches the parameter ``v`` (seconds):

- ``"constant"``: ``h(t) = v``;
- ``"abs-sine"``: ``h(t) = v |sin(frequency t)|`` (no offset; ``frequency`` 1 rad/s by default,
  the paper's S1 frequency), so ``v`` is the amplitude and the largest delay;
- ``"abs-sine-offset"``: ``h(t) = v/2 + (v/2) |sin(frequency t)|``, a delay that never drops
  below half its maximum ``v``.

A run **passes** when it ends with status ``ok`` (no divergence, see
:func:`delaytrack.sim.simulate`) and, in every coordinate ``j``, its tracking metric is at most
``threshold`` (one number for every coordinate, or ``threshold[j]`` in coordinate ``j``'s own
unit: a robot's ``x`` in m beside its heading in rad). The metric is one of the running metrics
over the window ``[settle, duration]``: ``"ae"`` (mean ``|e1|``), ``"rms"`` or ``"max"``
(``max |e1|``).

**Search.** One batched simulation over the coarse grid ``0, upper/grid, ..., upper``; the
first failing grid point ``f`` and the point before it ``p`` bracket the margin. Then rounds
of multi-section, each one batched simulation of ``points`` equally spaced values inside
``(p, f)``: the first failing one becomes ``f``, the value before it ``p``, until
``f - p <= resolution``. The margin is ``p``: the largest delay known to pass with no failure
found below it. Values above the first failure are never used: a loop that fails at ``f`` and
passes again at a larger delay (a time-varying delay can do that) has margin below ``f``.
When no grid point fails the margin is not known; the result says so (``failure_found``
False, ``margin`` is ``upper``, a lower bound). Every evaluated value with its metric and status
is kept.

Given a list of controllers, :func:`empirical_margin` runs their searches in lockstep, one
batched simulation per round for all of them; the results equal separate calls.
"""

from __future__ import annotations

import decimal
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any, overload

import numpy as np
import pandas as pd

from delaytrack._validation import (
    ArgumentError,
    finite_array,
    is_integer_at_least,
    positive_scalar,
)
from delaytrack.controllers import Controller
from delaytrack.delays import AbsSineDelay, ConstantDelay, DelayProfile
from delaytrack.plants.base import ELPlant
from delaytrack.scenario import BuiltScenario, Scenario, ScenarioError
from delaytrack.sim import STATUS_NAMES, simulate
from delaytrack.sim.certified_bound import stated_by_the_caller
from delaytrack.sim.simulate import MAX_STEPS
from delaytrack.units import coordinate_units, value_with_unit

__all__ = [
    "METRICS",
    "MIN_RESOLUTION",
    "PROFILES",
    "EmpiricalMargin",
    "MissedWithoutDelay",
    "empirical_margin",
    "resolved_text",
    "resolved_texts",
]

#: Delay families: name -> (value v, frequency) -> profile.
PROFILES: dict[str, Callable[[float, float], DelayProfile]] = {
    "constant": lambda v, _: ConstantDelay(v),
    "abs-sine": lambda v, w: AbsSineDelay(offset=0.0, amplitude=v, frequency=w),
    "abs-sine-offset": lambda v, w: AbsSineDelay(offset=v / 2, amplitude=v / 2, frequency=w),
}
#: Tracking metrics (keys of ``SimResult.metrics``), each per coordinate.
METRICS = {"ae": "mean |e1|", "rms": "RMS of e1", "max": "max |e1|"}
#: Finest search resolution (s): a nanosecond, far below any plant step a scenario uses.
MIN_RESOLUTION = 1e-9
#: Finest resolution relative to ``upper``: brackets narrower than this are near the spacing of
#: double-precision times and would stop shrinking.
_RELATIVE_RESOLUTION = 1e-12
#: Largest ``grid`` and ``points``: each is one batch of runs held in memory at once.
MAX_BATCH_POINTS = 10_000


@dataclass(frozen=True, eq=False)
class EmpiricalMargin:
    """Result of :func:`empirical_margin`.

    Attributes
    ----------
    margin : float
        Largest evaluated value (s) that passes with no failing value below it. When
        ``failure_found`` is False it is ``upper``: only a lower bound.
    failure_found : bool
        Whether some value up to ``upper`` fails.
    first_failure : float or None
        Smallest failing value found (s); ``first_failure - margin <= resolution``.
    profile, frequency : str, float
        Delay family and its angular frequency (rad/s; not used by ``"constant"``).
    metric, threshold, settle : str, float or tuple of float, float
        A run passes when it is ok and ``metric`` over ``[settle, duration]`` is
        ``<= threshold`` in every coordinate (a tuple: one bound per coordinate, each in that
        coordinate's unit).
    resolution, upper : float
        Requested width of the final bracket and the search limit (s).
    values, statuses : ndarray, shape (k,)
        Every evaluated value in increasing order and its status (0 ok, 1 diverged, 2 delay
        beyond history).
    coordinate_metrics : ndarray, shape (k, n)
        The metric of every evaluated value in each coordinate (NaN when the run is not ok).
    coordinate_names : tuple of str
        The plant's coordinate names (``q1``, ``q2``, ... when it has none).
    coordinate_units : tuple of str or None, optional
        Each coordinate's unit (None where the plant declares none, or for all when not given).
    scenario, controller : str
        Scenario name and controller type.
    simulations, rounds : int
        Runs simulated and batched simulations (coarse grid included) for this search.
    """

    margin: float
    failure_found: bool
    first_failure: float | None
    profile: str
    frequency: float
    metric: str
    threshold: float | tuple[float, ...]
    settle: float
    resolution: float
    upper: float
    values: np.ndarray
    statuses: np.ndarray
    coordinate_metrics: np.ndarray
    coordinate_names: tuple[str, ...]
    scenario: str
    controller: str
    simulations: int
    rounds: int
    coordinate_units: tuple[str | None, ...] | None = None

    @property
    def metric_values(self) -> np.ndarray:
        """The metric of every evaluated value, the largest over the coordinates (NaN when the
        run is not ok), shape (k,)."""
        return self.coordinate_metrics.max(axis=1)

    @property
    def passes(self) -> np.ndarray:
        """Whether each evaluated value passes (ok and metric within the threshold)."""
        within = self.coordinate_metrics <= np.asarray(self.threshold)
        return (self.statuses == 0) & np.all(within, axis=1)

    def describe(self) -> str:
        """One line: the margin with its threshold and resolution, or that none was found. The
        margin is shown rounded down and the first failure up to the decimals of the
        resolution: the bracket shown holds the one found, and no digit claims more than the
        search resolved."""
        rule = f"{self.metric} <= {self._threshold_text()} after t = {self.settle:g} s"
        if not self.failure_found:
            return (
                f"no failure up to upper = {self.upper:g} s ({rule}): the margin is at least "
                f"{self.upper:g} s"
            )
        assert self.first_failure is not None  # a failure was found
        margin = resolved_text(self.margin, self.resolution)
        failure = resolved_text(self.first_failure, self.resolution, up=True)
        return f"{margin} s (first failure {failure} s; {rule}; resolution {self.resolution:g} s)"

    def _threshold_text(self) -> str:
        """The threshold with the coordinates' units where the plant declares them:
        ``0.05 m``, ``0.2 in each coordinate (x in m, heading in rad)``,
        ``(x 0.05 m, heading 0.1 rad)``."""
        units = self.coordinate_units or (None,) * len(self.coordinate_names)
        known = None not in units
        if isinstance(self.threshold, tuple):
            bounds = ", ".join(
                value_with_unit(f"{name} {bound:g}", unit)
                for name, bound, unit in zip(
                    self.coordinate_names, self.threshold, units, strict=True
                )
            )
            return f"({bounds})" + ("" if known else " (each in its coordinate's unit)")
        if not known:
            return f"{self.threshold:g} (in each coordinate's unit)"
        if len(set(units)) == 1:
            return f"{self.threshold:g} {units[0]}"
        each = ", ".join(
            f"{name} in {unit}" for name, unit in zip(self.coordinate_names, units, strict=True)
        )
        return f"{self.threshold:g} in each coordinate ({each})"

    def to_frame(self) -> pd.DataFrame:
        """Every evaluated value: ``value, metric, status, passes`` and the metric of each
        coordinate, ``metric_<name>``; ``status`` by name (``ok``, ``diverged``, ...)."""
        columns = {"value": self.values, "metric": self.metric_values}
        for j, name in enumerate(self.coordinate_names):
            columns[f"metric_{name}"] = self.coordinate_metrics[:, j]
        status = [STATUS_NAMES[int(code)] for code in self.statuses]
        return pd.DataFrame({**columns, "status": status, "passes": self.passes})

    def to_dict(self) -> dict[str, Any]:
        """Plain data (JSON-ready)."""
        return {
            "margin": self.margin,
            "failure_found": self.failure_found,
            "first_failure": self.first_failure,
            "profile": self.profile,
            "frequency": self.frequency,
            "metric": self.metric,
            "threshold": list(self.threshold)
            if isinstance(self.threshold, tuple)
            else self.threshold,
            "settle": self.settle,
            "resolution": self.resolution,
            "upper": self.upper,
            "scenario": self.scenario,
            "controller": self.controller,
            "simulations": self.simulations,
            "rounds": self.rounds,
            "evaluated": [
                [float(v), None if math.isnan(m) else float(m), int(s)]
                for v, m, s in zip(self.values, self.metric_values, self.statuses, strict=True)
            ],
            "coordinate_names": list(self.coordinate_names),
            "coordinate_units": None
            if self.coordinate_units is None
            else list(self.coordinate_units),
            "coordinate_metrics": [
                [None if math.isnan(m) else float(m) for m in row]
                for row in self.coordinate_metrics
            ],
        }


def _choice(name: str, value: object, valid: Sequence[str]) -> str:
    if value not in valid:
        raise ValueError(f"{name} must be one of {list(valid)}; got {value!r}")
    return str(value)


def _count(name: str, value: object, least: int) -> int:
    if not is_integer_at_least(value, least):
        raise ValueError(f"{name} must be an integer >= {least}; got {value!r}")
    return int(value)


class _Search:
    """The bracket ``(passed, failed)`` of one controller and everything it evaluated."""

    def __init__(self) -> None:
        self.passed = 0.0
        self.failed: float | None = None
        self.rows: list[tuple[float, int, np.ndarray]] = []
        self.rounds = 0

    def take(
        self, values: list[float], metrics: np.ndarray, status: np.ndarray, ok: np.ndarray
    ) -> None:
        """Record a batch of increasing values with their metrics per coordinate ``(k, n)``;
        move the bracket to its first failure."""
        self.rows += [(v, int(s), row) for v, s, row in zip(values, status, metrics, strict=True)]
        self.rounds += 1
        for value, passes in zip(values, ok, strict=True):
            if not passes:
                self.failed = value
                return
            self.passed = value

    def next_values(self, points: int, resolution: float) -> list[float]:
        """The values of the next multi-section round; none when the bracket is narrow enough."""
        if self.failed is None or self.failed - self.passed <= resolution:
            return []
        width = self.failed - self.passed
        k = min(points, math.ceil(width / resolution) - 1)
        values = [self.passed + width * j / (k + 1) for j in range(1, k + 1)]
        # Termination: every value must lie strictly inside the bracket and be new, so that each
        # round shrinks it. Near floating-point spacing that fails, and the search ends there.
        inside = sorted({v for v in values if self.passed < v < self.failed})
        return inside if len(inside) == len(values) else []


@overload
def empirical_margin(
    scenario: Scenario,
    controller: Controller | None = None,
    *,
    threshold: float | Sequence[float] | np.ndarray,
    profile: str = "constant",
    metric: str = "ae",
    settle: float | None = None,
    resolution: float = 0.005,
    upper: float = 1.0,
    frequency: float = 1.0,
    grid: int = 16,
    points: int = 4,
    workers: int | None = None,
    progress: bool = False,
) -> EmpiricalMargin: ...


@overload
def empirical_margin(
    scenario: Scenario,
    controller: Sequence[Controller],
    *,
    threshold: float | Sequence[float] | np.ndarray,
    profile: str = "constant",
    metric: str = "ae",
    settle: float | None = None,
    resolution: float = 0.005,
    upper: float = 1.0,
    frequency: float = 1.0,
    grid: int = 16,
    points: int = 4,
    workers: int | None = None,
    progress: bool = False,
) -> list[EmpiricalMargin]: ...


def empirical_margin(
    scenario: Scenario,
    controller: Controller | Sequence[Controller] | None = None,
    *,
    threshold: float | Sequence[float] | np.ndarray,
    profile: str = "constant",
    metric: str = "ae",
    settle: float | None = None,
    resolution: float = 0.005,
    upper: float = 1.0,
    frequency: float = 1.0,
    grid: int = 16,
    points: int = 4,
    workers: int | None = None,
    progress: bool = False,
) -> EmpiricalMargin | list[EmpiricalMargin]:
    """The largest delay (or delay amplitude) at which the closed loop still meets ``threshold``.

    Parameters
    ----------
    scenario : Scenario
        Plant, nominal model, reference, ``x0``, duration, ``dt`` and ``T_c``; its ``[delay]`` is
        replaced by the searched family.
    controller : Controller or list of Controller, optional
        The scenario's controller by default. A list (of one kind) is searched in lockstep: each
        round is one batched simulation of every unfinished search, and each result equals
        the search of that controller alone.
    threshold : float or sequence of float
        Largest acceptable value of ``metric``, > 0: one number for every coordinate, or one
        per coordinate, each in that coordinate's unit (the plant's ``coordinate_units``).
    profile : {"constant", "abs-sine", "abs-sine-offset"}
        Delay family (module docstring); the searched value ``v`` is the largest delay of each.
    metric : {"ae", "rms", "max"}
        Mean ``|e1|``, RMS of ``e1`` or ``max |e1|`` over ``[settle, duration]``, in each
        coordinate.
    settle : float, optional
        Start of the metric window, seconds in ``[0, duration)``; half the duration by default.
    resolution : float
        The search stops when the bracket ``(margin, first_failure)`` is at most this wide (s);
        at least :data:`MIN_RESOLUTION` and ``1e-12 * upper``. The search always ends: each
        round shrinks the bracket ``points + 1``-fold, so it takes at most
        ``log(upper / resolution) / log(points + 1) + 1`` rounds after the grid.
    upper : float
        Search limit (s), ``> resolution`` and at most the scenario's duration (a longer delay
        means that no command ever reaches the plant).
    frequency : float
        Angular frequency of the ``abs-sine`` families, rad/s.
    grid : int
        Intervals of the coarse grid over ``[0, upper]`` (``grid + 1`` runs), from 2 to 10000.
    points : int
        Values per multi-section round, from 1 to 10000; each round narrows the bracket
        ``points + 1``-fold.
    workers : int, optional
        Threads of each batched simulation (all cores by default).
    progress : bool
        Show each batched simulation's progress bar.

    Returns
    -------
    EmpiricalMargin, or a list of them (one per controller) when ``controller`` is a list.

    Raises
    ------
    ValueError
        For an argument out of range, or a threshold the loop misses already at zero delay.
    ScenarioError
        When the scenario cannot be built or simulated.
    """
    if not isinstance(scenario, Scenario):
        raise TypeError(f"scenario must be a Scenario; got {type(scenario).__name__}")
    single = controller is None or isinstance(controller, Controller)
    controllers = _controllers(scenario, controller)
    settings = _settings(scenario, threshold, profile, metric, settle, resolution, upper)
    frequency = positive_scalar("frequency", frequency)
    grid, points = _batch_sizes(grid, points)
    built = scenario.build()
    settings["threshold"] = _per_coordinate(settings["threshold"], built.plant)
    _check_switches(scenario, settings, frequency)
    _check_reach(scenario, controllers, settings, frequency)
    lockstep = _Lockstep(
        scenario=scenario,
        built=built,
        frequency=frequency,
        settings=settings,
        workers=workers,
        progress=progress,
        single=single,
    )
    searches = lockstep.run(controllers, grid, points)
    units = coordinate_units(built.plant)
    results = [
        _result(search, scenario, item, frequency, settings, units)
        for search, item in zip(searches, controllers, strict=True)
    ]
    return results[0] if single else results


def _controllers(
    scenario: Scenario, controller: Controller | Sequence[Controller] | None
) -> list[Controller]:
    """The controllers to search: the scenario's, the one given or the list given."""
    if controller is None:
        controllers = [scenario.build().controller]
    elif isinstance(controller, Controller):
        controllers = [controller]
    elif isinstance(controller, list | tuple) and controller:
        controllers = list(controller)
    else:
        raise TypeError(
            f"controller must be a Controller, a non-empty list of them or None; got {controller!r}"
        )
    for i, item in enumerate(controllers):
        if not isinstance(item, Controller):
            raise TypeError(f"controller[{i}] must be a Controller; got {type(item).__name__}")
    return controllers


def _batch_sizes(grid: int, points: int) -> tuple[int, int]:
    """``grid`` and ``points`` checked: runs of one batched simulation each."""
    grid, points = _count("grid", grid, 2), _count("points", points, 1)
    for name, value in (("grid", grid), ("points", points)):
        if value > MAX_BATCH_POINTS:
            raise ValueError(
                f"{name} must be at most {MAX_BATCH_POINTS} (the runs of one batched "
                f"simulation); got {value}"
            )
    return grid, points


def _check_switches(scenario: Scenario, settings: dict[str, Any], frequency: float) -> None:
    """The largest searched delay switches the command at most :data:`MAX_STEPS` times."""
    delay = PROFILES[settings["profile"]](settings["upper"], frequency)
    switches = delay.switch_bound(0.0, scenario.duration, scenario.T_c)
    if not switches <= MAX_STEPS:
        raise ArgumentError(
            "frequency",
            f"must be low enough for the delay to switch the command at most "
            f"{MAX_STEPS:.0e} times in the run; at {frequency:g} rad/s with upper = "
            f"{settings['upper']:g} s it may switch {switches:.3g} times",
        )


def _check_reach(
    scenario: Scenario,
    controllers: Sequence[Controller],
    settings: dict[str, Any],
    frequency: float,
) -> None:
    """Every controller runs under the largest searched delay (a predictor's history holds
    it), or an :class:`ArgumentError` of ``upper`` says which cannot: found in the first
    batch, the refusal did not say that ``upper`` set that delay."""
    h_max = PROFILES[settings["profile"]](settings["upper"], frequency).h_max
    for controller in controllers:
        try:
            controller.check_run(scenario.T_c, h_max)
        except ValueError as error:
            raise ArgumentError(
                "upper",
                f"= {settings['upper']:g} s searches delays up to {h_max:g} s, under which "
                f"{type(controller).__name__} cannot run ({error}); give a smaller $upper",
                ("upper",),
            ) from None


@dataclass(frozen=True)
class _Lockstep:
    """The searches of several controllers in one scenario, one batched simulation per round."""

    scenario: Scenario
    built: BuiltScenario
    frequency: float
    #: The checked settings (:func:`_settings`, with the threshold per coordinate).
    settings: dict[str, Any]
    workers: int | None
    progress: bool
    #: Whether one controller is searched (its refusals name no index).
    single: bool

    @property
    def limits(self) -> np.ndarray:
        """The threshold of each coordinate, ``(n,)``."""
        threshold = np.asarray(self.settings["threshold"], dtype=float)
        return np.broadcast_to(threshold, (self.built.plant.n,))

    def run(self, controllers: list[Controller], grid: int, points: int) -> list[_Search]:
        """Every controller's search: the coarse grid of ``grid`` intervals, then rounds of
        ``points`` values, until each bracket is narrow enough."""
        searches = [_Search() for _ in controllers]
        coarse = [self.settings["upper"] * k / grid for k in range(grid + 1)]
        jobs = {i: coarse for i in range(len(controllers))}
        while jobs:
            flat = [(i, v) for i, values in jobs.items() for v in values]
            status, passes, metrics = self.evaluate(
                [v for _, v in flat], [controllers[i] for i, _ in flat]
            )
            start = 0
            for i, values in jobs.items():
                part = slice(start, start + len(values))
                start += len(values)
                if values is coarse and not passes[part][0]:
                    raise self.missed_without_delay(i, metrics[part][0], status[part][0])
                searches[i].take(values, metrics[part], status[part], passes[part])
            jobs = {}
            for i, search in enumerate(searches):
                values = search.next_values(points, self.settings["resolution"])
                if values:
                    jobs[i] = values
        return searches

    def evaluate(
        self, values: list[float], controllers: list[Controller]
    ) -> tuple[np.ndarray, ...]:
        """``(status, passes, metrics)`` of one batched simulation, a run per value with its
        controller; the metrics per coordinate ``(k, n)``, NaN where the run is not ok."""
        make, scenario = PROFILES[self.settings["profile"]], self.scenario
        try:
            with stated_by_the_caller():  # it measures how far beyond h_m the loop holds
                result = simulate(
                    self.built.plant,
                    controllers,
                    [make(v, self.frequency) for v in values],
                    self.built.x0,
                    reference=self.built.reference,
                    trajectories=False,
                    metrics_from=self.settings["settle"],
                    workers=self.workers,
                    progress=self.progress,
                    **scenario.simulation_settings(),
                )
        except ValueError as error:
            raise ScenarioError(f"scenario {scenario.name!r}: {error}") from None
        ok = result.status == 0
        metrics = np.full((len(values), self.built.plant.n), np.nan)  # ok runs only
        metrics[ok] = result.metrics[self.settings["metric"]][ok]
        return result.status, ok & np.all(metrics <= self.limits, axis=1), metrics

    def missed_without_delay(self, i: int, metrics: np.ndarray, status: int) -> ArgumentError:
        """The refusal of a threshold that controller ``i`` misses at ``h = 0``."""
        where = "" if self.single else f" (controller[{i}])"
        found = _missed(self.settings["metric"], metrics, status, self.limits, self.built.plant)
        advice = (
            "give a larger threshold or a later settle time"
            if status == 0
            else "a larger threshold would not help a run that does not finish: check the "
            "scenario (its gains, error_bound, plant and reference; delaytrack simulate shows "
            "the run)"
        )
        return MissedWithoutDelay(
            "threshold",
            f"= {_shown(self.settings['threshold'])} is missed already without delay: "
            f"{found} at h = 0{where}; {advice}",
            index=i,
            found=found,
            finished=status == 0,
        )


class MissedWithoutDelay(ArgumentError):
    """The refusal of a threshold that a controller misses already at ``h = 0``: ``index`` is
    the controller's place in the list searched, ``found`` what its run gave (``ae of q1 =
    0.2956 rad``, or how it stopped), ``finished`` whether that run ended ok (else no threshold
    would help), for a caller that words it in its own terms."""

    def __init__(
        self, argument: str, problem: str, *, index: int, found: str, finished: bool
    ) -> None:
        super().__init__(argument, problem)
        self.index = index
        self.found = found
        self.finished = finished

    def __reduce__(self) -> tuple[Any, ...]:
        # Rebuilt with its parts (an error raised in a worker process crosses back pickled).
        parts = (self.argument, self.problem, self.index, self.found, self.finished)
        return _missed_again, parts


def _missed_again(
    argument: str, problem: str, index: int, found: str, finished: bool
) -> MissedWithoutDelay:
    """A :class:`MissedWithoutDelay` made again from its parts (unpickling)."""
    return MissedWithoutDelay(argument, problem, index=index, found=found, finished=finished)


def resolved_text(value: float, resolution: float, *, up: bool = False) -> str:
    """A delay a search found, to the decimals of its ``resolution`` (s) and no finer: rounded
    down (a margin: never above the value that passed), or up with ``up`` (a first failure),
    so that a bracket shown holds the bracket found: ``resolved_text(0.63333, 0.005)`` is
    ``"0.633"``."""
    decimals = max(0, math.ceil(-math.log10(resolution)))
    return _rounded(value, decimals, decimal.ROUND_CEILING if up else decimal.ROUND_FLOOR)


def resolved_texts(values: Iterable[float], resolution: float) -> list[str | None]:
    """:func:`resolved_text` of each of ``values`` (margins: rounded down), None where there is
    none (NaN: no failure found, or not searched), for a column of a table a user reads."""
    return [None if math.isnan(value) else resolved_text(value, resolution) for value in values]


def _rounded(value: float, decimals: int, rounding: str) -> str:
    """``value`` to ``decimals`` decimals, rounded as ``rounding`` says (``decimal.ROUND_FLOOR``,
    ``decimal.ROUND_CEILING``), from its decimal form to three more decimals: a grid value
    that carries binary noise (0.6000000000000001, 0.7 stored as 0.6999...) is rounded as the
    value it stands for, 0.600 and 0.700, not 0.601 or 0.699, whatever its size."""
    exact = decimal.Context(prec=decimal.MAX_PREC)  # a large value keeps all its digits
    step = decimal.Decimal(1).scaleb(-decimals)
    near = decimal.Decimal(f"{value:.{decimals + 3}f}")
    return format(near.quantize(step, rounding, exact), "f")


def _shown(threshold: float | tuple[float, ...]) -> str:
    """``0.2`` or ``[0.01, 0.01, 0.05]``."""
    if isinstance(threshold, tuple):
        return "[" + ", ".join(f"{bound:g}" for bound in threshold) + "]"
    return f"{threshold:g}"


def _per_coordinate(
    threshold: float | Sequence[float] | np.ndarray, plant: ELPlant
) -> float | tuple[float, ...]:
    """The threshold as given: one number, or a tuple of one per coordinate of ``plant``."""
    if np.ndim(threshold) == 0:
        return positive_scalar("threshold", threshold)
    bounds = finite_array("threshold", threshold, ndim=1)
    if bounds.size != plant.n or not np.all(bounds > 0.0):
        coordinates = ", ".join(
            name + (f" [{unit}]" if unit else "") for name, unit in coordinate_units(plant).items()
        )
        raise ArgumentError(
            "threshold",
            f"must be a number > 0, or a list of one number > 0 per coordinate "
            f"({plant.n}: {coordinates}); got {_shown(tuple(float(b) for b in bounds))}",
        )
    return tuple(float(bound) for bound in bounds)


def _missed(
    metric: str, values: np.ndarray, status: int, limits: np.ndarray, plant: ELPlant
) -> str:
    """What failed a run: its status, or the coordinate whose ``metric`` exceeds its bound in
    ``limits`` the most, relative to it, with its unit (``ae of x = 0.31 m``); ``values`` holds
    the run's metric per coordinate."""
    if status != 0:
        return f"status {STATUS_NAMES[int(status)]!r}"
    j = int(np.argmax(values / limits))
    name, unit = list(coordinate_units(plant).items())[j]
    return value_with_unit(f"{metric} of {name} = {values[j]:.4g}", unit)


def _settings(
    scenario: Scenario,
    threshold: float | Sequence[float] | np.ndarray,
    profile: str,
    metric: str,
    settle: float | None,
    resolution: float,
    upper: float,
) -> dict[str, Any]:
    """Check the search's settings; return them as the result states them."""
    resolution = positive_scalar("resolution", resolution)
    upper = positive_scalar("upper", upper)
    if upper > scenario.duration:
        raise ArgumentError(
            "upper",
            f"must be at most the scenario's duration {scenario.duration:g} s (a longer "
            f"delay means that no command ever reaches the plant); got {upper:g}",
        )
    finest = max(MIN_RESOLUTION, _RELATIVE_RESOLUTION * upper)
    if resolution < finest:
        raise ArgumentError(
            "resolution",
            f"must be at least {finest:g} s (the larger of {MIN_RESOLUTION:g} s and "
            f"{_RELATIVE_RESOLUTION:g} x upper: finer brackets are below what the simulation "
            f"resolves in double precision); got {resolution:g}",
        )
    if resolution >= upper:
        raise ArgumentError(
            "resolution",
            f"must be smaller than $upper; got resolution = {resolution:g} s, upper = {upper:g} s",
            mentions=("upper",),
        )
    settle = scenario.duration / 2 if settle is None else settle
    settle = positive_scalar("settle", settle, strictly=False)
    if settle >= scenario.duration:
        raise ArgumentError(
            "settle",
            f"must be below the scenario's duration {scenario.duration:g} s (the metric "
            f"window is [settle, duration]); got {settle:g}",
        )
    return {
        "profile": _choice("profile", profile, tuple(PROFILES)),
        "metric": _choice("metric", metric, tuple(METRICS)),
        "threshold": threshold,  # checked against the plant's coordinates once it is built
        "settle": settle,
        "resolution": resolution,
        "upper": upper,
    }


def _result(
    search: _Search,
    scenario: Scenario,
    controller: Controller,
    frequency: float,
    settings: dict[str, Any],
    units: dict[str, str | None],
) -> EmpiricalMargin:
    rows = sorted(search.rows, key=lambda row: row[0])
    found = search.failed is not None
    return EmpiricalMargin(
        margin=search.passed,
        failure_found=found,
        first_failure=search.failed,
        frequency=frequency,
        values=np.array([row[0] for row in rows]),
        statuses=np.array([row[1] for row in rows], dtype=int),
        coordinate_metrics=np.array([row[2] for row in rows]),
        coordinate_names=tuple(units),
        coordinate_units=tuple(units.values()),
        scenario=scenario.name,
        controller=controller.type_name,
        simulations=len(rows),
        rounds=search.rounds,
        **settings,
    )
