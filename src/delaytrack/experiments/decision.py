"""The decision rule: which controller and which outer-loop gains to use for a delay envelope.

**The envelope** (:class:`Envelope`): the largest delay ``h_max`` and how well the delay is
known, which sets what the predictors are told:

- ``exact``: told the true delay;
- ``within`` ``x`` (``±x``): told a delay off by up to ``x``, i.e. ``(1 − x) h`` and
  ``(1 + x) h``;
- ``unknown``: told a fixed guess, ``ĥ = h_max / 2``, the middle of ``[0, h_max]``: of all
  fixed guesses it is the one whose largest error over the envelope, ``h_max / 2``, is smallest.

**The conditions** that cover the envelope are constant true delays (a constant delay at the
bound is where the margins of the trade-off are measured): ``h = h_max``, told ``h_max``
(exact); ``h = h_max`` told ``(1 − x) h_max`` and told ``(1 + x) h_max`` (within ``±x``);
``h = h_max`` and ``h = 0``, both told ``ĥ`` (unknown: told too short and told too long by
``h_max / 2``). Under a constant true delay PCON told ``s h`` is PCONf's law told
``h̄ = s h``, so the predictor is one candidate per gain point, run as PCONf told the
condition's delay; AROLC and the outer loop are told nothing.

**The candidates** are the trade-off's controllers at its gain points ``ω_n``
(:mod:`~delaytrack.experiments.tradeoff`). In each condition the robots are drawn as in the
trade-off (the same seed and rule of staying on the path).

**The rule** (:func:`decide`). A candidate *qualifies* when, in every condition, the Wilson
95 % lower bound of the share of drawn robots that stay on the path is at least ``p = 0.95``
(:data:`REQUIRED_SHARE`). Its *worst-case AE* is the largest, over the conditions, of the median
AE of its runs on the path. The **winner** is the qualifying candidate with the smallest
worst-case AE; the **runner-up** the best qualifying candidate of another controller (the
question is which controller; the next gain point of the same one differs only by the sweep's
step); the **margin** is the runner-up's worst-case AE minus the winner's, and their ratio.

**Draws it needs.** With every one of ``n`` robots on the path, Wilson's lower bound is
``n / (n + z²)`` (``z = 1.96``), which reaches ``p`` only for ``n >= p z² / (1 − p)``: 73 draws
per condition for 0.95 (:func:`draws_needed`). Below that, or when no candidate reaches ``p``,
the rule names no winner and says which of the two it is.

:func:`run_decision` draws the conditions on the trade-off's sweep machinery (resumable Parquet
parts, any executor) and returns a :class:`Decision`, which
:mod:`delaytrack.report.tradeoff` writes.
"""

from __future__ import annotations

import dataclasses
import math
import re
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np
import pandas as pd

from delaytrack._deprecated import moved_object
from delaytrack._validation import ArgumentError, is_integer_at_least
from delaytrack.experiments.intervals import Z95, wilson_interval
from delaytrack.experiments.tradeoff import (
    FAMILIES,
    TradeoffStudy,
    drawn_runs,
    family_gains,
    family_tables,
    on_path_summary,
)
from delaytrack.sweeps.executors import Executor

__all__ = [
    "DECISION_DRAWS",
    "KNOWLEDGE",
    "REQUIRED_SHARE",
    "Choice",
    "Decision",
    "Envelope",
    "Refusal",
    "Shortfall",
    "decide",
    "draws_needed",
    "run_decision",
]

#: How well the delay is known.
KNOWLEDGE: tuple[str, ...] = ("exact", "within", "unknown")
#: The share of drawn robots that must stay on the path, by the Wilson lower bound.
REQUIRED_SHARE = 0.95
#: Robots drawn per candidate and condition by default (at least :func:`draws_needed`).
DECISION_DRAWS = 80
#: The columns :func:`decide` reads.
_COLUMNS = ("controller", "omega_n", "k1", "k2", "delay", "told", "runs", "on_path", "ae_median")
#: The counts of the runs off the path by reason (:func:`~delaytrack.experiments.tradeoff.
#: on_path_summary`), kept in :attr:`Decision.table` when the table has them.
_REASONS = ("stopped", "over_threshold")
#: ``±X%`` as the command line writes it.
_WITHIN = re.compile(r"(?:±|\+-|\+/-)?\s*([0-9]*\.?[0-9]+)\s*%")


def draws_needed(share: float = REQUIRED_SHARE, z: float = Z95) -> int:
    """The fewest draws ``n`` whose Wilson lower bound reaches ``share`` when all ``n`` robots
    stay on the path: the smallest ``n`` with ``n / (n + z²) >= share``, i.e.
    ``n >= share z² / (1 − share)`` (73 for 0.95)."""
    return math.ceil(share * z * z / (1.0 - share))


@dataclass(frozen=True)
class Envelope:
    """A delay envelope: the largest delay and how well the delay is known (module docstring).

    Attributes
    ----------
    h_max : float
        The largest delay (s), ``> 0``.
    knowledge : str
        ``"exact"``, ``"within"`` or ``"unknown"`` (:data:`KNOWLEDGE`).
    within : float
        ``x`` of ``±x`` (a fraction, ``0 < x <= 1``) for ``"within"``; 0 otherwise.
    """

    h_max: float
    knowledge: str
    within: float = 0.0

    def __post_init__(self) -> None:
        if not (isinstance(self.h_max, int | float) and 0 < self.h_max < math.inf):
            raise ArgumentError("h_max", f"must be a delay > 0 (s); got {self.h_max!r}")
        if self.knowledge not in KNOWLEDGE:
            raise ArgumentError(
                "knowledge", f"must be exact, ±X% (0 < X <= 100) or unknown; got {self.knowledge!r}"
            )
        bounded = 0 < self.within <= 1 if self.knowledge == "within" else self.within == 0
        if not bounded:
            raise ArgumentError(
                "within", f"must be 0 < x <= 1 for 'within' and 0 otherwise; got {self.within!r}"
            )
        object.__setattr__(self, "h_max", float(self.h_max))
        object.__setattr__(self, "within", float(self.within))

    @classmethod
    def from_text(cls, h_max: float, knowledge: str) -> Envelope:
        """The envelope of ``h_max`` and ``knowledge`` written ``exact``, ``±X%`` (also ``X%``,
        ``+-X%``; ``0 < X <= 100``) or ``unknown``."""
        text = knowledge.strip()
        if text in ("exact", "unknown"):
            return cls(h_max, text)
        match = _WITHIN.fullmatch(text)
        if match is None or not 0 < float(match[1]) <= 100:
            raise ArgumentError(
                "knowledge", f"must be exact, ±X% (0 < X <= 100) or unknown; got {knowledge!r}"
            )
        return cls(h_max, "within", float(match[1]) / 100.0)

    def check_run_length(self, duration: float) -> None:
        """Refuse an envelope whose largest delay is not shorter than the runs' ``duration`` (s):
        under it no command would reach the plant, and every candidate would run open loop
        alike."""
        if self.h_max >= duration:
            raise ArgumentError(
                "h_max",
                f"must be less than the scenario's duration {duration:g} s (under a delay that "
                f"long no command reaches the plant); got {self.h_max:g}",
            )

    @property
    def delays(self) -> tuple[float, ...]:
        """The constant true delays of the conditions (s)."""
        return (self.h_max, 0.0) if self.knowledge == "unknown" else (self.h_max,)

    @property
    def told(self) -> tuple[float, ...]:
        """What the predictors are told in the conditions (s)."""
        if self.knowledge == "within":
            return ((1.0 - self.within) * self.h_max, (1.0 + self.within) * self.h_max)
        return (self.h_max / 2,) if self.knowledge == "unknown" else (self.h_max,)

    @property
    def text(self) -> str:
        """The envelope in words."""
        known = {
            "exact": "delay known exactly",
            "within": f"delay known within ±{100 * self.within:g} %",
            "unknown": f"delay unknown (predictors told the guess {self.h_max / 2:g} s)",
        }[self.knowledge]
        return f"h_max = {self.h_max:g} s, {known}"


@dataclass(frozen=True)
class Choice:
    """A chosen candidate: its controller, gains (``K1 = k1 I``, ``K2 = k2 I`` at ``ω_n``), its
    worst-case AE, its worst (smallest) Wilson lower bound over the conditions, and
    ``at_largest_omega_n``: whether its ``ω_n`` is the largest of the candidates' (the edge of
    the sweep: larger gains were not tried)."""

    controller: str
    omega_n: float
    k1: float
    k2: float
    worst_ae: float
    worst_share_low: float
    at_largest_omega_n: bool


@dataclass(frozen=True)
class Shortfall:
    """Why a candidate does not qualify: the condition where its Wilson lower bound is smallest.

    Attributes
    ----------
    controller : str
    omega_n : float
        The candidate.
    share_low : float
        Its Wilson 95 % lower bound there, below the required share.
    delay, told : float
        The condition: the true constant delay and what the predictor is told (s; NaN: told
        nothing).
    on_path, runs : int
        Robots on the path of those drawn there.
    too_few_draws : bool
        Whether ``runs`` is below :func:`draws_needed`, so no outcome could have qualified.
    """

    controller: str
    omega_n: float
    share_low: float
    delay: float
    told: float
    on_path: int
    runs: int
    too_few_draws: bool


@dataclass(frozen=True)
class Refusal:
    """Why the rule chose no candidate.

    Attributes
    ----------
    too_few_draws : bool
        True: ``draws`` is below :func:`draws_needed`, so no candidate can qualify whatever the
        robots do; False: there were enough draws and no candidate qualifies.
    draws : int
        The fewest robots drawn per condition.
    ceiling : float
        ``n / (n + z²)`` for ``n = draws``: the largest Wilson lower bound those draws allow.
    closest : Shortfall or None
        When ``too_few_draws`` is False: the candidate whose worst Wilson lower bound is the
        largest, and why it does not qualify (None otherwise).
    """

    too_few_draws: bool
    draws: int
    ceiling: float
    closest: Shortfall | None = None


@dataclass(frozen=True)
class Decision:
    """What the rule decided (module docstring), with every number behind it.

    Attributes
    ----------
    envelope : Envelope
    table : DataFrame
        One row per candidate and condition: ``controller``, ``omega_n``, ``k1``, ``k2``,
        ``delay`` (the true constant delay, s), ``told`` (what the predictor is told, s; NaN
        for the controllers told nothing), ``runs``, ``on_path``, ``share_on_path``,
        ``share_low``, ``share_high`` (Wilson 95 %), ``ae_median`` (over the runs on the path),
        then the candidate's ``worst_share_low``, ``worst_ae``, ``qualifies`` and ``status``
        (``winner``, ``runner-up``, ``qualifies`` or ``excluded``).
        :func:`delaytrack.report.decision.decision_table` adds why each was not chosen.
    candidates : DataFrame
        One row per candidate (the candidate's columns of ``table``), best first
        (:func:`delaytrack.report.decision.candidates_table` adds why each was not chosen).
    winner, runner_up : Choice or None
    ae_difference, ae_ratio : float
        The runner-up's worst-case AE minus the winner's, and divided by it (NaN without both,
        and the ratio NaN when the winner's is 0).
    refused : Refusal or None
        Why no candidate was chosen (None when one was);
        :func:`delaytrack.report.decision.refusal_text` says it in words.
    required_share : float
    draws : int
        Robots per candidate and condition (the fewest when they differ).
    draws_needed : int
        :func:`draws_needed` of ``required_share``.
    excluded : Mapping[str, str]
        Controller -> why it was not a candidate.
    shortfalls : Mapping[tuple[str, float], Shortfall]
        ``(controller, omega_n)`` -> why that candidate does not qualify, for every candidate
        that does not.
    ae_unit : str or None
    runs : DataFrame
        Every drawn run (empty when the table was given by hand).
    seconds : float
    computed, resumed : int
        Work units of the draws computed and found finished.
    drawn : bool
        Whether the scenario drew its robots; False when it has nothing to draw, so that each
        condition is one run, which can never show the required share on the path.
    """

    envelope: Envelope
    table: pd.DataFrame
    candidates: pd.DataFrame
    winner: Choice | None
    runner_up: Choice | None
    ae_difference: float
    ae_ratio: float
    refused: Refusal | None
    required_share: float
    draws: int
    draws_needed: int
    excluded: Mapping[str, str]
    shortfalls: Mapping[tuple[str, float], Shortfall]
    ae_unit: str | None = None
    runs: pd.DataFrame = dataclasses.field(default_factory=pd.DataFrame)
    seconds: float = 0.0
    computed: int = 0
    resumed: int = 0
    drawn: bool = True

    @property
    def refusal(self) -> str | None:
        """Why no candidate was chosen, in words (None when one was). Deprecated: the words are
        the report's, :func:`delaytrack.report.decision.refusal_text`; the facts are
        :attr:`refused`. A moved name (:mod:`delaytrack._deprecated`): it warns and loads the
        report only when read."""
        refusal_text = moved_object(
            f"{__name__}.Decision.refusal", "delaytrack.report.decision:refusal_text"
        )
        text: str | None = refusal_text(self)
        return text


def _choice(row: Any, largest_omega_n: float) -> Choice:
    return Choice(
        row.controller,
        row.omega_n,
        row.k1,
        row.k2,
        row.worst_ae,
        row.worst_share_low,
        at_largest_omega_n=bool(row.omega_n == largest_omega_n),
    )


def _check_table(table: pd.DataFrame, required_share: float) -> None:
    """Refuse a ``table`` :func:`decide` cannot read as its docstring says, and a
    ``required_share`` outside ``(0, 1)``."""
    if not (isinstance(required_share, int | float) and 0 < required_share < 1):
        raise ArgumentError(
            "required_share",
            f"must be a share strictly between 0 and 1 (0.95: 95 %); got {required_share!r}",
        )
    if not isinstance(table, pd.DataFrame):
        raise ArgumentError("table", f"must be a pandas DataFrame; got {type(table).__name__}")
    missing = [c for c in _COLUMNS if c not in table.columns]
    if missing:
        raise ArgumentError("table", f"lacks the columns {missing}; needs {list(_COLUMNS)}")
    if table.empty:
        raise ArgumentError("table", "has no rows: it needs one per candidate and condition")
    runs = pd.to_numeric(table.runs, errors="coerce").to_numpy(dtype=float)
    on_path = pd.to_numeric(table.on_path, errors="coerce").to_numpy(dtype=float)
    if not (np.all(np.isfinite(runs) & (runs >= 1) & (runs == np.round(runs)))):
        raise ArgumentError("table", f"runs must be whole numbers >= 1; got {list(table.runs)}")
    if not np.all((on_path >= 0) & (on_path <= runs) & (on_path == np.round(on_path))):
        raise ArgumentError(
            "table", f"on_path must be whole numbers from 0 to runs; got {list(table.on_path)}"
        )
    ae = pd.to_numeric(table.ae_median, errors="coerce").to_numpy(dtype=float)
    stayed = on_path > 0
    if not (np.all(np.isfinite(ae[stayed]) & (ae[stayed] >= 0)) and np.all(np.isnan(ae[~stayed]))):
        raise ArgumentError(
            "table",
            "ae_median must be a number >= 0 where some run stayed on the path and NaN where "
            f"none did; got {list(table.ae_median)} for on_path {list(table.on_path)}",
        )
    gains = table.groupby(["controller", "omega_n"])[["k1", "k2"]].nunique()
    if (gains > 1).any(axis=None):
        raise ArgumentError(
            "table", "must give each candidate (controller, omega_n) one k1 and one k2"
        )


def _with_shares(table: pd.DataFrame) -> pd.DataFrame:
    """The columns :func:`decide` reads, with the share on the path and its Wilson 95 % bounds
    (``share_on_path``, ``share_low``, ``share_high``) after ``on_path``, and the counts off the
    path by reason (:data:`_REASONS`) last, when ``table`` has them."""
    reasons = [c for c in _REASONS if c in table.columns]
    frame = table.loc[:, [*_COLUMNS, *reasons]].reset_index(drop=True)
    bounds = [
        wilson_interval(int(k), int(n)) for k, n in zip(frame.on_path, frame.runs, strict=True)
    ]
    frame.insert(8, "share_on_path", frame.on_path / frame.runs)
    frame.insert(9, "share_low", [low for low, _ in bounds])
    frame.insert(10, "share_high", [high for _, high in bounds])
    return frame


def _candidate_rows(
    frame: pd.DataFrame, required_share: float, needed: int
) -> tuple[list[dict[str, Any]], dict[tuple[str, float], Shortfall]]:
    """One row per candidate of ``frame`` (its worst share and AE, whether it qualifies), and
    the shortfall of each candidate that does not qualify."""
    rows = []
    shortfalls: dict[tuple[str, float], Shortfall] = {}
    for (controller, omega), conditions in frame.groupby(["controller", "omega_n"], sort=False):
        worst = conditions.loc[conditions.share_low.idxmin()]
        qualifies = bool(worst.share_low >= required_share)
        if not qualifies:
            shortfalls[controller, omega] = _shortfall(controller, omega, worst, needed)
        rows.append(
            {
                "controller": controller,
                "omega_n": omega,
                "k1": conditions.k1.iloc[0],
                "k2": conditions.k2.iloc[0],
                "worst_share_low": float(worst.share_low),
                # NaN when some condition kept no run on the path: no AE there to compare.
                "worst_ae": float(conditions.ae_median.max(skipna=False)),
                "qualifies": qualifies,
                "status": "qualifies" if qualifies else "excluded",
            }
        )
    return rows, shortfalls


def _shortfall(controller: str, omega: float, worst: Any, needed: int) -> Shortfall:
    """The :class:`Shortfall` of a candidate whose smallest Wilson lower bound is in the
    condition ``worst`` (a row of the table)."""
    return Shortfall(
        controller=controller,
        omega_n=omega,
        share_low=float(worst.share_low),
        delay=float(worst.delay),
        told=float(worst.told),
        on_path=int(worst.on_path),
        runs=int(worst.runs),
        too_few_draws=bool(worst.runs < needed),
    )


def _ranked(rows: list[dict[str, Any]]) -> pd.DataFrame:
    """The candidates' ``rows`` best first: qualifying, smallest worst-case AE, largest worst
    share, then in the order of :data:`FAMILIES` and of ``ω_n``."""
    order = {family: i for i, family in enumerate(FAMILIES)}
    candidates = pd.DataFrame(rows)
    candidates = candidates.assign(
        _rank=candidates.controller.map(lambda c: order.get(c, len(order)))
    )
    return (
        candidates.sort_values(
            ["qualifies", "worst_ae", "worst_share_low", "_rank", "omega_n"],
            ascending=[False, True, False, True, True],
            kind="stable",
        )
        .drop(columns="_rank")
        .reset_index(drop=True)
    )


def _refusal(
    candidates: pd.DataFrame,
    shortfalls: Mapping[tuple[str, float], Shortfall],
    fewest: int,
    needed: int,
) -> Refusal:
    """Why no candidate qualifies with ``fewest`` draws per condition: too few draws, or
    enough and the closest candidate's shortfall."""
    closest = None
    if fewest >= needed:
        best = candidates.sort_values("worst_share_low", ascending=False).iloc[0]
        closest = shortfalls[best.controller, best.omega_n]
    return Refusal(
        too_few_draws=fewest < needed,
        draws=fewest,
        ceiling=fewest / (fewest + Z95 * Z95),
        closest=closest,
    )


def _mark_choices(candidates: pd.DataFrame, chosen: pd.DataFrame) -> tuple[Choice, Choice | None]:
    """The winner and the runner-up (None without one) of the qualifying ``chosen``, their
    ``status`` set in ``candidates``."""
    largest = candidates.omega_n.max()
    first = chosen.iloc[0]
    winner = _choice(first, largest)
    candidates.loc[chosen.index[0], "status"] = "winner"
    others = chosen[chosen.controller != first.controller]
    if others.empty:
        return winner, None
    candidates.loc[others.index[0], "status"] = "runner-up"
    return winner, _choice(others.iloc[0], largest)


def decide(
    table: pd.DataFrame,
    envelope: Envelope,
    *,
    required_share: float = REQUIRED_SHARE,
    excluded: Mapping[str, str] | None = None,
    ae_unit: str | None = None,
) -> Decision:
    """Apply the rule of the module docstring to a table of candidates and conditions.

    Parameters
    ----------
    table : DataFrame
        One row per candidate and condition with ``controller``, ``omega_n``, ``k1``, ``k2``,
        ``delay``, ``told`` (NaN: told nothing), ``runs`` (robots drawn), ``on_path`` (of them
        on the path) and ``ae_median`` (median AE of those on the path; NaN when none).
    envelope : Envelope
        The envelope the conditions cover.
    required_share : float
        ``p``: the Wilson 95 % lower bound of the share on the path must reach it in every
        condition.
    excluded : mapping, optional
        Controllers that were not candidates, and why.
    ae_unit : str, optional
        The unit of AE, for the texts.
    """
    _check_table(table, required_share)
    needed = draws_needed(required_share)
    frame = _with_shares(table)
    rows, shortfalls = _candidate_rows(frame, required_share, needed)
    candidates = _ranked(rows)
    chosen = candidates[candidates.qualifies]
    winner = runner_up = None
    difference = ratio = math.nan
    refused = None
    fewest = int(frame.runs.min())
    if chosen.empty:
        refused = _refusal(candidates, shortfalls, fewest, needed)
    else:
        winner, runner_up = _mark_choices(candidates, chosen)
        if runner_up is not None:
            difference = runner_up.worst_ae - winner.worst_ae
            # no ratio to a winner that tracked without error (AE 0 to the digits kept)
            ratio = runner_up.worst_ae / winner.worst_ae if winner.worst_ae > 0 else math.nan
    merged = frame.merge(candidates, on=["controller", "omega_n", "k1", "k2"], how="left")
    return Decision(
        envelope=envelope,
        table=merged,
        candidates=candidates,
        winner=winner,
        runner_up=runner_up,
        ae_difference=difference,
        ae_ratio=ratio,
        refused=refused,
        required_share=required_share,
        draws=fewest,
        draws_needed=needed,
        excluded=MappingProxyType(dict(excluded or {})),
        shortfalls=MappingProxyType(shortfalls),
        ae_unit=ae_unit,
    )


def run_decision(
    study: TradeoffStudy,
    envelope: Envelope,
    out: str | Path,
    *,
    draws: int | None = None,
    executor: Executor | None = None,
    progress: bool = False,
) -> Decision:
    """Draw the envelope's conditions for the trade-off's candidates and apply the rule.

    Parameters
    ----------
    study : TradeoffStudy
        The trade-off: its scenario, gain points, controllers, rule of staying on the path,
        draws' distributions and seed.
    envelope : Envelope
        The delay envelope; its ``h_max`` must be less than the scenario's duration.
    out : path
        Folder of the conditions' sweep (``out/decision-sweep``: parts, resumable).
    draws : int, optional
        Robots per candidate and condition (:data:`DECISION_DRAWS` by default when something
        is drawn; one run each when nothing is, which can never qualify).
    executor : Executor, optional
        Where the draws' units run (all local cores by default).
    progress : bool
        Progress on standard error.
    """
    start = time.perf_counter()
    if draws is not None and not is_integer_at_least(draws, 1):
        raise ArgumentError("draws", f"must be an integer >= 1; got {draws!r}")
    envelope.check_run_length(study.scenario.duration)
    scenario = study.scenario.replace(delay={"type": "constant", "h": envelope.h_max})
    history = max(envelope.h_max, *envelope.told)
    tables, left_out = family_tables(scenario, study.zeta, study.omegas, history)
    excluded = dict(study.left_out)
    for family, why in left_out.items():  # a predictor cannot hold the envelope's history
        excluded.setdefault(family, f"under the envelope's largest delay, {why}")
    if "pcon" in study.families:
        excluded["pcon"] = (
            "under a constant true delay PCON told s h is PCONf's law told h̄ = s h: the "
            "predictor is evaluated once, as PCONf"
        )
    families = [f for f in study.families if f != "pcon" and f in tables]
    controllers: list[dict[str, Any]] = []
    labels: list[dict[str, Any]] = []
    for family in families:
        for omega, table in zip(study.omegas, tables[family], strict=True):
            k1, k2 = family_gains(omega, study.zeta)
            for told in envelope.told if family == "pconf" else (math.nan,):
                controllers.append(table if math.isnan(told) else {**table, "h_bar": told})
                labels.append(
                    {"controller": family, "omega_n": omega, "k1": k1, "k2": k2, "told": told}
                )
    points = [{"delay": h, **label} for h in envelope.delays for label in labels]
    drawn = dict(study.random)
    count = (DECISION_DRAWS if draws is None else int(draws)) if drawn else 1
    runs, outcome = drawn_runs(
        scenario,
        {
            "delay": tuple({"type": "constant", "h": h} for h in envelope.delays),
            "controller": tuple(controllers),
        },
        points,
        drawn,
        count,
        study.seed,
        study.threshold,
        out,
        "decision-sweep",
        executor=executor,
        progress=progress,
    )
    rows = [
        {**point, **on_path_summary(runs.iloc[i * count : (i + 1) * count])}
        for i, point in enumerate(points)
    ]
    decision = decide(pd.DataFrame(rows), envelope, excluded=excluded, ae_unit=study.ae_unit)
    return dataclasses.replace(
        decision,
        runs=runs,
        seconds=time.perf_counter() - start,
        computed=outcome.computed,
        resumed=outcome.resumed,
        drawn=bool(drawn),
    )
