"""``delaytrack tradeoff``: the accuracy–delay-margin trade-off of a scenario's gains."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from delaytrack._cli_options import (
    count,
    decimal,
    integer,
    quiet_argument,
    trust_argument,
    within,
)
from delaytrack._output import check_output_folder, plain_folder_name
from delaytrack._words import counted, quantity_text
from delaytrack.cli._numbers import numbers
from delaytrack.cli._scenarios import scenario_source, trusted
from delaytrack.cli._usage import UsageError, flagged
from delaytrack.warning import one_line

if TYPE_CHECKING:
    from delaytrack.experiments.decision import Envelope

__all__ = ["add_command", "run"]

#: The flags of :func:`~delaytrack.experiments.tradeoff.run_tradeoff`'s arguments.
_FLAGS = {
    "zeta": "--zeta",
    "omegas": "--omega",
    "draws": "--draws",
    "threshold": "--threshold",
    "upper": "--upper",
}
#: The flags of :class:`~delaytrack.experiments.decision.Envelope`'s fields.
_ENVELOPE_FLAGS = {"h_max": "--envelope", "knowledge": "--knowledge"}


def add_command(commands: argparse._SubParsersAction) -> None:
    """Add ``tradeoff`` to ``commands``."""
    command = commands.add_parser(
        "tradeoff",
        help="accuracy against delay margin over the outer-loop gains (K1 = w^2 I, "
        "K2 = 2 zeta w I), per controller, with the Pareto front",
        description="Sweep the outer-loop gains of a scenario along K1 = w_n^2 I, "
        "K2 = 2 zeta w_n I and report, per gain point and controller (AROLC, the outer loop, "
        "PCON and PCONf when the model supports them): Theorem 1's h_m, the exact margin of "
        "the linear outer loop, the empirical constant-delay margin, and at the scenario's "
        "delay the share of drawn robots on the path (Wilson 95 %), median AE and TV; the "
        "Pareto front of AE against the empirical margin. The draws run on the sweep "
        "machinery: resumable, --scheduler for Dask. With --envelope, also decide which "
        "controller and gains to use for that delay envelope: the smallest worst-case AE among "
        "those on the path in >= 95 % of the drawn robots by the Wilson lower bound. See "
        "docs/tradeoff.md.",
    )
    command.add_argument(
        "scenario", metavar="SCENARIO", help="scenario .toml file or built-in name"
    )
    command.add_argument(
        "--zeta",
        type=within(decimal, "a damping ratio > 0", lambda v: v > 0),
        default=1.0,
        metavar="Z",
        help="damping ratio of the family (default 1)",
    )
    command.add_argument(
        "--omega",
        nargs=3,
        default=None,
        metavar=("LO", "HI", "N"),
        help="N log-spaced natural frequencies from LO to HI rad/s (default: the scenario's "
        "own divided and multiplied by 4, 7 points)",
    )
    command.add_argument(
        "--draws",
        type=count,
        default=None,
        metavar="N",
        help="robots drawn per point and controller (default 40; one run when the scenario "
        "has nothing to draw), and per condition for --envelope's decision unless "
        "--decision-draws is given",
    )
    command.add_argument(
        "--decision-draws",
        type=count,
        default=None,
        metavar="N",
        help="with --envelope: robots drawn per condition for the decision (default --draws, "
        "or 80 without it; one run when the scenario has nothing to draw)",
    )
    command.add_argument(
        "--threshold",
        default="1",
        metavar="VALUE",
        help="largest mean |e1| over the run that counts as on the path, in each scored "
        "coordinate's unit: one number, or a comma list of one per scored coordinate (those "
        "the scenario's error_bound bounds; every coordinate when it has none) (default 1)",
    )
    command.add_argument(
        "--upper",
        type=within(decimal, "seconds > 0", lambda v: v > 0),
        default=None,
        metavar="S",
        help="limit of the empirical margin search (default: 1 s or half the duration)",
    )
    command.add_argument(
        "--envelope",
        type=within(decimal, "a largest delay > 0 (s)", lambda v: v > 0),
        default=None,
        metavar="H_MAX",
        help="decide the controller and gains for delays up to H_MAX s, less than the "
        "scenario's duration (decision.csv and a section of report.html)",
    )
    command.add_argument(
        "--knowledge",
        default=None,
        metavar="KNOWLEDGE",
        help="with --envelope: how well the delay is known, exact, ±X%% or unknown; the "
        "predictors are told the true "
        "delay (exact), a delay off by X %% either way (±X%%, also X%%), or the fixed guess "
        "H_MAX/2 (unknown, the default)",
    )
    command.add_argument(
        "--out",
        default=None,
        metavar="DIR",
        help="results folder (default results/tradeoff/<name>)",
    )
    command.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="run the draws on a Dask cluster: a scheduler address (tcp://host:8786) or "
        "'local-cluster' (needs delaytrack[dask]); default: this process, all cores",
    )
    trust_argument(command)
    quiet_argument(command, "progress")
    command.set_defaults(handler=run)


def _omegas(given: list[str] | None) -> list[float] | None:
    """``--omega LO HI N``: N log-spaced values from LO to HI, 0 < LO <= HI, N >= 1."""
    if given is None:
        return None
    import numpy as np

    from delaytrack.experiments.tradeoff import MAX_OMEGAS

    text = " ".join(given)
    valid = (
        f"LO HI N with 0 < LO <= HI (rad/s) and N an integer from 1 to {MAX_OMEGAS} (N = 1 "
        "needs LO = HI, N > 1 needs LO < HI)"
    )
    try:
        low, high = decimal(given[0]), decimal(given[1])
        count = integer(given[2])
    except argparse.ArgumentTypeError:
        raise UsageError(f"--omega must be {valid}; got {text!r}") from None
    if not (0 < low <= high and 1 <= count <= MAX_OMEGAS and (count > 1) == (low < high)):
        raise UsageError(f"--omega must be {valid}; got {text!r}")
    return [float(v) for v in np.geomspace(low, high, count)]


def _envelope(args: argparse.Namespace) -> Envelope | None:
    """``--envelope H_MAX`` with ``--knowledge`` (unknown by default), or None without it."""
    from delaytrack.experiments.decision import Envelope

    if args.envelope is None:
        if args.knowledge is not None:
            raise UsageError(f"--knowledge {args.knowledge} needs --envelope H_MAX")
        return None
    try:
        return Envelope.from_text(args.envelope, args.knowledge or "unknown")
    except ValueError as error:
        raise flagged(error, _ENVELOPE_FLAGS) from None


def _folder(args: argparse.Namespace, name: str) -> Path:
    if args.out is not None:
        return check_output_folder(args.out, "--out")
    folder = plain_folder_name(name, f"scenario name {name!r}")
    return check_output_folder(Path("results/tradeoff") / folder, "the results folder")


def _one_run_text(flag: str, asked: int) -> str:
    """Why a study ran one run where ``flag`` asked for ``asked`` draws."""
    return (
        f" (not the {asked} of {flag}: the scenario draws nothing, so every draw would be the "
        "same run)"
    )


def run(args: argparse.Namespace) -> int:
    """Run (or resume) the trade-off and write its table, figure and report."""
    from delaytrack.experiments.decision import run_decision
    from delaytrack.experiments.empirical_margin import resolved_text
    from delaytrack.experiments.tradeoff import LOWER_BOUND, run_tradeoff
    from delaytrack.report.tradeoff import decision_lines, write_tradeoff
    from delaytrack.scenario import Scenario
    from delaytrack.sweeps import SweepError, SweepUnitsFailed, make_executor
    from delaytrack.sweeps.executors import checked_scheduler

    omegas = _omegas(args.omega)
    envelope = _envelope(args)
    if args.decision_draws is not None and envelope is None:
        raise UsageError(f"--decision-draws {args.decision_draws} needs --envelope H_MAX")
    bounds = numbers("--threshold", args.threshold)
    threshold = float(bounds[0]) if bounds.size == 1 else [float(b) for b in bounds]
    try:
        checked_scheduler(args.scheduler)
    except SweepError as error:
        raise flagged(error) from None
    scenario = Scenario.from_toml(scenario_source(args.scenario), trust=trusted(args))
    if envelope is not None:  # before the trade-off runs, not after
        try:
            envelope.check_run_length(scenario.duration)
        except ValueError as error:
            raise flagged(error, _ENVELOPE_FLAGS) from None
    folder = _folder(args, scenario.name)
    try:
        study = run_tradeoff(
            scenario,
            folder,
            zeta=args.zeta,
            omegas=omegas,
            draws=args.draws,
            threshold=threshold,
            upper=args.upper,
            executor=make_executor(args.scheduler, progress=not args.quiet),
            progress=not args.quiet,
        )
        decision = (
            None
            if envelope is None
            else run_decision(
                study,
                envelope,
                folder,
                draws=args.draws if args.decision_draws is None else args.decision_draws,
                executor=make_executor(args.scheduler, progress=not args.quiet),
                progress=not args.quiet,
            )
        )
    except KeyboardInterrupt as interrupted:
        print(one_line(str(interrupted)) or "interrupted", file=sys.stderr)
        return 130
    except SweepUnitsFailed as failed:
        print(one_line(f"error: {failed}"), file=sys.stderr)
        return 1
    except ValueError as error:
        raise flagged(error, _FLAGS) from None
    files = write_tradeoff(study, folder, decision)
    front = study.front
    one_run = (
        _one_run_text("--draws", args.draws)
        if args.draws is not None and study.draws != args.draws
        else ""
    )
    print(
        f"tradeoff {scenario.name}: {counted(len(study.omegas), 'gain point')} x "
        f"{counted(len(study.families), 'controller')}, {counted(study.draws, 'draw')} each"
        f"{one_run}, {study.seconds:.1f} s ({counted(study.computed, 'unit')} computed, "
        f"{study.resumed} resumed)"
    )
    print("Pareto front (empirical margin, median AE):")
    largest = front.ae_median.abs().max()  # every AE in one unit (a robot's m as mm)
    for row in front.itertuples():
        ae = quantity_text(row.ae_median, study.ae_unit, 4, largest=largest)
        print(
            f"  {row.controller:<10} omega_n = {row.omega_n:<8.4g} rad/s  margin = "
            f"{resolved_text(row.empirical_margin, study.resolution)}"
            f"{'+' if row.margin_search == LOWER_BOUND else ''} s  "
            f"AE = {ae}"
        )
    if (front.margin_search == LOWER_BOUND).any():
        print(
            f"  +: a lower bound: the loop did not leave the path up to --upper, {study.upper:g} s"
        )
    table = study.table
    off = table[table.on_path == 0]
    if len(off):
        print(
            f"  {len(off)} of {counted(len(table), 'point')} (gain point x controller) had no "
            "run on the path: no median AE, not on the front (tradeoff.csv lists them)"
        )
    if decision is not None:
        if not decision.drawn and args.decision_draws is not None:
            print(
                "decision: 1 run per condition"
                + _one_run_text("--decision-draws", args.decision_draws)
            )
        print("\n".join(decision_lines(decision)))
    print(f"wrote {len(files)} files to {folder}/; report: {folder / 'report.html'}")
    return 0
