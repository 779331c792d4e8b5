"""The paper job: the paper's experiment (:mod:`delaytrack.experiments.paper`) run and its report
(:mod:`delaytrack.report.paper`) written, and the whole of ``delaytrack reproduce``: the literal
and the consistent run, the robustness study and, when asked, the decision study."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pandas as pd

from delaytrack._output import check_output_folder, check_results_root
from delaytrack._validation import ArgumentError, integer_multiple
from delaytrack.experiments import tuning
from delaytrack.experiments.paper import PaperStudy, contact_ahead, run_study
from delaytrack.experiments.paper_setup import DURATION, T_C
from delaytrack.experiments.robustness import RobustnessStudy
from delaytrack.jobs._background import second_process
from delaytrack.jobs.robustness import run_robustness
from delaytrack.report.paper import write_study

if TYPE_CHECKING:
    from delaytrack.experiments.decision_study import DecisionStudy

__all__ = ["reproduce", "run_paper"]


def run_paper(
    out_dir: str | Path,
    *,
    reference: str = "consistent",
    duration: float = DURATION,
    progress: bool = True,
    check_dt: bool = True,
    literal_summary: pd.DataFrame | None = None,
    contact: bool | None = None,
    robustness: RobustnessStudy | None = None,
    gains: tuning.GainsSource = None,
    decision: DecisionStudy | None = None,
) -> PaperStudy:
    """Run the paper's experiment and write ``out_dir`` (the files of
    :mod:`delaytrack.experiments.paper`'s docstring); return the study.
    ``gains``: the gains file (or its record) of the tuned controllers; the shipped one by
    default. ``robustness`` and ``decision`` (studies already run) add their sections to the
    report."""
    study = _paper_study(reference, duration, progress, check_dt, gains, contact)
    write_study(
        study,
        out_dir,
        literal_summary=literal_summary,
        robustness=robustness,
        decision=decision,
    )
    return study


def _paper_study(
    reference: str,
    duration: float,
    progress: bool,
    check_dt: bool,
    gains: tuning.GainsSource,
    contact: bool | None = None,
) -> PaperStudy:
    """The paper's experiment run (:func:`~delaytrack.experiments.paper.run_study`) after
    ``duration`` is checked."""
    if not (math.isfinite(duration) and duration > 0):
        raise ValueError(f"duration must be a positive number of seconds; got {duration!r}")
    return run_study(
        reference=reference,
        duration=duration,
        progress=progress,
        check_dt=check_dt,
        gains_path=gains,
        contact=contact,
    )


#: Longest ``duration`` of the paper job (s): ten times the paper's runs. The job keeps every
#: tick of every run (about 1 MB of memory a second of run, measured) for its report.
MAX_DURATION = 10 * DURATION


def _check_duration(duration: float) -> None:
    """Refuse a ``duration`` that is not a positive integer multiple of the controller period
    :data:`T_C` (the engine ends every run on a controller tick), or beyond
    :data:`MAX_DURATION`."""
    if duration > MAX_DURATION:  # first: 1e308 is no multiple of T_c, nor worth being one
        raise ArgumentError(
            "duration",
            f"must be at most {MAX_DURATION:g} s (ten times the paper's {DURATION:g} s runs: the "
            f"job keeps every tick of every run for its report); got {duration:g}",
        )
    if integer_multiple(duration, T_C) is None:
        raise ArgumentError(
            "duration",
            f"must be a positive integer multiple of 'T_c' = {T_C:g} s; got {duration:g}",
        )


def reproduce(
    out: str | Path = "results",
    *,
    duration: float = DURATION,
    check_dt: bool = True,
    progress: bool = True,
    contact: bool | None = None,
    robustness: str | None = "default",
    executor: Any = None,
    gains: tuning.GainsSource = None,
    decision: str | DecisionStudy | None = None,
) -> dict[str, Any]:
    """``<out>/paper-literal/``, ``<out>/robustness/`` (the robustness study at size
    ``robustness``; None skips it) and ``<out>/paper/`` (whose report cites the literal run and
    the study's verdicts, and has the runs with contact physics when ``contact``; by default
    when MuJoCo is installed), with the tuned gains of ``gains`` (a gains file; the shipped one
    by default); ``decision``, a decision study already run
    (:func:`~delaytrack.experiments.decision_study.run_decision_study`) or the size of one to
    run into ``<out>/decision/`` (resumed), adds its section to ``<out>/paper/``'s report.
    Returns ``{"consistent", "literal", "robustness"}``.
    ``duration`` must be a positive integer multiple of :data:`T_C`; ``out`` must be new, empty
    or hold only results of this toolkit, and each job's folder new, empty or its own earlier
    results (all checked before anything runs)."""
    _check_duration(duration)
    root = check_results_root(out, "out")
    gains = tuning.load_tuning_record(gains)
    folders = {
        name: check_output_folder(root / name)
        for name in (
            "paper-literal",
            "paper",
            *(("robustness",) if robustness else ()),
            *(("decision",) if isinstance(decision, str) else ()),
        )
    }
    if isinstance(decision, str):
        from delaytrack.jobs import decision_study

        decision, _ = decision_study.reproduce(
            out, size=decision, executor=executor, progress=progress
        )
    # The literal run's report is drawn in a second process, when a core is idle, while this
    # one runs the next studies; started once the literal run's first compile is done (which
    # takes both cores), it imports the report's modules while the literal run runs.
    # The literal run's first compile also compiles the contact runs' integrator, if they run.
    with (
        second_process(("delaytrack.report.paper",), after_first_compile=True) as second,
        contact_ahead(duration, contact),
    ):
        literal = _paper_study("literal", duration, progress, check_dt, gains)
        second.run(write_study, literal, folders["paper-literal"])
        study = (
            run_robustness(
                folders["robustness"],
                size=robustness,
                executor=executor,
                progress=progress,
                gains=gains,
            )
            if robustness
            else None
        )
        consistent = run_paper(
            folders["paper"],
            reference="consistent",
            duration=duration,
            progress=progress,
            check_dt=check_dt,
            literal_summary=literal.summary,
            contact=contact,
            robustness=study,
            gains=gains,
            decision=decision,
        )
    return {"consistent": consistent, "literal": literal, "robustness": study}
