"""The decision job: the decision study (:mod:`delaytrack.experiments.decision_study`) run (or
resumed) into ``<out>/decision/`` and its report (:mod:`delaytrack.report.decision_study`)
written there."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from delaytrack._output import check_output_folder, check_results_root
from delaytrack.experiments.decision_study import (
    FOLDER,
    DecisionSize,
    DecisionStudy,
    run_decision_study,
    study_size,
)
from delaytrack.report.decision_study import write_decision_study
from delaytrack.sweeps.executors import Executor

__all__ = ["reproduce"]


def reproduce(
    out: str | Path = "results",
    *,
    size: str | DecisionSize = "default",
    executor: Callable[[], Executor] | None = None,
    progress: bool = True,
) -> tuple[DecisionStudy, list[Path]]:
    """``delaytrack reproduce --job decision``: run the study into ``<out>/decision/`` and write
    its files there; return the study and the files written. ``size`` is checked, and ``out``
    and the job's folder, before anything runs."""
    size = study_size(size)
    folder = check_output_folder(check_results_root(out, "out") / FOLDER)
    study = run_decision_study(folder, size=size, executor=executor, progress=progress)
    return study, write_decision_study(study, folder)
