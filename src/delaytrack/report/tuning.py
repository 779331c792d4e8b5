"""The tuning's report: the chosen gains as text, one line per controller and gain set, made
from a :class:`~delaytrack.experiments.tuning.TuningStudy` (or a gains file's chosen sets) that
already holds every number quoted here (this module computes none)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from delaytrack.experiments.tuning import TuningStudy

__all__ = ["chosen_gains_lines", "gains_text"]


def gains_text(kind: str, gains: Mapping[str, float]) -> str:
    """The gains of one chosen set as text (``κ = 8, k_b = 3 I, ϑ = 0.35 M̂⁻¹``).

    AROLC's read ``k``, ``ζ`` (``zeta``), ``α`` (``alpha``) and the outer loop's ``K1 = k²``,
    ``K2 = 2 ζ k`` they give (``K1``, ``K2``: as in a gains file and in
    :attr:`TuningResult.best <delaytrack.experiments.tuning.TuningResult>`).
    """
    if kind == "AROLC":
        return (
            f"k = {gains['k']:g}, ζ = {gains['zeta']:g} (K1 = {gains['K1']:g} I, "
            f"K2 = {gains['K2']:g} I), α = {gains['alpha']:g}"
        )
    inverse = "M̂_r⁻¹" if kind == "PCON-wheel" else "M̂⁻¹"
    return f"κ = {gains['kappa']:g}, k_b = {gains['k_b']:g} I, ϑ = {gains['c']:g} {inverse}"


def chosen_gains_lines(study: TuningStudy) -> list[str]:
    """One line per controller and gain set: the chosen gains, their objective (the worst mean
    AE over the set's conditions) and whether a chosen gain lies on its grid's edge."""
    lines = []
    for kind, result in study.items():
        for gain_set, best in result.best.items():
            edge = "" if result.inside[gain_set] else ", ON THE GRID'S EDGE"
            lines.append(
                f"{kind} ({gain_set}): {gains_text(kind, best)} "
                f"(worst mean AE {best['objective']:.3g} mm{edge})"
            )
    return lines
