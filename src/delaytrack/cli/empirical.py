"""``delaytrack empirical``: the empirical delay margin of a scenario's closed loop."""

from __future__ import annotations

import argparse
import json
import time
from typing import TYPE_CHECKING

import numpy as np

from delaytrack._cli_options import quiet_argument, trust_argument
from delaytrack._words import with_scaled
from delaytrack.cli._numbers import numbers, scalar
from delaytrack.cli._scenarios import scenario_source, trusted
from delaytrack.cli._usage import UsageError, flagged
from delaytrack.metrics import COORDINATE_METRICS

if TYPE_CHECKING:
    from delaytrack.experiments import EmpiricalMargin

__all__ = ["add_command", "run"]

#: The flags of :func:`~delaytrack.experiments.empirical_margin`'s settings that the command sets.
_FLAGS = {name: f"--{name}" for name in ("threshold", "settle", "resolution", "upper", "frequency")}


def add_command(commands: argparse._SubParsersAction) -> None:
    """Add ``empirical`` to ``commands``."""
    command = commands.add_parser(
        "empirical",
        help="empirical delay margin of a scenario's closed loop (batched bisection)",
        description="The largest delay (constant h, or the amplitude a of h(t) = a |sin(w t)|) "
        "at which the scenario's closed loop ends ok and keeps the tracking metric at most "
        "--threshold: a coarse grid over [0, --upper], then multi-section down to --resolution. "
        "The scenario's [delay] is replaced. Example: delaytrack empirical two_link_margins "
        "--threshold 0.2",
    )
    command.add_argument(
        "scenario", metavar="SCENARIO", help="scenario .toml file or built-in name"
    )
    command.add_argument(
        "--threshold",
        required=True,
        metavar="VALUE",
        help="largest acceptable tracking metric: one number for every coordinate, or a comma "
        "list of one per coordinate, each in its own unit (0.05,0.1 for a plant whose coordinates "
        "are in m and rad; required: what 'still tracks' means)",
    )
    command.add_argument(
        "--profile",
        choices=("constant", "abs-sine", "abs-sine-offset"),
        default="constant",
        help="delay family (default constant)",
    )
    command.add_argument(
        "--metric",
        choices=COORDINATE_METRICS,
        default="ae",
        help="mean |e1|, RMS or max |e1| over [settle, duration], largest over the coordinates "
        "(default ae)",
    )
    command.add_argument(
        "--settle",
        default=None,
        metavar="S",
        help="start of the metric window (default: half the duration)",
    )
    command.add_argument(
        "--resolution", default="0.005", metavar="S", help="final bracket width (default 0.005 s)"
    )
    command.add_argument("--upper", default=None, metavar="S", help="search limit (default 1 s)")
    command.add_argument(
        "--frequency",
        default=None,
        metavar="W",
        help="w of the abs-sine families (default 1 rad/s; not with --profile constant)",
    )
    command.add_argument(
        "--json", action="store_true", help="print one JSON object instead of text"
    )
    trust_argument(command)
    quiet_argument(command)
    command.set_defaults(handler=run)


def _threshold(text: str) -> float | np.ndarray:
    """``--threshold``: one number for every coordinate, or a comma list of one per coordinate."""
    bounds = numbers("--threshold", text)
    return float(bounds[0]) if bounds.size == 1 else bounds


def _analytic(controller: object) -> dict[str, float]:
    """Theorem 1's h_m (the controller's Q, else I; the paper's beta and r) and the exact
    constant-delay margin of a controller with gains K1 and K2; empty for any other."""
    from delaytrack.analysis import exact_delay_margin, razumikhin_bound
    from delaytrack.analysis.razumikhin import PAPER_BETA, PAPER_R

    if not (hasattr(controller, "K1") and hasattr(controller, "K2")):
        return {}
    n = controller.K1.shape[0]
    Q = getattr(controller, "Q", np.eye(2 * n))
    return {
        "h_m": razumikhin_bound(controller.K1, controller.K2, Q, PAPER_BETA, PAPER_R, n=n).h_m,
        "h_exact": exact_delay_margin(controller.K1, controller.K2).h,
    }


def run(args: argparse.Namespace) -> int:
    """Search the margin and print it beside Theorem 1's h_m and the exact margin when the
    controller has K1 and K2 (or one JSON object with ``--json``)."""
    from delaytrack.experiments import empirical_margin
    from delaytrack.scenario import Scenario

    scenario = Scenario.from_toml(scenario_source(args.scenario), trust=trusted(args))
    controller = scenario.build().controller
    threshold = _threshold(args.threshold)
    settle = None if args.settle is None else scalar("--settle", args.settle)
    resolution = scalar("--resolution", args.resolution)
    upper = 1.0 if args.upper is None else scalar("--upper", args.upper)
    if args.frequency is not None and args.profile == "constant":
        raise UsageError(
            f"--frequency {args.frequency} sets w of the abs-sine families; --profile constant "
            "has none (give --profile abs-sine or abs-sine-offset, or leave --frequency out)"
        )
    frequency = 1.0 if args.frequency is None else scalar("--frequency", args.frequency)
    start = time.perf_counter()
    try:
        result = empirical_margin(
            scenario,
            controller,
            threshold=threshold,
            profile=args.profile,
            metric=args.metric,
            settle=settle,
            resolution=resolution,
            upper=upper,
            frequency=frequency,
            progress=not args.quiet,
        )
    except ValueError as error:
        usage = flagged(error, _FLAGS)
        if args.upper is None and getattr(error, "argument", None) == "upper":
            advised = "upper" in getattr(error, "mentions", ())  # its advice names --upper
            advice = "" if advised else "; give a smaller --upper S"
            usage = UsageError(f"{usage} (the default of --upper{advice})")
        raise usage from None
    seconds = time.perf_counter() - start
    analytic = _analytic(controller)
    if args.json:
        print(json.dumps({**result.to_dict(), **analytic, "seconds": seconds}))
        return 0
    weight = "Q" if hasattr(controller, "Q") else "Q = I"
    _print(scenario.name, result, analytic, weight, seconds)
    return 0


def _print(
    name: str, result: EmpiricalMargin, analytic: dict[str, float], weight: str, seconds: float
) -> None:
    """The margin as text, with Theorem 1's h_m (weight ``weight``) and the exact margin."""
    from delaytrack.analysis.razumikhin import PAPER_BETA, PAPER_R

    family = {
        "constant": "constant delay h",
        "abs-sine": f"h(t) = a |sin({result.frequency:g} t)|, margin in a",
        "abs-sine-offset": f"h(t) = a/2 + (a/2) |sin({result.frequency:g} t)|, margin in a",
    }[result.profile]
    print(f"Empirical delay margin of {name!r} ({result.controller}; {family})")
    print(f"  margin      = {result.describe()}")
    print(
        f"  search      = {result.simulations} simulations in {result.rounds} "
        f"batch{'' if result.rounds == 1 else 'es'}, "
        f"{seconds:.1f} s wall time"
    )
    if analytic:
        print(
            f"  h_m         = {with_scaled(analytic['h_m'], 's')}, by Theorem 1 (the "
            f"controller's K1, K2, "
            f"{weight}; beta = {PAPER_BETA:g}, r = {PAPER_R:g})"
        )
        print(
            f"  h_exact     = {with_scaled(analytic['h_exact'], 's')}, exact (constant delay, "
            "nominal dynamics)"
        )
