"""``delaytrack reproduce``: the paper's robot experiment, and the two-link, margins,
robustness and decision jobs."""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from delaytrack._cli_options import quiet_argument
from delaytrack._compile.helper_ahead import helper_ahead
from delaytrack._output import OutputFolderError, check_output_folder, check_results_root
from delaytrack._validation import ArgumentError
from delaytrack._words import table_text
from delaytrack.cli._numbers import scalar
from delaytrack.cli._usage import UsageError, flagged

__all__ = ["add_command", "run"]

#: The flag of the jobs' ``duration`` argument (and of the scenario key it sets).
_DURATION = {"duration": "--duration"}


def add_command(commands: argparse._SubParsersAction) -> None:
    """Add ``reproduce`` to ``commands``."""
    command = commands.add_parser(
        "reproduce",
        help="the main job: the paper's robot experiment (S1-S4, AROLC vs PCON/PCONf)",
        description="Run the paper's robot experiment and write <out>/paper/ and "
        "<out>/paper-literal/: summary.csv, tables.md, dt_check.csv, figures and a "
        "self-contained report.html. --job two-link runs the earlier two-link job into "
        "<out>/two-link/ instead; --job margins compares certified, exact and empirical delay "
        "margins over a grid of gains into <out>/margins/; --job decision says which controller "
        "and gains to use for the paper's delay envelopes into <out>/decision/.",
    )
    command.add_argument(
        "--out", default="results", metavar="DIR", help="output root (default results)"
    )
    command.add_argument(
        "--duration",
        default=None,
        metavar="SECONDS",
        help="override the duration (paper: 60 s, a multiple of T_c = 10 ms, at most 600 s; "
        "two-link: 30 s, a multiple of 2 ms; margins: 30 s, a multiple of 2 ms); for quick checks",
    )
    command.add_argument(
        "--job",
        choices=("paper", "two-link", "margins", "robustness", "decision"),
        default="paper",
        help="which job to run (default paper, which includes the robustness study at "
        "--size; robustness: the study alone into <out>/robustness/; decision: the trade-off "
        "on robot_S1 and the decision rule for S1-S4 (delay known, known within ±25 %%) and "
        "the delay unknown up to 300 ms, into <out>/decision/)",
    )
    command.add_argument(
        "--size",
        choices=("default", "full"),
        default="default",
        help="size of the robustness study (default: about 6400 runs, under a minute on two "
        "cores once compiled; full: ten times the draws, meant for a Dask cluster) and of the "
        "decision study (default: 5 gain points, 80 draws per condition, about 14 400 runs; "
        "full: 9 gain points and ten times the draws)",
    )
    command.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="run the robustness (or decision) study's sweeps on a Dask cluster: a scheduler "
        "address "
        "(tcp://host:8786) or local-cluster",
    )
    command.add_argument(
        "--no-robustness",
        action="store_true",
        help="paper job without the robustness study (its report then judges one run per case)",
    )
    command.add_argument("--no-dt-check", action="store_true", help="skip the dt/2 rerun")
    command.add_argument(
        "--decision",
        action="store_true",
        help="paper job with the decision study (into <out>/decision/, resumed if --job "
        "decision ran there): its report then says which controller and gains to use for each "
        "of the paper's delay envelopes",
    )
    command.add_argument(
        "--no-contact",
        action="store_true",
        help="skip the runs on the robot with real wheels (MuJoCo; run by default when it is "
        "installed)",
    )
    command.add_argument(
        "--gains",
        default=None,
        metavar="PATH",
        help="gains file to use instead of the shipped one (written by tune-baselines)",
    )
    quiet_argument(command)
    command.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Check ``--gains``, ``--out`` and ``--duration``, then run the job ``--job``."""
    if args.gains is not None:
        args.gains = _checked_gains(args.gains)
    args.out = str(check_results_root(args.out, "--out"))
    try:
        with helper_ahead():  # its first compile's helper, started while the job sets up
            return _job(args)
    except OutputFolderError as error:  # a job's folder under --out, checked before computing
        raise UsageError(f"--out {args.out!r}: {error}") from None


def _checked_gains(text: str) -> Path:
    """``--gains``: a gains file with every controller and gain set, each checked
    (:func:`~delaytrack.experiments.tuning.load_tuning_record`), as an absolute path."""
    from delaytrack.experiments.tuning import GAIN_SETS, KINDS, GainsFileError, load_gains

    path = Path(text).resolve()
    if not path.is_file():
        raise UsageError(f"--gains {text!r} is not a file; give a file written by tune-baselines")
    try:
        gains = load_gains(path)
    except GainsFileError as error:
        raise UsageError(f"--gains {text!r}: {error.problem}") from None
    missing = [
        f"{kind} ({gain_set})"
        for kind in KINDS
        for gain_set in GAIN_SETS
        if gain_set not in gains.get(kind, {})
    ]
    if missing:
        raise UsageError(
            f"--gains {text!r} lacks {', '.join(missing)}; write it with delaytrack tune-baselines"
        )
    return path


def _job(args: argparse.Namespace) -> int:
    """Read ``--duration`` (positive; each job checks its own grid) and run the job."""
    if args.duration is not None:
        args.duration = scalar("--duration", args.duration)
        if args.duration <= 0:
            raise UsageError(
                f"--duration must be a positive number of seconds; got {args.duration:g}"
            )
    _check_flags_apply(args)
    if args.job == "two-link":
        return _two_link(args)
    if args.job == "margins":
        return _margins(args)
    executor = _study_executor(args)
    if args.job == "robustness":
        return _robustness(args, executor)
    if args.job == "decision":
        return _decision(args, executor)
    return _paper(args, executor)


#: The jobs each flag changes; given to another job, it is refused rather than ignored.
_FLAG_JOBS = {
    "duration": ("--duration", ("paper", "two-link", "margins")),
    "size": ("--size", ("paper", "robustness", "decision")),
    "scheduler": ("--scheduler", ("paper", "robustness", "decision")),
    "no_robustness": ("--no-robustness", ("paper",)),
    "no_dt_check": ("--no-dt-check", ("paper", "two-link")),
    "decision": ("--decision", ("paper",)),
    "no_contact": ("--no-contact", ("paper",)),
    "gains": ("--gains", ("paper", "robustness")),
}


def _check_flags_apply(args: argparse.Namespace) -> None:
    """Refuse a flag given to a job it does not change (``--scheduler`` with ``--job
    two-link``; ``--size`` or ``--scheduler`` with a paper job that runs no study), naming
    the jobs it applies to: a flag silently ignored lets a user believe it was used."""
    defaults = {"duration": None, "size": "default", "scheduler": None, "gains": None}
    for name, (flag, jobs) in _FLAG_JOBS.items():
        if getattr(args, name) == defaults.get(name, False):  # not given
            continue
        if args.job not in jobs:
            why = " (its runs are 60 s)" if name == "duration" else ""
            named = jobs[0] if len(jobs) == 1 else f"{', '.join(jobs[:-1])} or {jobs[-1]}"
            raise UsageError(
                f"{flag} does not apply to --job {args.job}{why}; it applies to --job {named}"
            )
        if name in ("size", "scheduler") and args.job == "paper":
            if args.no_robustness and not args.decision:
                raise UsageError(
                    f"{flag} sets the robustness and decision studies, which this paper job "
                    "does not run (--no-robustness, no --decision)"
                )


def _study_executor(args: argparse.Namespace):
    """A factory of the robustness study's executors (``--scheduler``), checked before running."""
    from delaytrack.sweeps import SweepError, make_executor
    from delaytrack.sweeps.executors import checked_scheduler

    try:
        checked_scheduler(args.scheduler, None)
    except SweepError as error:
        raise UsageError(str(error)) from None
    return lambda: make_executor(args.scheduler, progress=not args.quiet)


def _paper(args: argparse.Namespace, executor) -> int:
    """The paper job: ``<out>/paper-literal/``, ``<out>/robustness/`` and ``<out>/paper/``."""
    from delaytrack.experiments.paper import DURATION
    from delaytrack.jobs.paper import reproduce
    from delaytrack.report.dt_check import dt_check_line
    from delaytrack.report.paper import summary_text

    start = time.perf_counter()
    try:
        studies = reproduce(
            args.out,
            duration=DURATION if args.duration is None else args.duration,
            check_dt=not args.no_dt_check,
            progress=not args.quiet,
            contact=False if args.no_contact else None,
            robustness=None if args.no_robustness else args.size,
            executor=executor,
            gains=args.gains,
            decision=args.size if args.decision else None,
        )
    except ArgumentError as error:  # a --duration off the controller's grid, checked first
        if error.argument not in _DURATION:
            raise
        raise flagged(error, _DURATION) from None
    seconds = time.perf_counter() - start
    out = Path(args.out)
    print(
        f"paper job done in {seconds:.1f} s wall time; wrote {out / 'paper'}/ and "
        f"{out / 'paper-literal'}/"
    )
    study = studies["consistent"]
    print(summary_text(study.summary, study.findings.stopped, study.reference))
    if study.dt_verdict is not None:
        print(dt_check_line(study.dt_verdict))
    if study.contact is not None:
        from delaytrack.report.contact import contact_paragraphs

        print("with contact physics (MuJoCo): " + contact_paragraphs(study.findings.contact)[0])
    print(f"report: {out / 'paper' / 'report.html'}")
    return 0


def _robustness(args: argparse.Namespace, executor) -> int:
    """The robustness study alone, into ``<out>/robustness/``."""
    from delaytrack.jobs.robustness import run_robustness
    from delaytrack.report.robustness import findings

    folder = check_output_folder(Path(args.out) / "robustness", "--out")
    start = time.perf_counter()
    study = run_robustness(
        folder, size=args.size, executor=executor, progress=not args.quiet, gains=args.gains
    )
    seconds = time.perf_counter() - start
    print(f"robustness job done in {seconds:.1f} s wall time; wrote {folder}/")
    for line in findings(study):
        print(f"- {line}")
    print(f"report: {folder / 'report.html'}")
    return 0


def _decision(args: argparse.Namespace, executor) -> int:
    """The decision study, into ``<out>/decision/``."""
    from delaytrack.experiments.decision_study import FOLDER
    from delaytrack.jobs.decision_study import reproduce
    from delaytrack.report.decision_study import decision_sentence

    study = _timed(
        "decision",
        FOLDER,
        args,
        lambda: reproduce(args.out, size=args.size, executor=executor, progress=not args.quiet),
    )
    for name, decision in study.decisions.items():
        print(f"- {decision_sentence(study.cases[name], decision)}")
    print(f"report: {Path(args.out) / FOLDER / 'report.html'}")
    return 0


def _timed(job: str, folder: str, args: argparse.Namespace, run: Callable[[], tuple]) -> Any:
    """Run a job's ``reproduce``, print how long it took and where it wrote; its study."""
    start = time.perf_counter()
    study, files = run()
    seconds = time.perf_counter() - start
    print(
        f"{job} job done in {seconds:.1f} s wall time; wrote {len(files)} files to "
        f"{Path(args.out) / folder}/"
    )
    return study


def _two_link(args: argparse.Namespace) -> int:
    """The two-link job, into ``<out>/two-link/``."""
    from delaytrack.experiments.two_link import FOLDER
    from delaytrack.jobs.two_link import reproduce
    from delaytrack.report.dt_check import dt_check_line
    from delaytrack.scenario import ScenarioError

    try:
        study = _timed(
            "two-link",
            FOLDER,
            args,
            lambda: reproduce(
                args.out,
                duration=args.duration,
                check_dt=not args.no_dt_check,
                progress=not args.quiet,
            ),
        )
    except ScenarioError as error:  # a --duration the job's scenarios refuse
        raise flagged(error, keys=_DURATION) from None
    columns = ["scenario", "controller", "ae_q1", "ae_q2", "tv", "status"]
    print(table_text(study.summary[columns].rename(columns=study.columns_with_units)))
    if study.dt_verdict is not None:
        print(dt_check_line(study.dt_verdict))
    print(f"report: {Path(args.out) / FOLDER / 'report.html'}")
    return 0


def _margins(args: argparse.Namespace) -> int:
    """The margins job, into ``<out>/margins/``."""
    from delaytrack.experiments.margins import FOLDER
    from delaytrack.jobs.margins import reproduce
    from delaytrack.report.margins import terminal_text

    try:
        study = _timed(
            "margins",
            FOLDER,
            args,
            lambda: reproduce(args.out, duration=args.duration, progress=not args.quiet),
        )
    except ValueError as error:  # a --duration too short for the job's tracking rule
        raise UsageError(f"margins job: {flagged(error, _DURATION)}") from None
    print(terminal_text(study))
    print(f"report: {Path(args.out) / FOLDER / 'report.html'}")
    return 0
