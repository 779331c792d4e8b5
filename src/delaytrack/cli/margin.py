"""``delaytrack margin``: Theorem 1's certified h_m beside the exact constant-delay margin."""

from __future__ import annotations

import argparse
import json

from delaytrack._words import with_scaled
from delaytrack.cli._theorem_1 import theorem_1, theorem_1_arguments

__all__ = ["add_command", "run"]


def add_command(commands: argparse._SubParsersAction) -> None:
    """Add ``margin`` to ``commands``."""
    command = commands.add_parser(
        "margin",
        help="certified h_m beside the exact constant-delay margin h_exact",
        description="Theorem 1's certified bound h_m and the exact delay margin h_exact of "
        "e1'' = -K2 e1'(t-h) - K1 e1(t-h) for a constant delay h (the smallest h with a root of "
        "det(s^2 I + (K2 s + K1) e^(-sh)) on the imaginary axis). Lists as for bound. "
        "Example: delaytrack margin --k1 1 --k2 1",
    )
    theorem_1_arguments(command, q_default="1")
    command.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Print h_m, h_exact and their ratio (or one JSON object with ``--json``)."""
    from delaytrack.analysis import exact_delay_margin

    bound, settings = theorem_1(args)
    exact = exact_delay_margin(bound.K1, bound.K2)
    ratio = bound.h_m / exact.h
    if args.json:
        data = {
            "n": bound.n,
            "h_m": bound.h_m,
            "h_exact": exact.h,
            "omega_exact": exact.omega,
            "ratio": ratio,
            "crossing_omegas": list(exact.crossing_omegas),
            "crossing_delays": list(exact.crossing_delays),
        }
        print(json.dumps(data))
        return 0
    print("Delay margins of the nominal error dynamics e1'' = -K2 e1'(t-h) - K1 e1(t-h)")
    print(settings)
    print(f"  h_m (certified, Theorem 1)  = {with_scaled(bound.h_m, 's')}")
    print(
        f"  h_exact (constant delay)    = {with_scaled(exact.h, 's')} "
        f"at omega_exact = {exact.omega:.6g} rad/s"
    )
    print(f"  h_m / h_exact               = {ratio:.4g}")
    print("h_m holds for every time-varying delay below it, with uncertainty; h_exact only for a")
    print("constant delay without uncertainty (a root reaches s = j omega_exact there).")
    return 0
