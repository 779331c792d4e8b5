"""The decision rule's tables and conditions as the trade-off's page and the decision study's
page show them, made from a :class:`~delaytrack.experiments.decision.Decision` (this module
computes nothing)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from delaytrack.units import with_unit

if TYPE_CHECKING:
    from delaytrack.experiments.decision import Envelope

__all__ = ["conditions_text", "decision_columns"]


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


def conditions_text(envelope: Envelope, predictor: str) -> str:
    """The envelope's conditions in words: each true delay with what ``predictor`` (as the page
    names it) is told."""
    return "; ".join(
        f"true delay {h:g} s, {predictor} told {told:g} s"
        for h in envelope.delays
        for told in envelope.told
    )
