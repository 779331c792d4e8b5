"""The two-link job: the two-link study (:mod:`delaytrack.experiments.two_link`) run and its
report (:mod:`delaytrack.report.two_link`) written to ``<out>/two-link/``."""

from __future__ import annotations

from pathlib import Path

from delaytrack._output import check_output_folder, check_results_root
from delaytrack.experiments.two_link import FOLDER, TwoLinkStudy, run_study
from delaytrack.report.two_link import write_study

__all__ = ["reproduce"]


def reproduce(
    out: str | Path = "results",
    *,
    duration: float | None = None,
    check_dt: bool = True,
    progress: bool = True,
) -> tuple[TwoLinkStudy, list[Path]]:
    """Run the job and write ``<out>/two-link/``; return the study and the files written."""
    folder = check_output_folder(check_results_root(out, "out") / FOLDER)
    study = run_study(duration=duration, check_dt=check_dt, progress=progress)
    files = write_study(study, folder)
    return study, files
