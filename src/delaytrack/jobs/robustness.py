"""The robustness job: the robustness study (:mod:`delaytrack.experiments.robustness`) run (or
resumed) and its report (:mod:`delaytrack.report.robustness`) written."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from delaytrack.experiments import tuning
from delaytrack.experiments.robustness import RobustnessStudy, StudySize, run_study
from delaytrack.report.robustness import write_robustness

__all__ = ["run_robustness"]


def run_robustness(
    out: str | Path,
    *,
    size: str | StudySize = "default",
    executor: Any = None,
    progress: bool = True,
    gains: tuning.GainsSource = None,
) -> RobustnessStudy:
    """Run (or resume) the study's sweeps into ``out/sweeps/<name>/``
    (:func:`delaytrack.experiments.robustness.run_study`, which takes the same arguments) and
    write its tables, figure and report into ``out``
    (:func:`~delaytrack.report.robustness.write_robustness`); return the study."""
    study = run_study(out, size=size, executor=executor, progress=progress, gains=gains)
    write_robustness(study, out)
    return study
