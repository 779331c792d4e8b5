"""The decision rule's tables, conditions and reasons as the trade-off's page and the decision
study's page show them, made from a :class:`~delaytrack.experiments.decision.Decision` (this
module computes nothing: every reason it words is a fact the decision holds)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from delaytrack._words import counted, quantity_text
from delaytrack.units import value_with_unit, with_unit

if TYPE_CHECKING:
    import pandas as pd

    from delaytrack.experiments.decision import Choice, Decision, Envelope, Shortfall

__all__ = [
    "ae_text",
    "candidates_table",
    "conditions_text",
    "decision_columns",
    "decision_table",
    "edge_text",
    "gains_text",
    "ratio_text",
    "refusal_text",
    "shortfall_text",
]

#: The predictors, whose gains are ``κ`` and ``k_b``, not ``K1`` and ``K2``.
_PREDICTORS = ("pcon", "pconf")


def decision_columns(ae_unit: str | None) -> dict[str, str]:
    """The columns of the rule's tables (candidates, candidates and conditions) renamed with
    their units: ``omega_n`` (rad/s), ``k1`` (1/s²), ``k2`` (1/s), ``delay`` and ``told`` (s),
    ``ae_median`` and ``worst_ae`` (``ae_unit``)."""
    return {
        "omega_n": "omega_n_rad_per_s",
        "k1": "k1_per_s2",
        "k2": "k2_per_s",
        "delay": "delay_s",
        "told": "told_s",
        "ae_median": with_unit("ae_median", ae_unit),
        "worst_ae": with_unit("worst_ae", ae_unit),
    }


def gains_text(choice: Choice, digits: int = 4) -> str:
    """The gains an engineer sets for a chosen candidate: ``K1 = k1 I, K2 = k2 I`` for AROLC and
    the outer loop; for a predictor, whose delay-free nominal loop is the same, ``κ = K1/K2`` and
    ``k_b = K2 M̂(q0)`` (``M̂(q0)`` the nominal mass matrix at the initial pose)."""
    if choice.controller in _PREDICTORS:
        return (
            f"κ = {choice.k1 / choice.k2:.{digits}g}, k_b = {choice.k2:.{digits}g} M̂(q0), "
            "M̂(q0) the nominal mass matrix at the initial pose"
        )
    return f"K1 = {choice.k1:.{digits}g} I, K2 = {choice.k2:.{digits}g} I"


def edge_text(choice: Choice) -> str:
    """A note when a chosen candidate's ``ω_n`` is the largest of the sweep ("" otherwise):
    larger gains were not tried, so a more accurate candidate may lie beyond it."""
    if not choice.at_largest_omega_n:
        return ""
    return (
        " (the largest ω_n of the sweep: larger gains were not tried and may be more accurate "
        "still)"
    )


def ratio_text(decision: Decision, template: str) -> str:
    """``template`` filled with the runner-up's worst-case AE over the winner's, or "" when that
    ratio is not defined (the winner's worst-case AE is 0)."""
    return "" if math.isnan(decision.ae_ratio) else template.format(decision.ae_ratio)


def conditions_text(envelope: Envelope, predictor: str) -> str:
    """The envelope's conditions in words: each true delay with what ``predictor`` (as the page
    names it) is told."""
    return "; ".join(
        f"true delay {h:g} s, {predictor} told {told:g} s"
        for h in envelope.delays
        for told in envelope.told
    )


def shortfall_text(shortfall: Shortfall, decision: Decision) -> str:
    """Why a candidate does not qualify: its smallest Wilson lower bound against the required
    share, where, how many robots stayed on the path, and whether its draws were too few."""
    told = "" if math.isnan(shortfall.told) else f", told {shortfall.told:g} s"
    text = (
        f"Wilson lower bound {shortfall.share_low:.3f} < {decision.required_share:g} at "
        f"delay {shortfall.delay:g} s{told} ({shortfall.on_path} of {shortfall.runs} on the path)"
    )
    if shortfall.too_few_draws:
        text += (
            f"; {counted(shortfall.runs, 'draw')} cannot reach it (at least "
            f"{decision.draws_needed})"
        )
    return text


def refusal_text(decision: Decision) -> str | None:
    """Why no candidate was chosen (None when one was): too few draws for the Wilson lower bound
    to reach the required share, or none reaching it, with the closest candidate."""
    refused = decision.refused
    if refused is None:
        return None
    closest = refused.closest
    if not decision.drawn:
        return (
            "no candidate qualifies: the scenario draws nothing, so each condition is one run, "
            f"whose Wilson lower bound cannot exceed {refused.ceiling:.3f} < "
            f"{decision.required_share:g} even on the path; more draws cannot help, only a "
            "scenario with something to draw (the payload robot's payload and friction)"
        )
    if refused.too_few_draws or closest is None:
        return (
            f"no candidate qualifies at this size: with {counted(refused.draws, 'draw')} per "
            "condition the "
            f"Wilson lower bound cannot exceed n/(n + z²) = {refused.ceiling:.3f} "
            f"< {decision.required_share:g} even with every robot on the path; at least "
            f"{decision.draws_needed} draws are needed"
        )
    return (
        f"no candidate qualifies: none stays on the path in at least "
        f"{100 * decision.required_share:g} % of the drawn robots by the Wilson lower bound in "
        f"every condition (closest: {closest.controller} at omega_n = {closest.omega_n:g} "
        f"rad/s, {shortfall_text(closest, decision)})"
    )


def ae_text(decision: Decision, value: float, digits: int = 3) -> str:
    """An AE of ``decision`` with its unit, in the unit the larger worst-case AE of its
    winner and runner-up reads best in (a robot's metres as mm below a metre), so that every
    AE of one decision is in one unit: ``9.51 mm``."""
    chosen = [c.worst_ae for c in (decision.winner, decision.runner_up) if c is not None]
    return quantity_text(value, decision.ae_unit, digits, largest=max(chosen, default=value))


def _why(decision: Decision, table: pd.DataFrame) -> list[str]:
    """Per row of ``table`` (the decision's candidates, or candidates and conditions): why the
    candidate was not chosen; empty for the winner and the runner-up. In the table's unit (the
    AE columns beside it), not scaled as the sentences are."""
    reasons = []
    for row in table.itertuples(index=False):
        if row.status == "excluded":
            reasons.append(
                shortfall_text(decision.shortfalls[row.controller, row.omega_n], decision)
            )
        elif row.status == "qualifies" and decision.winner is not None:
            reasons.append(
                "worst-case AE "
                + value_with_unit(f"{row.worst_ae:.4g}", decision.ae_unit)
                + " against the winner's "
                + value_with_unit(f"{decision.winner.worst_ae:.4g}", decision.ae_unit)
            )
        else:
            reasons.append("")
    return reasons


def candidates_table(decision: Decision) -> pd.DataFrame:
    """The decision's candidates, best first, with ``why``: why each was not chosen."""
    return decision.candidates.assign(why=_why(decision, decision.candidates))


def decision_table(decision: Decision) -> pd.DataFrame:
    """The decision's candidates and conditions (``decision.csv`` of the trade-off), with
    ``why``: why each candidate was not chosen."""
    return decision.table.assign(why=_why(decision, decision.table))
