"""Tuning of the predictor baselines PCON and PCONf for the robot experiment (SPEC §4, §6).

The paper gives no gains for its baselines, and a comparison against an untuned baseline is
worthless (SPEC §4). This module is the documented, seeded and reproducible procedure that chooses
them; ``delaytrack tune-baselines`` runs it and writes ``delaytrack/data/baseline_gains.toml``,
which :mod:`delaytrack.experiments.paper` reads.

Procedure (one full-factorial grid search per baseline):

- **Gains searched.** ``κ`` (scalar), ``k_b`` (scalar, i.e. ``k_b I``) and ``ϑ = c · M̂(q_d(0))⁻¹``
  with ``M̂`` the nominal robot's (:class:`~delaytrack.plants.robot.NominalRobot`) mass matrix at
  the reference's initial pose: ``ϑ`` is the law's estimate of ``M⁻¹`` (SPEC §4), scaled by ``c``.
  docs/decisions.md D23: the sampled law is stable only for roughly
  ``T_c · k_b · λ_max(ϑ) < 2``; ``λ_max(M̂⁻¹) = 1/I_w = 100`` (the wheels), so with
  ``T_c = 10 ms`` this needs ``k_b · c < 2``. The grid straddles that boundary so that the optimum
  is interior (checked and reported: :attr:`TuningResult.interior`).
- **Held-out conditions** (none of S1–S4): PCON on ``h(t) = 10 + 120 |sin(0.5 t + 0.7)|`` ms
  with the true delay given to it; PCONf on a constant ``130 ms`` with ``h̄ = 130 ms``. Their
  largest delays (130 ms) exceed those of every reported scenario (S2: 125 ms, S4: 120 ms): gains
  tuned on milder delays (a first attempt used 10 + 100 |sin| ms and 90 ms) sit so close to the
  sampled law's stability limit that they went unstable under S2 and S4. Truth plant: the
  payload robot with friction (package defaults) and payload seed :data:`TUNING_SEED`, which differs
  from the seed of the reported runs; the ``consistent`` reference started on it; 30 s runs with
  the reported runs' ``dt = 1 ms``, ``T_c = 10 ms``.
- **Objective**: the mean of AE-x and AE-y (mm) over the whole run. Runs that stop as diverged, or
  whose objective exceeds :data:`DIVERGED_AE_MM` (the robot left the path: the loop is unstable
  although the state stayed finite), are *diverged* and excluded. The grid point with the
  smallest objective wins (ties: the first in grid order).

Everything is deterministic (no random element besides the seeded payload placements), so the same
seed and grid give the same result.
"""

from __future__ import annotations

import itertools
import time
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from delaytrack._io import write_text
from delaytrack.controllers import PCON, PCONf
from delaytrack.delays import AbsSineDelay, ConstantDelay, DelayProfile
from delaytrack.experiments.scenario import dumps_toml
from delaytrack.metrics import mean_absolute_error, total_variation
from delaytrack.plants.robot import NominalRobot, PayloadRobot, initial_state, paper_reference
from delaytrack.sim import simulate

__all__ = [
    "BASELINES",
    "DIVERGED_AE_MM",
    "GRID",
    "TUNING_SEED",
    "TuningResult",
    "default_gains_path",
    "load_gains",
    "make_baseline",
    "tune",
    "tune_baselines",
    "vartheta_base",
    "write_gains",
]

#: Payload seed of the tuning runs (the reported runs use another one).
TUNING_SEED = 7
#: Seconds simulated per tuning run.
TUNING_DURATION = 30.0
#: Plant step and controller period (those of the reported runs).
DT, T_C = 1e-3, 0.01
#: Seconds of command history PCON keeps (covers every delay used: S2's maximum is 125 ms).
HISTORY = 0.15
#: A run whose objective exceeds this (mm) left the path and counts as diverged.
DIVERGED_AE_MM = 1000.0
#: The grid: ``kappa``, ``k_b`` and ``c`` (``ϑ = c M̂(q_d(0))⁻¹``).
GRID: dict[str, tuple[float, ...]] = {
    "kappa": (4.0, 6.0, 8.0, 12.0, 16.0),
    "k_b": (1.0, 1.5, 2.0, 3.0, 4.0),
    "c": (0.1, 0.15, 0.25, 0.35, 0.5),
}
#: Held-out tuning conditions per baseline: (delay profile, h̄ for PCONf, description).
BASELINES: dict[str, tuple[DelayProfile, float | None, str]] = {
    "PCON": (
        AbsSineDelay(offset=0.01, amplitude=0.12, frequency=0.5, phase=0.7),
        None,
        "h(t) = 10 + 120 |sin(0.5 t + 0.7)| ms, the true h(t) given to PCON",
    ),
    "PCONf": (ConstantDelay(0.13), 0.13, "h = 130 ms constant, h̄ = 130 ms"),
}


def default_gains_path() -> Path:
    """The shipped gains file, ``delaytrack/data/baseline_gains.toml``."""
    return Path(str(resources.files("delaytrack").joinpath("data", "baseline_gains.toml")))


def vartheta_base(reference: str = "consistent") -> np.ndarray:
    """``M̂(q_d(0))⁻¹`` of the nominal robot at the reference's initial pose (5×5)."""
    x0 = initial_state(paper_reference(reference))
    mass = NominalRobot().mass_matrix(x0[:5])[0]
    inverse = np.linalg.inv(mass)
    return 0.5 * (inverse + inverse.T)


def make_baseline(
    kind: str,
    kappa: float,
    k_b: float,
    c: float,
    *,
    h_bar: float | None = None,
    history: float = HISTORY,
    reference: str = "consistent",
) -> PCON | PCONf:
    """PCON (``kind="PCON"``) or PCONf (``kind="PCONf"``, needs ``h_bar``) on the nominal robot."""
    vartheta = c * vartheta_base(reference)
    common = dict(kappa=kappa, vartheta=vartheta, k_b=k_b, history=history, T_c=T_C)
    if kind == "PCON":
        return PCON(NominalRobot(), **common)
    if kind == "PCONf":
        if h_bar is None:
            raise ValueError("PCONf needs h_bar")
        return PCONf(NominalRobot(), h_bar=h_bar, **common)
    raise ValueError(f"kind must be 'PCON' or 'PCONf'; got {kind!r}")


@dataclass(frozen=True)
class TuningResult:
    """One baseline's grid search.

    Attributes
    ----------
    kind : str
        ``"PCON"`` or ``"PCONf"``.
    table : DataFrame
        One row per grid point (grid order): ``kappa, k_b, c, ae_x_mm, ae_y_mm, objective, tv,
        status``; ``objective`` is NaN for diverged runs.
    best : dict
        The chosen ``kappa, k_b, c`` (and ``h_bar`` for PCONf) and its ``objective``.
    interior : dict
        Per gain, whether the chosen value is strictly inside the grid's range.
    seconds : float
        Wall time.
    """

    kind: str
    table: pd.DataFrame
    best: dict[str, float]
    interior: dict[str, bool]
    seconds: float


def tune(
    kind: str,
    *,
    grid: Mapping[str, Sequence[float]] = GRID,
    seed: int = TUNING_SEED,
    duration: float = TUNING_DURATION,
    progress: bool = False,
) -> TuningResult:
    """Grid-search one baseline on its held-out condition (module docstring); one batched run."""
    delay, h_bar, _ = BASELINES[kind]
    points = list(itertools.product(grid["kappa"], grid["k_b"], grid["c"]))
    controllers = [make_baseline(kind, k, kb, c, h_bar=h_bar) for k, kb, c in points]
    reference = paper_reference()
    start = time.perf_counter()
    result = simulate(
        PayloadRobot(seed=seed, duration=duration),
        controllers,
        delay,
        initial_state(reference),
        reference=reference,
        t1=duration,
        dt=DT,
        T_c=T_C,
        progress=progress,
    )
    seconds = time.perf_counter() - start
    ae = 1e3 * mean_absolute_error(result)[:, :2]
    objective = ae.mean(axis=1)
    status = list(result.status_names)
    for i, value in enumerate(objective):
        if not np.isfinite(value) or value > DIVERGED_AE_MM:
            objective[i] = np.nan
            if status[i] == "ok":
                status[i] = "left path"
    table = pd.DataFrame(
        {
            "kappa": [p[0] for p in points],
            "k_b": [p[1] for p in points],
            "c": [p[2] for p in points],
            "ae_x_mm": ae[:, 0],
            "ae_y_mm": ae[:, 1],
            "objective": objective,
            "tv": total_variation(result),
            "status": status,
        }
    )
    if not np.any(np.isfinite(objective)):
        raise RuntimeError(f"every {kind} grid point diverged; widen the grid")
    index = int(np.nanargmin(objective))
    best: dict[str, float] = {
        "kappa": float(points[index][0]),
        "k_b": float(points[index][1]),
        "c": float(points[index][2]),
        "objective": float(objective[index]),
    }
    if h_bar is not None:
        best["h_bar"] = float(h_bar)
    interior = {
        name: min(values) < best[name] < max(values)
        for name, values in grid.items()
        if name in ("kappa", "k_b", "c")
    }
    return TuningResult(kind, table, best, interior, seconds)


def tune_baselines(
    *,
    grid: Mapping[str, Sequence[float]] = GRID,
    seed: int = TUNING_SEED,
    duration: float = TUNING_DURATION,
    progress: bool = False,
) -> dict[str, TuningResult]:
    """Tune PCON and PCONf (:func:`tune` each); returns ``kind -> TuningResult``."""
    results = {}
    with tqdm(total=len(BASELINES), desc="tuning", unit="baseline", disable=not progress) as bar:
        for kind in BASELINES:
            bar.set_postfix_str(kind)
            results[kind] = tune(kind, grid=grid, seed=seed, duration=duration)
            bar.update()
    return results


def write_gains(
    results: Mapping[str, TuningResult],
    path: str | Path | None = None,
    *,
    grid: Mapping[str, Sequence[float]] = GRID,
    seed: int = TUNING_SEED,
    duration: float = TUNING_DURATION,
) -> Path:
    """Write the chosen gains, the grid, the objective values and the conditions as TOML."""
    path = default_gains_path() if path is None else Path(path)
    data: dict[str, Any] = {
        "generated_by": "delaytrack tune-baselines (delaytrack.experiments.tuning)",
        "procedure": "full-factorial grid search over kappa, k_b and c (vartheta = c "
        "inv(Mhat(q_d(0)))); objective = mean of AE-x and AE-y in mm over the whole run; "
        f"diverged runs (status not ok, or objective > {DIVERGED_AE_MM:g} mm) excluded; "
        "smallest objective wins",
        "payload_seed": int(seed),
        "duration": float(duration),
        "dt": DT,
        "T_c": T_C,
        "history": HISTORY,
        "reference": "consistent",
        "grid_kappa": [float(v) for v in grid["kappa"]],
        "grid_k_b": [float(v) for v in grid["k_b"]],
        "grid_c": [float(v) for v in grid["c"]],
    }
    for kind, result in results.items():
        table = {
            "condition": BASELINES[kind][2],
            **{k: v for k, v in result.best.items()},
            "interior": all(result.interior.values()),
            "columns": ["kappa", "k_b", "c", "ae_x_mm", "ae_y_mm", "objective", "tv"],
            "rows": [
                [float(v) for v in row]
                for row in result.table[
                    ["kappa", "k_b", "c", "ae_x_mm", "ae_y_mm", "objective", "tv"]
                ].to_numpy()
            ],
        }
        data[kind] = table
    return write_text(path, dumps_toml(data))


def load_gains(path: str | Path | None = None) -> dict[str, dict[str, float]]:
    """The chosen gains per baseline: ``{"PCON": {"kappa", "k_b", "c"}, "PCONf": {...}}``."""
    path = default_gains_path() if path is None else Path(path)
    data = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    return {
        kind: {key: float(data[kind][key]) for key in ("kappa", "k_b", "c")} for kind in BASELINES
    }


def load_tuning_record(path: str | Path | None = None) -> dict[str, Any]:
    """The whole gains file as data (grid, objective rows, conditions)."""
    path = default_gains_path() if path is None else Path(path)
    return tomllib.loads(Path(path).read_text(encoding="utf-8"))
