"""The decision rule for the P3-DX, for the paper's delay envelopes: which controller and which
outer-loop gains to use on the payload robot when the delay is that of S1–S4 (known exactly or
within ±25 %) or unknown up to 300 ms.

**The trade-off** (:func:`~delaytrack.experiments.tradeoff.run_tradeoff`) runs on the shipped
``robot_S1`` scenario (the paper job's payload robot, nominal model, circle and times) with its
drawn robots (payload placement and wheel friction, the robustness study's seed): the gains
``K1 = ω_n² I``, ``K2 = 2ζω_n I`` at :attr:`DecisionSize.points` log-spaced ``ω_n`` around the
scenario's own (``ζ = 1``), AROLC, the outer loop and the predictors at each.

**The envelopes** (:func:`paper_envelopes`): for each of S1–S4, ``h_max`` = the profile's
largest delay (S1 100 ms, S2 125 ms, S3 60 ms, S4 120 ms), the delay known exactly and known
within ±25 % (:data:`WITHIN`); and the delay unknown up to 300 ms (:data:`UNKNOWN_UP_TO`, the
robustness map's largest delay).

**The rule** (:func:`~delaytrack.experiments.decision.run_decision`, per envelope): the candidate
with the smallest worst-case AE among those whose share of drawn robots on the path has a
Wilson 95 % lower bound of at least 0.95 in every condition of the envelope; the runner-up is the
best qualifying candidate of another controller, the margin the difference of their worst-case
AE. It needs at least 73 draws per condition to name a winner at all.

:func:`run_decision_study` runs both (resumable sweeps, any executor) and returns a
:class:`DecisionStudy`; :func:`delaytrack.jobs.decision_study.reproduce` is
``delaytrack reproduce --job decision``, which writes ``<out>/decision/``
(:func:`~delaytrack.report.decision_study.write_decision_study`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

import pandas as pd

from delaytrack._deprecated import moved_names
from delaytrack._output import claim_output_folder
from delaytrack._validation import ArgumentError, is_integer_at_least
from delaytrack.experiments.decision import Decision, Envelope, run_decision
from delaytrack.experiments.paper_setup import SCENARIOS
from delaytrack.experiments.tradeoff import TradeoffStudy, default_omegas, run_tradeoff
from delaytrack.scenario import load_builtin
from delaytrack.sweeps.executors import Executor, LocalExecutor

__all__ = [
    "FOLDER",
    "SCENARIO",
    "SIZES",
    "UNKNOWN_UP_TO",
    "WITHIN",
    "DecisionSize",
    "DecisionStudy",
    "envelope_table",
    "paper_envelopes",
    "run_decision_study",
    "study_size",
]
#: Running the study and writing its report is a job (:mod:`delaytrack.jobs.decision_study`).
__getattr__ = moved_names(__name__, {"reproduce": "delaytrack.jobs.decision_study:reproduce"})

#: The job's folder under ``reproduce``'s ``out``.
FOLDER = "decision"
#: The shipped scenario the trade-off runs on: the paper job's AROLC / S1 run.
SCENARIO = "robot_S1"
#: ``x`` of "the delay known within ±x" (a fraction).
WITHIN = 0.25
#: The largest delay (s) of the envelope "delay unknown".
UNKNOWN_UP_TO = 0.3
#: Damping ratio of the gain family (the trade-off's default: critically damped).
ZETA = 1.0


@dataclass(frozen=True)
class DecisionSize:
    """The size of the study.

    Attributes
    ----------
    points : int
        Gain points ``ω_n`` of the trade-off, log-spaced
        (:func:`~delaytrack.experiments.tradeoff.default_omegas`).
    tradeoff_draws : int
        Robots drawn per gain point and controller at the scenario's own delay.
    decision_draws : int
        Robots drawn per candidate and condition of each envelope; below 73 the rule can name
        no winner (it says so).
    """

    points: int
    tradeoff_draws: int
    decision_draws: int

    def __post_init__(self) -> None:
        for name in ("points", "tradeoff_draws", "decision_draws"):
            value = getattr(self, name)
            if not is_integer_at_least(value, 1):
                raise ArgumentError("size", f"{name} must be an integer >= 1; got {value!r}")


#: ``default``: what ``delaytrack reproduce --job decision`` runs: 5 gain points (0.25 to
#: 4 rad/s, by factors of 2), 40 robots per trade-off point, 80 per candidate and condition
#: (about 14 400 runs of 60 s). ``full``: 9 gain points and ten times the draws, meant for a
#: Dask cluster.
SIZES: dict[str, DecisionSize] = {
    "default": DecisionSize(points=5, tradeoff_draws=40, decision_draws=80),
    "full": DecisionSize(points=9, tradeoff_draws=400, decision_draws=800),
}


def study_size(size: str | DecisionSize) -> DecisionSize:
    """``size`` by name (:data:`SIZES`) or as given; anything else refused in one line."""
    if isinstance(size, DecisionSize):
        return size
    if isinstance(size, str) and size in SIZES:
        return SIZES[size]
    raise ArgumentError(
        "size", f"must be one of {', '.join(SIZES)} or a DecisionSize; got {size!r}"
    )


def paper_envelopes(
    within: float = WITHIN, unknown_up_to: float = UNKNOWN_UP_TO
) -> dict[str, tuple[str, Envelope]]:
    """The paper's envelopes, name -> (delay case, envelope): for each of S1–S4 (``h_max`` =
    the profile's largest delay) the delay known exactly (``S1-exact``) and within ±``within``
    (``S1-within``); the delay unknown up to ``unknown_up_to`` s (``unknown``, case ``any``)."""
    envelopes: dict[str, tuple[str, Envelope]] = {}
    for case, delay in SCENARIOS.items():
        h_max = float(delay.h_max)
        envelopes[f"{case}-exact"] = (case, Envelope(h_max, "exact"))
        envelopes[f"{case}-within"] = (case, Envelope(h_max, "within", within))
    envelopes["unknown"] = ("any", Envelope(unknown_up_to, "unknown"))
    return envelopes


def _knowledge(envelope: Envelope) -> str:
    if envelope.knowledge == "within":
        return f"±{100 * envelope.within:g} %"
    return envelope.knowledge


def envelope_table(decisions: Mapping[str, Decision], cases: Mapping[str, str]) -> pd.DataFrame:
    """One row per envelope: ``envelope``, ``case``, ``h_max``, ``knowledge``, the winner
    (``winner``, ``omega_n``, ``k1``, ``k2``, ``worst_ae``, ``worst_share_low``: the smallest
    Wilson lower bound of its share on the path over the conditions), the runner-up
    (``runner_up``, ``runner_up_omega_n``, ``runner_up_worst_ae``) and the margin
    (``ae_difference`` = the runner-up's worst-case AE minus the winner's, ``ae_ratio``). Winner
    and runner-up columns are empty (NaN) where there is none; why no candidate was chosen is
    each decision's :attr:`~delaytrack.experiments.decision.Decision.refused`, which
    :func:`~delaytrack.report.decision_study.display_envelopes` adds as ``reason``."""
    rows = []
    for name, decision in decisions.items():
        winner, second = decision.winner, decision.runner_up
        rows.append(
            {
                "envelope": name,
                "case": cases[name],
                "h_max": decision.envelope.h_max,
                "knowledge": _knowledge(decision.envelope),
                "winner": winner.controller if winner else "",
                "omega_n": winner.omega_n if winner else math.nan,
                "k1": winner.k1 if winner else math.nan,
                "k2": winner.k2 if winner else math.nan,
                "worst_ae": winner.worst_ae if winner else math.nan,
                "worst_share_low": winner.worst_share_low if winner else math.nan,
                "runner_up": second.controller if second else "",
                "runner_up_omega_n": second.omega_n if second else math.nan,
                "runner_up_worst_ae": second.worst_ae if second else math.nan,
                "ae_difference": decision.ae_difference,
                "ae_ratio": decision.ae_ratio,
            }
        )
    return pd.DataFrame(rows)


@dataclass(frozen=True)
class DecisionStudy:
    """What :func:`run_decision_study` computed: every number of its page.

    Attributes
    ----------
    tradeoff : TradeoffStudy
        The trade-off on :data:`SCENARIO` (its candidates, rule of staying on the path and
        draws).
    decisions : Mapping[str, Decision]
        Envelope name -> the rule's decision (:func:`paper_envelopes`'s names and order).
    cases : Mapping[str, str]
        Envelope name -> its delay case (``S1`` … ``S4``, ``any``).
    table : DataFrame
        :func:`envelope_table`: one row per envelope.
    size : DecisionSize
    seconds : float
        Wall time.
    computed, resumed : int
        Work units of every sweep computed and found finished.
    """

    tradeoff: TradeoffStudy
    decisions: Mapping[str, Decision]
    cases: Mapping[str, str]
    table: pd.DataFrame
    size: DecisionSize
    seconds: float
    computed: int = 0
    resumed: int = 0


def run_decision_study(
    out: str | Path,
    *,
    size: str | DecisionSize = "default",
    executor: Callable[[], Executor] | None = None,
    progress: bool = False,
) -> DecisionStudy:
    """Run (or resume) the trade-off on :data:`SCENARIO` into ``out/tradeoff/`` and the rule for
    each of :func:`paper_envelopes` into ``out/<envelope>/`` (module docstring); write nothing
    else.

    Parameters
    ----------
    out : path
        The study's folder (the sweeps' Parquet parts, resumed when the same size runs again).
    size : str or DecisionSize
        ``"default"``, ``"full"`` (:data:`SIZES`) or a size of one's own.
    executor : callable, optional
        Makes an :class:`~delaytrack.sweeps.executors.Executor` per sweep (default: all local
        cores).
    progress : bool
        Progress on standard error.
    """
    size = study_size(size)
    make = executor if executor is not None else LocalExecutor
    out = claim_output_folder(out)
    start = time.perf_counter()
    scenario = load_builtin(SCENARIO)
    tradeoff = run_tradeoff(
        scenario,
        out / "tradeoff",
        zeta=ZETA,
        omegas=[float(w) for w in default_omegas(scenario, ZETA, size.points)],
        draws=size.tradeoff_draws,
        executor=make(),
        progress=progress,
    )
    envelopes = paper_envelopes()
    decisions = {
        name: run_decision(
            tradeoff,
            envelope,
            out / name,
            draws=size.decision_draws,
            executor=make(),
            progress=progress,
        )
        for name, (_, envelope) in envelopes.items()
    }
    cases = {name: case for name, (case, _) in envelopes.items()}
    return DecisionStudy(
        tradeoff=tradeoff,
        decisions=MappingProxyType(decisions),
        cases=MappingProxyType(cases),
        table=envelope_table(decisions, cases),
        size=size,
        seconds=time.perf_counter() - start,
        computed=tradeoff.computed + sum(d.computed for d in decisions.values()),
        resumed=tradeoff.resumed + sum(d.resumed for d in decisions.values()),
    )
