"""The tuning's report: the chosen gains as text, one line per controller and gain set, made
from a :class:`~delaytrack.experiments.tuning.TuningStudy` (or a gains file's chosen sets) that
already holds every number quoted here (this module computes none)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from delaytrack.experiments.tuning import recorded_gains_text as gains_text

if TYPE_CHECKING:
    from delaytrack.experiments.tuning import TuningStudy

__all__ = ["chosen_gains_lines", "gains_text"]


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
