"""``delaytrack design``: diagonal gains that maximise Theorem 1's certified h_m."""

from __future__ import annotations

import argparse
import json
from typing import TYPE_CHECKING

from delaytrack._cli_options import integer
from delaytrack._words import shown_number, with_scaled
from delaytrack.cli._numbers import scalar
from delaytrack.cli._theorem_1 import joints, r_and_json_arguments, razumikhin_factor
from delaytrack.cli._usage import flagged

if TYPE_CHECKING:
    from delaytrack.analysis import GainDesign

__all__ = ["add_command", "run"]

#: The flags of :func:`~delaytrack.analysis.design_gains`' arguments that the command sets.
_FLAGS = {
    "r": "--r",
    "gain_bound": "--gain-bound",
    "min_bandwidth": "--min-bandwidth",
    "seed": "--seed",
}


def add_command(commands: argparse._SubParsersAction) -> None:
    """Add ``design`` to ``commands``."""
    command = commands.add_parser(
        "design",
        help="diagonal K1, K2, Q and beta that maximise the certified h_m",
        description="Search diagonal K1, K2, Q and beta (seeded differential evolution) for the "
        "largest delay Theorem 1 certifies, with every diagonal entry of K1 and K2 at most "
        "--gain-bound. Example: delaytrack design --gain-bound 1 --seed 0",
    )
    command.add_argument("--n", type=integer, default=1, help="number of joints (default 1)")
    command.add_argument(
        "--gain-bound",
        default="1",
        metavar="B",
        help="largest diagonal entry of K1 and K2 (default 1, the paper's K1 = K2 = I)",
    )
    command.add_argument(
        "--min-bandwidth",
        default=None,
        metavar="W",
        help="least natural frequency sqrt(k1) of the delay-free loop, rad/s (default: none)",
    )
    command.add_argument("--seed", type=integer, default=0, help="search seed (default 0)")
    r_and_json_arguments(command)
    command.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Print the designed gains with their h_m beside the paper's (or one JSON object)."""
    from delaytrack.analysis import design_gains

    gain_bound, r = scalar("--gain-bound", args.gain_bound), razumikhin_factor(args.r)
    bandwidth = (
        None if args.min_bandwidth is None else scalar("--min-bandwidth", args.min_bandwidth)
    )
    try:
        design = design_gains(
            n=joints(args.n), gain_bound=gain_bound, min_bandwidth=bandwidth, r=r, seed=args.seed
        )
    except ValueError as error:  # out of range: the error names the argument
        raise flagged(error, _FLAGS, given={"--r": args.r}) from None
    if args.json:
        print(json.dumps(design.to_dict()))
        return 0
    _print(design, bandwidth)
    return 0


def _print(design: GainDesign, bandwidth: float | None) -> None:
    """The design as text."""
    gain = 100.0 * (design.h_m / design.reference_h_m - 1.0)
    gain_text = f"{gain:+.2f}" if abs(gain) < 1e4 else f"{gain:+.3g}"
    bandwidth_text = "" if bandwidth is None else f"; sqrt(k1) >= {bandwidth:g} rad/s"
    print(
        f"Gain design for Theorem 1 (diagonal K1, K2, Q; every entry of K1 and K2 <= "
        f"{design.gain_bound:g}{bandwidth_text})"
    )
    print(
        f"  n = {design.n}, K1 = {design.K1[0, 0]:.6g} I, K2 = {design.K2[0, 0]:.6g} I, "
        f"Q = diag(1, {design.Q[-1, -1]:.6g}) per joint, beta = {design.beta:.6g}, "
        f"r = {shown_number(design.r)}"
    )
    print(
        f"  h_m = {with_scaled(design.h_m, 's')}; the paper's K1 = K2 = Q = I, "
        f"beta = 1: {with_scaled(design.reference_h_m, 's')} ({gain_text} %)"
    )
    print(
        f"  exact margin of these gains (constant delay): {with_scaled(design.exact.h, 's')} at "
        f"{design.exact.omega:.6g} rad/s"
    )
    active = {True: "active", False: "inactive"}
    bandwidth_state = "" if bandwidth is None else f"; bandwidth {active[design.bandwidth_active]}"
    print(
        f"  gain bound {active[design.bound_active]}{bandwidth_state}; seed {design.seed}; "
        f"{design.evaluations} evaluations in {design.seconds:.1f} s"
    )
