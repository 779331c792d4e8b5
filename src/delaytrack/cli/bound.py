"""``delaytrack bound``: Theorem 1's certified delay bound h_m."""

from __future__ import annotations

import argparse
import json

from delaytrack._words import with_scaled
from delaytrack.cli._theorem_1 import theorem_1, theorem_1_arguments

__all__ = ["add_command", "run"]


def add_command(commands: argparse._SubParsersAction) -> None:
    """Add ``bound`` to ``commands``."""
    command = commands.add_parser(
        "bound",
        help="the certified maximum input delay h_m of Theorem 1",
        description="Theorem 1's certified delay bound h_m = lambda_min(Q) / ||E||_2. A single "
        "number means a multiple of the identity, a comma list a diagonal (k1, k2 of length n, "
        "q of length 2n). Example: delaytrack bound --k1 1 --k2 1 --q 1 --beta 1 --r 1.1",
    )
    theorem_1_arguments(command, q_default="1")
    command.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Print h_m with lambda_min(Q) and ||E||_2 (or one JSON object with ``--json``)."""
    bound, settings = theorem_1(args)
    if args.json:
        data = bound.to_dict()
        data["h_m_ms"] = 1e3 * bound.h_m
        print(json.dumps(data))
        return 0
    print("Razumikhin delay bound (Roy & Kar, Theorem 1)")
    print(settings)
    print(f"  lambda_min(Q) = {bound.lambda_min_Q:.6g}")
    print(f"  ||E||_2       = {bound.E_norm:.6g}")
    print(f"  h_m           = {with_scaled(bound.h_m, 's')}")
    print(
        "AROLC is certified for every input delay 0 <= h(t) < h_m "
        "(Q - h E stays positive definite)."
    )
    return 0
