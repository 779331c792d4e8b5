"""The tuning protocol: one procedure, one budget and one condition set for every controller.

The paper gives no gains for its baselines, and a comparison against an untuned baseline is
worthless; a comparison of tuned baselines against an untuned AROLC is not fair either. This
module chooses the gains of AROLC, PCON (in five coordinates and in wheel space) and PCONf by the
SAME procedure; ``delaytrack tune-baselines`` runs it and writes
``delaytrack/data/baseline_gains.toml``, which the paper job and the robustness study read. The
conditions are drawn from stated distributions rather than designed; the rules below were set
before the gains they produce were run on S1–S4 or in the robustness study, and no gain was
adjusted after (an earlier protocol, with designed conditions, had been run on S1–S4 before
this one was written).

**Conditions** (:func:`draw_conditions`, drawn, not designed). Six 30 s runs of the paper's robot
(truth: the payload robot with the package's wheel friction, the ``consistent`` circle started on
it, ``dt = 1 ms``, ``T_c = 10 ms``), three per delay class, drawn with
``numpy.random.default_rng(TUNING_SEED)``:

- *varying*: ``h(t) = a + b |sin(ω t + φ)|`` with ``a ~ U(5, 30) ms``, ``b ~ U(40, 110) ms``,
  ``ω ~ U(0.1, 1.5) rad/s``, ``φ ~ U(0, π)`` (so ``h`` stays within 5–140 ms, ``|ḣ| < 0.17``);
- *constant*: ``h ~ U(20, 140) ms``;
- each with a payload seed ``~ integers(0, 2³¹)`` (the paper job's 2024 excluded).

What each controller is told of the delay: AROLC nothing; PCON the true ``h(t)`` (its
assumption); PCONf the constant ``h̄`` = the profile's long-run mean ``a + 2b/π`` (the delay
itself in the constant class).

**Budget and grids** (:data:`GRIDS`): three gains per controller, five values each, 125 grid
points, every one run on every condition.

- PCON, PCON in wheel space, PCONf: ``κ``, ``k_b`` (times I) and ``ϑ = c ϑ₀`` with ``ϑ₀`` the
  nominal model's estimate of the inverse mass matrix at the reference's initial pose
  (:func:`vartheta_base`): ``M̂⁻¹`` (5×5) for the five-coordinate law, ``M̂_r⁻¹ = (SᵀM̂S)⁻¹``
  (2×2) for the wheel-space law (paper Refs 31–32: ``ϑ`` estimates ``M⁻¹``). The same ``c``
  grid for all three, reaching ``c = 1`` (the model's own estimate). The sampled law is stable
  only for about ``T_c k_b c λ_max(ϑ₀) < 2`` (docs/decisions.md, D23; ``λ_max`` is 100 for ``M̂⁻¹``,
  about 19 for ``M̂_r⁻¹``): the initial grid crosses that edge for the five-coordinate law and
  reaches about 0.76 of it for the wheel-space law, whose optimum the edge rule then follows.
- AROLC: a gain scale ``k``, ``K1 = k² I``, ``K2 = 2 ζ k I`` (outer loop of natural frequency
  ``k`` rad/s and damping ``ζ``), the damping ``ζ`` and the switching gain ``α``; ``Q = I``,
  ``ε = 0.1``, ``γ = 0.001`` are the paper's. The paper's own gains are the point ``k = 1``,
  ``ζ = 0.5`` (``K1 = K2 = I``), with ``α = 2`` between grid values.

**Edges** (the same rule for all). When a gain set's chosen value of a gain is the largest
(smallest) of its grid, the grid of that gain is extended by one value, 1.5 times the largest
(the smallest divided by 1.5), the new points are run, and the choice is made again; at most
:data:`MAX_EXTENSIONS` rounds. A choice still on an edge after them is reported as such.

**Objective** (the same for all): for each condition the mean of AE-x and AE-y (mm) over the
whole run; a gain set's objective is the WORST (largest) of these over its conditions. A grid
point that diverges under any of its conditions (the run stops, or its mean AE exceeds
:data:`DIVERGED_AE_MM`: it diverged from the path with a finite state) is excluded. Smallest
objective wins; ties go to the first in grid order.

**Gain sets** (:data:`GAIN_SETS`), for every controller: ``all`` (one gain set for every delay,
all six conditions), ``varying`` and ``constant`` (one gain set per delay class, its three
conditions). Every run is simulated once; the sets differ only in which conditions the worst
case is taken over.

For AROLC, Theorem 1's certified delay bound ``h_m`` (``razumikhin_bound(K1, K2, Q, β = 1,
r = 1.1)``) is published beside each choice; the predictors have no such certificate.

**Reading a gains file** (:func:`load_tuning_record`, :func:`load_gains`): every chosen gain
set is checked when the file is read, before anything runs: each gain a finite TOML number
``> 0`` (never text, true/false, nan or inf; ``objective`` and ``h_m`` ``>= 0``), and the
controller it is for built with them, so that its own checks apply (AROLC's ``α <= 1e100``).
Errors (:class:`GainsFileError`) name the file, the table (``[AROLC.varying]``), the key, the
value and what is valid.

Everything is deterministic (the draws and payload placements are seeded).
:func:`tune_controllers` returns a :class:`TuningStudy` holding every number of the tuning's
report (:mod:`delaytrack.report.tuning`: the chosen gains as text).
"""

from __future__ import annotations

import itertools
import math
import time
import tomllib
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Any, NoReturn, Unpack

import numpy as np
import pandas as pd
import tomli_w
from tqdm.auto import tqdm

from delaytrack._io import MAX_TOML_BYTES, read_file_bytes, toml_data, write_text
from delaytrack.analysis import razumikhin_bound
from delaytrack.analysis.razumikhin import PAPER_BETA as BETA
from delaytrack.analysis.razumikhin import PAPER_R as R
from delaytrack.controllers import AROLC, PCON, PCONf
from delaytrack.controllers.base import Controller
from delaytrack.controllers.delay_knowledge import DelayKnowledge
from delaytrack.delays import AbsSineDelay, ConstantDelay, DelayProfile

# The plant step and controller period of the reported runs, and their payload seed.
from delaytrack.experiments.paper_setup import DT, PAYLOAD_SEED, T_C
from delaytrack.metrics import mean_absolute_error, total_variation
from delaytrack.plants.robot import NominalRobot, PayloadRobot, initial_state, paper_reference
from delaytrack.plants.robot.kinematics import kinematic_map
from delaytrack.sim import simulate
from delaytrack.sim.certified_bound import stated_by_the_caller

__all__ = [
    "AROLC_FIXED",
    "CONDITIONS",
    "DELAY_CLASSES",
    "DIVERGED_AE_MM",
    "GAIN_NAMES",
    "GainsFileError",
    "GAIN_SETS",
    "GRIDS",
    "KINDS",
    "PREDICTORS",
    "TUNING_SEED",
    "Condition",
    "TuningResult",
    "TuningStudy",
    "arolc_gains",
    "certified_bound",
    "default_gains_path",
    "draw_conditions",
    "gains_text",
    "grid_table",
    "long_run_mean",
    "load_gains",
    "load_tuning_record",
    "make_controller",
    "off_path",
    "recorded_gains_text",
    "set_conditions",
    "tune",
    "tune_controllers",
    "vartheta_base",
    "write_gains",
]

#: Seed of the conditions' draws (:func:`draw_conditions`).
TUNING_SEED = 7
#: Conditions drawn per delay class.
CONDITIONS_PER_CLASS = 3
#: Seconds simulated per tuning run.
TUNING_DURATION = 30.0
#: Most rounds of grid extension (module docstring, "Edges").
MAX_EXTENSIONS = 3
#: Factor of one grid extension.
EXTENSION_FACTOR = 1.5
#: Seconds of command history the predictors keep (every tuning delay is below 140 ms).
HISTORY = 0.15
#: A run whose mean AE over the whole run exceeds this (mm) counts as diverged, beside the runs
#: the engine stopped (diverged, or left the path by the scenario's ``error_bound``): a grid
#: point so detuned that its error averages a metre while its state stays finite and within the
#: bound is excluded from the choice as if it had stopped.
DIVERGED_AE_MM = 1000.0


def off_path(ok: np.ndarray, ae_mm: np.ndarray) -> np.ndarray:
    """Whether each run counts as off the path by the rule of the tuning, the robustness study
    and the paper job's claims: it did not end ``ok`` (``ok`` False), or its mean AE (mm) is
    not finite or above :data:`DIVERGED_AE_MM`."""
    ae = np.asarray(ae_mm, dtype=float)
    return ~np.asarray(ok, dtype=bool) | ~np.isfinite(ae) | (ae > DIVERGED_AE_MM)


#: The tuned controllers. ``PCON-wheel`` is PCON in wheel space (``space="actuator"``).
KINDS: tuple[str, ...] = ("AROLC", "PCON", "PCON-wheel", "PCONf")
#: The controllers that are told the delay.
PREDICTORS: tuple[str, ...] = ("PCON", "PCON-wheel", "PCONf")
#: Delay classes of the conditions.
DELAY_CLASSES: tuple[str, ...] = ("varying", "constant")
#: Gain sets chosen per controller: one for every delay, one per delay class.
GAIN_SETS: tuple[str, ...] = ("all", *DELAY_CLASSES)
_PREDICTOR_GRID: dict[str, tuple[float, ...]] = {
    "kappa": (4.0, 6.0, 8.0, 12.0, 16.0),
    "k_b": (1.0, 1.5, 2.0, 3.0, 4.0),
    "c": (0.1, 0.2, 0.35, 0.6, 1.0),
}
#: Each controller's grid (gain name -> values; three gains, five values each).
GRIDS: dict[str, dict[str, tuple[float, ...]]] = {
    "AROLC": {
        "k": (1.0, 2.0, 3.0, 4.0, 6.0),
        "zeta": (0.5, 0.7, 1.0, 1.4, 2.0),
        "alpha": (1.0, 2.0, 4.0, 8.0, 16.0),
    },
    **{kind: dict(_PREDICTOR_GRID) for kind in PREDICTORS},
}
GAIN_NAMES: dict[str, tuple[str, ...]] = {kind: tuple(grid) for kind, grid in GRIDS.items()}
#: AROLC's gains that are not tuned (the paper's).
AROLC_FIXED = dict(Q=1.0, epsilon=0.1, gamma=0.001)


@dataclass(frozen=True)
class Condition:
    """One tuning condition: the true delay, its class, the constant ``h̄`` PCONf is told, the
    payload seed and a description."""

    delay: DelayProfile
    delay_class: str
    h_bar: float
    seed: int
    text: str


def draw_conditions(
    seed: int = TUNING_SEED, per_class: int = CONDITIONS_PER_CLASS
) -> tuple[Condition, ...]:
    """The tuning conditions: ``per_class`` varying, then ``per_class`` constant delays, drawn
    from the distributions of the module docstring with ``numpy.random.default_rng(seed)``."""
    rng = np.random.default_rng(seed)
    conditions = []
    for _ in range(per_class):
        a, b = rng.uniform(0.005, 0.03), rng.uniform(0.04, 0.11)
        omega, phi = rng.uniform(0.1, 1.5), rng.uniform(0.0, math.pi)
        payload = _payload_seed(rng)
        text = (
            f"h(t) = {1e3 * a:.1f} + {1e3 * b:.1f} |sin({omega:.3f} t + {phi:.3f})| ms, "
            f"payload seed {payload}"
        )
        delay = AbsSineDelay(offset=a, amplitude=b, frequency=omega, phase=phi)
        conditions.append(Condition(delay, "varying", long_run_mean(delay), payload, text))
    for _ in range(per_class):
        h = rng.uniform(0.02, 0.14)
        payload = _payload_seed(rng)
        text = f"h = {1e3 * h:.1f} ms constant, payload seed {payload}"
        conditions.append(Condition(ConstantDelay(h), "constant", h, payload, text))
    return tuple(conditions)


def long_run_mean(delay: AbsSineDelay) -> float:
    """``a + 2b/π``: the long-run mean (s) of ``h(t) = a + b |sin(ω t + φ)|``, the constant
    PCONf is told of a time-varying delay."""
    return float(delay.offset + 2.0 * delay.amplitude / math.pi)


def _payload_seed(rng: np.random.Generator) -> int:
    """A drawn payload seed, never the paper job's (:data:`PAYLOAD_SEED`)."""
    while (seed := int(rng.integers(0, 2**31))) == PAYLOAD_SEED:
        pass
    return seed


#: The conditions every controller is tuned on.
CONDITIONS: tuple[Condition, ...] = draw_conditions()


def default_gains_path() -> Path:
    """The shipped gains file, ``delaytrack/data/baseline_gains.toml``."""
    return Path(str(resources.files("delaytrack").joinpath("data", "baseline_gains.toml")))


#: Where gains come from: a gains file, its contents as :func:`load_tuning_record` gives them,
#: or None for :func:`default_gains_path`.
GainsSource = str | Path | Mapping[str, Any] | None


@lru_cache(maxsize=16)
def vartheta_base(kind: str = "PCON", reference: str = "consistent") -> np.ndarray:
    """``ϑ₀``: the nominal robot's inverse mass matrix at the reference's initial pose.

    ``M̂⁻¹`` (5×5) for the five-coordinate law (``PCON``, ``PCONf``), ``(S(q)ᵀ M̂ S(q))⁻¹``
    (2×2, the reduced mass matrix's inverse) for ``PCON-wheel``. Computed once per kind and
    reference (read-only).
    """
    robot = NominalRobot()
    q = initial_state(paper_reference(reference))[:5]
    mass = robot.mass_matrix(q)[0]
    if kind == "PCON-wheel":
        S = kinematic_map(q, robot.wheel_radius, robot.half_track, robot.d)
        mass = S.T @ mass @ S
    inverse = np.linalg.inv(mass)
    base = 0.5 * (inverse + inverse.T)
    base.setflags(write=False)
    return base


def arolc_gains(k: float, zeta: float, alpha: float) -> dict[str, float]:
    """AROLC's gains for scale ``k`` and damping ``ζ``: ``K1 = k²``, ``K2 = 2 ζ k`` (times I),
    ``α``, and the paper's ``Q, ε, γ``."""
    return dict(K1=k * k, K2=2.0 * zeta * k, alpha=alpha, **AROLC_FIXED)


def _with_outer_loop_gains(kind: str, gains: Mapping[str, float]) -> dict[str, float]:
    """``gains`` and, for AROLC, the outer loop's ``K1 = k²``, ``K2 = 2 ζ k`` they give
    (:func:`arolc_gains`)."""
    if kind != "AROLC":
        return dict(gains)
    g = arolc_gains(gains["k"], gains["zeta"], gains["alpha"])
    return {**gains, "K1": g["K1"], "K2": g["K2"]}


def gains_text(kind: str, gains: Mapping[str, float]) -> str:
    """The gains of one chosen set as text (``κ = 8, k_b = 3 I, ϑ = 0.35 M̂⁻¹``); AROLC's
    with the outer loop's ``K1 = k²``, ``K2 = 2 ζ k`` they give (``k = 6 rad/s, ζ = 0.7
    (K1 = 36 I, K2 = 8.4 I), α = 54``)."""
    return recorded_gains_text(kind, _with_outer_loop_gains(kind, gains))


def recorded_gains_text(kind: str, gains: Mapping[str, float]) -> str:
    """The gains of one chosen set as text, as a gains file records them.

    AROLC's read ``k``, ``ζ`` (``zeta``), ``α`` (``alpha``) and the outer loop's ``K1 = k²``,
    ``K2 = 2 ζ k`` they give (``K1``, ``K2``: as in a gains file and in
    :attr:`TuningResult.best`); :func:`gains_text` computes those two.
    """
    if kind == "AROLC":
        return (
            f"k = {gains['k']:g} rad/s, ζ = {gains['zeta']:g} (K1 = {gains['K1']:g} I, "
            f"K2 = {gains['K2']:g} I), α = {gains['alpha']:g}"
        )
    inverse = "M̂_r⁻¹" if kind == "PCON-wheel" else "M̂⁻¹"
    return f"κ = {gains['kappa']:g}, k_b = {gains['k_b']:g} I, ϑ = {gains['c']:g} {inverse}"


def certified_bound(k: float, zeta: float) -> float:
    """Theorem 1's ``h_m`` (s) for AROLC with :func:`arolc_gains` (``β = 1``, ``r = 1.1``)."""
    g = arolc_gains(k, zeta, 1.0)
    return float(razumikhin_bound(g["K1"], g["K2"], g["Q"], BETA, R, n=NominalRobot.n).h_m)


def make_controller(
    kind: str,
    gains: Mapping[str, float],
    *,
    h_bar: float | None = None,
    history: float = HISTORY,
    reference: str = "consistent",
    **knowledge: Unpack[DelayKnowledge],
) -> Controller:
    """One of :data:`KINDS` on the nominal robot with the grid's ``gains`` (names of
    :data:`GAIN_NAMES`).

    ``PCONf`` needs ``h_bar``; ``knowledge`` (``delay_scale``, ``delay_offset``, ``delay_noise``,
    ``noise_seed``) is what PCON is told of the delay (:class:`~delaytrack.controllers.PCON`).
    """
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {KINDS}; got {kind!r}")
    if kind == "AROLC":
        return AROLC(NominalRobot(), **arolc_gains(gains["k"], gains["zeta"], gains["alpha"]))
    kappa = gains["kappa"]
    vartheta = gains["c"] * vartheta_base(kind, reference)
    k_b = gains["k_b"]
    space = "actuator" if kind == "PCON-wheel" else "generalised"
    if kind == "PCONf":
        if h_bar is None:
            raise ValueError("PCONf needs h_bar")
        return PCONf(NominalRobot(), kappa, vartheta, k_b, history, T_C, h_bar, space=space)
    return PCON(NominalRobot(), kappa, vartheta, k_b, history, T_C, space=space, **knowledge)


@dataclass(frozen=True)
class TuningResult:
    """One controller's grid search.

    Attributes
    ----------
    kind : str
        One of :data:`KINDS`.
    table : DataFrame
        One row per grid point (grid order): the gains, AROLC's ``h_m`` (s), ``ae_mm_1 …
        ae_mm_m`` (mean AE in mm per condition, NaN when the run diverged), ``tv_1 … tv_m``
        (N·m) and ``status`` (``ok`` or what diverged first, naming the condition).
    best : dict
        Per gain set (:data:`GAIN_SETS`): the chosen gains and their ``objective`` (mm; AROLC also
        ``h_m`` and the outer loop's ``K1``, ``K2``).
    interior : dict
        Per gain set and gain: whether the chosen value is strictly inside the grid's range.
    conditions : tuple of Condition
        The conditions (``ae_mm_i`` is condition ``i``).
    duration : float
        Simulated seconds per run.
    seconds : float
        Wall time.
    """

    kind: str
    table: pd.DataFrame
    best: dict[str, dict[str, float]]
    interior: dict[str, dict[str, bool]]
    conditions: tuple[Condition, ...]
    duration: float
    seconds: float

    @property
    def inside(self) -> dict[str, bool]:
        """Per gain set: whether every chosen value lies strictly inside its grid (else the set
        is on an edge of it)."""
        return {gain_set: all(flags.values()) for gain_set, flags in self.interior.items()}


def set_conditions(classes: Sequence[str], gain_set: str) -> list[int]:
    """The numbers (from 1) of a gain set's conditions (``classes``: each condition's delay
    class, in order; ``"all"``: every one)."""
    return [
        j
        for j, delay_class in enumerate(classes, start=1)
        if gain_set == "all" or delay_class == gain_set
    ]


def _members(classes: Sequence[str], gain_set: str) -> list[str]:
    """The ``ae_mm_<j>`` columns of a gain set's conditions (:func:`set_conditions`)."""
    return [f"ae_mm_{j}" for j in set_conditions(classes, gain_set)]


def _objective(table: pd.DataFrame, columns: list[str]) -> np.ndarray:
    """Worst mean AE over ``columns``; NaN when any of them diverged."""
    values = table[columns].to_numpy()
    return np.where(np.isnan(values).any(axis=1), np.nan, np.nanmax(values, axis=1, initial=-1.0))


def _evaluate(
    kind: str,
    points: list[dict[str, float]],
    conditions: Sequence[Condition],
    duration: float,
) -> list[tuple[list[float], list[float], str]]:
    """Mean AE (mm, NaN when diverged), TV (N·m) per condition and the status of each point: one
    batched simulation (all points) per condition."""
    reference = paper_reference()
    ae_all = np.full((len(points), len(conditions)), np.nan)
    tv_all = np.full((len(points), len(conditions)), np.nan)
    status = ["ok"] * len(points)
    for j, condition in enumerate(conditions):
        with stated_by_the_caller():  # gains are tried beyond their h_m on purpose
            result = simulate(
                PayloadRobot(seed=condition.seed, duration=duration),
                [make_controller(kind, p, h_bar=condition.h_bar) for p in points],
                condition.delay,
                initial_state(reference),
                reference=reference,
                t1=duration,
                dt=DT,
                T_c=T_C,
            )
        ae = 1e3 * mean_absolute_error(result)[:, :2].mean(axis=1)
        names = np.asarray(result.status_names)
        left = off_path(names == "ok", ae)
        for i in np.flatnonzero(left):
            if status[i] == "ok":
                name = "left path" if names[i] == "ok" else names[i]
                status[i] = f"{name} (condition {j + 1})"
        ae_all[:, j] = np.where(left, np.nan, ae)
        tv_all[:, j] = np.where(left, np.nan, total_variation(result))
    return [(list(a), list(t), s) for a, t, s in zip(ae_all, tv_all, status, strict=True)]


def _choose(
    kind: str, table: pd.DataFrame, conditions: Sequence[Condition]
) -> dict[str, dict[str, float]]:
    """The chosen point per gain set (smallest worst-case AE; ties: first in table order)."""
    best = {}
    for gain_set in GAIN_SETS:
        members = _members([c.delay_class for c in conditions], gain_set)
        objective = _objective(table, members)
        if not np.any(np.isfinite(objective)):
            raise RuntimeError(f"every {kind} grid point diverged on gain set {gain_set!r}")
        index = int(np.nanargmin(objective))
        chosen = {name: float(table[name].iloc[index]) for name in GAIN_NAMES[kind]}
        chosen["objective"] = float(objective[index])
        if kind == "AROLC":
            chosen["h_m"] = float(table["h_m"].iloc[index])
        best[gain_set] = _with_outer_loop_gains(kind, chosen)
    return best


def _extend(grid: dict[str, tuple[float, ...]], best: dict[str, dict[str, float]]) -> bool:
    """Extend every gain whose choice (in any gain set) is on its grid's edge; True if any."""
    extended = False
    for name, values in grid.items():
        chosen = {b[name] for b in best.values()}
        low, high = min(values), max(values)
        if high in chosen:
            values = (*values, high * EXTENSION_FACTOR)
        if low in chosen:
            values = (low / EXTENSION_FACTOR, *values)
        extended = extended or values != grid[name]
        grid[name] = values
    return extended


def tune(
    kind: str,
    *,
    grid: Mapping[str, Sequence[float]] | None = None,
    conditions: Sequence[Condition] = CONDITIONS,
    duration: float = TUNING_DURATION,
    extensions: int = MAX_EXTENSIONS,
    progress: bool = False,
) -> TuningResult:
    """Grid-search one controller on the conditions, extending edge choices at most
    ``extensions`` times (module docstring)."""
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {KINDS}; got {kind!r}")
    names = GAIN_NAMES[kind]
    axes = {
        name: tuple(float(v) for v in (GRIDS[kind] if grid is None else grid)[name])
        for name in names
    }
    results: dict[tuple[float, ...], tuple[list[float], list[float], str]] = {}
    start = time.perf_counter()
    with tqdm(desc=f"tuning {kind}", unit="round", disable=not progress) as bar:
        for round_ in range(extensions + 1):
            points = [dict(zip(names, p, strict=True)) for p in itertools.product(*axes.values())]
            new = [p for p in points if tuple(p.values()) not in results]
            for p, outcome in zip(new, _evaluate(kind, new, conditions, duration), strict=True):
                results[tuple(p.values())] = outcome
            table = _table(kind, points, [results[tuple(p.values())] for p in points])
            best = _choose(kind, table, conditions)
            bar.update()
            if round_ == extensions or not _extend(axes, best):
                break
    interior = {
        gain_set: {name: min(axes[name]) < chosen[name] < max(axes[name]) for name in names}
        for gain_set, chosen in best.items()
    }
    seconds = time.perf_counter() - start
    return TuningResult(kind, table, best, interior, tuple(conditions), duration, seconds)


def _table(
    kind: str,
    points: list[dict[str, float]],
    outcomes: list[tuple[list[float], list[float], str]],
) -> pd.DataFrame:
    columns: dict[str, Any] = {name: [p[name] for p in points] for name in GAIN_NAMES[kind]}
    if kind == "AROLC":
        bounds = {key: certified_bound(*key) for key in {(p["k"], p["zeta"]) for p in points}}
        columns["h_m"] = [bounds[(p["k"], p["zeta"])] for p in points]
    m = len(outcomes[0][0])
    for j in range(m):
        columns[f"ae_mm_{j + 1}"] = [o[0][j] for o in outcomes]
    for j in range(m):
        columns[f"tv_{j + 1}"] = [o[1][j] for o in outcomes]
    columns["status"] = [o[2] for o in outcomes]
    return pd.DataFrame(columns)


@dataclass(frozen=True)
class TuningStudy(Mapping[str, TuningResult]):
    """Every controller's grid search, as :func:`tune_controllers` returns it: a read-only
    mapping ``kind -> TuningResult`` in the order tuned (``results``)."""

    results: Mapping[str, TuningResult]

    def __getitem__(self, kind: str) -> TuningResult:
        return self.results[kind]

    def __iter__(self) -> Iterator[str]:
        return iter(self.results)

    def __len__(self) -> int:
        return len(self.results)


def tune_controllers(
    *,
    kinds: Sequence[str] = KINDS,
    grids: Mapping[str, Mapping[str, Sequence[float]]] | None = None,
    conditions: Sequence[Condition] = CONDITIONS,
    duration: float = TUNING_DURATION,
    progress: bool = False,
) -> TuningStudy:
    """:func:`tune` every controller of ``kinds``; returns ``kind -> TuningResult``."""
    grids = grids or {}
    results = {}
    with tqdm(total=len(kinds), desc="tuning", unit="controller", disable=not progress) as bar:
        for kind in kinds:
            bar.set_postfix_str(kind)
            results[kind] = tune(
                kind, grid=grids.get(kind), conditions=conditions, duration=duration
            )
            bar.update()
    return TuningStudy(results)


def write_gains(results: Mapping[str, TuningResult], path: str | Path | None = None) -> Path:
    """Write the protocol, the conditions, every grid with its per-condition results and the
    chosen gains per gain set as TOML (default: :func:`default_gains_path`)."""
    path = default_gains_path() if path is None else Path(path)
    first = next(iter(results.values()))
    data: dict[str, Any] = {
        "generated_by": "delaytrack tune-baselines (delaytrack.experiments.tuning)",
        "procedure": "full-factorial grid of 3 gains x 5 values per controller, every point run "
        "on every condition; a gain set's objective is the WORST over its conditions of "
        "mean(AE-x, AE-y) in mm over the whole run; a point that diverges under any of its "
        f"conditions (status not ok, or mean AE > {DIVERGED_AE_MM:g} mm) is excluded; smallest "
        "objective wins (ties: first in grid order)",
        "duration": first.duration,
        "dt": DT,
        "T_c": T_C,
        "history": HISTORY,
        "reference": "consistent",
        "condition_seed": TUNING_SEED,
        "conditions": [c.text for c in first.conditions],
        "condition_classes": [c.delay_class for c in first.conditions],
        "condition_h_bar": [c.h_bar for c in first.conditions],
        "arolc_fixed": {k: float(v) for k, v in AROLC_FIXED.items()},
    }
    for kind, result in results.items():
        columns = [c for c in result.table.columns if c != "status"]
        section: dict[str, Any] = {
            "grid": {name: sorted(set(map(float, result.table[name]))) for name in GAIN_NAMES[kind]}
        }
        for gain_set, chosen in result.best.items():
            section[gain_set] = {**chosen, "interior": result.inside[gain_set]}
        section["columns"] = columns
        section["status"] = list(result.table["status"])
        section["rows"] = [[float(v) for v in row] for row in result.table[columns].to_numpy()]
        data[kind] = section
    return write_text(path, tomli_w.dumps(data))


class GainsFileError(ValueError):
    """A gains file (or record) that cannot be used: one line naming the file, the table and
    key, the value and what is valid; ``problem`` is the same without the file."""

    def __init__(self, message: str, problem: str | None = None) -> None:
        super().__init__(message)
        self.problem = message if problem is None else problem


#: The numbers read from a chosen gain set besides its gains, and whether each may be zero.
_AROLC_RECORDED = (("h_m", True), ("K1", False), ("K2", False))
_RECORDED: dict[str, tuple[tuple[str, bool], ...]] = {
    kind: (("objective", True), *(_AROLC_RECORDED if kind == "AROLC" else ())) for kind in KINDS
}


def load_tuning_record(source: GainsSource = None) -> Mapping[str, Any]:
    """The whole gains file as data (protocol, conditions, grids, per-condition results), its
    chosen gain sets checked (module docstring, "Reading a gains file"); a record already
    loaded is checked and returned as it is (load it once, pass it on).

    Raises
    ------
    GainsFileError
        For a file that is not a regular file or not TOML, or a chosen gain set that is not
        usable, naming the file, the table, the key, the value and what is valid.
    """
    if isinstance(source, Mapping):
        _check_chosen(source, "the gains record")
        return source
    path = default_gains_path() if source is None else Path(source)
    where = f"gains file {str(path)!r}"
    raw = read_file_bytes(path, "gains file", GainsFileError, largest=MAX_TOML_BYTES)
    try:
        record = toml_data(raw.decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as error:
        problem = f"is not TOML ({error}); give a gains file written by tune-baselines"
        raise GainsFileError(f"{where} {problem}", problem) from None
    _check_chosen(record, where)
    return record


def _check_chosen(record: Mapping[str, Any], where: str) -> None:
    """Check every chosen gain set of ``record`` (module docstring); ``where`` names it."""
    for kind in KINDS:
        sets = record.get(kind)
        if sets is None:
            continue
        if not isinstance(sets, Mapping):
            _refuse(where, f"[{kind}] is {sets!r}; it must be a table of gain sets")
        for gain_set in GAIN_SETS:
            if gain_set not in sets:
                continue
            table = f"[{kind}.{gain_set}]"
            chosen = sets[gain_set]
            if not isinstance(chosen, Mapping):
                _refuse(where, f"{table} is {chosen!r}; it must be a table of gains")
            gains = {
                key: _number(where, table, chosen, key, zero=False) for key in GAIN_NAMES[kind]
            }
            for key, zero in _RECORDED[kind]:
                _number(where, table, chosen, key, zero=zero)
            try:
                make_controller(kind, gains, h_bar=0.0)
            except (ValueError, TypeError) as error:
                shown = gains_text(kind, gains)
                _refuse(where, f"{table} {shown}: {kind} refuses these gains ({error})")


def _number(where: str, table: str, chosen: Mapping[str, Any], key: str, *, zero: bool) -> float:
    """``chosen[key]``: a finite TOML number, ``> 0`` (``>= 0`` when ``zero``)."""
    valid = (
        f"it must be a finite number {'>= 0' if zero else '> 0'}, written as a TOML number "
        "(such as 6.0; not text, true/false, nan or inf)"
    )
    if key not in chosen:
        _refuse(where, f"{table} lacks {key}; {valid}")
    value = chosen[key]
    if isinstance(value, bool):
        wrong = "true/false"
    elif isinstance(value, str):
        wrong = "text"
    elif not isinstance(value, int | float):
        wrong = "not a number"
    else:
        try:
            number = float(value)
        except OverflowError:  # a TOML integer beyond double precision
            number = math.inf
        if math.isfinite(number) and (number > 0 or (zero and number == 0)):
            return number
        wrong = "not finite" if not math.isfinite(number) else "negative" if number < 0 else "zero"
    shown = str(value).lower() if isinstance(value, bool) else repr(value)
    _refuse(where, f"{table} {key} = {shown} is {wrong}; {valid}")


def _refuse(where: str, problem: str) -> NoReturn:
    raise GainsFileError(f"{where}: {problem}", problem)


def load_gains(source: GainsSource = None) -> dict[str, dict[str, dict[str, float]]]:
    """The chosen gains: ``kind -> gain set -> {gain: value, "objective": mm}`` (AROLC also
    ``h_m``, ``K1``, ``K2``), for every kind and gain set in the file, checked
    (:func:`load_tuning_record`)."""
    record = load_tuning_record(source)
    out: dict[str, dict[str, dict[str, float]]] = {}
    for kind in KINDS:
        if kind not in record:
            continue
        keys = (*GAIN_NAMES[kind], *(key for key, _ in _RECORDED[kind]))
        out[kind] = {
            gain_set: {key: float(record[kind][gain_set][key]) for key in keys}
            for gain_set in GAIN_SETS
            if gain_set in record[kind]
        }
    return out


def grid_table(kind: str, gain_set: str = "all", source: GainsSource = None) -> pd.DataFrame:
    """One controller's grid from the gains file: gains, per-condition results, ``status`` and
    the gain set's ``objective`` (mm, NaN where a run of the set diverged)."""
    record = load_tuning_record(source)
    section = record[kind]
    table = pd.DataFrame(section["rows"], columns=section["columns"])
    table["status"] = section["status"]
    members = _members(record["condition_classes"], gain_set)
    return table.assign(objective=_objective(table, members))
