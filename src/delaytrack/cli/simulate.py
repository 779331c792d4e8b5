"""``delaytrack simulate``: run one scenario file and write a results folder."""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from delaytrack._cli_options import quiet_argument, trust_argument
from delaytrack._output import check_output_folder
from delaytrack._words import table_text, with_scaled
from delaytrack.cli._scenarios import scenario_source, trusted
from delaytrack.warning import one_line

if TYPE_CHECKING:
    from delaytrack.jobs.scenario_run import RunOutput

__all__ = ["add_command", "run"]


def add_command(commands: argparse._SubParsersAction) -> None:
    """Add ``simulate`` to ``commands``."""
    command = commands.add_parser(
        "simulate",
        help="run one scenario file and write a results folder",
        description="Run a scenario TOML file (or the name of a shipped scenario such as "
        "two_link_S1) and write scenario.toml (as run), trajectories, metrics.csv and figures. "
        "For AROLC it prints Theorem 1's certified delay bound h_m and says when the run's "
        "largest delay exceeds it (the end of the guarantee, not by itself instability).",
    )
    command.add_argument(
        "scenario", metavar="SCENARIO", help="scenario .toml file or built-in name"
    )
    command.add_argument(
        "--out",
        default=None,
        metavar="DIR",
        help="results folder (default results/<scenario name>)",
    )
    command.add_argument(
        "--format",
        choices=("parquet", "csv", "both"),
        default="parquet",
        help="trajectory file format (default parquet)",
    )
    trust_argument(command)
    quiet_argument(command)
    command.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Run the scenario, write its folder and print its summary and files."""
    from delaytrack.jobs.scenario_run import run_to_folder
    from delaytrack.scenario import Scenario

    scenario = Scenario.from_toml(scenario_source(args.scenario), trust=trusted(args))
    folder = (
        check_output_folder(args.out, "--out")
        if args.out is not None
        else check_output_folder(Path("results") / scenario.name, "the results folder")
    )
    formats = ("parquet", "csv") if args.format == "both" else (args.format,)
    start = time.perf_counter()
    output = run_to_folder(scenario, folder, formats=formats, progress=not args.quiet)
    seconds = time.perf_counter() - start
    status = ", ".join(output.result.status_names)
    print(
        f"simulated {scenario.name!r}: {scenario.duration:g} s in {seconds:.1f} s wall time, "
        f"status {status}"
    )
    print(table_text(output.result.summary().reset_index()))
    _no_command_arrives(output)
    _certified_bound(output)
    print(f"wrote {len(output.files)} files to {folder}/:")
    for path in output.files:
        print(f"  {path.relative_to(folder)}")
    return 0


def _no_command_arrives(output: RunOutput) -> None:
    """One line on stderr when the delay is never shorter than the run: no command reached the
    plant (:mod:`delaytrack.sim.no_command`)."""
    from delaytrack.sim.no_command import no_command_arrives

    warning = no_command_arrives([output.built.delay], 0.0, output.scenario.duration)
    if warning is not None:
        print(one_line(f"warning: {warning}"), file=sys.stderr)


def _certified_bound(output: RunOutput) -> None:
    """For AROLC, Theorem 1's h_m, and one line on stderr when the run's largest delay exceeds
    it (:mod:`delaytrack.sim.certified_bound`)."""
    from delaytrack.analysis.razumikhin import PAPER_BETA, PAPER_R
    from delaytrack.sim.certified_bound import beyond_certified_bound, certified_bounds

    built = output.built  # the objects the run used: no factory runs again
    h_m = certified_bounds([built.controller])[0]
    if not math.isfinite(h_m):  # not AROLC: no certificate
        return
    print(
        f"AROLC's certified delay bound h_m = {with_scaled(h_m, 's')}, by Theorem 1 with the "
        f"scenario's K1, K2, Q and the paper's beta = {PAPER_BETA:g}, r = {PAPER_R:g}"
    )
    warning = beyond_certified_bound([built.controller], [built.delay], output.result)
    if warning is not None:
        print(one_line(f"warning: {warning}"), file=sys.stderr)
