"""The margins job: the margins study (:mod:`delaytrack.experiments.margins`) run and its report
(:mod:`delaytrack.report.margins`) written to ``<out>/margins/``."""

from __future__ import annotations

from pathlib import Path

from delaytrack._output import check_output_folder, check_results_root
from delaytrack.experiments.margins import FOLDER, MarginStudy, run_study
from delaytrack.report.margins import write_study

__all__ = ["reproduce"]


def reproduce(
    out: str | Path = "results", *, duration: float | None = None, progress: bool = True
) -> tuple[MarginStudy, list[Path]]:
    """Run the job and write ``<out>/margins/``; return the study and the files written."""
    folder = check_output_folder(check_results_root(out, "out") / FOLDER)
    study = run_study(duration=duration, progress=progress)
    return study, write_study(study, folder)
