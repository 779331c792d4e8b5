"""``delaytrack sweep``: many runs over a grid and seeded random draws, resumable."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from delaytrack._cli_options import integer, quiet_argument, trust_argument
from delaytrack._output import check_output_folder, plain_folder_name, record_outputs
from delaytrack._words import counted
from delaytrack.cli._scenarios import trusted
from delaytrack.cli._usage import UsageError, flagged
from delaytrack.warning import one_line

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["add_command", "run"]


def add_command(commands: argparse._SubParsersAction) -> None:
    """Add ``sweep`` to ``commands``."""
    command = commands.add_parser(
        "sweep",
        help="many runs over a grid and seeded random draws, resumable, locally or on Dask",
        description="Expand a sweep file (a base scenario, [grid] and [random] over its keys; "
        "see docs/sweeps.md) into work units and run them: <out>/parts/ gets one Parquet part "
        "per finished unit, written atomically; running the same command again skips finished "
        "units. At the end: runs.parquet/.csv, summary.csv (per controller x delay class), "
        "figures/ and report.html.",
    )
    command.add_argument(
        "spec",
        metavar="SWEEP",
        help="sweep file (TOML: a base scenario with [grid] and [random] tables over its keys; "
        "not a scenario file)",
    )
    command.add_argument(
        "--out", default=None, metavar="DIR", help="results folder (default results/sweeps/<name>)"
    )
    command.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="run the units on a Dask cluster: a scheduler address (tcp://host:8786) or "
        "'local-cluster' to start one here (needs delaytrack[dask]); default: this process, all "
        "cores",
    )
    command.add_argument(
        "--workers",
        default=None,
        metavar="N",
        help="threads of the local executor, or worker processes of --scheduler local-cluster "
        "(default: all cores)",
    )
    trust_argument(command)
    quiet_argument(command)
    command.set_defaults(handler=run)


def _count(flag: str, text: str) -> int:
    """``text`` as an integer >= 1 in decimal digits (:func:`integer`'s rule), else refused."""
    try:
        value = integer(text)
    except argparse.ArgumentTypeError:
        value = 0
    if value < 1:
        raise UsageError(f"{flag} must be a positive integer; got {text!r}")
    return value


def unfinished_runs_line(status: pd.Series) -> str:
    """``"  6 of 8 runs did not finish (4 left the path, 2 diverged): ..."``, or ``""`` when
    every run finished: what a sweep's empty metrics are."""
    stopped = status[status != "ok"]
    if stopped.empty:
        return ""
    kinds = ", ".join(f"{count} {name}" for name, count in stopped.value_counts().items())
    return (
        f"  {len(stopped)} of {counted(len(status), 'run')} did not finish ({kinds}): their "
        "metrics are empty in runs.csv, and summary.csv counts those that diverged or left "
        "the path in its divergence rate"
    )


def _folder(args: argparse.Namespace) -> Path:
    """``--out``, else ``results/sweeps/<sweep file name>``, checked."""
    if args.out is not None:
        return check_output_folder(args.out, "--out")
    name = plain_folder_name(Path(args.spec).stem, f"sweep file {args.spec!r}")
    return check_output_folder(Path("results/sweeps") / name, "the results folder")


def run(args: argparse.Namespace) -> int:
    """Run the sweep's units (skipping finished ones), write its tables, figures and report."""
    from delaytrack.report.sweep import write_sweep_outputs
    from delaytrack.sweeps import (
        SweepError,
        SweepSpec,
        SweepUnitsFailed,
        make_executor,
        run_sweep,
    )
    from delaytrack.sweeps.executors import checked_scheduler

    workers = None if args.workers is None else _count("--workers", args.workers)
    trust = trusted(args)
    try:
        checked_scheduler(args.scheduler, workers)
    except SweepError as error:
        raise flagged(error, {"workers": "--workers"}) from None
    folder = _folder(args)
    spec = SweepSpec.from_toml(args.spec, trust=trust, progress=not args.quiet)
    print(f"sweep {args.spec}: {len(spec.runs)} runs in {len(spec.units())} units -> {folder}/")
    if not args.quiet:  # the size of the work before it starts, as simulate says its own
        print(f"delaytrack: sweeping {spec.size_summary()}", file=sys.stderr, flush=True)
    executor = make_executor(args.scheduler, workers=workers, progress=not args.quiet)
    try:
        outcome = run_sweep(spec, folder, executor=executor, progress=not args.quiet)
    except KeyboardInterrupt as interrupted:
        print(one_line(str(interrupted)) or "interrupted", file=sys.stderr)
        return 130
    except SweepUnitsFailed as failed:
        print(one_line(f"error: {failed}"), file=sys.stderr)
        return 1
    files = write_sweep_outputs(outcome)
    record_outputs(folder, [*files, folder / "runs.parquet", folder / "runs.csv"])
    print(
        f"{counted(len(spec.runs), 'run')} done ({counted(outcome.computed, 'unit')} computed, "
        f"{outcome.resumed} found "
        f"finished) in {outcome.seconds:.1f} s on {outcome.executor}"
    )
    unfinished = unfinished_runs_line(outcome.runs.status)
    if unfinished:
        print(unfinished)
    for name, reason in outcome.rejected.items():
        print(f"  part {name} did not count: {reason}")
    print(f"wrote runs.parquet, runs.csv and {len(files)} files to {folder}/")
    print(f"report: {folder / 'report.html'}")
    return 0
