"""The margins job: certified vs exact vs empirical delay margins over a grid of gains.

``delaytrack reproduce --job margins`` runs :func:`delaytrack.jobs.margins.reproduce`, which
writes ``<out>/margins/``:

- ``margins.csv``: one row per gain pair ``K1 = k1 I``, ``K2 = k2 I`` (:data:`GAINS`; columns
  ``k1_per_s2``, ``k2_per_s``): Theorem 1's certified ``h_m`` (AROLC with ``Q = I``, ``β = 1``,
  ``r = 1.1``), the exact constant-delay margin ``h_exact`` of the nominal error dynamics, and
  the empirical margins of AROLC and of the plain outer loop under a constant delay ``h`` and
  under ``h(t) = a |sin t|`` (the largest delay ``a``), in seconds (columns ending ``_s``), with
  ``h_m / h_exact`` and ``h_m`` over AROLC's empirical constant-delay margin;
- ``evaluated.csv``: every simulated (gains, controller, profile, delay ``delay_s``, the tracking
  metric of each joint in radians, status);
- ``figures/margins.png|svg``: the margins of each gain pair side by side, log scale;
- ``scenario.toml``: the scenario (two_link_margins) with the paper's gains;
- ``report.html``: settings, the table, the figure and what the gap means.

The empirical margins come from :func:`~delaytrack.experiments.empirical_margin.empirical_margin`
on the shipped scenario ``two_link_margins`` (true arm without friction, nominal model 20 %
light), with the tracking rule ``max_j mean |e1_j| <= 0.2 rad`` over the last 15 of 30 s. All
gain pairs of one controller and profile are searched in lockstep (one batched simulation per
round).

:func:`run_study` returns a :class:`MarginStudy` holding every number of the report, which
:func:`~delaytrack.report.margins.write_study` writes; :func:`delaytrack.jobs.margins.reproduce`
does both.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import ClassVar, TypedDict

import numpy as np
import pandas as pd

from delaytrack._deprecated import moved_names
from delaytrack._result_columns import shared_unit
from delaytrack._validation import ArgumentError
from delaytrack.analysis import exact_delay_margin, razumikhin_bound
from delaytrack.analysis.razumikhin import PAPER_BETA as BETA
from delaytrack.analysis.razumikhin import PAPER_R as R
from delaytrack.experiments.empirical_margin import (
    EmpiricalMargin,
    MissedWithoutDelay,
    empirical_margin,
)
from delaytrack.scenario import Scenario, load_builtin
from delaytrack.units import coordinate_units, value_with_unit

__all__ = ["FOLDER", "GAINS", "MarginStudy", "run_study"]
#: Running the study and writing its report is a job (:mod:`delaytrack.jobs.margins`).
__getattr__ = moved_names(
    __name__,
    {
        "reproduce": "delaytrack.jobs.margins:reproduce",
        "write_study": "delaytrack.report.margins:write_study",
    },
)

FOLDER = "margins"
SCENARIO = "two_link_margins"
#: Values of k1 and of k2 (K1 = k1 I, K2 = k2 I); every pair is run.
GAINS = (0.5, 1.0, 2.0)


class SearchSettings(TypedDict):
    """Settings of an empirical margin search: the keywords of
    :func:`~delaytrack.experiments.empirical_margin.empirical_margin` that the job fixes."""

    threshold: float
    metric: str
    resolution: float
    upper: float
    frequency: float
    grid: int
    points: int


#: Search settings of every empirical margin.
SEARCH = SearchSettings(
    threshold=0.2, metric="ae", resolution=0.005, upper=2.0, frequency=1.0, grid=16, points=4
)
#: Controllers (scenario type -> column prefix) and delay families searched.
CONTROLLERS = {"arolc": "arolc", "outer-loop": "outer_loop"}
#: The controllers as a sentence names them.
_NAMES = {"arolc": "AROLC", "outer-loop": "the outer loop"}
PROFILES = ("constant", "abs-sine")
#: The outer loop's empirical constant-delay margin counts as close to ``h_exact`` within this
#: many percent of it.
CLOSE_PERCENT = 15.0


@dataclass(frozen=True)
class MarginGap:
    """How the margins compare over the gain pairs (ranges are ``(smallest, largest)``).

    Attributes
    ----------
    pairs : int
        Gain pairs.
    certified_over_exact, certified_over_arolc : tuple of float
        Ranges of ``h_m / h_exact`` and of ``h_m`` over AROLC's empirical constant-delay margin.
    conservatism : tuple of float
        The range of the inverse of the latter: the factor by which the certificate is
        conservative.
    above_certified : int
        Pairs in which both empirical AROLC margins lie above ``h_m``.
    close_to_exact : int
        Pairs whose outer-loop empirical constant-delay margin ``h_o`` is within
        :data:`CLOSE_PERCENT` of ``h_exact``: ``|h_o / h_exact - 1| <= CLOSE_PERCENT / 100``.
    below_exact, above_exact : int
        Pairs whose ``h_o`` lies further below, or further above, ``h_exact``.
    outer_unbounded : int
        Pairs whose outer-loop search found no failure up to its limit (``h_o`` NaN).
    ended_on_path : int
        Of those, the pairs whose first failing run ended without divergence (a finite metric).
    largest_ended_error : float
        The largest metric (mean ``|e1|``, rad) of those runs (NaN when there is none).
    arolc_constant, h_exact : tuple of float
        Ranges of AROLC's empirical constant-delay margin and of ``h_exact`` (s).
    """

    pairs: int
    certified_over_exact: tuple[float, float]
    certified_over_arolc: tuple[float, float]
    conservatism: tuple[float, float]
    above_certified: int
    close_to_exact: int
    below_exact: int
    above_exact: int
    outer_unbounded: int
    ended_on_path: int
    largest_ended_error: float
    arolc_constant: tuple[float, float]
    h_exact: tuple[float, float]


@dataclass(frozen=True)
class MarginStudy:
    """What the job computed: every number of its report.

    Attributes
    ----------
    table : DataFrame
        One row per gain pair: ``k1``, ``k2``, ``h_m``, ``h_exact``, the empirical margins (s;
        NaN: no failure up to the upper limit) and the ratios.
    searches : dict
        ``(controller, profile) -> EmpiricalMargin`` per gain pair, in the table's order.
    evaluated : DataFrame
        Every simulated point of every search: the gains, controller, profile, the delay
        (``value``), each joint's metric and the status.
    gap : MarginGap
        How the margins compare.
    scenario : Scenario
        The scenario as searched.
    window : tuple of float
        The scored window ``[duration / 2, duration]`` of the tracking rule (s).
    seconds : float
        Wall time.

    The design travels with every study as class attributes: ``search`` (:data:`SEARCH`),
    ``beta``, ``r`` (:data:`BETA`, :data:`R`), ``gain_values`` (:data:`GAINS`) and
    ``close_percent`` (:data:`CLOSE_PERCENT`).
    """

    search: ClassVar[SearchSettings] = SEARCH
    beta: ClassVar[float] = BETA
    r: ClassVar[float] = R
    gain_values: ClassVar[tuple[float, ...]] = GAINS
    close_percent: ClassVar[float] = CLOSE_PERCENT

    table: pd.DataFrame
    searches: dict[tuple[str, str], list[EmpiricalMargin]]
    evaluated: pd.DataFrame
    gap: MarginGap
    scenario: Scenario
    window: tuple[float, float]
    seconds: float


def _column(controller: str, profile: str) -> str:
    return f"{CONTROLLERS[controller]}_{profile.replace('-', '_')}"


def run_study(*, duration: float | None = None, progress: bool = False) -> MarginStudy:
    """Compute every margin of every gain pair.

    ``duration`` overrides 30 s (for smoke tests); it must be at least twice the largest searched
    delay (4 s), else the search would see no effect of the delay and its margins would mean
    nothing.
    """
    start = time.perf_counter()
    scenario = load_builtin(SCENARIO)
    job_duration = scenario.duration  # the job's own, which meets its rule
    if duration is not None:
        shortest = 2.0 * SEARCH["upper"]
        if not duration >= shortest:
            raise ArgumentError(
                "duration",
                f"must be at least {shortest:g} s for the margins job, twice its largest "
                f"searched delay ({SEARCH['upper']:g} s), so that the metric window "
                f"[duration/2, duration] begins after the longest delay has passed; got "
                f"{duration:g}",
            )
        scenario = scenario.replace(duration=duration)
    pairs = [(k1, k2) for k1 in GAINS for k2 in GAINS]
    rows = []
    for k1, k2 in pairs:
        K1, K2 = k1 * np.eye(2), k2 * np.eye(2)
        h_m = razumikhin_bound(K1, K2, np.eye(4), BETA, R, n=2).h_m
        rows.append({"k1": k1, "k2": k2, "h_m": h_m, "h_exact": exact_delay_margin(K1, K2).h})
    searches: dict[tuple[str, str], list[EmpiricalMargin]] = {}
    for controller in CONTROLLERS:
        base = scenario.controller if controller == "arolc" else {"type": controller}
        built = [
            scenario.replace(controller={**base, "K1": k1, "K2": k2}).build().controller
            for k1, k2 in pairs
        ]
        for profile in PROFILES:
            try:
                found = empirical_margin(
                    scenario, built, profile=profile, progress=progress, **SEARCH
                )
            except MissedWithoutDelay as missed:
                if duration is None or duration >= job_duration or not missed.finished:
                    raise  # not mended by a longer run
                pair = pairs[missed.index]
                raise _too_short(
                    duration, job_duration, controller, pair, missed, scenario
                ) from None
            searches[controller, profile] = found
            for row, result in zip(rows, found, strict=True):
                row[_column(controller, profile)] = (
                    result.margin if result.failure_found else np.nan
                )
    table = pd.DataFrame(rows)
    table["h_m_over_h_exact"] = table["h_m"] / table["h_exact"]
    table["h_m_over_arolc_constant"] = table["h_m"] / table["arolc_constant"]
    return MarginStudy(
        table=table,
        searches=searches,
        evaluated=_evaluated(table, searches),
        gap=_gap(table, searches),
        scenario=scenario,
        window=(scenario.duration / 2, scenario.duration),
        seconds=time.perf_counter() - start,
    )


def _too_short(
    duration: float,
    job: float,
    controller: str,
    gains: tuple[float, float],
    missed: MissedWithoutDelay,
    scenario: Scenario,
) -> ArgumentError:
    """The refusal of a ``duration`` shorter than the job's own ``job`` that leaves a run
    without delay above the job's tracking rule: with the metric window the second half of
    the run, a run that short has not settled by then."""
    k1, k2 = gains
    unit = shared_unit(tuple(coordinate_units(scenario.build().plant).values()))
    rule = value_with_unit(f"{SEARCH['metric']} <= {SEARCH['threshold']:g}", unit)
    return ArgumentError(
        "duration",
        f"= {duration:g} s is too short: {_NAMES[controller]} at K1 = {k1:g} I, K2 = {k2:g} I "
        f"misses the job's rule ({rule} over the second half of the run) already without "
        f"delay ({missed.found}); give a longer $duration (the job's own, {job:g} s, meets it)",
        ("duration",),
    )


def _evaluated(
    table: pd.DataFrame, searches: dict[tuple[str, str], list[EmpiricalMargin]]
) -> pd.DataFrame:
    """Every simulated point of every search, with its gains, controller and profile."""
    frames = []
    for (controller, profile), results in searches.items():
        for (k1, k2), result in zip(table[["k1", "k2"]].to_numpy(), results, strict=True):
            frame = result.to_frame()
            for position, (name, value) in enumerate(
                {"k1": k1, "k2": k2, "controller": controller, "profile": profile}.items()
            ):
                frame.insert(position, name, value)
            frames.append(frame)
    return pd.concat(frames, ignore_index=True)


def _gap(table: pd.DataFrame, searches: dict[tuple[str, str], list[EmpiricalMargin]]) -> MarginGap:
    """:class:`MarginGap` of the margins table and the searches."""
    ratio, exact_ratio = table["h_m_over_arolc_constant"], table["h_m_over_h_exact"]
    outer = table["outer_loop_constant"] / table["h_exact"] - 1.0
    tolerance = CLOSE_PERCENT / 100
    lower = [
        result
        for result, below_exact in zip(
            searches["outer-loop", "constant"], outer < -tolerance, strict=True
        )
        if below_exact
    ]
    ended_ok = [r.metric_values[r.values == r.first_failure][0] for r in lower]
    ended_ok = [value for value in ended_ok if np.isfinite(value)]
    return MarginGap(
        pairs=len(table),
        certified_over_exact=(exact_ratio.min(), exact_ratio.max()),
        certified_over_arolc=(ratio.min(), ratio.max()),
        conservatism=(1 / ratio.max(), 1 / ratio.min()),
        above_certified=int(
            (table["h_m"] < table[["arolc_constant", "arolc_abs_sine"]].min(axis=1)).sum()
        ),
        close_to_exact=int((outer.abs() <= tolerance).sum()),
        below_exact=len(lower),
        above_exact=int((outer > tolerance).sum()),
        outer_unbounded=int(outer.isna().sum()),
        ended_on_path=len(ended_ok),
        largest_ended_error=max(ended_ok) if ended_ok else math.nan,
        arolc_constant=(table["arolc_constant"].min(), table["arolc_constant"].max()),
        h_exact=(table["h_exact"].min(), table["h_exact"].max()),
    )
