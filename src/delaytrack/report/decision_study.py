"""The decision study's page (``delaytrack reproduce --job decision``): ``decision.csv`` (one
row per envelope), ``candidates.csv`` (every candidate and condition of every envelope),
``report.html`` and the trade-off's own files in ``tradeoff/``, made from a
:class:`~delaytrack.experiments.decision_study.DecisionStudy` that already holds every number
shown (this module computes none); and the sentences the paper report quotes."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import pandas as pd

from delaytrack._io import write_frame
from delaytrack._output import claim_output_folder, record_outputs
from delaytrack._version import __version__
from delaytrack._words import counted
from delaytrack.report.decision import (
    ae_text,
    candidates_table,
    conditions_text,
    decision_columns,
    decision_table,
    edge_text,
    gains_text,
    ratio_text,
    refusal_text,
)
from delaytrack.report.html import HtmlReport
from delaytrack.report.tradeoff import threshold_text, write_tradeoff
from delaytrack.units import with_unit

if TYPE_CHECKING:
    from delaytrack.experiments.decision import Choice, Decision
    from delaytrack.experiments.decision_study import DecisionStudy

__all__ = ["decision_sentence", "display_envelopes", "write_decision_study"]

#: The candidates as a sentence names them (the predictor is PCONf told the condition's delay).
_NAMES = {"arolc": "AROLC", "outer-loop": "the outer loop (AROLC without Δu)", "pconf": "PCONf"}


def _named(controller: str) -> str:
    return _NAMES.get(controller, controller)


def _envelope_name(case: str, decision: Decision) -> str:
    """``S1, h_max = 0.1 s, delay known exactly``; ``Any delay, ...`` for case ``any``."""
    return f"{'Any delay' if case == 'any' else case}, {decision.envelope.text}"


def _choice(choice: Choice) -> str:
    return (
        f"{_named(choice.controller)} at ω_n = {choice.omega_n:.3g} rad/s ({gains_text(choice, 3)})"
    )


def decision_sentence(case: str, decision: Decision) -> str:
    """One sentence for an envelope: the winner with its gains (and whether they are the
    sweep's largest), worst-case AE and the smallest Wilson lower bound of its share on the
    path, the runner-up and the margin; or why no candidate is recommended."""
    name = _envelope_name(case, decision)
    winner, second = decision.winner, decision.runner_up
    if winner is None:
        return f"{name}: no recommendation, {refusal_text(decision)}."
    edge = edge_text(winner)
    sentence = (
        f"{name}: use {_choice(winner)}{edge}; its worst-case AE is "
        f"{ae_text(decision, winner.worst_ae)} and at least "
        f"{100 * winner.worst_share_low:.1f} % of drawn robots stay on the path in every "
        f"condition (Wilson 95 % lower bound, {counted(decision.draws, 'draw')} per condition)"
    )
    if second is None:
        return f"{sentence}; no other controller qualifies."
    return (
        f"{sentence}; the runner-up, {_choice(second)}, has a worst-case AE of "
        f"{ae_text(decision, second.worst_ae)}: {ae_text(decision, decision.ae_difference)} "
        f"more than the winner's{ratio_text(decision, ' ({:.3g} times)')}."
    )


def display_envelopes(study: DecisionStudy) -> pd.DataFrame:
    """``decision.csv``: the study's table with the units in the column names and ``reason``:
    why no candidate was chosen (empty when one was)."""
    unit = study.tradeoff.ae_unit
    reasons = [refusal_text(study.decisions[name]) or "" for name in study.table.envelope]
    return study.table.assign(reason=reasons).rename(
        columns={
            "h_max": "h_max_s",
            "omega_n": "omega_n_rad_per_s",
            "k1": "k1_per_s2",
            "k2": "k2_per_s",
            "worst_ae": with_unit("worst_ae", unit),
            "runner_up_omega_n": "runner_up_omega_n_rad_per_s",
            "runner_up_worst_ae": with_unit("runner_up_worst_ae", unit),
            "ae_difference": with_unit("ae_difference", unit),
        }
    )


def _candidates(study: DecisionStudy) -> pd.DataFrame:
    """Every envelope's candidates and conditions (the rule's table), with the envelope."""
    frames = [
        decision_table(decision).assign(envelope=name) for name, decision in study.decisions.items()
    ]
    table = pd.concat(frames, ignore_index=True)
    table = table[["envelope", *(c for c in table.columns if c != "envelope")]]
    return table.rename(columns=decision_columns(study.tradeoff.ae_unit))


def write_decision_study(study: DecisionStudy, folder: str | Path) -> list[Path]:
    """Write ``decision.csv``, ``candidates.csv`` and ``report.html`` into ``folder`` and the
    trade-off's files into ``folder/tradeoff``; return their paths."""
    folder = claim_output_folder(folder)
    mine = [
        write_frame(display_envelopes(study), folder / "decision.csv"),
        write_frame(_candidates(study), folder / "candidates.csv"),
        _report(study).write(folder / "report.html"),
    ]
    record_outputs(folder, mine)
    return [*mine, *write_tradeoff(study.tradeoff, folder / "tradeoff")]


def _report(study: DecisionStudy) -> HtmlReport:
    tradeoff = study.tradeoff
    first = next(iter(study.decisions.values()))
    report = HtmlReport("Which controller for which delay envelope")
    report.paragraph(
        "For the payload robot of the paper's experiment (scenario "
        f"{tradeoff.scenario.name}): which controller and which outer-loop gains to use for each "
        "delay envelope of decision.csv (a largest delay and how well the delay is known). The "
        "rule: among the candidates (AROLC, the outer loop and the predictor PCONf at each gain "
        "point of the trade-off, K1 = ω_n² I, K2 = 2ζω_n I), those whose share of drawn robots "
        f"on the path has a Wilson 95 % lower bound of at least {first.required_share:g} in "
        "every condition of the envelope qualify; the winner has the smallest worst-case AE (the "
        "largest over the conditions of the median AE of the runs on the path); the runner-up "
        "is the best qualifying candidate of another controller."
    )
    report.bullets(
        decision_sentence(study.cases[name], decision) for name, decision in study.decisions.items()
    )
    report.table(
        display_envelopes(study),
        caption="decision.csv: one row per envelope; worst_share_low is the winner's smallest "
        "Wilson lower bound of the share on the path over the conditions; ae_difference and "
        "ae_ratio compare the runner-up's worst-case AE with the winner's; reason: why no "
        "candidate was chosen.",
    )
    drawn = ", ".join(tradeoff.random) or "nothing"
    report.settings(
        {
            "trade-off": f"tradeoff/report.html: ζ = {tradeoff.zeta:g}, ω_n in "
            + ", ".join(f"{w:.3g}" for w in tradeoff.omegas)
            + f" rad/s, {tradeoff.draws} drawn robots per point and controller",
            "drawn": f"{drawn}; seed {tradeoff.seed}",
            "on the path": f"run ok and mean |e1| over the whole run: {threshold_text(tradeoff)}",
            "conditions": "constant true delays; AROLC and the outer loop are told nothing, "
            "PCONf (under a constant delay the law of PCON told the same delay) is told a "
            "delay as listed under each envelope below",
            "draws": f"{first.draws} per candidate and condition (the lower bound can reach "
            f"{first.required_share:g} only from {first.draws_needed} on)",
            "version": f"delaytrack {__version__}; wall time {study.seconds:.1f} s; units "
            f"{study.computed} computed, {study.resumed} resumed",
        }
    )
    for name, decision in study.decisions.items():
        with report.folded(f"{_envelope_name(study.cases[name], decision)}: every candidate"):
            report.paragraph(f"Conditions: {conditions_text(decision.envelope, 'PCONf')}.")
            report.table(
                candidates_table(decision).rename(columns=decision_columns(study.tradeoff.ae_unit)),
                caption="One row per candidate, best first (candidates.csv has every condition).",
            )
    return report
