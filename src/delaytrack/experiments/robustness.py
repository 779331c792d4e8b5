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
percentile-bootstrap 95 % intervals (:mod:`~delaytrack.experiments.outcomes`). Each claim "A
below B" gets two verdicts, draw by draw on the same robots: staying on the path (McNemar's exact
test on the draws where only one side diverged) and accuracy given both stayed on the path (the
sign test and the paired median difference), every draw counted in one of four categories and
every test of the study corrected together with Holm's method
(:mod:`~delaytrack.experiments.verdicts`). Each verdict carries the delays its scenario reaches
beside those the tuning conditions of its delay class covered (:func:`tuning_envelope`).

:func:`run_study` returns a :class:`RobustnessStudy` holding every number of the study's report,
which :mod:`delaytrack.report.robustness` writes; :func:`delaytrack.jobs.robustness.run_robustness`
does both.
"""

from __future__ import annotations

import math
import time
from collections.abc import Collection, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pandas as pd

from delaytrack._deprecated import moved_names
from delaytrack._output import claim_output_folder
from delaytrack.delays import AbsSineDelay, delay_from_spec
from delaytrack.experiments import tuning
from delaytrack.experiments.drawn_robots import DRAWN_COLUMNS, FRICTION, PAYLOAD_ROBOT, SEED
from delaytrack.experiments.intervals import wilson_interval
from delaytrack.experiments.outcomes import delay_reach, outcome_table
from delaytrack.experiments.pairing import AROLC_GAINS, BASELINE, DELAY_CLASS
from delaytrack.experiments.verdicts import (
    ALPHA,
    MIN_DECIDED,
    attribution,
    attribution_ranges,
    claim_verdicts,
    survival_verdicts,
    verdict_counts,
)
from delaytrack.plants.robot import P3DX_WHEEL_TORQUE_LIMIT as WHEEL_TORQUE_LIMIT
from delaytrack.scenario import Scenario, load_builtin
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
    "knowledge_table",
    "repeated_in",
    "run_study",
    "scenario_delay_ranges",
    "study_specs",
    "tuning_envelope",
    "wilson_interval",
]
#: The statistics and the report's text moved; reading them here still works, with a warning.
__getattr__ = moved_names(
    __name__,
    {
        "median_interval": "delaytrack.experiments.intervals:median_interval",
        "findings": "delaytrack.report.robustness:findings",
        "display_verdicts": "delaytrack.report.robustness:display_verdicts",
        "display_attribution": "delaytrack.report.robustness:display_attribution",
        "display_knowledge": "delaytrack.report.robustness:display_knowledge",
        "display_outcomes": "delaytrack.report.robustness:display_outcomes",
        "robustness_map": "delaytrack.report.robustness:robustness_map",
        "run_robustness": "delaytrack.jobs.robustness:run_robustness",
    },
)

#: Scales ``s`` of what the predictors are told (``s h``).
SCALES: tuple[float, ...] = (0.5, 0.75, 1.0, 1.25, 1.5, 2.0)
#: Constant true delays of the map (s): the tuning covered 20–140 ms.
TRUE_DELAYS: tuple[float, ...] = (0.02, 0.06, 0.1, 0.12, 0.13, 0.15, 0.2, 0.3)
#: A run *wound up* when its commanded TV exceeds this many times the TV its wheels received:
#: the controller's commands ran away while the torque limit held the wheels (without limits
#: the two differ only by the delay's shift).
WOUND_UP = 100.0
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
#: The shipped scenario every run starts from (the paper job's AROLC / S1 run).
BASE_SCENARIO = "robot_S1"
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
    #: Draws of a map cell at a controller's divergence edge (:func:`edge_cells`), refined after
    #: the map's first pass; 0: no refinement.
    map_edge: int = 0


#: ``default``: what ``delaytrack reproduce`` runs (about 6 400 runs). 40 draws per claim put
#: the Wilson 95 % half-width of a share near one half at about 0.15, so a claim that holds (or
#: fails) in 70 % of draws is decided; 8 draws per map cell find where a controller diverges in
#: most draws, and the cells at that edge are run again with 40 draws: none diverged in 40 bounds
#: the divergence rate below 9 % (Wilson), where none in 8 still allowed 32 %. ``full``: ten
#: times the draws.
SIZES: dict[str, StudySize] = {
    "default": StudySize(map=8, knowledge=8, claims=40, map_edge=40),
    "full": StudySize(map=80, knowledge=80, claims=400, map_edge=400),
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
            "random": {**PAYLOAD_ROBOT, **(extra or {})},
        }
    )


def _map_rows(gains: Gains) -> list[tuple[str, float, dict[str, Any]]]:
    """The map's controllers: ``(name, scale, controller table)``."""
    rows: list[tuple[str, float, dict[str, Any]]] = [
        ("AROLC (paper gains)", math.nan, _arolc_table(AROLC_GAINS)),
        ("AROLC (tuned)", math.nan, _arolc_table(_tuned_arolc(gains, "all"))),
        ("outer loop (paper gains)", math.nan, _outer_table(AROLC_GAINS)),
    ]
    for kind in tuning.PREDICTORS:
        law = "PCON" if kind == "PCONf" else None
        rows += [(kind, s, _predictor_table(gains, kind, "all", scale=s, law=law)) for s in SCALES]
    return rows


def _map_sweep(
    gains: Gains,
    draws: int,
    delays: tuple[float, ...] = TRUE_DELAYS,
    chosen: Collection[int] | None = None,
    name: str = "map",
) -> _Sweep:
    """The map's runs at the constant true ``delays`` (s) for the controllers ``chosen``
    (indices into :func:`_map_rows`; all by default), each over ``draws`` drawn robots."""
    rows = [row for i, row in enumerate(_map_rows(gains)) if chosen is None or i in chosen]
    labels = [
        {"delay_ms": 1e3 * h, "controller": label, "scale": scale}
        for h in delays
        for label, scale, _ in rows
    ]
    tables = [table for _, _, table in rows]
    grid = {"delay": [{"type": "constant", "h": h} for h in delays], "controller": tables}
    return _Sweep(name, _spec(grid, draws), labels)


def edge_cells(outcomes: pd.DataFrame) -> list[tuple[float, int]]:
    """The cells ``(delay_ms, row)`` of a map's outcomes (``runs`` and ``diverged`` per cell, as
    :func:`outcome_table` gives them) at a controller's divergence edge: a cell where some but
    not all runs diverged, and a cell next (in the true delay) to one that differs from it in
    whether any run diverged. ``row`` indexes
    :func:`_map_rows` (the table's rows come per delay in that order)."""
    count = len(outcomes) // len(TRUE_DELAYS)
    diverged = outcomes.diverged.to_numpy().reshape(len(TRUE_DELAYS), count)
    runs = outcomes.runs.to_numpy().reshape(len(TRUE_DELAYS), count)
    cells = []
    for row in range(count):
        some = diverged[:, row] > 0
        for i, h in enumerate(TRUE_DELAYS):
            mixed = 0 < diverged[i, row] < runs[i, row]
            neighbours = [j for j in (i - 1, i + 1) if 0 <= j < len(TRUE_DELAYS)]
            if mixed or any(some[j] != some[i] for j in neighbours):
                cells.append((1e3 * h, row))
    return cells


def edge_sweeps(gains: Gains, outcomes: pd.DataFrame, draws: int) -> list[_Sweep]:
    """The map's cells at the divergence edge (:func:`edge_cells`) again with ``draws`` drawn
    robots, one sweep per true delay (``map-edge-<ms>ms``). Draw ``i`` is the same robot as in
    the map (a key's draws do not depend on their number), so the first runs repeat the map's."""
    cells = edge_cells(outcomes)
    sweeps = []
    for h in TRUE_DELAYS:
        rows = {row for delay_ms, row in cells if delay_ms == 1e3 * h}
        if rows:
            name = f"map-edge-{1e3 * h:g}ms"
            sweeps.append(_map_sweep(gains, draws, (h,), rows, name))
    return sweeps


def _cells(runs: pd.DataFrame) -> dict[tuple[float, str, float], pd.DataFrame]:
    """The runs per map cell ``(delay_ms, controller, scale)`` in their order (no scale: -1)."""
    return {
        (delay_ms, controller, -1.0 if math.isnan(scale) else scale): group
        for (delay_ms, controller, scale), group in runs.groupby(
            ["delay_ms", "controller", "scale"], sort=False, dropna=False
        )
    }


def refined_map(map_runs: pd.DataFrame, edge_runs: list[pd.DataFrame]) -> pd.DataFrame:
    """The map's runs, each refined cell's replaced by its edge sweep's (in the map's order)."""
    refined = _cells(pd.concat(edge_runs)) if edge_runs else {}
    parts = [refined.get(cell, group) for cell, group in _cells(map_runs).items()]
    return pd.concat(parts, ignore_index=True)


def repeated_in(runs: Mapping[str, pd.DataFrame]) -> pd.Series:
    """Per run of the map's first pass (``runs["map"]``, in its order): the edge sweep that ran
    its draw again with the cell's other draws (:func:`edge_sweeps`: draw ``i`` is the same
    robot in both, so the numbers are the same), or an empty text."""
    first = runs["map"]
    where = pd.Series("", index=first.index, dtype=object)
    cells = _cells(first)
    for name, frame in runs.items():
        if name.startswith("map-edge-"):
            for cell in _cells(frame):
                where[cells[cell].index] = name
    return where


def _knowledge_sweep(gains: Gains, case: str, draws: int) -> _Sweep:
    rows: list[tuple[str, float, dict[str, Any]]] = [
        ("AROLC (paper gains)", math.nan, _arolc_table(AROLC_GAINS)),
        ("AROLC (tuned)", math.nan, _arolc_table(_tuned_arolc(gains, "varying"))),
    ]
    delay = delay_from_spec(_SCENARIOS[case])
    assert isinstance(delay, AbsSineDelay)  # the knowledge cases S1 and S2 are |sin| delays
    mean = tuning.long_run_mean(delay)
    for s in SCALES:
        rows.append(("PCON", s, _predictor_table(gains, "PCON", "varying", scale=s)))
        rows.append(("PCON-wheel", s, _predictor_table(gains, "PCON-wheel", "varying", scale=s)))
        rows.append(("PCONf", s, _predictor_table(gains, "PCONf", "varying", h_bar=s * mean)))
    labels = [{"scenario": case, "controller": name, "scale": s} for name, s, _ in rows]
    grid = {"delay": [_SCENARIOS[case]], "controller": [table for _, _, table in rows]}
    return _Sweep(f"knowledge-{case}", _spec(grid, draws), labels)


def _claims_sweep(gains: Gains, case: str, draws: int, limited: bool = False) -> _Sweep:
    """The claims case ``case`` (``claims-<case>``), or with every wheel's torque limited to
    :data:`WHEEL_TORQUE_LIMIT` (``actuators-<case>``)."""
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
    grid: dict[str, list[Any]] = {
        "delay": [_SCENARIOS[case]],
        "measurement_noise": [table for _, table in noise],
        "controller": [table for _, table in rows],
    }
    if limited:
        grid = {"input_limits": [WHEEL_TORQUE_LIMIT], **grid}
    noise_seed = {"measurement_noise.seed": {"dist": "integers", "low": 0, "high": 2**32 - 1}}
    name = f"{'actuators' if limited else 'claims'}-{case}"
    return _Sweep(name, _spec(grid, draws, noise_seed), labels)


def study_specs(
    size: str | StudySize = "default", gains: tuning.GainsSource = None
) -> list[_Sweep]:
    """The study's sweeps at a size (:data:`SIZES`): map, knowledge-S1/S2, claims-S1..S4, with
    the tuned gains of ``gains`` (a gains file or its record; the shipped file by default)."""
    size = SIZES[size] if isinstance(size, str) else size
    return _study_sweeps(size, tuning.load_gains(gains))


def _study_sweeps(size: StudySize, gains: Gains) -> list[_Sweep]:
    """:func:`study_specs` with the chosen ``gains`` already loaded (:func:`tuning.load_gains`)."""
    return [
        _map_sweep(gains, size.map),
        *(_knowledge_sweep(gains, case, size.knowledge) for case in ("S1", "S2")),
        *(_claims_sweep(gains, case, size.claims) for case in _SCENARIOS),
        *(_claims_sweep(gains, case, size.claims, limited=True) for case in _SCENARIOS),
    ]


# --------------------------------------------------------------------------------------------
# The study's tables


def wound_up(tv: np.ndarray, received: np.ndarray) -> np.ndarray:
    """Whether each run's commands ran away from what its actuators received: commanded TV not
    finite or above :data:`WOUND_UP` times the TV received (a controller wound up at a limit)."""
    return ~np.isfinite(tv) | (tv > WOUND_UP * received)


def _runs_frame(sweep: _Sweep, runs: pd.DataFrame) -> pd.DataFrame:
    """One row per run: the grid point's labels, the draw, AE (mm), TV (N·m), divergence."""
    draws = sweep.spec.draws
    runs = runs.sort_values("run").reset_index(drop=True)
    frame = pd.DataFrame(sweep.labels).iloc[runs.run // draws].reset_index(drop=True)
    frame["draw"] = (runs.run % draws).to_numpy()
    for key, column in DRAWN_COLUMNS.items():
        frame[column] = runs[key].to_numpy()
    frame["ae_mm"] = (500.0 * (runs.ae_x + runs.ae_y)).to_numpy()
    frame["tv_Nm"] = runs.tv.to_numpy()
    if sweep.name.startswith("actuators"):  # on torque-limited wheels: what they received
        frame["tv_received_Nm"] = runs.tv_applied.to_numpy()
        frame["wound_up"] = wound_up(frame.tv_Nm.to_numpy(), frame.tv_received_Nm.to_numpy())
    frame["status"] = runs.status.to_numpy()
    frame["t_stop_s"] = runs.t_stop.to_numpy()
    frame["diverged"] = tuning.off_path(frame.status == "ok", frame.ae_mm)
    return frame


def _cell(table: pd.DataFrame, **where: Any) -> pd.Series:
    rows = table
    for key, value in where.items():
        rows = rows[rows[key].isna()] if value is None else rows[rows[key] == value]
    if len(rows) != 1:
        raise KeyError(f"no single row of the study for {where}")
    return rows.iloc[0]


def knowledge_table(knowledge: pd.DataFrame, map_table: pd.DataFrame) -> pd.DataFrame:
    """What the predictors tolerate of a wrong delay, case by case, from the outcome tables of
    the knowledge sweeps and of the map: the truth, what the predictor is told, its divergence
    rate, median AE and median time of leaving the path, beside AROLC's (paper gains) under the
    same truth."""
    cases: list[tuple[str, str, str, pd.Series, pd.Series]] = []
    k, m = knowledge, map_table
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


def _delay_range_ms(delays: list[Any], duration: float, dt: float) -> tuple[float, float]:
    """Smallest and largest delay (ms) of the profiles ``delays`` over ``[0, duration]``,
    sampled every ``dt``."""
    t = np.linspace(0.0, duration, int(round(duration / dt)) + 1)
    h = np.concatenate([delay.h(t) for delay in delays])
    return 1e3 * float(h.min()), 1e3 * float(h.max())


def tuning_envelope(record: Mapping[str, Any]) -> dict[str, tuple[float, float]]:
    """Per delay class, the smallest and largest delay (ms) that the tuning conditions of
    ``record`` (a gains record) reached over their runs: the delays its gain sets were chosen
    on. The conditions are drawn again from the record's seed and checked against its
    descriptions."""
    conditions = tuning.draw_conditions(
        record["condition_seed"], len(record["conditions"]) // len(tuning.DELAY_CLASSES)
    )
    if [c.text for c in conditions] != list(record["conditions"]):
        raise ValueError("the gains record's conditions are not those its condition_seed draws")
    return {
        delay_class: _delay_range_ms(
            [c.delay for c in conditions if c.delay_class == delay_class],
            record["duration"],
            record["dt"],
        )
        for delay_class in tuning.DELAY_CLASSES
    }


def scenario_delay_ranges(scenario: Scenario) -> dict[str, tuple[float, float]]:
    """Smallest and largest delay (ms) of S1–S4 over a run of ``scenario`` (its duration and
    ``dt``)."""
    return {
        case: _delay_range_ms([delay_from_spec(spec)], scenario.duration, scenario.dt)
        for case, spec in _SCENARIOS.items()
    }


def _with_tuning_envelope(
    verdicts: pd.DataFrame,
    envelope: Mapping[str, tuple[float, float]],
    ranges: Mapping[str, tuple[float, float]],
) -> pd.DataFrame:
    """``verdicts`` with the delays each row's scenarios reach (``scenario_delay_min_ms``,
    ``scenario_delay_max_ms``), those the tuning conditions of their delay class covered
    (``tuning_delay_min_ms``, ``tuning_delay_max_ms``) and whether the scenario's delays leave
    them (``outside_tuning``)."""
    columns: dict[str, list[Any]] = {
        key: []
        for key in (
            "scenario_delay_min_ms",
            "scenario_delay_max_ms",
            "tuning_delay_min_ms",
            "tuning_delay_max_ms",
            "outside_tuning",
        )
    }
    for label in verdicts.scenario:
        cases = label.split(" -> ")  # "S3 -> S4": both scenarios
        low = min(ranges[case][0] for case in cases)
        high = max(ranges[case][1] for case in cases)
        tuned_low, tuned_high = envelope[DELAY_CLASS[cases[0]]]
        columns["scenario_delay_min_ms"].append(low)
        columns["scenario_delay_max_ms"].append(high)
        columns["tuning_delay_min_ms"].append(tuned_low)
        columns["tuning_delay_max_ms"].append(tuned_high)
        columns["outside_tuning"].append(bool(low < tuned_low or high > tuned_high))
    at = verdicts.columns.get_loc("draws")
    out = verdicts.copy()
    for offset, (key, values) in enumerate(columns.items()):
        out.insert(at + offset, key, values)
    return out


def _edges(record: Mapping[str, Any]) -> tuple[tuple[str, str], ...]:
    """The tuned gain sets ``(kind, gain set)`` still on an edge of their grid after the
    extensions (the gains file's ``interior`` is false)."""
    return tuple(
        (kind, gain_set)
        for kind in tuning.KINDS
        for gain_set in tuning.GAIN_SETS
        if not record[kind][gain_set]["interior"]
    )


@dataclass(frozen=True)
class RobustnessStudy:
    """Everything :func:`run_study` computed: every number of the study's report.

    Attributes
    ----------
    size : StudySize
    scenario : Scenario
        The shipped scenario every run starts from (:data:`BASE_SCENARIO`).
    runs : dict
        Sweep name -> one row per run (:func:`_runs_frame` columns).
    run_count : int
        Runs over every sweep.
    refined_cells : int
        Map cells at a divergence edge run again with ``size.map_edge`` draws
        (:func:`edge_sweeps`); ``map`` holds their refined outcomes.
    map, knowledge : DataFrame
        :func:`~delaytrack.experiments.outcomes.outcome_table` per (true delay, controller,
        scale) and per (scenario, controller, scale).
    claims : DataFrame
        :func:`~delaytrack.experiments.outcomes.outcome_table` per (scenario, noise,
        controller).
    actuators : DataFrame
        The same for the claims cases run again with every wheel's torque limited to
        ``wheel_torque_limit``: TV commanded and TV received, and the runs that wound up.
    verdicts : DataFrame
        :func:`~delaytrack.experiments.verdicts.claim_verdicts`, one row per claim, with the
        delays of its scenario and of the tuning beside it (:func:`_with_tuning_envelope`).
    survival_verdicts : DataFrame
        :func:`~delaytrack.experiments.verdicts.survival_verdicts` of ``verdicts``: one row per
        survival comparison.
    verdict_counts : DataFrame
        :func:`~delaytrack.experiments.verdicts.verdict_counts` of ``verdicts``: how many
        verdicts hold, fail, are undecided or reach no decision, per kind and noise level.
    tuning_envelope : mapping
        :func:`tuning_envelope` of the tuning record: per delay class, the delays (ms) its
        tuning conditions covered.
    attribution : DataFrame
        :func:`~delaytrack.experiments.verdicts.attribution`.
    knowledge_table : DataFrame
        :func:`knowledge_table`: what the predictors tolerate of a wrong delay.
    reach : DataFrame
        :func:`~delaytrack.experiments.outcomes.delay_reach` of the map: per controller and
        scale, the longest delay with no diverged run.
    attribution_ranges : DataFrame
        :func:`~delaytrack.experiments.verdicts.attribution_ranges` of ``attribution``.
    edges : tuple of (str, str)
        The tuned gain sets ``(kind, gain set)`` still on an edge of their grid.
    tuning_record : mapping
        The gains file the tuned controllers came from (:func:`tuning.load_tuning_record`).
    seconds : float
        Wall time of the sweeps.
    computed, resumed : int
        Work units computed and resumed.

    The design travels with every study as class attributes: ``scales`` (:data:`SCALES`),
    ``true_delays`` (:data:`TRUE_DELAYS`, s), ``predictors`` (the controllers told the delay),
    ``friction`` (the drawn friction ranges), ``wheel_torque_limit`` (N·m, every run's
    actuator limit in the ``actuators`` sweeps), ``wound_up`` (:data:`WOUND_UP`),
    ``diverged_ae_mm``, ``alpha`` (the verdicts'
    family-wise error rate) and ``min_decided`` (the fewest decided draws of a verdict).
    """

    scales: ClassVar[tuple[float, ...]] = SCALES
    true_delays: ClassVar[tuple[float, ...]] = TRUE_DELAYS
    predictors: ClassVar[tuple[str, ...]] = tuning.PREDICTORS
    friction: ClassVar[Mapping[str, Mapping[str, Any]]] = FRICTION
    wheel_torque_limit: ClassVar[float] = WHEEL_TORQUE_LIMIT
    wound_up: ClassVar[float] = WOUND_UP
    diverged_ae_mm: ClassVar[float] = DIVERGED_AE_MM
    alpha: ClassVar[float] = ALPHA
    min_decided: ClassVar[int] = MIN_DECIDED

    size: StudySize
    scenario: Scenario
    runs: dict[str, pd.DataFrame]
    run_count: int
    refined_cells: int
    map: pd.DataFrame
    knowledge: pd.DataFrame
    claims: pd.DataFrame
    actuators: pd.DataFrame
    verdicts: pd.DataFrame
    survival_verdicts: pd.DataFrame
    verdict_counts: pd.DataFrame
    tuning_envelope: Mapping[str, tuple[float, float]]
    attribution: pd.DataFrame
    knowledge_table: pd.DataFrame
    reach: pd.DataFrame
    attribution_ranges: pd.DataFrame
    edges: tuple[tuple[str, str], ...]
    tuning_record: Mapping[str, Any]
    seconds: float
    computed: int = 0
    resumed: int = 0


def run_study(
    out: str | Path,
    *,
    size: str | StudySize = "default",
    executor: Any = None,
    progress: bool = True,
    gains: tuning.GainsSource = None,
) -> RobustnessStudy:
    """Run (or resume) the study's sweeps into ``out/sweeps/<name>/``; return the study
    (:func:`delaytrack.jobs.robustness.run_robustness` also writes its report into ``out``).

    ``executor`` makes an :class:`~delaytrack.sweeps.executors.Executor` per sweep (a callable
    without arguments; default: all local cores); ``gains`` is where the tuned gains come
    from (a gains file or its record; the shipped file by default).
    """
    record = tuning.load_tuning_record(gains)
    chosen = tuning.load_gains(record)
    size = SIZES[size] if isinstance(size, str) else size
    make = executor if executor is not None else LocalExecutor
    out = claim_output_folder(out)
    start = time.perf_counter()
    frames: dict[str, pd.DataFrame] = {}
    counts = {"computed": 0, "resumed": 0}

    def run(sweep: _Sweep) -> None:
        if progress:
            print(f"robustness: sweep {sweep.name} ({len(sweep.spec.runs)} runs)", flush=True)
        outcome = run_sweep(
            sweep.spec, out / "sweeps" / sweep.name, executor=make(), progress=progress
        )
        counts["computed"] += outcome.computed
        counts["resumed"] += outcome.resumed
        frames[sweep.name] = _runs_frame(sweep, outcome.runs)

    for sweep in _study_sweeps(size, chosen):
        run(sweep)
    cell = ["delay_ms", "controller", "scale"]
    # what edge_cells reads: per map cell in the map's order, its runs and diverged runs
    diverged = frames["map"].groupby(cell, sort=False, dropna=False).diverged
    counted = diverged.agg(runs="size", diverged="sum").reset_index()
    edges = edge_sweeps(chosen, counted, size.map_edge) if size.map_edge > size.map else []
    for sweep in edges:
        run(sweep)
    computed, resumed = counts["computed"], counts["resumed"]
    seconds = time.perf_counter() - start
    knowledge = pd.concat([f for n, f in frames.items() if n.startswith("knowledge")])
    claims = pd.concat([f for n, f in frames.items() if n.startswith("claims")])
    limited = pd.concat([f for n, f in frames.items() if n.startswith("actuators")])
    map_runs = refined_map(frames["map"], [frames[sweep.name] for sweep in edges])
    map_outcomes = outcome_table(map_runs, cell)
    knowledge_outcomes = outcome_table(knowledge, ["scenario", "controller", "scale"])
    attributed = attribution(claims)
    scenario = load_builtin(BASE_SCENARIO)
    envelope = tuning_envelope(record)
    verdicts = _with_tuning_envelope(
        claim_verdicts(claims), envelope, scenario_delay_ranges(scenario)
    )
    return RobustnessStudy(
        size=size,
        scenario=scenario,
        runs=frames,
        run_count=sum(len(frame) for frame in frames.values()),
        refined_cells=sum(len(sweep.labels) for sweep in edges),
        map=map_outcomes,
        knowledge=knowledge_outcomes,
        claims=outcome_table(claims, ["scenario", "noise", "controller"]),
        actuators=outcome_table(limited, ["scenario", "noise", "controller"]),
        verdicts=verdicts,
        survival_verdicts=survival_verdicts(verdicts),
        verdict_counts=verdict_counts(verdicts),
        tuning_envelope=envelope,
        attribution=attributed,
        knowledge_table=knowledge_table(knowledge_outcomes, map_outcomes),
        reach=delay_reach(map_outcomes),
        attribution_ranges=attribution_ranges(attributed),
        edges=_edges(record),
        tuning_record=record,
        seconds=seconds,
        computed=computed,
        resumed=resumed,
    )
