"""What the commands on Theorem 1 share (``bound``, ``margin``, ``design``): their gain, weight
and Razumikhin options, read into :func:`~delaytrack.analysis.razumikhin_bound`'s arguments."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

import numpy as np

from delaytrack._cli_options import integer, quiet_argument
from delaytrack._words import shown_number
from delaytrack.cli._numbers import numbers, scalar
from delaytrack.cli._usage import UsageError, flagged

if TYPE_CHECKING:
    from delaytrack.analysis import RazumikhinBound

__all__ = [
    "MAX_JOINTS",
    "joints",
    "r_and_json_arguments",
    "razumikhin_factor",
    "theorem_1",
    "theorem_1_arguments",
]

#: Largest --n: E is 2n x 2n and dense, so n = 1000 already needs tens of MB per matrix.
MAX_JOINTS = 1000

#: The flags of :func:`~delaytrack.analysis.razumikhin_bound`'s arguments.
_FLAGS = {"K1": "--k1", "K2": "--k2", "Q": "--q", "beta": "--beta", "r": "--r"}


def theorem_1_arguments(command: argparse.ArgumentParser, q_default: str | None) -> None:
    """Add --k1, --k2, --q, --beta, --r, --n, --json and --quiet; --q is required when it has no
    default."""
    command.add_argument(
        "--k1",
        required=True,
        metavar="K1",
        help="proportional gain K1 of the outer loop, 1/s^2: a number (times I) or a comma list "
        "of n (the diagonal), e.g. 1,2",
    )
    command.add_argument(
        "--k2",
        required=True,
        metavar="K2",
        help="derivative gain K2 of the outer loop, 1/s: a number (times I) or a comma list of n "
        "(the diagonal)",
    )
    command.add_argument(
        "--q",
        required=q_default is None,
        default=q_default,
        metavar="Q",
        help="weight Q of the Lyapunov equation A^T P + P A = -Q, no unit: a number (times I) or "
        "a comma list of 2n (the diagonal)"
        + ("" if q_default is None else f" (default {q_default})"),
    )
    command.add_argument(
        "--beta",
        default="1",
        metavar="BETA",
        help="weight beta > 0 of Theorem 1's inequality, no unit (default 1, the paper's)",
    )
    command.add_argument(
        "--n",
        type=integer,
        default=None,
        help="number of joints (default: length of a comma list, else 1)",
    )
    r_and_json_arguments(command)


def r_and_json_arguments(command: argparse.ArgumentParser) -> None:
    """Add --r (the Razumikhin factor), --json and --quiet (accepted as by every command;
    nothing here runs long enough for a progress bar)."""
    command.add_argument(
        "--r",
        default="1.1",
        metavar="R",
        help="Razumikhin factor r > 1 in V(e(xi)) < r V(e(t)), no unit (default 1.1, the paper's)",
    )
    command.add_argument(
        "--json", action="store_true", help="print one JSON object instead of text"
    )
    quiet_argument(command, "progress bars (none here: the computation is short)")


def joints(n: int) -> int:
    """Check --n."""
    if not 1 <= n <= MAX_JOINTS:
        raise UsageError(
            f"--n must be an integer from 1 to {MAX_JOINTS} (the number of joints); got {n}"
        )
    return n


def razumikhin_factor(text: str) -> float:
    """Parse and check --r."""
    r = scalar("--r", text)
    if r <= 1.0:
        raise UsageError(
            f"--r must be > 1 (the Razumikhin factor in V(e(xi)) < r V(e(t))); got {text}"
        )
    return r


def _dimension(args: argparse.Namespace, k1: np.ndarray, k2: np.ndarray, q: np.ndarray) -> int:
    """n from --n, else from the length of a comma list, else 1; check every list fits it."""
    if args.n is not None:
        n = joints(args.n)
    else:
        candidates = {len(v) for v in (k1, k2) if len(v) > 1}
        if len(q) > 1:
            if len(q) % 2:
                raise UsageError(
                    f"--q has {len(q)} entries; as a diagonal it needs 2n entries (an even count)"
                )
            candidates.add(len(q) // 2)
        if len(candidates) > 1:
            raise UsageError(
                f"the comma lists disagree on n: --k1 has {len(k1)}, --k2 {len(k2)} and --q "
                f"{len(q)} entries (k1, k2 need n, q needs 2n); give matching lists or --n"
            )
        n = candidates.pop() if candidates else 1
    for flag, values, size in (("--k1", k1, n), ("--k2", k2, n), ("--q", q, 2 * n)):
        if len(values) not in (1, size):
            raise UsageError(
                f"{flag} has {len(values)} entries; with n = {n} it needs 1 (a multiple of I) or "
                f"{size} (a diagonal)"
            )
    return n


def _diagonal(values: np.ndarray, size: int) -> np.ndarray:
    return np.diag(np.broadcast_to(values, (size,)).astype(float))


def _shown(values: np.ndarray) -> str:
    """``"2 I"`` for one value, ``"diag(1, 2)"`` for a list."""
    if len(values) == 1:
        return f"{shown_number(values[0])} I"
    return "diag(" + ", ".join(shown_number(v) for v in values) + ")"


def theorem_1(args: argparse.Namespace) -> tuple[RazumikhinBound, str]:
    """Parse --k1, --k2, --q, --beta, --r, --n; return Theorem 1's result and a settings line."""
    from delaytrack.analysis import razumikhin_bound

    given = {"--k1": args.k1, "--k2": args.k2, "--q": args.q, "--beta": args.beta, "--r": args.r}
    k1, k2, q = numbers("--k1", args.k1), numbers("--k2", args.k2), numbers("--q", args.q)
    beta, r = scalar("--beta", args.beta), razumikhin_factor(args.r)
    n = _dimension(args, k1, k2, q)
    try:
        bound = razumikhin_bound(
            _diagonal(k1, n), _diagonal(k2, n), _diagonal(q, 2 * n), beta, r, n=n
        )
    except (ValueError, TypeError) as error:
        raise flagged(error, _FLAGS, given=given) from None
    settings = (
        f"  n = {n}, K1 = {_shown(k1)}, K2 = {_shown(k2)}, Q = {_shown(q)}, "
        f"beta = {shown_number(beta)}, r = {shown_number(r)}"
    )
    return bound, settings
