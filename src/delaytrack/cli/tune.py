"""``delaytrack tune-baselines``: tune AROLC, PCON (two spaces) and PCONf by one protocol."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from delaytrack._cli_options import quiet_argument
from delaytrack._output import check_writable_location, is_gains_file
from delaytrack.cli._usage import UsageError

__all__ = ["add_command", "run"]


def add_command(commands: argparse._SubParsersAction) -> None:
    """Add ``tune-baselines`` to ``commands``."""
    command = commands.add_parser(
        "tune-baselines",
        help="tune AROLC, PCON (two spaces) and PCONf by one protocol on drawn conditions",
        description="Tune AROLC, PCON, PCON in wheel space and PCONf by the same seeded "
        "worst-case grid search (delaytrack.experiments.tuning), one gain set for all delays and "
        "one per delay class each, and write the chosen gains, grids and per-condition results "
        "as TOML to --out (default results/baseline_gains.toml). The paper job reads the gains "
        "shipped with the package unless given this file with delaytrack reproduce --gains.",
    )
    command.add_argument(
        "--out",
        default=str(Path("results") / "baseline_gains.toml"),
        metavar="PATH",
        help="gains file to write (default results/baseline_gains.toml; use it with "
        "delaytrack reproduce --gains PATH)",
    )
    quiet_argument(command)
    command.set_defaults(handler=run)


def _gains_path(text: str) -> Path:
    """``--out``: a new ``.toml`` file, or a gains file of an earlier run (replaced)."""
    path = check_writable_location(text, "--out")
    if path.is_dir():
        raise UsageError(f"--out {text!r} is a folder; it must name the gains file to write")
    if Path(text).suffix != ".toml":
        raise UsageError(
            f"--out {text!r} must end in .toml: tune-baselines writes a TOML gains file "
            "(read by delaytrack reproduce --gains), and a later run replaces only such a file"
        )
    if path.exists() and not is_gains_file(path):
        raise UsageError(
            f"--out {text!r} is a file that tune-baselines did not write; name a new file "
            "(or a gains file of an earlier run, which is replaced), so that nothing of yours is "
            "overwritten"
        )
    return path


def run(args: argparse.Namespace) -> int:
    """Tune every controller, write the gains file and print the chosen gains."""
    from delaytrack.experiments.tuning import tune_controllers, write_gains
    from delaytrack.report.tuning import chosen_gains_lines

    path = _gains_path(args.out)
    start = time.perf_counter()
    results = tune_controllers(progress=not args.quiet)
    path = write_gains(results, path)
    seconds = time.perf_counter() - start
    for line in chosen_gains_lines(results):
        print(line)
    print(f"wrote {path} in {seconds:.1f} s")
    print(f"use these gains with: delaytrack reproduce --gains {path}")
    return 0
