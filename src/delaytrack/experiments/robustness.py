"""The robustness study: which controller to use when the delay is not known, over distributions.

The paper's case for AROLC is that it needs no knowledge of the delay, while its predictor
baselines assume they know it. The paper job compares one run per case; this study asks the
question over distributions, on the sweep machinery (resumable Parquet parts, any executor,
``delaytrack reproduce --job robustness``; ``--size full`` for the large version, which
``--scheduler`` runs on a Dask cluster). Every run is the paper job's robot run (60 s, the
``consistent`` circle, ``dt = 1 ms``, ``T_c = 10 ms``) with, per draw,

- a payload seed (the paper's 3.5 kg, 5 s on / 5 s off, at a random point of the top plate),
- the wheel friction drawn uniformly from the documented ranges of
  :data:`~delaytrack.plants.robot.P3DX_SOURCES` (viscous 0.001–0.02 N·m·s/rad, Coulomb
  0.07–0.35 N·m),

the same draws for every controller and condition (common random numbers: draw ``i`` is the
same robot everywhere). Three sweeps:

- **map**: a constant true delay (:data:`TRUE_DELAYS`, up to well beyond the tuned range) ×
  what the predictors are told, ``s h`` for the scales :data:`SCALES` (PCONf told
  ``h̄ = s h``: for a constant delay the law of PCON told ``s h``, run as such). The gain sets
  are the tuning's ``all`` (one gain set for every delay).
- **knowledge**: the paper's time-varying S1 and S2 with the predictors told ``s h(t)`` (PCON in
  both spaces) or the constant ``h̄ = s`` times the profile's long-run mean (PCONf); gain sets
  ``varying``.
- **claims**: S1–S4 with the paper job's pairing (PCON for S1, S2; PCONf for S3, S4; class gain
  sets), AROLC with the paper's and the tuned gains, the outer loop at both, PCON in wheel space;
  without and with measurement noise (:data:`NOISE`).

Statistics: a run *diverged* when it stopped (diverged or left the path: an x or y error beyond
10 m) or its mean AE exceeds the tuning's 1 m. Divergence rates carry Wilson 95 % intervals;
medians of AE (the mean of AE-x and AE-y, mm, over runs that stayed on the path) carry
percentile-bootstrap 95 % intervals. A claim "A below B" is decided per draw (a diverged run
loses) and its verdict comes from the share of draws in which it holds: *holds* when the
Wilson interval of that share lies above one half, *fails* when below, *undecided* otherwise.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from scipy import stats

from delaytrack._io import write_frame
from delaytrack._output import claim_output_folder, record_outputs
from delaytrack.delays import delay_from_spec
from delaytrack.experiments import tuning
from delaytrack.experiments.pairing import AROLC_GAINS, BASELINE, DELAY_CLASS
from delaytrack.experiments.scenario import load_builtin
from delaytrack.report import HtmlReport, save_figure
from delaytrack.sweeps import SweepSpec, run_sweep
from delaytrack.sweeps.executors import LocalExecutor

__all__ = [
    "NOISE",
    "SCALES",
    "SIZES",
    "TRUE_DELAYS",
    "RobustnessStudy",
    "StudySize",
    "claim_verdicts",
    "run_robustness",
    "study_specs",
    "wilson_interval",
]

#: Scales ``s`` of what the predictors are told (``s h``).
SCALES: tuple[float, ...] = (0.5, 0.75, 1.0, 1.25, 1.5, 2.0)
#: Constant true delays of the map (s): the tuning covered 20–140 ms.
TRUE_DELAYS: tuple[float, ...] = (0.02, 0.06, 0.1, 0.12, 0.13, 0.15, 0.2, 0.3)
#: Seconds of command history of the study's predictors (the longest told window is 0.6 s).
HISTORY = 0.65
#: Measurement noise of the noisy runs: the P3-DX's wheel encoders (500 ticks per motor turn
#: through a 19.7:1 gear: 2π/9850 rad on the wheel angles), 1 mm / 2 mrad white noise on the
#: look-ahead point and the heading (odometry), and velocity noise of 5 mm/s, 10 mrad/s and
#: 20 mrad/s on the wheel rates.
NOISE: dict[str, Any] = {
    "quantization": [0.0, 0.0, 0.0, 2 * math.pi / 9850, 2 * math.pi / 9850],
    "position": [0.001, 0.001, 0.002, 0.0, 0.0],
    "velocity": [0.005, 0.005, 0.01, 0.02, 0.02],
    "seed": 5,
}
_NO_NOISE: dict[str, Any] = {"quantization": 0.0, "position": 0.0, "velocity": 0.0, "seed": 0}
#: A run whose mean AE exceeds this (mm) counts as diverged (the tuning's rule).
DIVERGED_AE_MM = tuning.DIVERGED_AE_MM
#: Seed of the study's draws.
SEED = 2027
#: The shipped scenario every run starts from (the paper job's AROLC / S1 run).
BASE_SCENARIO = "robot_S1"
_FRICTION = {
    "plant.viscous_friction": {"dist": "uniform", "low": 0.001, "high": 0.02},
    "plant.coulomb_friction": {"dist": "uniform", "low": 0.07, "high": 0.35},
}
_PAYLOAD = {"plant.seed": {"dist": "integers", "low": 0, "high": 2**31 - 1}}
_SCENARIOS = {
    "S1": {"type": "S1"},
    "S2": {"type": "S2"},
    "S3": {"type": "S3"},
    "S4": {"type": "S4"},
}


@dataclass(frozen=True)
class StudySize:
    """Draws (robots) per condition of each sweep."""

    map: int
    knowledge: int
    claims: int


#: ``default``: what ``delaytrack reproduce`` runs (about 3 600 runs). 40 draws per claim put
#: the Wilson 95 % half-width of a share near one half at about 0.15, so a claim that holds (or
#: fails) in 70 % of draws is decided; 8 draws per map cell find where a controller diverges in
#: most draws. ``full``: ten times the draws.
SIZES: dict[str, StudySize] = {
    "default": StudySize(map=8, knowledge=8, claims=40),
    "full": StudySize(map=80, knowledge=80, claims=400),
}


def _arolc_table(gains: Mapping[str, float]) -> dict[str, Any]:
    return {"type": "arolc", **{k: float(v) for k, v in gains.items()}}


def _outer_table(gains: Mapping[str, float]) -> dict[str, Any]:
    return {"type": "outer-loop", "K1": float(gains["K1"]), "K2": float(gains["K2"])}


#: The chosen gains as :func:`~delaytrack.experiments.tuning.load_gains` gives them.
Gains = Mapping[str, Mapping[str, Mapping[str, float]]]


def _tuned_arolc(gains: Gains, gain_set: str) -> dict[str, float]:
    g = gains["AROLC"][gain_set]
    return tuning.arolc_gains(g["k"], g["zeta"], g["alpha"])


def _predictor_table(
    gains: Gains,
    kind: str,
    gain_set: str,
    *,
    scale: float = 1.0,
    h_bar: float | None = None,
    law: str | None = None,
) -> dict[str, Any]:
    """A predictor with ``kind``'s gains of ``gain_set`` as a controller table: PCON / PCON-wheel
    told ``scale · h``, PCONf with ``h_bar``; ``law`` runs the gains with another kind's law
    (``"PCON"``: PCONf's gains told ``scale · h``, which for a constant delay ``h`` is PCONf
    told ``h̄ = scale · h``)."""
    chosen = gains[kind][gain_set]
    controller = tuning.make_controller(law or kind, chosen, h_bar=h_bar, history=HISTORY)
    table = controller.to_spec()
    if table["type"] == "pcon" and scale != 1.0:
        table["delay_scale"] = float(scale)
    return table


@dataclass(frozen=True)
class _Sweep:
    """A sweep of the study: its spec and a label per grid point (``labels[i]`` describes runs
    ``i * draws .. (i + 1) * draws - 1``)."""

    name: str
    spec: SweepSpec
    labels: list[dict[str, Any]]


def _spec(
    grid: Mapping[str, list[Any]], draws: int, extra: Mapping[str, Any] | None = None
) -> SweepSpec:
    return SweepSpec.from_dict(
        {
            "scenario": BASE_SCENARIO,
            "unit_size": 64,
            "draws": draws,
            "seed": SEED,
            "metrics": ["ae_x", "ae_y", "tv"],
            "grid": dict(grid),
            "random": {**_PAYLOAD, **_FRICTION, **(extra or {})},
        }
    )


def _map_sweep(gains: Gains, draws: int) -> _Sweep:
    rows: list[tuple[str, float, dict[str, Any]]] = [
        ("AROLC (paper gains)", math.nan, _arolc_table(AROLC_GAINS)),
        ("AROLC (tuned)", math.nan, _arolc_table(_tuned_arolc(gains, "all"))),
        ("outer loop (paper gains)", math.nan, _outer_table(AROLC_GAINS)),
    ]
    for kind in tuning.PREDICTORS:
        law = "PCON" if kind == "PCONf" else None
        rows += [(kind, s, _predictor_table(gains, kind, "all", scale=s, law=law)) for s in SCALES]
    delays = [{"type": "constant", "h": h} for h in TRUE_DELAYS]
    labels = [
        {"delay_ms": 1e3 * h, "controller": name, "scale": scale}
        for h in TRUE_DELAYS
        for name, scale, _ in rows
    ]
    grid = {"delay": delays, "controller": [table for _, _, table in rows]}
    return _Sweep("map", _spec(grid, draws), labels)


def _knowledge_sweep(gains: Gains, case: str, draws: int) -> _Sweep:
    rows: list[tuple[str, float, dict[str, Any]]] = [
        ("AROLC (paper gains)", math.nan, _arolc_table(AROLC_GAINS)),
        ("AROLC (tuned)", math.nan, _arolc_table(_tuned_arolc(gains, "varying"))),
    ]
    mean = tuning.long_run_mean(delay_from_spec(_SCENARIOS[case]))
    for s in SCALES:
        rows.append(("PCON", s, _predictor_table(gains, "PCON", "varying", scale=s)))
        rows.append(("PCON-wheel", s, _predictor_table(gains, "PCON-wheel", "varying", scale=s)))
        rows.append(("PCONf", s, _predictor_table(gains, "PCONf", "varying", h_bar=s * mean)))
    labels = [{"scenario": case, "controller": name, "scale": s} for name, s, _ in rows]
    grid = {"delay": [_SCENARIOS[case]], "controller": [table for _, _, table in rows]}
    return _Sweep(f"knowledge-{case}", _spec(grid, draws), labels)


def _claims_sweep(gains: Gains, case: str, draws: int) -> _Sweep:
    gain_set = DELAY_CLASS[case]
    tuned = _tuned_arolc(gains, gain_set)
    baseline = BASELINE[case]
    h_bar = float(delay_from_spec(_SCENARIOS[case]).h_max) if baseline == "PCONf" else None
    rows = [
        ("AROLC (paper gains)", _arolc_table(AROLC_GAINS)),
        ("outer loop (paper gains)", _outer_table(AROLC_GAINS)),
        ("AROLC (tuned)", _arolc_table(tuned)),
        ("outer loop (tuned gains)", _outer_table(tuned)),
        (baseline, _predictor_table(gains, baseline, gain_set, h_bar=h_bar)),
        ("PCON-wheel", _predictor_table(gains, "PCON-wheel", gain_set)),
    ]
    noise = [("off", _NO_NOISE), ("on", NOISE)]
    labels = [
        {"scenario": case, "noise": level, "controller": name}
        for level, _ in noise
        for name, _ in rows
    ]
    grid = {
        "delay": [_SCENARIOS[case]],
        "measurement_noise": [table for _, table in noise],
        "controller": [table for _, table in rows],
    }
    noise_seed = {"measurement_noise.seed": {"dist": "integers", "low": 0, "high": 2**32 - 1}}
    return _Sweep(f"claims-{case}", _spec(grid, draws, noise_seed), labels)


def study_specs(
    size: str | StudySize = "default", gains: tuning.GainsSource = None
) -> list[_Sweep]:
    """The study's sweeps at a size (:data:`SIZES`): map, knowledge-S1/S2, claims-S1..S4, with
    the tuned gains of ``gains`` (a gains file or its record; the shipped file by default)."""
    size = SIZES[size] if isinstance(size, str) else size
    chosen = tuning.load_gains(gains)
    return [
        _map_sweep(chosen, size.map),
        *(_knowledge_sweep(chosen, case, size.knowledge) for case in ("S1", "S2")),
        *(_claims_sweep(chosen, case, size.claims) for case in _SCENARIOS),
    ]


# --------------------------------------------------------------------------------------------
# Statistics


def wilson_interval(k: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """Wilson score interval (95 % by default) of a proportion ``k / n``; ``(nan, nan)`` for
    ``n = 0``."""
    if n == 0:
        return math.nan, math.nan
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def median_interval(values: Sequence[float], seed: int = 0) -> tuple[float, float, float]:
    """Median and its percentile-bootstrap 95 % interval (:func:`scipy.stats.bootstrap`, 2000
    resamples); NaN where fewer than two values are given."""
    data = np.asarray(values, dtype=float)
    if len(data) == 0:
        return math.nan, math.nan, math.nan
    median = float(np.median(data))
    if len(data) < 2 or np.all(data == data[0]):
        return median, median if len(data) > 1 else math.nan, median if len(data) > 1 else math.nan
    result = stats.bootstrap(
        (data,),
        np.median,
        n_resamples=2000,
        method="percentile",
        random_state=np.random.default_rng(seed),
    )
    return median, float(result.confidence_interval.low), float(result.confidence_interval.high)


def _runs_frame(sweep: _Sweep, runs: pd.DataFrame) -> pd.DataFrame:
    """One row per run: the grid point's labels, the draw, AE (mm), TV (N·m), divergence."""
    draws = sweep.spec.draws
    runs = runs.sort_values("run").reset_index(drop=True)
    frame = pd.DataFrame(sweep.labels).iloc[runs.run // draws].reset_index(drop=True)
    frame["draw"] = (runs.run % draws).to_numpy()
    frame["payload_seed"] = runs["plant.seed"].to_numpy()
    frame["viscous_friction_Nms_per_rad"] = runs["plant.viscous_friction"].to_numpy()
    frame["coulomb_friction_Nm"] = runs["plant.coulomb_friction"].to_numpy()
    frame["ae_mm"] = (500.0 * (runs.ae_x + runs.ae_y)).to_numpy()
    frame["tv_Nm"] = runs.tv.to_numpy()
    frame["status"] = runs.status.to_numpy()
    frame["t_stop_s"] = runs.t_stop.to_numpy()
    frame["diverged"] = (
        (frame.status != "ok") | ~np.isfinite(frame.ae_mm) | (frame.ae_mm > DIVERGED_AE_MM)
    )
    return frame


def outcome_table(frame: pd.DataFrame, by: list[str]) -> pd.DataFrame:
    """Per group: runs, divergence rate with its Wilson interval, median AE (mm) and TV (N·m)
    of the runs that stayed on the path with bootstrap intervals."""
    rows = []
    for key, group in frame.groupby(by, sort=False, dropna=False):
        kept = group[~group.diverged]
        k, n = int(group.diverged.sum()), len(group)
        low, high = wilson_interval(k, n)
        ae = median_interval(kept.ae_mm)
        tv = median_interval(kept.tv_Nm)
        rows.append(
            {
                **dict(zip(by, key if isinstance(key, tuple) else (key,), strict=True)),
                "runs": n,
                "diverged": k,
                "divergence_rate": k / n,
                "divergence_ci_low": low,
                "divergence_ci_high": high,
                "median_ae_mm": ae[0],
                "median_ae_ci_low_mm": ae[1],
                "median_ae_ci_high_mm": ae[2],
                "median_tv_Nm": tv[0],
                "median_tv_ci_low_Nm": tv[1],
                "median_tv_ci_high_Nm": tv[2],
                "median_t_stop_of_diverged_s": (
                    float(group[group.diverged].t_stop_s.median()) if k else math.nan
                ),
            }
        )
    return pd.DataFrame(rows)


def _per_draw(frame: pd.DataFrame, who: str, column: str) -> pd.Series:
    """``column`` of controller ``who`` indexed by draw (diverged runs: +inf); each draw once."""
    rows = frame[frame.controller == who]
    if rows.draw.duplicated().any():
        raise ValueError(f"{who!r} has more than one run per draw")
    return pd.Series(np.where(rows.diverged, np.inf, rows[column]), index=rows.draw.to_numpy())


def _paired(frame: pd.DataFrame, a: str, b: str, column: str) -> tuple[np.ndarray, np.ndarray]:
    """``column`` of controllers ``a`` and ``b`` on the same draws (diverged runs: +inf)."""
    first, second = _per_draw(frame, a, column), _per_draw(frame, b, column)
    if set(first.index) != set(second.index):
        raise ValueError(f"{a!r} and {b!r} were not run on the same draws")
    draws = np.sort(first.index.to_numpy())
    return first[draws].to_numpy(float), second[draws].to_numpy(float)


def _verdict(a: np.ndarray, b: np.ndarray) -> dict[str, Any]:
    """Whether ``a < b`` draw by draw. Draws where both diverged decide nothing and are left
    out (counted); the share and its Wilson interval are over the decided draws. The paired
    median difference ``a − b`` over draws where both stayed on the path gives the size."""
    both = np.isinf(a) & np.isinf(b)
    holds = (a < b)[~both]
    k, n = int(holds.sum()), len(holds)
    low, high = wilson_interval(k, n)
    if n == 0:
        verdict = "no decision (both diverged in every draw)"
    else:
        verdict = "holds" if low > 0.5 else "fails" if high < 0.5 else "undecided"
    finite = np.isfinite(a) & np.isfinite(b)
    median, d_low, d_high = median_interval(a[finite] - b[finite], seed=2)
    return {
        "share_holds": k / n if n else math.nan,
        "ci_low": low,
        "ci_high": high,
        "verdict": verdict,
        "draws_decided": n,
        "draws_both_diverged": int(both.sum()),
        "median_difference": median,
        "difference_ci_low": d_low,
        "difference_ci_high": d_high,
    }


def claim_verdicts(claims: pd.DataFrame) -> pd.DataFrame:
    """The paper's claims per scenario and noise level, for AROLC with the paper's and the
    tuned gains: AE below the baseline, TV below the baseline, and AROLC's AE larger in S4 than
    in S3 — each decided draw by draw on the same robots (:func:`_verdict`: a diverged run
    loses, a draw where both diverged is left out). ``median_difference`` is in mm for AE and
    N·m for TV (AROLC minus the baseline; S4 minus S3)."""
    rows = []
    for (case, noise), frame in claims.groupby(["scenario", "noise"], sort=False):
        baseline = BASELINE[case]
        for who in ("AROLC (paper gains)", "AROLC (tuned)"):
            for metric, column in (("AE", "ae_mm"), ("TV", "tv_Nm")):
                a, b = _paired(frame, who, baseline, column)
                rows.append(
                    {
                        "scenario": case,
                        "noise": noise,
                        "claim": f"{metric} below {baseline}",
                        "controller": who,
                        **_verdict(a, b),
                    }
                )
    for noise in claims.noise.unique():
        s3 = claims[(claims.scenario == "S3") & (claims.noise == noise)]
        s4 = claims[(claims.scenario == "S4") & (claims.noise == noise)]
        if s3.empty or s4.empty:
            continue
        for who in ("AROLC (paper gains)", "AROLC (tuned)"):
            first, second = _per_draw(s3, who, "ae_mm"), _per_draw(s4, who, "ae_mm")
            draws = np.sort(first.index.to_numpy())
            # "AE grows": S3's AE below S4's, draw by draw.
            verdict = _verdict(first[draws].to_numpy(float), second[draws].to_numpy(float))
            for key in ("median_difference", "difference_ci_low", "difference_ci_high"):
                verdict[key] = -verdict[key]  # S4 minus S3
            low, high = verdict["difference_ci_low"], verdict["difference_ci_high"]
            verdict["difference_ci_low"], verdict["difference_ci_high"] = high, low
            rows.append(
                {
                    "scenario": "S3 -> S4",
                    "noise": noise,
                    "claim": "AE grows from S3 to S4",
                    "controller": who,
                    **verdict,
                }
            )
    return pd.DataFrame(rows)


#: Attribution pairs: (what, the controller with it, the controller without it).
ATTRIBUTION = (
    ("Δu at the paper's gains", "AROLC (paper gains)", "outer loop (paper gains)"),
    ("Δu at the tuned gains", "AROLC (tuned)", "outer loop (tuned gains)"),
    ("tuning (AROLC)", "AROLC (tuned)", "AROLC (paper gains)"),
)


def attribution(claims: pd.DataFrame) -> pd.DataFrame:
    """What each part contributes: the paired change of AE and TV from the second controller of
    each :data:`ATTRIBUTION` pair to the first (medians over draws with bootstrap intervals;
    draws where either diverged are left out and counted)."""
    rows = []
    for (case, noise), frame in claims.groupby(["scenario", "noise"], sort=False):
        for what, with_it, without in ATTRIBUTION:
            out = {"scenario": case, "noise": noise, "part": what}
            for metric, column in (("ae", "ae_mm"), ("tv", "tv_Nm")):
                a, b = _paired(frame, with_it, without, column)
                both = np.isfinite(a) & np.isfinite(b)
                median, low, high = median_interval(a[both] - b[both], seed=1)
                unit = "mm" if metric == "ae" else "Nm"
                out[f"median_change_{metric}_{unit}"] = median
                out[f"change_ci_low_{metric}_{unit}"] = low
                out[f"change_ci_high_{metric}_{unit}"] = high
            out["draws_compared"] = int(both.sum())
            rows.append(out)
    return pd.DataFrame(rows)


# --------------------------------------------------------------------------------------------
# Figures, report, job

#: The map's controllers, in panel order.
MAP_CONTROLLERS = (
    "PCON",
    "PCON-wheel",
    "PCONf",
    "AROLC (paper gains)",
    "AROLC (tuned)",
    "outer loop (paper gains)",
)


def robustness_map(table: pd.DataFrame) -> Figure:
    """Per controller: divergence rate (colour) and median AE in mm of the runs that stayed on
    the path (text) against the true constant delay and the scale of what it is told."""
    figure = Figure(figsize=(12.0, 7.5), layout="constrained")
    axes = figure.subplots(2, 3, sharey=True)
    delays = sorted(table.delay_ms.unique())
    image = None
    for ax, name in zip(axes.ravel(), MAP_CONTROLLERS, strict=True):
        rows = table[table.controller == name]
        told = name in tuning.PREDICTORS
        columns = list(SCALES) if told else [math.nan]
        rate = np.full((len(delays), len(columns)), np.nan)
        for i, h in enumerate(delays):
            for j, scale in enumerate(columns):
                row = rows[
                    (rows.delay_ms == h) & (rows.scale.isna() if not told else rows.scale == scale)
                ]
                if row.empty:
                    continue
                rate[i, j] = row.divergence_rate.iloc[0]
                ae = row.median_ae_mm.iloc[0]
                ax.text(
                    j,
                    i,
                    "—" if not math.isfinite(ae) else f"{ae:.3g}",
                    ha="center",
                    va="center",
                    fontsize=8,
                    color="white" if rate[i, j] > 0.5 else "black",
                )
        image = ax.imshow(rate, cmap="Reds", vmin=0.0, vmax=1.0, aspect="auto", origin="lower")
        ax.set_title(name, fontsize=10)
        ax.set_xticks(range(len(columns)))
        ax.set_xticklabels([f"{c:g}" for c in columns] if told else ["not told"])
        ax.set_xlabel("told delay / true delay (ratio)" if told else "delay unknown to the law")
        ax.set_yticks(range(len(delays)))
        ax.set_yticklabels([f"{h:g}" for h in delays])
    for ax in axes[:, 0]:
        ax.set_ylabel("true constant delay h (ms)")
    figure.colorbar(image, ax=axes, label="divergence rate (share of draws)", shrink=0.8)
    figure.suptitle("Robustness map: colour = divergence rate, text = median AE (mm)")
    return figure


@dataclass(frozen=True)
class RobustnessStudy:
    """Everything :func:`run_robustness` computed.

    Attributes
    ----------
    size : StudySize
    runs : dict
        Sweep name -> one row per run (:func:`_runs_frame` columns).
    map, knowledge : DataFrame
        :func:`outcome_table` per (true delay, controller, scale) and per (scenario, controller,
        scale).
    claims : DataFrame
        :func:`outcome_table` per (scenario, noise, controller).
    verdicts, attribution : DataFrame
        :func:`claim_verdicts` and :func:`attribution`.
    tuning_record : mapping
        The gains file the tuned controllers came from (:func:`tuning.load_tuning_record`).
    seconds : float
        Wall time of the sweeps.
    """

    size: StudySize
    runs: dict[str, pd.DataFrame]
    map: pd.DataFrame
    knowledge: pd.DataFrame
    claims: pd.DataFrame
    verdicts: pd.DataFrame
    attribution: pd.DataFrame
    tuning_record: Mapping[str, Any]
    seconds: float
    computed: int = 0
    resumed: int = 0


def run_robustness(
    out: str | Path,
    *,
    size: str | StudySize = "default",
    executor: Any = None,
    progress: bool = True,
    gains: tuning.GainsSource = None,
) -> RobustnessStudy:
    """Run (or resume) the study's sweeps into ``out/sweeps/<name>/`` and write its tables,
    figure and report into ``out``.

    ``executor`` makes an :class:`~delaytrack.sweeps.executors.Executor` per sweep (a callable
    without arguments; default: all local cores); ``gains`` is where the tuned gains come
    from (a gains file or its record; the shipped file by default).
    """
    record = tuning.load_tuning_record(gains)
    size = SIZES[size] if isinstance(size, str) else size
    make = executor if executor is not None else LocalExecutor
    out = claim_output_folder(out)
    start = time.perf_counter()
    frames, computed, resumed = {}, 0, 0
    for sweep in study_specs(size, record):
        if progress:
            print(f"robustness: sweep {sweep.name} ({len(sweep.spec.runs)} runs)", flush=True)
        outcome = run_sweep(
            sweep.spec, out / "sweeps" / sweep.name, executor=make(), progress=progress
        )
        computed += outcome.computed
        resumed += outcome.resumed
        frames[sweep.name] = _runs_frame(sweep, outcome.runs)
    seconds = time.perf_counter() - start
    knowledge = pd.concat([f for n, f in frames.items() if n.startswith("knowledge")])
    claims = pd.concat([f for n, f in frames.items() if n.startswith("claims")])
    study = RobustnessStudy(
        size=size,
        runs=frames,
        map=outcome_table(frames["map"], ["delay_ms", "controller", "scale"]),
        knowledge=outcome_table(knowledge, ["scenario", "controller", "scale"]),
        claims=outcome_table(claims, ["scenario", "noise", "controller"]),
        verdicts=claim_verdicts(claims),
        attribution=attribution(claims),
        tuning_record=record,
        seconds=seconds,
        computed=computed,
        resumed=resumed,
    )
    write_robustness(study, out)
    return study


def _cell(table: pd.DataFrame, **where: Any) -> pd.Series:
    rows = table
    for key, value in where.items():
        rows = rows[rows[key].isna()] if value is None else rows[rows[key] == value]
    if len(rows) != 1:
        raise KeyError(f"no single row of the study for {where}")
    return rows.iloc[0]


def knowledge_table(study: RobustnessStudy) -> pd.DataFrame:
    """What the predictors tolerate of a wrong delay, case by case: the truth, what the
    predictor is told, its divergence rate, median AE and median time of leaving the path,
    beside AROLC's (paper gains) under the same truth."""
    cases: list[tuple[str, str, str, pd.Series, pd.Series]] = []
    k, m = study.knowledge, study.map
    for case, predictor, scale, told in (
        ("S1", "PCON", 1.0, "the true h(t)"),
        ("S1", "PCON", 2.0, "2·h(t)"),
        ("S2", "PCON", 0.5, "0.5·h(t)"),
        ("S2", "PCONf", 1.0, "its constant long-run mean"),
    ):
        cases.append(
            (
                case,
                told,
                f"{predictor} (varying set)",
                _cell(k, scenario=case, controller=predictor, scale=scale),
                _cell(k, scenario=case, controller="AROLC (paper gains)", scale=None),
            )
        )
    for h, scale, told in ((60.0, 2.0, "h̄ = 120 ms"), (120.0, 0.5, "h̄ = 60 ms")):
        cases.append(
            (
                f"{h:g} ms constant",
                told,
                "PCONf (all set)",
                _cell(m, delay_ms=h, controller="PCONf", scale=scale),
                _cell(m, delay_ms=h, controller="AROLC (paper gains)", scale=None),
            )
        )
    for h in (150.0, 200.0, 300.0):
        for predictor in tuning.PREDICTORS:
            cases.append(
                (
                    f"{h:g} ms constant",
                    "the true delay",
                    f"{predictor} (all set)",
                    _cell(m, delay_ms=h, controller=predictor, scale=1.0),
                    _cell(m, delay_ms=h, controller="AROLC (paper gains)", scale=None),
                )
            )
    rows = []
    for truth, told, predictor, p, a in cases:
        rows.append(
            {
                "truth": truth,
                "predictor told": told,
                "predictor": predictor,
                "predictor_divergence_rate": p.divergence_rate,
                "predictor_median_t_stop_of_diverged_s": p.median_t_stop_of_diverged_s,
                "predictor_median_ae_mm": p.median_ae_mm,
                "arolc_paper_divergence_rate": a.divergence_rate,
                "arolc_paper_median_ae_mm": a.median_ae_mm,
                "runs": int(p.runs),
            }
        )
    return pd.DataFrame(rows)


def findings(study: RobustnessStudy) -> list[str]:
    """The study's findings as sentences, every number computed from its tables."""
    out = []
    table = study.map
    exact = table[(table.scale == 1.0) | table.scale.isna()]
    for name in MAP_CONTROLLERS:
        rows = exact[exact.controller == name].sort_values("delay_ms")
        clean = rows[rows.diverged == 0]
        lost = rows[rows.divergence_rate >= 0.5]
        told = " (told the true delay)" if name in tuning.PREDICTORS else ""
        text = f"{name}{told}: " + (
            f"no run diverged up to {_longest_clean(rows):g} ms"
            if not clean.empty and rows.diverged.iloc[0] == 0
            else f"runs diverged already at {rows.delay_ms.min():g} ms"
        )
        if not lost.empty:
            text += f"; at least half of the runs diverged from {lost.delay_ms.min():g} ms on"
        text += f" ({rows.runs.iloc[0]} draws per delay; tested up to {rows.delay_ms.max():g} ms)."
        out.append(text)
    for name in tuning.PREDICTORS:
        parts = []
        for scale in SCALES:
            rows = table[(table.controller == name) & (table.scale == scale)]
            rows = rows.sort_values("delay_ms")
            clean = "none" if rows.diverged.iloc[0] else f"{_longest_clean(rows):g} ms"
            parts.append(f"told {scale:g}·h: {clean}")
        out.append(
            f"{name}, largest true delay up to which no run diverged, by what it is told: "
            + "; ".join(parts)
            + "."
        )
    paper_safe = [
        name
        for name in ("AROLC (paper gains)", "outer loop (paper gains)")
        if table[table.controller == name].diverged.sum() == 0
    ]
    if len(paper_safe) == 2:
        out.append(
            "At the paper's gains AROLC and the plain outer loop both stay on the path at every "
            f"tested delay up to {table.delay_ms.max():g} ms: the robustness to the delay "
            "observed here does not come from the switching term Δu, since the outer loop "
            "without it is as robust in this test."
        )
    record = study.tuning_record
    edges = [
        f"{kind} ({gain_set})"
        for kind in tuning.KINDS
        for gain_set in tuning.GAIN_SETS
        if not record[kind][gain_set]["interior"]
    ]
    if edges:
        out.append(
            "Tuned gain sets still on an edge of their grid after the extensions, so possibly "
            "not fully tuned: " + ", ".join(edges) + " (gains file, 'interior')."
        )
    quiet = study.attribution[study.attribution.noise == "off"]
    for part, rows in quiet.groupby("part", sort=False):
        ae, tv = rows.median_change_ae_mm, rows.median_change_tv_Nm
        out.append(
            f"{part} (noise off, S1–S4, median paired change over draws): AE "
            f"{ae.min():+.3g} to {ae.max():+.3g} mm, TV {tv.min():+.3g} to {tv.max():+.3g} N·m"
            + (
                f"; in {', '.join(rows[rows.draws_compared == 0].scenario)} no draw could be "
                "compared (one side diverged in every draw)"
                if (rows.draws_compared == 0).any()
                else ""
            )
            + "."
        )
    verdicts = study.verdicts
    for noise in verdicts.noise.unique():
        rows = verdicts[verdicts.noise == noise]
        groups = []
        for verdict in ("holds", "fails", "undecided"):
            chosen = rows[rows.verdict == verdict]
            names = [
                f"{r.controller}: {r.claim}"
                + ("" if r.scenario == "S3 -> S4" else f" in {r.scenario}")
                for r in chosen.itertuples()
            ]
            groups.append(f"{verdict.upper()} ({len(names)}): " + ("; ".join(names) or "none"))
        out.append(f"Claims with measurement noise {noise}. " + ". ".join(groups) + ".")
    return out


def _interval_text(value: float, low: float, high: float, scale: float = 1.0) -> str:
    """``value (low to high)`` scaled, or a dash when the value is missing."""
    if not math.isfinite(value):
        return "—"
    if not (math.isfinite(low) and math.isfinite(high)):
        return f"{scale * value:.3g}"
    return f"{scale * value:.3g} ({scale * low:.3g} to {scale * high:.3g})"


def display_verdicts(verdicts: pd.DataFrame) -> pd.DataFrame:
    """:func:`claim_verdicts` for reading: the share of draws with its interval in one column."""
    return pd.DataFrame(
        {
            "scenario": verdicts.scenario,
            "noise": verdicts.noise,
            "controller": verdicts.controller,
            "claim": verdicts.claim,
            "holds in % of draws (95 % CI)": [
                _interval_text(r.share_holds, r.ci_low, r.ci_high, 100.0)
                for r in verdicts.itertuples()
            ],
            "draws (both diverged)": [
                f"{r.draws_decided} ({r.draws_both_diverged})" for r in verdicts.itertuples()
            ],
            "median difference (95 % CI)": [
                _interval_text(r.median_difference, r.difference_ci_low, r.difference_ci_high)
                + (" N·m" if r.claim.startswith("TV") else " mm")
                if math.isfinite(r.median_difference)
                else "—"
                for r in verdicts.itertuples()
            ],
            "verdict": verdicts.verdict,
        }
    )


def display_attribution(table: pd.DataFrame) -> pd.DataFrame:
    """:func:`attribution` for reading: each median change with its interval in one column."""
    ae = zip(
        table.median_change_ae_mm,
        table.change_ci_low_ae_mm,
        table.change_ci_high_ae_mm,
        strict=True,
    )
    tv = zip(
        table.median_change_tv_Nm,
        table.change_ci_low_tv_Nm,
        table.change_ci_high_tv_Nm,
        strict=True,
    )
    return pd.DataFrame(
        {
            "part": table.part,
            "scenario": table.scenario,
            "noise": table.noise,
            "AE change, mm (95 % CI)": [_interval_text(*values) for values in ae],
            "TV change, N·m (95 % CI)": [_interval_text(*values) for values in tv],
            "draws compared": table.draws_compared,
        }
    )


def display_knowledge(table: pd.DataFrame) -> pd.DataFrame:
    """:func:`knowledge_table` for reading: shares in %, times in s, AE in mm."""

    def number(value: float, digits: str = ".3g") -> str:
        return "—" if not math.isfinite(value) else format(value, digits)

    return pd.DataFrame(
        {
            "truth": table.truth,
            "predictor": table.predictor,
            "told": table["predictor told"],
            "diverged, %": [number(100 * v, ".0f") for v in table.predictor_divergence_rate],
            "left the path at, s (median)": [
                number(v) for v in table.predictor_median_t_stop_of_diverged_s
            ],
            "AE, mm (median)": [number(v) for v in table.predictor_median_ae_mm],
            "AROLC diverged, %": [
                number(100 * v, ".0f") for v in table.arolc_paper_divergence_rate
            ],
            "AROLC AE, mm": [number(v) for v in table.arolc_paper_median_ae_mm],
        }
    )


def display_outcomes(table: pd.DataFrame, by: list[str]) -> pd.DataFrame:
    """:func:`outcome_table` for reading: divergence and medians with their intervals."""
    ae = zip(table.median_ae_mm, table.median_ae_ci_low_mm, table.median_ae_ci_high_mm, strict=True)
    tv = zip(table.median_tv_Nm, table.median_tv_ci_low_Nm, table.median_tv_ci_high_Nm, strict=True)
    columns: dict[str, Any] = {key: table[key] for key in by}
    columns["diverged / runs"] = [
        f"{k} / {n}" for k, n in zip(table.diverged, table.runs, strict=True)
    ]
    columns["median AE, mm (95 % CI)"] = [_interval_text(*values) for values in ae]
    columns["median TV, N·m (95 % CI)"] = [_interval_text(*values) for values in tv]
    return pd.DataFrame(columns)


def _longest_clean(rows: pd.DataFrame) -> float:
    """The largest delay (ms) up to which no run of ``rows`` (sorted by delay) diverged."""
    first_bad = rows[rows.diverged > 0].delay_ms.min()
    clean = rows if not math.isfinite(first_bad) else rows[rows.delay_ms < first_bad]
    return float(clean.delay_ms.max())


def write_robustness(study: RobustnessStudy, out: str | Path) -> list[Path]:
    """Write ``runs.csv`` (every run), ``map.csv``, ``knowledge.csv``, ``claims.csv``,
    ``verdicts.csv``, ``attribution.csv``, the map figure and ``report.html``."""
    out = Path(out)
    files = []
    every = pd.concat(
        [frame.assign(sweep=name) for name, frame in study.runs.items()], ignore_index=True
    )
    files.append(write_frame(every, out / "runs.csv"))
    for name in ("map", "knowledge", "claims", "verdicts", "attribution"):
        files.append(write_frame(getattr(study, name), out / f"{name}.csv"))
    files.append(write_frame(knowledge_table(study), out / "knowledge_table.csv"))
    saved = save_figure(robustness_map(study.map), out / "figures" / "robustness_map")
    files += saved
    image = next(path for path in saved if path.suffix == ".png").read_bytes()
    report = HtmlReport("delaytrack: robustness study (which controller when the delay is unknown)")
    base = load_builtin(BASE_SCENARIO)
    viscous = _FRICTION["plant.viscous_friction"]
    coulomb = _FRICTION["plant.coulomb_friction"]
    report.paragraph(
        "The paper's case for AROLC is that it needs no knowledge of the delay, while its "
        "predictor baselines assume they know it. This study asks which controller to use over "
        "distributions of robots rather than one run: every run is the paper job's robot run "
        f"({base.duration:g} s, the consistent circle, dt = {1e3 * base.dt:g} ms, T_c = "
        f"{1e3 * base.T_c:g} ms) with a drawn payload seed and wheel friction drawn uniformly "
        f"from its documented ranges (viscous {viscous['low']:g}–{viscous['high']:g} N·m·s/rad, "
        f"Coulomb {coulomb['low']:g}–{coulomb['high']:g} N·m); draw i is the same robot for "
        "every controller and condition, and each draw has its own noise seed. Three "
        "parts: a robustness map (constant true delays "
        + ", ".join(f"{1e3 * h:g}" for h in TRUE_DELAYS)
        + " ms against what the predictors are told, "
        + ", ".join(f"{s:g}" for s in SCALES)
        + " times the delay; gain sets tuned for all delays), the paper's S1 and S2 with wrong "
        "delay estimates (gain sets for time-varying delays), and S1–S4 as in the paper job "
        "(class gain sets), without and with measurement noise (encoder quantisation and white "
        f"noise). A run diverged when it stopped or its mean AE exceeded {DIVERGED_AE_MM:g} mm. "
        "A claim is judged per draw (a diverged run loses): it holds when the Wilson 95 % "
        "interval of the share of draws in which it holds lies above one half, fails when below, "
        "and is undecided otherwise. Medians carry percentile-bootstrap 95 % intervals."
    )
    n_runs = sum(len(f) for f in study.runs.values())
    report.paragraph(
        f"Size: {n_runs} runs of 60 s ({study.size.map} draws per map cell, "
        f"{study.size.knowledge} per delay-knowledge case, {study.size.claims} per claims case); "
        f"{study.computed} work units computed and {study.resumed} resumed in "
        f"{study.seconds:.1f} s."
    )
    report.heading("Findings")
    report.bullets(findings(study))
    report.figure(
        image,
        "Robustness map: divergence rate (colour) and median AE in mm of the "
        "runs that stayed on the path (text), per controller, against the true "
        "constant delay and what the predictors are told of it.",
    )
    report.heading("The paper's claims over draws")
    report.table(
        display_verdicts(study.verdicts),
        "Verdict per claim: share of draws in which it holds, with its "
        "Wilson 95 % interval (holds: interval above 50 %; fails: below).",
    )
    report.heading("Attribution: outer loop, Δu, tuning")
    report.table(
        display_attribution(study.attribution),
        "Paired change of AE (mm) and TV (N·m) per draw, median with bootstrap 95 % interval.",
    )
    report.heading("Robustness map (table)")
    report.table(
        display_outcomes(study.map, ["delay_ms", "controller", "scale"]),
        "Per true delay (ms), controller and scale: divergence and medians (map.csv).",
    )
    report.heading("What the predictors tolerate of a wrong delay")
    report.table(
        display_knowledge(knowledge_table(study)),
        "Case by case (knowledge_table.csv): divergence rate, median time of leaving the path of "
        "the runs that did, and median AE (mm) of those that did not, beside AROLC's.",
    )
    report.heading("Delay knowledge under S1 and S2")
    report.table(
        display_outcomes(study.knowledge, ["scenario", "controller", "scale"]),
        "Predictors told s·h(t) (PCON, PCON-wheel) or s times the profile's long-run mean (PCONf).",
    )
    report.heading("S1–S4 per controller and noise level")
    report.table(
        display_outcomes(study.claims, ["scenario", "noise", "controller"]),
        "Outcomes per scenario, noise level and controller (claims.csv).",
    )
    files.append(report.write(out / "report.html"))
    record_outputs(out, files)
    return files
