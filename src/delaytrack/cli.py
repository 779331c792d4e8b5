"""The ``delaytrack`` command: thin wrappers that parse, call the library and print.

Commands::

    delaytrack bound --k1 1 --k2 1 [--q 1] [--beta 1] [--r 1.1] [--n 5] [--json]
    delaytrack margin --k1 1 --k2 1 [--q 1] [--beta 1] [--r 1.1] [--n 5] [--json]
    delaytrack design [--n 2] [--gain-bound 1] [--min-bandwidth W] [--r 1.1] [--seed 0] [--json]
    delaytrack simulate SCENARIO.toml [--out DIR] [--format parquet|csv|both] [--trust NAME]
        [--quiet]
    delaytrack empirical SCENARIO.toml --threshold VALUE[,VALUE...]
        [--profile constant|abs-sine|abs-sine-offset]
        [--metric ae|rms|max] [--settle S] [--resolution S] [--upper S] [--frequency W] [--json]
        [--trust NAME] [--quiet]
    delaytrack reproduce [--out results] [--duration SECONDS] [--no-dt-check] [--no-contact]
        [--no-robustness] [--size default|full] [--scheduler ADDRESS] [--gains PATH] [--quiet]
        [--job paper|two-link|margins|robustness]
    delaytrack sweep SPEC.toml [--out DIR] [--scheduler ADDRESS] [--workers N] [--trust NAME]
        [--quiet]
    delaytrack tune-baselines [--out PATH] [--quiet]

Long work shows progress bars on stderr; ``--quiet`` turns them off, in every command.

A factory that a scenario or sweep file names (``type = "python:..."``) is Python code: only a
``.py`` file beside that file (or below) runs unless ``--trust NAME`` (repeatable: a module name,
or a path to a ``.py`` file or a folder) allows more.

Bad input ends with exit code 2 and a one-line ``error: ...`` naming the argument, the value and
what is valid; never a traceback.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from delaytrack._cli_options import (
    EXIT_USAGE,
    OptionParser,
    integer,
    quiet_argument,
    trust_argument,
)
from delaytrack._output import (
    OutputFolderError,
    check_output_folder,
    check_results_root,
    check_writable_location,
    is_gains_file,
    plain_folder_name,
    record_outputs,
)
from delaytrack._validation import DECIMAL_NOTATION, NumberTextError, decimal_number

if TYPE_CHECKING:
    from delaytrack.analysis import RazumikhinBound

__all__ = ["main"]

#: A reader closed standard output (``| head``): 128 + SIGPIPE, as a shell reports a program
#: that the pipe's signal ended.
EXIT_BROKEN_PIPE = 141


class UsageError(Exception):
    """Bad command-line input; the message is shown as ``error: <message>``."""


# --------------------------------------------------------------------------------------------
# bound


def _float(flag: str, part: str, text: str, what: str) -> float:
    """One number of ``text`` by the rule of every number the toolkit reads
    (:func:`~delaytrack._validation.decimal_number`): ``1``, ``-2.5``, ``3e-2``, finite and
    not rounded to 0; ``1_000``, ``0x10`` and ``٣`` are refused.
    """
    try:
        return decimal_number(part)
    except NumberTextError as error:
        if error.notation:
            message = f"{flag} must be {what} in {DECIMAL_NOTATION}"
        elif part.strip() == text.strip():
            message = f"{flag} {error}"
        else:
            message = f"{flag} entry {part.strip()} {error}"
        raise UsageError(f"{message}; got {text!r}") from None


def _numbers(flag: str, text: str) -> np.ndarray:
    """Parse ``"1"`` or ``"1,2.5,3"`` into a 1-D array of finite floats."""
    what = "a number or a comma-separated list of numbers"
    return np.array([_float(flag, part, text, what) for part in text.split(",")])


def _scalar(flag: str, text: str) -> float:
    """Parse one finite float."""
    return _float(flag, text, text, "a single number" if "," in text else "a number")


def _threshold(text: str) -> float | np.ndarray:
    """``--threshold``: one number for every coordinate, or a comma list of one per coordinate."""
    bounds = _numbers("--threshold", text)
    return float(bounds[0]) if bounds.size == 1 else bounds


def _dimension(args: argparse.Namespace, k1: np.ndarray, k2: np.ndarray, q: np.ndarray) -> int:
    """n from --n, else from the length of a comma list, else 1; check every list fits it."""
    if args.n is not None:
        n = _joints(args.n)
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


#: Largest --n: E is 2n x 2n and dense, so n = 1000 already needs tens of MB per matrix.
_MAX_JOINTS = 1000


def _joints(n: int) -> int:
    """Check --n."""
    if not 1 <= n <= _MAX_JOINTS:
        raise UsageError(
            f"--n must be an integer from 1 to {_MAX_JOINTS} (the number of joints); got {n}"
        )
    return n


def _diagonal(values: np.ndarray, size: int) -> np.ndarray:
    return np.diag(np.broadcast_to(values, (size,)).astype(float))


_LIBRARY_NAMES = {"K1": "--k1", "K2": "--k2", "Q": "--q", "beta": "--beta", "r": "--r"}


def _shown(values: np.ndarray) -> str:
    """``"2 I"`` for one value, ``"diag(1, 2)"`` for a list."""
    if len(values) == 1:
        return f"{values[0]:g} I"
    return "diag(" + ", ".join(f"{v:g}" for v in values) + ")"


def _with_flag(message: str, flags: dict[str, str], raw: dict[str, str]) -> str:
    """A library message that starts with an argument's name, starting with its flag instead.

    ``raw`` maps flags to the text given, added as ``(got --flag text)`` when present.
    """
    for name, flag in flags.items():
        if message.startswith(f"{name} "):
            given = f" (got {flag} {raw[flag]})" if flag in raw else ""
            return f"{flag} {message[len(name) + 1 :]}{given}"
    return message


def _razumikhin_factor(text: str) -> float:
    """Parse and check --r."""
    r = _scalar("--r", text)
    if r <= 1.0:
        raise UsageError(
            f"--r must be > 1 (the Razumikhin factor in V(e(xi)) < r V(e(t))); got {text}"
        )
    return r


def _theorem_1(args: argparse.Namespace) -> tuple[RazumikhinBound, str]:
    """Parse --k1, --k2, --q, --beta, --r, --n; return Theorem 1's result and a settings line."""
    from delaytrack.analysis import razumikhin_bound

    raw = {"--k1": args.k1, "--k2": args.k2, "--q": args.q, "--beta": args.beta, "--r": args.r}
    k1, k2, q = _numbers("--k1", args.k1), _numbers("--k2", args.k2), _numbers("--q", args.q)
    beta, r = _scalar("--beta", args.beta), _razumikhin_factor(args.r)
    if beta <= 0.0:
        raise UsageError(
            f"--beta must be > 0 (the weight of the paper's inequality); got {args.beta}"
        )
    n = _dimension(args, k1, k2, q)
    try:
        bound = razumikhin_bound(
            _diagonal(k1, n), _diagonal(k2, n), _diagonal(q, 2 * n), beta, r, n=n
        )
    except (ValueError, TypeError) as error:
        raise UsageError(_with_flag(str(error), _LIBRARY_NAMES, raw)) from None
    settings = (
        f"  n = {n}, K1 = {_shown(k1)}, K2 = {_shown(k2)}, Q = {_shown(q)}, beta = {beta:g}, "
        f"r = {r:g}"
    )
    return bound, settings


def _bound(args: argparse.Namespace) -> int:
    bound, settings = _theorem_1(args)
    if args.json:
        data = bound.to_dict()
        data["h_m_ms"] = 1e3 * bound.h_m
        print(json.dumps(data))
        return 0
    print("Razumikhin delay bound (Roy & Kar, Theorem 1)")
    print(settings)
    print(f"  lambda_min(Q) = {bound.lambda_min_Q:.6g}")
    print(f"  ||E||_2       = {bound.E_norm:.6g}")
    print(f"  h_m           = {bound.h_m:.6g} s ({1e3 * bound.h_m:.4g} ms)")
    print(
        "AROLC is certified for every input delay 0 <= h(t) < h_m "
        "(Q - h E stays positive definite)."
    )
    return 0


# --------------------------------------------------------------------------------------------
# margin


def _margin(args: argparse.Namespace) -> int:
    from delaytrack.analysis import exact_delay_margin

    bound, settings = _theorem_1(args)
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
    print(f"  h_m (certified, Theorem 1)  = {bound.h_m:.6g} s ({1e3 * bound.h_m:.4g} ms)")
    print(
        f"  h_exact (constant delay)    = {exact.h:.6g} s ({1e3 * exact.h:.4g} ms) "
        f"at omega_exact = {exact.omega:.6g} rad/s"
    )
    print(f"  h_m / h_exact               = {ratio:.4g}")
    print("h_m holds for every time-varying delay below it, with uncertainty; h_exact only for a")
    print("constant delay without uncertainty (a root reaches s = j omega_exact there).")
    return 0


# --------------------------------------------------------------------------------------------
# design


def _design(args: argparse.Namespace) -> int:
    from delaytrack.analysis import design_gains

    gain_bound, r = _scalar("--gain-bound", args.gain_bound), _razumikhin_factor(args.r)
    if gain_bound <= 0.0:
        raise UsageError(
            f"--gain-bound must be > 0 (the largest diagonal entry of K1 and K2); "
            f"got {args.gain_bound}"
        )
    if not 0 <= args.seed <= 2**32 - 1:
        raise UsageError(
            f"--seed must be a non-negative integer; got {args.seed} (seeds run from 0 to "
            f"2**32 - 1 = {2**32 - 1})"
        )
    bandwidth = None
    if args.min_bandwidth is not None:
        bandwidth = _scalar("--min-bandwidth", args.min_bandwidth)
        if bandwidth <= 0.0:
            raise UsageError(
                f"--min-bandwidth must be > 0 rad/s (the least natural frequency sqrt(k1)); "
                f"got {args.min_bandwidth}"
            )
    try:
        design = design_gains(
            n=_joints(args.n), gain_bound=gain_bound, min_bandwidth=bandwidth, r=r, seed=args.seed
        )
    except ValueError as error:  # out of range: the message names the argument
        message = _with_flag(str(error), {"r": "--r"}, {"--r": args.r})
        message = message.replace("min_bandwidth", "--min-bandwidth")
        raise UsageError(message.replace("gain_bound", "--gain-bound")) from None
    if args.json:
        print(json.dumps(design.to_dict()))
        return 0
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
        f"r = {design.r:g}"
    )
    print(
        f"  h_m = {design.h_m:.6g} s ({1e3 * design.h_m:.4g} ms); the paper's K1 = K2 = Q = I, "
        f"beta = 1: {design.reference_h_m:.6g} s ({gain_text} %)"
    )
    print(
        f"  exact margin of these gains (constant delay): {design.exact.h:.6g} s at "
        f"{design.exact.omega:.6g} rad/s"
    )
    active = {True: "active", False: "inactive"}
    bandwidth_state = "" if bandwidth is None else f"; bandwidth {active[design.bandwidth_active]}"
    print(
        f"  gain bound {active[design.bound_active]}{bandwidth_state}; seed {design.seed}; "
        f"{design.evaluations} evaluations in {design.seconds:.1f} s"
    )
    return 0


# --------------------------------------------------------------------------------------------
# simulate


def _scenario_source(text: str) -> Path:
    """A scenario file path, or the name of a shipped scenario (``two_link_S1``)."""
    from delaytrack.experiments import builtin_scenario_names, builtin_scenario_path

    path = Path(text)
    if path.exists() or path.suffix == ".toml":
        return path
    if text in builtin_scenario_names():
        return builtin_scenario_path(text)
    raise UsageError(
        f"scenario file {text!r} does not exist (nor is it a built-in scenario; those are "
        f"{builtin_scenario_names()})"
    )


def _trusted(args: argparse.Namespace) -> list[str]:
    """The ``--trust`` names, checked (:class:`delaytrack._trust.Trust`)."""
    from delaytrack._trust import Trust

    try:
        Trust.of(args.trust, "--trust")
    except ValueError as error:
        raise UsageError(str(error)) from None
    return args.trust


def _simulate(args: argparse.Namespace) -> int:
    from delaytrack.experiments import Scenario, run_to_folder

    scenario = Scenario.from_toml(_scenario_source(args.scenario), trust=_trusted(args))
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
    print(output.result.summary().to_string(float_format=lambda v: f"{v:.4g}"))
    print(f"wrote {len(output.files)} files to {folder}/:")
    for path in output.files:
        print(f"  {path.relative_to(folder)}")
    return 0


# --------------------------------------------------------------------------------------------
# empirical


def _empirical(args: argparse.Namespace) -> int:
    from delaytrack.analysis import exact_delay_margin, razumikhin_bound
    from delaytrack.experiments import Scenario, empirical_margin

    scenario = Scenario.from_toml(_scenario_source(args.scenario), trust=_trusted(args))
    controller = scenario.build().controller
    options = {
        "threshold": _threshold(args.threshold),
        "settle": None if args.settle is None else _scalar("--settle", args.settle),
        "resolution": _scalar("--resolution", args.resolution),
        "upper": _scalar("--upper", args.upper),
        "frequency": _scalar("--frequency", args.frequency),
    }
    start = time.perf_counter()
    try:
        result = empirical_margin(
            scenario,
            controller,
            profile=args.profile,
            metric=args.metric,
            progress=not args.quiet,
            **options,
        )
    except ValueError as error:
        flags = {name: f"--{name}" for name in options}
        message = _with_flag(str(error), flags, {}).replace("than upper;", "than --upper;")
        raise UsageError(message) from None
    seconds = time.perf_counter() - start
    analytic = {}
    if hasattr(controller, "K1") and hasattr(controller, "K2"):
        n = controller.K1.shape[0]
        Q = getattr(controller, "Q", np.eye(2 * n))
        analytic = {
            "h_m": razumikhin_bound(controller.K1, controller.K2, Q, 1.0, 1.1, n=n).h_m,
            "h_exact": exact_delay_margin(controller.K1, controller.K2).h,
        }
    if args.json:
        print(json.dumps({**result.to_dict(), **analytic, "seconds": seconds}))
        return 0
    family = {
        "constant": "constant delay h",
        "abs-sine": f"h(t) = a |sin({result.frequency:g} t)|, margin in a",
        "abs-sine-offset": f"h(t) = a/2 + (a/2) |sin({result.frequency:g} t)|, margin in a",
    }[result.profile]
    print(f"Empirical delay margin of {scenario.name!r} ({result.controller}; {family})")
    print(f"  margin      = {result.describe()}")
    print(
        f"  search      = {result.simulations} simulations in {result.rounds} "
        f"batch{'' if result.rounds == 1 else 'es'}, "
        f"{seconds:.1f} s wall time"
    )
    if analytic:
        weight = "Q" if hasattr(controller, "Q") else "Q = I"
        print(
            f"  h_m         = {analytic['h_m']:.6g} s (Theorem 1: the controller's K1, K2, "
            f"{weight}; beta = 1, r = 1.1)"
        )
        print(f"  h_exact     = {analytic['h_exact']:.6g} s (constant delay, nominal dynamics)")
    return 0


# --------------------------------------------------------------------------------------------
# reproduce


def _reproduce(args: argparse.Namespace) -> int:
    if args.gains is not None:
        args.gains = _checked_gains(args.gains)
    args.out = str(check_results_root(args.out, "--out"))
    try:
        return _reproduce_job(args)
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


def _study_executor(args: argparse.Namespace):
    """A factory of the robustness study's executors (``--scheduler``), checked before running."""
    from delaytrack.sweeps import SweepError, make_executor
    from delaytrack.sweeps.executors import checked_scheduler

    if args.duration is not None and args.job == "robustness":
        raise UsageError("--duration does not apply to --job robustness (its runs are 60 s)")
    try:
        checked_scheduler(args.scheduler, None)
    except SweepError as error:
        raise UsageError(str(error)) from None
    return lambda: make_executor(args.scheduler)


def _reproduce_robustness(args: argparse.Namespace, executor) -> int:
    from delaytrack.experiments.robustness import findings, run_robustness

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


def _reproduce_job(args: argparse.Namespace) -> int:
    if args.duration is not None:
        args.duration = _scalar("--duration", args.duration)
        if args.duration <= 0:
            raise UsageError(
                f"--duration must be a positive number of seconds; got {args.duration:g}"
            )
    if args.job == "two-link":
        return _reproduce_two_link(args)
    if args.job == "margins":
        return _reproduce_margins(args)
    executor = _study_executor(args)
    if args.job == "robustness":
        return _reproduce_robustness(args, executor)
    from delaytrack.experiments.paper import DURATION, SUMMARY_COLUMNS, reproduce

    if args.duration is not None:
        steps = args.duration / 0.01
        if abs(steps - round(steps)) > 1e-9 * max(1.0, steps) or round(steps) < 1:
            raise UsageError(
                f"--duration must be a positive integer multiple of 'T_c' = 0.01 s; got "
                f"{args.duration:g}"
            )
    start = time.perf_counter()
    studies = reproduce(
        args.out,
        duration=DURATION if args.duration is None else args.duration,
        check_dt=not args.no_dt_check,
        progress=not args.quiet,
        contact=False if args.no_contact else None,
        robustness=None if args.no_robustness else args.size,
        executor=executor,
        gains=args.gains,
    )
    seconds = time.perf_counter() - start
    out = Path(args.out)
    print(
        f"paper job done in {seconds:.1f} s wall time; wrote {out / 'paper'}/ and "
        f"{out / 'paper-literal'}/"
    )
    study = studies["consistent"]
    columns = SUMMARY_COLUMNS[:5] + ["tv"]
    print(study.summary[columns].to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    if study.dt_check is not None:
        print(f"largest relative change of a metric when dt is halved: {study.dt_max_change:.2e}")
    if study.contact is not None:
        from delaytrack.experiments.contact import contact_findings

        print("with contact physics (MuJoCo): " + contact_findings(study.contact)[0])
    print(f"report: {out / 'paper' / 'report.html'}")
    return 0


def _reproduce_two_link(args: argparse.Namespace) -> int:
    from delaytrack.experiments import ScenarioError
    from delaytrack.experiments.two_link import FOLDER, reproduce

    start = time.perf_counter()
    try:
        study, files = reproduce(
            args.out, duration=args.duration, check_dt=not args.no_dt_check, progress=not args.quiet
        )
    except ScenarioError as error:  # a --duration the job's scenarios refuse
        raise UsageError(str(error).replace("scenario key 'duration'", "--duration")) from None
    seconds = time.perf_counter() - start
    folder = Path(args.out) / FOLDER
    print(f"two-link job done in {seconds:.1f} s wall time; wrote {len(files)} files to {folder}/")
    columns = ["scenario", "controller", "ae_q1", "ae_q2", "tv", "status"]
    print(study.summary[columns].to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    if study.dt_check is not None:
        print(f"largest relative change of a metric when dt is halved: {study.dt_max_change:.2e}")
    print(f"report: {folder / 'report.html'}")
    return 0


def _reproduce_margins(args: argparse.Namespace) -> int:
    from delaytrack.experiments.margins import FOLDER, reproduce

    start = time.perf_counter()
    try:
        study, files = reproduce(args.out, duration=args.duration, progress=not args.quiet)
    except ValueError as error:  # a --duration too short for the job's tracking rule
        message = _with_flag(str(error), {"duration": "--duration"}, {})
        raise UsageError(f"margins job: {message}") from None
    seconds = time.perf_counter() - start
    folder = Path(args.out) / FOLDER
    print(f"margins job done in {seconds:.1f} s wall time; wrote {len(files)} files to {folder}/")
    print(study.table.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    print(f"report: {folder / 'report.html'}")
    return 0


# --------------------------------------------------------------------------------------------
# sweep


def _sweep(args: argparse.Namespace) -> int:
    from delaytrack.sweeps import (
        SweepError,
        SweepSpec,
        SweepUnitsFailed,
        make_executor,
        run_sweep,
        write_sweep_outputs,
    )
    from delaytrack.sweeps.executors import checked_scheduler

    workers = None if args.workers is None else _count("--workers", args.workers)
    trust = _trusted(args)
    try:
        checked_scheduler(args.scheduler, workers)
    except SweepError as error:
        raise UsageError(_with_flag(str(error), {"workers": "--workers"}, {})) from None
    folder = (
        check_output_folder(args.out, "--out")
        if args.out is not None
        else check_output_folder(
            Path("results/sweeps")
            / plain_folder_name(Path(args.spec).stem, f"sweep file {args.spec!r}"),
            "the results folder",
        )
    )
    spec = SweepSpec.from_toml(args.spec, trust=trust, progress=not args.quiet)
    print(f"sweep {args.spec}: {len(spec.runs)} runs in {len(spec.units())} units -> {folder}/")
    if not args.quiet:  # the size of the work before it starts, as simulate says its own
        print(f"delaytrack: sweeping {spec.size_summary()}", file=sys.stderr, flush=True)
    executor = make_executor(args.scheduler, workers=workers)
    try:
        outcome = run_sweep(spec, folder, executor=executor, progress=not args.quiet)
    except KeyboardInterrupt as interrupted:
        print(str(interrupted) or "interrupted", file=sys.stderr)
        return 130
    except SweepUnitsFailed as failed:
        print(f"error: {failed}", file=sys.stderr)
        return 1
    files = write_sweep_outputs(outcome)
    record_outputs(folder, [*files, folder / "runs.parquet", folder / "runs.csv"])
    print(
        f"{len(spec.runs)} runs done ({outcome.computed} units computed, {outcome.resumed} found "
        f"finished) in {outcome.seconds:.1f} s on {outcome.executor}"
    )
    for name, reason in outcome.rejected.items():
        print(f"  part {name} did not count: {reason}")
    print(f"wrote runs.parquet, runs.csv and {len(files)} files to {folder}/")
    print(f"report: {folder / 'report.html'}")
    return 0


def _count(flag: str, text: str) -> int:
    value = int(text) if text.strip().isascii() and text.strip().isdigit() else 0
    if value < 1:
        raise UsageError(f"{flag} must be a positive integer; got {text!r}")
    return value


# --------------------------------------------------------------------------------------------
# tune-baselines


def _tune_baselines(args: argparse.Namespace) -> int:
    from delaytrack.experiments.tuning import gains_text, tune_controllers, write_gains

    path = check_writable_location(args.out, "--out")
    if path.is_dir():
        raise UsageError(f"--out {args.out!r} is a folder; it must name the gains file to write")
    if Path(args.out).suffix != ".toml":
        raise UsageError(
            f"--out {args.out!r} must end in .toml: tune-baselines writes a TOML gains file "
            "(read by delaytrack reproduce --gains), and a later run replaces only such a file"
        )
    if path.exists() and not is_gains_file(path):
        raise UsageError(
            f"--out {args.out!r} is a file that tune-baselines did not write; name a new file "
            "(or a gains file of an earlier run, which is replaced), so that nothing of yours is "
            "overwritten"
        )
    start = time.perf_counter()
    results = tune_controllers(progress=not args.quiet)
    path = write_gains(results, path)
    seconds = time.perf_counter() - start
    for kind, result in results.items():
        for gain_set, best in result.best.items():
            edge = "" if all(result.interior[gain_set].values()) else ", ON THE GRID'S EDGE"
            print(
                f"{kind} ({gain_set}): {gains_text(kind, best)} "
                f"(worst mean AE {best['objective']:.3g} mm{edge})"
            )
    print(f"wrote {path} in {seconds:.1f} s")
    print(f"use these gains with: delaytrack reproduce --gains {path}")
    return 0


# --------------------------------------------------------------------------------------------


def _theorem_1_arguments(command: argparse.ArgumentParser, q_default: str | None) -> None:
    """Add --k1, --k2, --q, --beta, --r, --n and --json; --q is required when it has no default."""
    command.add_argument(
        "--k1",
        required=True,
        metavar="K1",
        help="proportional gain K1: a number (times I) or a comma list (the diagonal), e.g. 1,2",
    )
    command.add_argument("--k2", required=True, metavar="K2", help="derivative gain K2 (n)")
    command.add_argument(
        "--q",
        required=q_default is None,
        default=q_default,
        metavar="Q",
        help="Lyapunov weight Q (2n)" + ("" if q_default is None else f" (default {q_default})"),
    )
    command.add_argument("--beta", default="1", metavar="BETA", help="beta > 0 (default 1)")
    command.add_argument(
        "--n",
        type=integer,
        default=None,
        help="number of joints (default: length of a comma list, else 1)",
    )
    _r_and_json_arguments(command)


def _r_and_json_arguments(command: argparse.ArgumentParser) -> None:
    """Add --r (the Razumikhin factor) and --json."""
    command.add_argument(
        "--r", default="1.1", metavar="R", help="Razumikhin factor r > 1 (default 1.1)"
    )
    command.add_argument(
        "--json", action="store_true", help="print one JSON object instead of text"
    )


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``delaytrack`` command."""
    parser = OptionParser(
        prog="delaytrack",
        description="AROLC for Euler-Lagrange systems with unknown input delay: certified delay "
        "bound, simulation, and the main job.",
    )
    from delaytrack import __version__

    parser.add_argument("--version", action="version", version=f"delaytrack {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=OptionParser)
    commands.required = True

    bound = commands.add_parser(
        "bound",
        help="the certified maximum input delay h_m of Theorem 1",
        description="Theorem 1's certified delay bound h_m = lambda_min(Q) / ||E||_2. A single "
        "number means a multiple of the identity, a comma list a diagonal (k1, k2 of length n, "
        "q of length 2n). Example: delaytrack bound --k1 1 --k2 1 --q 1 --beta 1 --r 1.1",
    )
    _theorem_1_arguments(bound, q_default="1")
    bound.set_defaults(handler=_bound)

    margin = commands.add_parser(
        "margin",
        help="certified h_m beside the exact constant-delay margin h_exact",
        description="Theorem 1's certified bound h_m and the exact delay margin h_exact of "
        "e1'' = -K2 e1'(t-h) - K1 e1(t-h) for a constant delay h (the smallest h with a root of "
        "det(s^2 I + (K2 s + K1) e^(-sh)) on the imaginary axis). Lists as for bound. "
        "Example: delaytrack margin --k1 1 --k2 1",
    )
    _theorem_1_arguments(margin, q_default="1")
    margin.set_defaults(handler=_margin)

    design = commands.add_parser(
        "design",
        help="diagonal K1, K2, Q and beta that maximise the certified h_m",
        description="Search diagonal K1, K2, Q and beta (seeded differential evolution) for the "
        "largest delay Theorem 1 certifies, with every diagonal entry of K1 and K2 at most "
        "--gain-bound. Example: delaytrack design --gain-bound 1 --seed 0",
    )
    design.add_argument("--n", type=integer, default=1, help="number of joints (default 1)")
    design.add_argument(
        "--gain-bound",
        default="1",
        metavar="B",
        help="largest diagonal entry of K1 and K2 (default 1, the paper's K1 = K2 = I)",
    )
    design.add_argument(
        "--min-bandwidth",
        default=None,
        metavar="W",
        help="least natural frequency sqrt(k1) of the delay-free loop, rad/s (default: none)",
    )
    design.add_argument("--seed", type=integer, default=0, help="search seed (default 0)")
    _r_and_json_arguments(design)
    design.set_defaults(handler=_design)

    simulate = commands.add_parser(
        "simulate",
        help="run one scenario file and write a results folder",
        description="Run a scenario TOML file (or the name of a shipped scenario such as "
        "two_link_S1) and write scenario.toml (as run), trajectories, metrics.csv and figures.",
    )
    simulate.add_argument(
        "scenario", metavar="SCENARIO", help="scenario .toml file or built-in name"
    )
    simulate.add_argument(
        "--out",
        default=None,
        metavar="DIR",
        help="results folder (default results/<scenario name>)",
    )
    simulate.add_argument(
        "--format",
        choices=("parquet", "csv", "both"),
        default="parquet",
        help="trajectory file format (default parquet)",
    )
    trust_argument(simulate)
    quiet_argument(simulate)
    simulate.set_defaults(handler=_simulate)

    empirical = commands.add_parser(
        "empirical",
        help="empirical delay margin of a scenario's closed loop (batched bisection)",
        description="The largest delay (constant h, or the amplitude a of h(t) = a |sin(w t)|) "
        "at which the scenario's closed loop ends ok and keeps the tracking metric at most "
        "--threshold: a coarse grid over [0, --upper], then multi-section down to --resolution. "
        "The scenario's [delay] is replaced. Example: delaytrack empirical two_link_margins "
        "--threshold 0.2",
    )
    empirical.add_argument(
        "scenario", metavar="SCENARIO", help="scenario .toml file or built-in name"
    )
    empirical.add_argument(
        "--threshold",
        required=True,
        metavar="VALUE",
        help="largest acceptable tracking metric: one number for every coordinate, or a comma "
        "list of one per coordinate, each in its own unit (0.05,0.1 for a plant whose coordinates "
        "are in m and rad; required: what 'still tracks' means)",
    )
    empirical.add_argument(
        "--profile",
        choices=("constant", "abs-sine", "abs-sine-offset"),
        default="constant",
        help="delay family (default constant)",
    )
    empirical.add_argument(
        "--metric",
        choices=("ae", "rms", "max"),
        default="ae",
        help="mean |e1|, RMS or max |e1| over [settle, duration], largest over the coordinates "
        "(default ae)",
    )
    empirical.add_argument(
        "--settle",
        default=None,
        metavar="S",
        help="start of the metric window (default: half the duration)",
    )
    empirical.add_argument(
        "--resolution", default="0.005", metavar="S", help="final bracket width (default 0.005 s)"
    )
    empirical.add_argument("--upper", default="1", metavar="S", help="search limit (default 1 s)")
    empirical.add_argument(
        "--frequency", default="1", metavar="W", help="w of the abs-sine families (default 1 rad/s)"
    )
    empirical.add_argument(
        "--json", action="store_true", help="print one JSON object instead of text"
    )
    trust_argument(empirical)
    quiet_argument(empirical)
    empirical.set_defaults(handler=_empirical)

    reproduce = commands.add_parser(
        "reproduce",
        help="the main job: the paper's robot experiment (S1-S4, AROLC vs PCON/PCONf)",
        description="Run the paper's robot experiment and write <out>/paper/ and "
        "<out>/paper-literal/: summary.csv, tables.md, dt_check.csv, figures and a "
        "self-contained report.html. --job two-link runs the earlier two-link job into "
        "<out>/two-link/ instead; --job margins compares certified, exact and empirical delay "
        "margins over a grid of gains into <out>/margins/.",
    )
    reproduce.add_argument(
        "--out", default="results", metavar="DIR", help="output root (default results)"
    )
    reproduce.add_argument(
        "--duration",
        default=None,
        metavar="SECONDS",
        help="override the duration (paper: 60 s, a multiple of T_c = 10 ms; two-link: 30 s, "
        "a multiple of 2 ms; margins: 30 s, a multiple of 2 ms); for quick checks",
    )
    reproduce.add_argument(
        "--job",
        choices=("paper", "two-link", "margins", "robustness"),
        default="paper",
        help="which job to run (default paper, which includes the robustness study at "
        "--size; robustness: the study alone into <out>/robustness/)",
    )
    reproduce.add_argument(
        "--size",
        choices=("default", "full"),
        default="default",
        help="size of the robustness study (default: about 3600 runs, under a minute on two "
        "cores once compiled; full: ten times the draws, meant for a Dask cluster)",
    )
    reproduce.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="run the robustness study's sweeps on a Dask cluster: a scheduler address "
        "(tcp://host:8786) or local-cluster",
    )
    reproduce.add_argument(
        "--no-robustness",
        action="store_true",
        help="paper job without the robustness study (its report then judges one run per case)",
    )
    reproduce.add_argument("--no-dt-check", action="store_true", help="skip the dt/2 rerun")
    reproduce.add_argument(
        "--no-contact",
        action="store_true",
        help="skip the runs on the robot with real wheels (MuJoCo; run by default when it is "
        "installed)",
    )
    reproduce.add_argument(
        "--gains",
        default=None,
        metavar="PATH",
        help="gains file to use instead of the shipped one (written by tune-baselines)",
    )
    quiet_argument(reproduce)
    reproduce.set_defaults(handler=_reproduce)

    sweep = commands.add_parser(
        "sweep",
        help="many runs over a grid and seeded random draws, resumable, locally or on Dask",
        description="Expand a sweep file (a base scenario, [grid] and [random] over its keys; "
        "see docs/sweeps.md) into work units and run them: <out>/parts/ gets one Parquet part "
        "per finished unit, written atomically; running the same command again skips finished "
        "units. At the end: runs.parquet/.csv, summary.csv (per controller x delay class), "
        "figures/ and report.html.",
    )
    sweep.add_argument("spec", help="sweep file (TOML)")
    sweep.add_argument(
        "--out", default=None, metavar="DIR", help="results folder (default results/sweeps/<name>)"
    )
    sweep.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="run the units on a Dask cluster: a scheduler address (tcp://host:8786) or "
        "'local-cluster' to start one here (needs delaytrack[dask]); default: this process, all "
        "cores",
    )
    sweep.add_argument(
        "--workers",
        default=None,
        metavar="N",
        help="threads of the local executor, or worker processes of --scheduler local-cluster "
        "(default: all cores)",
    )
    trust_argument(sweep)
    quiet_argument(sweep)
    sweep.set_defaults(handler=_sweep)

    tune = commands.add_parser(
        "tune-baselines",
        help="tune AROLC, PCON (two spaces) and PCONf by one protocol on drawn conditions",
        description="Tune AROLC, PCON, PCON in wheel space and PCONf by the same seeded "
        "worst-case grid search (delaytrack.experiments.tuning), one gain set for all delays and "
        "one per delay class each, and write the chosen gains, grids and per-condition results "
        "as TOML (default: the package's data/baseline_gains.toml, which the paper job reads).",
    )
    tune.add_argument(
        "--out",
        default=str(Path("results") / "baseline_gains.toml"),
        metavar="PATH",
        help="gains file to write (default results/baseline_gains.toml; use it with "
        "delaytrack reproduce --gains PATH)",
    )
    quiet_argument(tune)
    tune.set_defaults(handler=_tune_baselines)

    from delaytrack.live.cli import add_live_commands  # the real-time loop (delaytrack[live])

    add_live_commands(commands)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``delaytrack`` command; return its exit code."""
    from delaytrack.experiments import ScenarioError
    from delaytrack.sim.interruptible import every_run_interruptible, work_left_running

    parser = build_parser()
    argv = sys.argv[1:] if argv is None else list(argv)
    if not argv:  # a bare call: the commands and what they do
        parser.print_help()
        return EXIT_USAGE
    args = parser.parse_args(argv)
    try:
        with every_run_interruptible():  # Ctrl-C ends even a run whose kernel never returns
            code = args.handler(args)
        sys.stdout.flush()  # here, where a reader that closed the pipe is caught
    except BrokenPipeError:
        # The reader of the output closed it (| head): end quietly, as a program that the
        # pipe's signal ends (Python's advice, "Note on SIGPIPE": no flush into the closed pipe).
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        code = EXIT_BROKEN_PIPE
    except (UsageError, ScenarioError, OutputFolderError) as error:
        # One line, whatever the input held (a key with a newline in it).
        print(f"error: {error}".replace("\n", "\\n"), file=sys.stderr)
        code = EXIT_USAGE
    except OSError as error:
        print(f"error: {error}", file=sys.stderr)
        code = 1
    except KeyboardInterrupt as interrupted:  # where, when a factory was interrupted
        print(str(interrupted).replace("\n", "\\n") or "interrupted", file=sys.stderr)
        code = 130
    if work_left_running():  # a compiled run that Ctrl-C left computing: nothing waits for it
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    return code


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
