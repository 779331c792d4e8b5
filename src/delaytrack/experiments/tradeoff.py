"""The accuracy–delay-margin trade-off of a scenario: how much delay margin each controller
gives up for accuracy as the outer-loop gains rise.

**The gain family.** The outer-loop gains are swept along one documented parameter, the natural
frequency ``ω_n`` (rad/s) of the delay-free error dynamics of the paper,

    ë1 = −K2 ė1 − K1 e1,      K1 = ω_n² I,   K2 = 2 ζ ω_n I,

at a fixed damping ratio ``ζ`` (1 by default: critically damped). By default ``ω_n`` takes
:data:`DEFAULT_POINTS` log-spaced values from a quarter of the scenario's own natural frequency
to four times it (``sqrt(λ_min(K1))`` and ``sqrt(λ_max(K1))`` of its controller, or
``2 ζ κ`` for a predictor), so the scenario's own gains lie inside the range.

**The controller families** at every point:

- ``arolc``: AROLC with these ``K1``, ``K2`` and the scenario controller's other parameters
  (``Q``, ``α``, ``ε``, ``γ``; the paper's ``Q = I``, ``α = 2``, ``ε = 0.1``, ``γ = 0.001`` when
  the scenario's controller is not AROLC);
- ``outer-loop``: the plain outer loop, AROLC without its switching term ``Δu``;
- ``pcon``, ``pconf``: the predictors, when the scenario's nominal model supports them, with
  ``κ = ω_n / (2ζ)`` and ``k_b = 2ζω_n M̂(q0)`` (``M̂(q0)`` the nominal mass matrix at the
  initial pose), so that the delay-free nominal loop ``M̂ ë1 = −k_b (ė1 + κ e1)`` is the same
  ``ë1 = −2ζω_n ė1 − ω_n² e1``; ``ϑ`` is the scenario predictor's, else ``M̂(q0)⁻¹``. PCON is
  told the true delay (its assumption), PCONf the constant ``h̄`` = the scenario delay's bound.

**What is computed per point and family** (:class:`TradeoffStudy`):

- ``h_m`` (AROLC rows): Theorem 1's certified bound, ``razumikhin_bound(K1, K2, Q, β, r)``;
- ``h_exact`` (AROLC and outer-loop rows): the exact constant-delay margin of the linear outer
  loop, ``exact_delay_margin(K1, K2)``;
- the empirical margin of the nonlinear closed loop under a constant delay
  (:func:`~delaytrack.experiments.empirical_margin.empirical_margin`, bounded search up to
  ``upper``; not for PCONf, whose window is fixed at ``h̄``: told a constant delay exactly,
  PCONf is PCON's law);
- over drawn robots at the scenario's own delay (the sweep machinery: Parquet parts, resumable,
  any executor): the share that stays on the path with its Wilson 95 % interval, and the
  median AE and TV over those that stay on it.

**Staying on the path** (one rule for the margin and the draws): the run ends ok (no
divergence, no ``error_bound`` exceeded) and each scored coordinate's mean ``|e1|`` over the
whole run is at most ``threshold`` (in that coordinate's unit; 1 by default). The scored
coordinates are those the scenario's ``error_bound`` bounds (``x``, ``y`` for the robot), every
coordinate when it has none. **AE** is the mean over the scored coordinates of their mean
``|e1|`` (the paper's AE for the robot: the mean of AE-x and AE-y).

**Draws.** ``random`` is a sweep file's ``[random]`` table (docs/sweeps.md). By default the
scenario's uncertain parameters are drawn where the toolkit knows them
(:func:`uncertain_parameters`: the payload robot's payload placement and wheel friction, as in
the robustness study); a scenario with nothing to draw has one run per point, and the study says
so.

**Pareto front** (accuracy against delay margin): among the rows with an empirical margin and
at least one run on the path, those no other row beats in both median AE (lower) and empirical
margin (higher). A margin at the search limit is only a lower bound, so no row is known to beat
it: such a row is on the front.

:func:`run_tradeoff` returns a :class:`TradeoffStudy` holding every number of its report, which
:func:`~delaytrack.report.tradeoff.write_tradeoff` writes.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np
import pandas as pd

from delaytrack._output import claim_output_folder
from delaytrack._result_columns import shared_unit
from delaytrack._validation import ArgumentError, is_integer_at_least, positive_scalar
from delaytrack._words import counted
from delaytrack.analysis import exact_delay_margin, razumikhin_bound
from delaytrack.analysis.razumikhin import PAPER_BETA as BETA
from delaytrack.analysis.razumikhin import PAPER_R as R
from delaytrack.controllers import AROLC

# The robustness study's seed and robots: the same robots where the keys are the same.
from delaytrack.experiments.drawn_robots import PAYLOAD_ROBOT, PAYLOAD_ROBOT_TYPE, SEED
from delaytrack.experiments.empirical_margin import EmpiricalMargin, empirical_margin
from delaytrack.experiments.intervals import wilson_interval
from delaytrack.experiments.pairing import AROLC_GAINS
from delaytrack.plants.base import ELPlant
from delaytrack.scenario import Scenario, ScenarioError
from delaytrack.sweeps import SweepOutcome, SweepSpec, run_sweep
from delaytrack.sweeps.executors import Executor
from delaytrack.sweeps.spec import MAX_RUNS
from delaytrack.units import default_names, with_unit

__all__ = [
    "DEFAULT_POINTS",
    "FAMILIES",
    "LOWER_BOUND",
    "MARGIN_SEARCHES",
    "TradeoffStudy",
    "default_omegas",
    "drawn_runs",
    "family_gains",
    "family_tables",
    "on_path_summary",
    "pareto_front",
    "run_tradeoff",
    "uncertain_parameters",
]

#: Controller families, in the order of the table.
FAMILIES: tuple[str, ...] = ("arolc", "outer-loop", "pcon", "pconf")
#: Points of the default ``ω_n`` range.
DEFAULT_POINTS = 7
#: Most ``ω_n`` points of one trade-off: each costs a margin search per controller family.
MAX_OMEGAS = 1000
#: Largest outer-loop gain of a point, and its inverse the smallest (AROLC refuses products of
#: its gains beyond 1e100).
_LARGEST_GAIN = 1e100
#: The default range spans this factor below and above the scenario's natural frequency.
DEFAULT_SPAN = 4.0
#: Runs per work unit of the draws' sweep.
UNIT_SIZE = 64
_DRAWN_BY_PLANT = {PAYLOAD_ROBOT_TYPE: PAYLOAD_ROBOT}
#: The largest double: the bound of a coordinate the rule does not score.
_UNSCORED = float(np.finfo(float).max)


def uncertain_parameters(scenario: Scenario) -> dict[str, dict[str, Any]]:
    """The ``[random]`` table of the scenario's uncertain parameters that the toolkit knows:
    for the payload robot (``wheeled-robot-payload``) the payload placement (``plant.seed``)
    and the wheel friction (viscous 0.001–0.02 N·m·s/rad, Coulomb 0.07–0.35 N·m); empty for
    any other plant (nothing to draw)."""
    return {
        key: dict(table) for key, table in _DRAWN_BY_PLANT.get(scenario.plant["type"], {}).items()
    }


def family_gains(omega: float, zeta: float) -> tuple[float, float]:
    """``(k1, k2) = (ω_n², 2 ζ ω_n)``: the outer-loop gains ``K1 = k1 I``, ``K2 = k2 I`` of
    ``ë1 = −K2 ė1 − K1 e1`` with natural frequency ``ω_n`` and damping ratio ``ζ``."""
    return omega * omega, 2.0 * zeta * omega


def default_omegas(scenario: Scenario, zeta: float, points: int = DEFAULT_POINTS) -> np.ndarray:
    """``points`` log-spaced natural frequencies from the scenario's own ``ω_n`` divided by
    :data:`DEFAULT_SPAN` to it times :data:`DEFAULT_SPAN`.

    The scenario's ``ω_n`` is ``sqrt(λ(K1))`` of its controller (the smallest and largest
    eigenvalue set the ends), ``2 ζ κ`` for a predictor (the family's ``κ = ω_n / (2ζ)``
    solved for ``ω_n``), and 1 rad/s for any other controller.
    """
    controller = scenario.build().controller
    if hasattr(controller, "K1"):
        eigenvalues = np.linalg.eigvalsh(controller.K1)
        low, high = math.sqrt(eigenvalues[0]), math.sqrt(eigenvalues[-1])
    elif hasattr(controller, "kappa"):
        low = high = 2.0 * zeta * float(controller.kappa)
    else:
        low = high = 1.0
    return np.geomspace(low / DEFAULT_SPAN, high * DEFAULT_SPAN, points)


@dataclass(frozen=True)
class TradeoffStudy:
    """What :func:`run_tradeoff` computed: every number of its report.

    Attributes
    ----------
    table : DataFrame
        One row per point and family: ``omega_n`` (rad/s), ``k1``, ``k2``, ``controller``,
        ``h_m``, ``h_exact``, ``empirical_margin`` (s; NaN where not defined),
        ``margin_found`` (False: no failure up to ``upper``, the margin is a lower bound),
        ``margin_search`` (what the search gave, a key of :data:`MARGIN_SEARCHES`),
        ``runs``, ``on_path``, ``stopped``, ``over_threshold`` (:func:`on_path_summary`),
        ``share_on_path`` with ``share_low``, ``share_high`` (Wilson 95 %), ``ae_median``,
        ``tv_median`` (over the runs on the path; NaN when none) and
        ``pareto`` (on the Pareto front).
    runs : DataFrame
        Every drawn run: ``omega_n``, ``controller``, ``draw``, the drawn values, ``status``,
        ``ae`` (the AE of the module docstring), ``tv`` and ``on_path``.
    evaluated : DataFrame
        Every simulated point of every margin search (``omega_n``, ``controller``, the delay
        ``value``, the metric per coordinate with its unit, ``metric_<name>_<unit>``, the
        largest over the scored coordinates when they share a unit (or none has one),
        ``metric_<unit>``, ``status``, ``passes``).
    scenario : Scenario
    zeta : float
    omegas : tuple of float
    families : tuple of str
        The families run; ``left_out`` says why any other was not.
    left_out : Mapping[str, str]
        Family -> why it was not run.
    threshold : Mapping[str, float]
        The scored coordinates (those that make AE and the rule) and the bound of each one's
        mean ``|e1|`` (its unit).
    ae_unit, tv_unit : str or None
        The unit of AE (the scored coordinates' common unit) and of TV (the inputs').
    random : Mapping[str, Mapping]
        What was drawn (empty: nothing; one run per point).
    draws, seed : int
    upper, resolution : float
        The margin search's limit and final bracket (s).
    beta, r : float
        Theorem 1's weights.
    seconds : float
    computed, resumed : int
        Work units of the draws computed and found finished.
    """

    table: pd.DataFrame
    runs: pd.DataFrame
    evaluated: pd.DataFrame
    scenario: Scenario
    zeta: float
    omegas: tuple[float, ...]
    families: tuple[str, ...]
    left_out: Mapping[str, str]
    threshold: Mapping[str, float]
    ae_unit: str | None
    tv_unit: str | None
    random: Mapping[str, Mapping[str, Any]]
    draws: int
    seed: int
    upper: float
    resolution: float
    beta: float
    r: float
    seconds: float
    computed: int = 0
    resumed: int = 0

    @property
    def front(self) -> pd.DataFrame:
        """The Pareto front's rows, by increasing empirical margin, then (rows whose margins
        tie, such as the lower bounds at the search limit) increasing median AE."""
        return self.table[self.table.pareto].sort_values(
            ["empirical_margin", "ae_median"], kind="stable"
        )


def pareto_front(
    ae: Sequence[float], margin: Sequence[float], exact: Sequence[bool] | None = None
) -> np.ndarray:
    """Which points are non-dominated when AE is minimised and the margin maximised.

    Point ``i`` is dominated when some ``j`` has ``ae_j <= ae_i`` and ``margin_j >= margin_i``
    with one of them strict. Points with a NaN are never on the front. ``exact[i]`` False marks
    a margin that is only a lower bound (no failure up to the search limit): its true margin
    may exceed any other's, so such a point is never dominated (all True by default).
    """
    errors, margins = np.asarray(ae, dtype=float), np.asarray(margin, dtype=float)
    known = np.ones(len(errors), dtype=bool) if exact is None else np.asarray(exact, dtype=bool)
    valid = np.isfinite(errors) & np.isfinite(margins)
    front = np.zeros(len(errors), dtype=bool)
    for i in np.flatnonzero(valid):
        no_worse = valid & (errors <= errors[i]) & (margins >= margins[i])
        better = (errors < errors[i]) | (margins > margins[i])
        front[i] = not (known[i] and np.any(no_worse & better))
    return front


def _scored(scenario: Scenario, names: tuple[str, ...]) -> tuple[bool, ...]:
    """The coordinates the scenario's ``error_bound`` bounds; all of them when it has none."""
    bound = np.broadcast_to(np.asarray(scenario.simulated_error_bound, dtype=float), (len(names),))
    finite = np.isfinite(bound)
    return tuple(bool(b) for b in (finite if finite.any() else np.ones(len(names), dtype=bool)))


def family_tables(
    scenario: Scenario, zeta: float, omegas: Sequence[float], history: float
) -> tuple[dict[str, list[dict[str, Any]]], dict[str, str]]:
    """The controller table of each family at each ``ω_n`` (module docstring; the predictors
    with ``history`` s of commands, PCONf told ``h̄`` = the scenario delay's bound), and why a
    family was left out."""
    built = scenario.build()
    own = dict(scenario.controller)
    arolc_base = own if own["type"] == "arolc" else {"type": "arolc", **AROLC_GAINS}
    tables: dict[str, list[dict[str, Any]]] = {"arolc": [], "outer-loop": []}
    for omega in omegas:
        k1, k2 = family_gains(omega, zeta)
        tables["arolc"].append({**arolc_base, "K1": k1, "K2": k2})
        tables["outer-loop"].append({"type": "outer-loop", "K1": k1, "K2": k2})
    left_out: dict[str, str] = {}
    model, n = built.model, built.model.n
    mass = model.mass_matrix(built.x0[:n])[0]
    is_predictor = own["type"] in ("pcon", "pconf")
    vartheta = own["vartheta"] if is_predictor else np.linalg.inv(0.5 * (mass + mass.T)).tolist()
    space = own.get("space", "generalised") if is_predictor else "generalised"
    h_bar = float(built.delay.h_max)
    for family in ("pcon", "pconf"):
        rows = []
        for omega in omegas:
            extra = {"h_bar": h_bar} if family == "pconf" else {}
            rows.append(
                {
                    "type": family,
                    "kappa": omega / (2.0 * zeta),
                    "k_b": (2.0 * zeta * omega * mass).tolist(),
                    "vartheta": vartheta,
                    "history": history,
                    "T_c": scenario.T_c,
                    "space": space,
                    **extra,
                }
            )
        try:
            scenario.replace(controller=rows[0]).build()
        except (ScenarioError, ValueError, TypeError) as error:
            left_out[family] = f"the scenario's nominal model does not support it: {error}"
            continue
        tables[family] = rows
    return tables, left_out


def _analytic(
    scenario: Scenario, tables: Mapping[str, list[dict[str, Any]]], beta: float, r: float
) -> tuple[list[float], list[float]]:
    """``h_m`` of AROLC and ``h_exact`` of the outer loop at each point (NaN where Theorem 1's
    bound cannot be computed in double precision)."""
    certified, exact = [], []
    for table in tables["arolc"]:
        arolc = scenario.replace(controller=table).build().controller
        assert isinstance(arolc, AROLC)  # the family's AROLC tables
        try:
            h_m = razumikhin_bound(arolc.K1, arolc.K2, arolc.Q, beta, r, n=arolc.n).h_m
        except ValueError:
            h_m = math.nan
        certified.append(float(h_m))
        exact.append(float(exact_delay_margin(arolc.K1, arolc.K2).h))
    return certified, exact


def _margins(
    scenario: Scenario, tables: list[dict[str, Any]], search: Mapping[str, Any]
) -> list[EmpiricalMargin | None]:
    """One family's empirical margins, searched in lockstep; when a point misses the rule
    already without delay, each point alone (None for those that miss it)."""
    controllers = [scenario.replace(controller=table).build().controller for table in tables]
    try:
        return list(empirical_margin(scenario, controllers, **search))
    except ArgumentError as error:
        if error.argument != "threshold":
            raise
    found: list[EmpiricalMargin | None] = []
    for controller in controllers:
        try:
            found.append(empirical_margin(scenario, controller, **search))
        except ArgumentError as error:
            if error.argument != "threshold":
                raise
            found.append(None)
    return found


def _checked(
    zeta: float, omegas: Sequence[float] | None, draws: int | None, scenario: Scenario
) -> tuple[float, tuple[float, ...]]:
    zeta = positive_scalar("zeta", zeta)
    chosen = default_omegas(scenario, zeta) if omegas is None else omegas
    array = np.asarray(chosen, dtype=float).ravel()
    if array.size > MAX_OMEGAS:
        raise ArgumentError(
            "omegas",
            f"must be at most {MAX_OMEGAS} natural frequencies (each costs a delay-margin search "
            f"per controller); got {array.size}",
        )
    values = tuple(float(v) for v in array)
    if not values or not all(math.isfinite(v) and v > 0 for v in values):
        raise ArgumentError("omegas", f"must be natural frequencies > 0 (rad/s); got {values}")
    repeated = sorted({v for v in values if values.count(v) > 1})
    if repeated:
        raise ArgumentError(
            "omegas",
            "must be distinct natural frequencies (a point's runs would be counted once for "
            f"each copy); got {', '.join(f'{v:g}' for v in repeated)} more than once",
        )
    for omega in values:  # K1 = ω² and K2 = 2ζω must be numbers a gain can be
        k1, k2 = family_gains(omega, zeta)
        if not all(1.0 / _LARGEST_GAIN < gain < _LARGEST_GAIN for gain in (k1, k2)):
            raise ArgumentError(
                "omegas",
                f"must give the gains K1 = omega_n² and K2 = 2 zeta omega_n between "
                f"{1.0 / _LARGEST_GAIN:g} and {_LARGEST_GAIN:g}; omega_n = {omega:g} rad/s "
                f"with $zeta = {zeta:g} gives K1 = {k1:g}, K2 = {k2:g}",
                mentions=("zeta",),
            )
    if draws is not None and not is_integer_at_least(draws, 1):
        raise ArgumentError("draws", f"must be an integer >= 1; got {draws!r}")
    return zeta, values


def run_tradeoff(
    scenario: Scenario,
    out: str | Path,
    *,
    zeta: float = 1.0,
    omegas: Sequence[float] | None = None,
    draws: int | None = None,
    random: Mapping[str, Mapping[str, Any]] | None = None,
    threshold: float | Sequence[float] = 1.0,
    upper: float | None = None,
    resolution: float = 0.005,
    beta: float = BETA,
    r: float = R,
    seed: int = SEED,
    executor: Executor | None = None,
    progress: bool = False,
) -> TradeoffStudy:
    """Sweep the outer-loop gains of ``scenario`` along ``K1 = ω_n² I``, ``K2 = 2ζω_n I`` and
    compute, per point and controller family, the margins, the share of drawn robots on the
    path, AE, TV and the Pareto front (module docstring).

    Parameters
    ----------
    scenario : Scenario
        Plant, nominal model, reference, delay (the draws run at it), times.
    out : path
        Folder of the draws' sweep (``out/sweep``: parts, resumable).
    zeta : float
        Damping ratio ``ζ > 0`` of the family.
    omegas : sequence of float, optional
        Natural frequencies ``ω_n`` (rad/s); :func:`default_omegas` by default.
    draws : int, optional
        Robots drawn per point and family (40 by default when something is drawn; ignored
        when nothing is).
    random : mapping, optional
        A sweep file's ``[random]`` table; :func:`uncertain_parameters` by default, ``{}`` for
        none.
    threshold : float or sequence of float
        Largest mean ``|e1|`` of a scored coordinate that still counts as on the path (its
        unit): one number, or one per scored coordinate, in their order (the coordinates the
        scenario's ``error_bound`` bounds; every coordinate when it has none).
    upper, resolution : float
        The margin search's limit (default the smaller of 1 s and half the duration) and final
        bracket (s).
    beta, r : float
        Theorem 1's weights for ``h_m``.
    seed : int
        Seed of the draws.
    executor : Executor, optional
        Where the draws' units run (all local cores by default).
    progress : bool
        Progress on standard error.
    """
    start = time.perf_counter()
    zeta, omegas = _checked(zeta, omegas, draws, scenario)
    beta = positive_scalar("beta", beta)
    if not (isinstance(r, (int, float)) and math.isfinite(r) and r > 1):
        raise ArgumentError("r", f"must be a number > 1 (Theorem 1's Razumikhin factor); got {r!r}")
    built = scenario.build()
    plant = built.plant
    names = default_names(plant.coordinate_names, plant.n)
    scored = _scored(scenario, names)
    rule = _rule(threshold, plant, names, scored)
    upper = min(1.0, scenario.duration / 2) if upper is None else positive_scalar("upper", upper)
    if not upper > resolution:
        raise ArgumentError(
            "upper",
            f"must be larger than the margin searches' resolution, {resolution:g} s; got {upper:g}",
        )
    history = max(upper, float(built.delay.h_max))
    tables, left_out = family_tables(scenario, zeta, omegas, history)
    families = tuple(f for f in FAMILIES if f in tables)
    drawn = _drawn(scenario, random)
    count = (40 if draws is None else int(draws)) if drawn else 1
    grid, labels = _grid_points(tables, omegas, families)
    if count * len(labels) > MAX_RUNS:  # before the margin searches, not after them
        raise ArgumentError(
            "draws",
            f"= {count} makes {count * len(labels)} runs ({len(omegas)} gain points x "
            f"{len(families)} controllers x {count} draws), more than a sweep holds "
            f"({MAX_RUNS}); give at most {MAX_RUNS // len(labels)} draws, or fewer gain points",
        )
    certified, exact = _analytic(scenario, tables, beta, r)
    margins = _family_margins(scenario, tables, families, rule, upper, resolution, progress)
    scored_bounds = {name: bound for name, bound, s in zip(names, rule, scored, strict=True) if s}
    runs, outcome = drawn_runs(
        scenario,
        grid,
        labels,
        drawn,
        count,
        int(seed),
        scored_bounds,
        out,
        "sweep",
        executor=executor,
        progress=progress,
    )
    units = tuple(plant.coordinate_units or [None] * plant.n)
    return TradeoffStudy(
        table=_table(omegas, zeta, families, runs, margins, certified, exact),
        runs=runs,
        evaluated=_evaluated(margins, omegas, names, units, scored),
        scenario=scenario,
        zeta=zeta,
        omegas=omegas,
        families=families,
        left_out=MappingProxyType(left_out),
        threshold=MappingProxyType(scored_bounds),
        ae_unit=shared_unit([u for u, s in zip(units, scored, strict=True) if s]),
        tv_unit=shared_unit(plant.input_units or [None]),
        random=MappingProxyType(drawn),
        draws=count,
        seed=int(seed),
        upper=upper,
        resolution=resolution,
        beta=beta,
        r=r,
        seconds=time.perf_counter() - start,
        computed=outcome.computed,
        resumed=outcome.resumed,
    )


def _rule(
    threshold: float | Sequence[float],
    plant: ELPlant,
    names: tuple[str, ...],
    scored: tuple[bool, ...],
) -> tuple[float, ...]:
    """The bound of each coordinate's mean ``|e1|``: ``threshold`` (checked: one number, or one
    per scored coordinate, in their order) where the coordinate is scored, :data:`_UNSCORED`
    elsewhere."""
    given = np.asarray(threshold, dtype=float)
    scored_names = [name for name, s in zip(names, scored, strict=True) if s]
    valid = (
        f"a number > 0 or one per scored coordinate ({len(scored_names)}: "
        f"{', '.join(scored_names)})"
    )
    if len(scored_names) < plant.n:
        valid += (
            "; the other coordinates are not scored (the scenario's error_bound bounds only these)"
        )
    if given.ndim > 1 or (given.ndim == 1 and given.size not in (1, len(scored_names))):
        raise ArgumentError("threshold", f"must be {valid}; got {threshold!r}")
    if not np.all(np.isfinite(given) & (given > 0)):
        raise ArgumentError("threshold", f"must be {valid}; got {threshold!r}")
    bounds = iter(np.broadcast_to(given.ravel(), (len(scored_names),)))
    return tuple(float(next(bounds)) if s else _UNSCORED for s in scored)


def _family_margins(
    scenario: Scenario,
    tables: Mapping[str, list[dict[str, Any]]],
    families: tuple[str, ...],
    rule: tuple[float, ...],
    upper: float,
    resolution: float,
    progress: bool,
) -> dict[str, list[EmpiricalMargin | None]]:
    """The empirical margins of every family but PCONf (module docstring), at every point."""
    search = {
        "threshold": rule,
        "settle": 0.0,
        "upper": upper,
        "resolution": resolution,
        "progress": progress,
    }
    margins = {}
    for family in (f for f in families if f != "pconf"):  # no margin from zero (docstring)
        _say(progress, f"{family}: empirical margins of {len(tables[family])} gain points")
        margins[family] = _margins(scenario, tables[family], search)
    return margins


def _drawn(
    scenario: Scenario, random: Mapping[str, Mapping[str, Any]] | None
) -> dict[str, dict[str, Any]]:
    """The ``[random]`` table of the draws: ``random``, else the scenario's uncertain
    parameters."""
    return (
        uncertain_parameters(scenario)
        if random is None
        else {k: dict(v) for k, v in random.items()}
    )


def _grid_points(
    tables: Mapping[str, list[dict[str, Any]]],
    omegas: tuple[float, ...],
    families: tuple[str, ...],
) -> tuple[dict[str, tuple[dict[str, Any], ...]], list[dict[str, Any]]]:
    """The draws' sweep grid, a controller table per point and family, and the labels of its
    points (``omega_n``, ``controller``)."""
    points = [(omega, family) for omega in omegas for family in families]
    grid = {"controller": tuple(tables[f][omegas.index(o)] for o, f in points)}
    return grid, [{"omega_n": omega, "controller": family} for omega, family in points]


def _table(
    omegas: tuple[float, ...],
    zeta: float,
    families: tuple[str, ...],
    runs: pd.DataFrame,
    margins: Mapping[str, list[EmpiricalMargin | None]],
    certified: list[float],
    exact: list[float],
) -> pd.DataFrame:
    """:attr:`TradeoffStudy.table`: one row per point and family, with the Pareto front."""
    rows = []
    for i, omega in enumerate(omegas):
        k1, k2 = family_gains(omega, zeta)
        for family in families:
            mine = runs[(runs.omega_n == omega) & (runs.controller == family)]
            found = margins[family][i] if family in margins else None
            rows.append(
                {
                    "omega_n": omega,
                    "k1": k1,
                    "k2": k2,
                    "controller": family,
                    "h_m": certified[i] if family == "arolc" else math.nan,
                    "h_exact": exact[i] if family in ("arolc", "outer-loop") else math.nan,
                    "empirical_margin": math.nan if found is None else found.margin,
                    "margin_found": found is not None and found.failure_found,
                    "margin_search": _search_outcome(family in margins, found),
                    **on_path_summary(mine),
                }
            )
    table = pd.DataFrame(rows)
    table["pareto"] = pareto_front(table.ae_median, table.empirical_margin, table.margin_found)
    return table


#: The ``margin_search`` of a margin that is only a lower bound (no failure up to the limit).
LOWER_BOUND = "no failure up to the limit"
#: What a point's margin search gave (:attr:`TradeoffStudy.table`'s ``margin_search``).
MARGIN_SEARCHES = {
    "failure found": "the margin is the largest delay that kept the rule",
    LOWER_BOUND: "the margin is a lower bound: the search limit",
    "rule missed without delay": "no margin: the closed loop misses the rule already at zero delay",
    "not searched": "no margin is defined for this controller",
}


def _search_outcome(searched: bool, found: EmpiricalMargin | None) -> str:
    """The key of :data:`MARGIN_SEARCHES` for a point's search (``searched``: its family is
    searched; ``found``: its result, None when the rule was missed at zero delay)."""
    if not searched:
        return "not searched"
    if found is None:
        return "rule missed without delay"
    return "failure found" if found.failure_found else LOWER_BOUND


def _say(progress: bool, text: str) -> None:
    """A stage of the study on standard error, when progress is shown."""
    if progress:
        print(f"tradeoff: {text}", file=sys.stderr, flush=True)


def drawn_runs(
    scenario: Scenario,
    grid: Mapping[str, Sequence[Any]],
    labels: Sequence[Mapping[str, Any]],
    random: Mapping[str, Mapping[str, Any]],
    draws: int,
    seed: int,
    threshold: Mapping[str, float],
    out: str | Path,
    name: str,
    *,
    executor: Executor | None = None,
    progress: bool = False,
) -> tuple[pd.DataFrame, SweepOutcome]:
    """Run the draws of ``grid`` on the sweep machinery and score each run with the rule.

    Parameters
    ----------
    scenario : Scenario
        The base of every run.
    grid : mapping
        The sweep's ``[grid]`` (a Cartesian product, first key outermost).
    labels : sequence of mapping
        The columns that describe each grid point, in the product's order.
    random : mapping
        The sweep's ``[random]`` table (empty: one run per point).
    draws, seed : int
        Draws per point and their seed.
    threshold : mapping
        The scored coordinates and the bound of each one's mean ``|e1|``
        (:attr:`TradeoffStudy.threshold`).
    out : path
        The study's folder (claimed once the sweep is valid).
    name : str
        The sweep's folder in ``out`` (Parquet parts, resumed when the same sweep runs again).
    executor : Executor, optional
        Where the units run (all local cores by default).
    progress : bool
        Progress on standard error.

    Returns
    -------
    runs : DataFrame
        One row per run: its labels, ``draw``, the drawn values, ``status``, ``ae`` (the mean
        over the scored coordinates of their mean ``|e1|``), ``tv`` and ``on_path`` (ok and
        every scored coordinate's mean ``|e1|`` at most its bound).
    outcome : SweepOutcome
        The sweep's (units computed and resumed).
    """
    spec = SweepSpec(
        base=scenario,
        grid=MappingProxyType({key: tuple(values) for key, values in grid.items()}),
        random=MappingProxyType(dict(random)),
        draws=draws,
        seed=seed,
        unit_size=UNIT_SIZE,
        progress=progress,
    )
    points = f"{counted(len(labels), 'point')} x {counted(draws, 'draw')}"
    _say(progress, f"draws: {counted(len(spec.runs), 'run')} ({points})")
    folder = claim_output_folder(out)
    outcome = run_sweep(spec, folder / name, executor=executor, progress=progress)
    runs = outcome.runs.sort_values("run").reset_index(drop=True)
    index = runs.run.to_numpy() // draws
    frame = pd.DataFrame({key: [labels[i][key] for i in index] for key in labels[0]})
    frame["draw"] = runs.run.to_numpy() % draws
    for key in random:
        frame[key] = runs[key].to_numpy()
    plant = scenario.build().plant
    names = default_names(plant.coordinate_names, plant.n)
    errors = np.column_stack([runs[f"ae_{c}"].to_numpy(dtype=float) for c in names])
    scored = [coordinate in threshold for coordinate in names]
    rule = np.array([threshold.get(coordinate, _UNSCORED) for coordinate in names])
    frame["status"] = runs.status.to_numpy()
    frame["ae"] = errors[:, scored].mean(axis=1)
    frame["tv"] = runs.tv.to_numpy(dtype=float)
    within = np.all(errors <= rule, axis=1)  # NaN (not ok) compares False
    frame["on_path"] = (frame.status == "ok").to_numpy() & within
    return frame, outcome


def on_path_summary(runs: pd.DataFrame) -> dict[str, Any]:
    """The drawn runs of one point (:func:`drawn_runs`' rows): ``runs``, ``on_path`` (of them
    on the path), the others by reason, ``stopped`` (the run did not end ok: it diverged or
    exceeded the scenario's ``error_bound``) and ``over_threshold`` (ended ok, a scored
    coordinate's mean ``|e1|`` above its bound), ``share_on_path`` ``= on_path / runs`` with
    its Wilson 95 % interval ``share_low``, ``share_high``, and the median ``ae`` and ``tv`` of
    the runs on the path (``ae_median``, ``tv_median``; NaN when none)."""
    kept = runs[runs.on_path]
    stopped = int((runs.status != "ok").sum())
    low, high = wilson_interval(len(kept), len(runs))
    return {
        "runs": len(runs),
        "on_path": len(kept),
        "stopped": stopped,
        "over_threshold": len(runs) - len(kept) - stopped,
        "share_on_path": len(kept) / len(runs),
        "share_low": low,
        "share_high": high,
        "ae_median": float(kept.ae.median()) if len(kept) else math.nan,
        "tv_median": float(kept.tv.median()) if len(kept) else math.nan,
    }


def _evaluated(
    margins: Mapping[str, list[EmpiricalMargin | None]],
    omegas: tuple[float, ...],
    names: tuple[str, ...],
    units: tuple[str | None, ...],
    scored: tuple[bool, ...],
) -> pd.DataFrame:
    """Every simulated point of every margin search, with its ``ω_n`` and family; each
    coordinate's metric with its unit (``metric_<name>_<unit>``) and, when the scored
    coordinates share a unit (or none has one), the largest of theirs (``metric_<unit>``, the
    unscored coordinates left out)."""
    per_coordinate = {
        f"metric_{name}": with_unit(f"metric_{name}", u)
        for name, u in zip(names, units, strict=True)
    }
    scored_columns = [f"metric_{name}" for name, s in zip(names, scored, strict=True) if s]
    scored_units = [u for u, s in zip(units, scored, strict=True) if s]
    # One unit for every scored coordinate (or none known for any): their largest is a number.
    comparable = len(set(scored_units)) == 1
    combined = with_unit("metric", shared_unit(scored_units))
    frames = []
    for family, found in margins.items():
        for omega, result in zip(omegas, found, strict=True):
            if result is None:
                continue
            frame = result.to_frame()
            if comparable:  # in the place of the search's own, the largest over every coordinate
                frame["metric"] = frame[scored_columns].max(axis=1, skipna=False)
            else:
                frame = frame.drop(columns="metric")
            frame = frame.rename(columns={**per_coordinate, "metric": combined})
            frame.insert(0, "controller", family)
            frame.insert(0, "omega_n", omega)
            frames.append(frame)
    if frames:
        return pd.concat(frames, ignore_index=True)
    # No search kept a point (each missed the rule without delay): the columns, no rows.
    metrics = [combined] if comparable else []
    columns = ["omega_n", "controller", "value", *metrics, *per_coordinate.values()]
    return pd.DataFrame(columns=[*columns, "status", "passes"])
