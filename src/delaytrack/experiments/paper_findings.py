"""Every number the paper job's report quotes beyond its tables, computed once with the study
(:func:`paper_findings`): the paper's claims case by case, what explains the outcome (the outer
loop's natural frequency and damping, the wheel friction the nominal model leaves out,
``λ_max(M̂⁻¹)``, the adaptive gain's peak, the tuning's spread), the baselines' failures,
Theorem 1's certificate per scenario, the paths' speeds and the runs with contact physics.

The report (:mod:`delaytrack.report.paper`) only writes these numbers down.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from delaytrack.analysis import RazumikhinBound
from delaytrack.experiments import tuning
from delaytrack.experiments.contact import ContactFindings, contact_findings
from delaytrack.experiments.convergence import dt_check_verdict
from delaytrack.experiments.pairing import AROLC_GAINS, BASELINE, DELAY_CLASS
from delaytrack.experiments.paper_setup import DT, PAPER_TABLE, SCENARIOS, T_C
from delaytrack.plants.mujoco import import_mujoco
from delaytrack.plants.robot import (
    P3DX,
    P3DX_MJCF,
    P3DX_PAYLOAD,
    NominalRobot,
    WheeledRobot,
    initial_state,
    paper_reference,
    wheel_rates,
)
from delaytrack.plants.robot.payload import placement_count
from delaytrack.plants.robot.reference import CIRCLE_RADIUS, CIRCLE_RATE
from delaytrack.sim import SimResult

__all__ = [
    "BaselineFailure",
    "Claims",
    "PaperFindings",
    "TuningGrid",
    "certified_scenarios",
    "claims",
    "paper_findings",
    "summary_row",
    "tuned_as_arolc",
]

#: The paper's claims, case by case: ``{"ae": {scenario: holds}, "tv": {...}, "growth":
#: {"S3->S4": holds}}`` (:func:`claims`); None where a run the claim compares left the path.
Claims = dict[str, dict[str, bool | None]]
#: A baseline's delay "dwells" above this share of its largest delay (:class:`BaselineFailure`).
_DWELL_SHARE = 0.9
#: Grid points of each tuning grid the report lists, best first.
_BEST_POINTS = 5


@dataclass(frozen=True)
class BaselineFailure:
    """A predictor baseline's run that did not finish, and the delay it met that its tuning
    never saw.

    Attributes
    ----------
    scenario, controller, delay_class : str
        The run, and the tuning's delay class of its gain set.
    t_stop : float
        When it stopped (s).
    largest_delay : float
        The scenario's largest delay ``h_max`` (s).
    dwell_level : float
        ``0.9 h_max`` (s).
    longest_dwell : float or None
        The longest stretch (s) over which the delay stays above ``dwell_level``; None when it
        never does or does so throughout the run (a constant delay).
    tuning_largest_delay : float
        The largest delay of the class's tuning conditions (s).
    stability_number : float
        ``T_c k_b λ_max(ϑ)`` (``ϑ = c ϑ₀``) of its gains: the sampled law is stable only
        for about ``< 2``.
    """

    scenario: str
    controller: str
    delay_class: str
    t_stop: float
    largest_delay: float
    dwell_level: float
    longest_dwell: float | None
    tuning_largest_delay: float
    stability_number: float


@dataclass(frozen=True)
class TuningGrid:
    """One controller's tuning grid for one gain set, as the report shows it.

    Attributes
    ----------
    best : DataFrame
        The five grid points of smallest objective (gains, per-condition AE, objective).
    excluded : int
        Grid points that diverged or left the path under one of the set's conditions.
    points : int
        Grid points run.
    """

    best: pd.DataFrame
    excluded: int
    points: int


@dataclass(frozen=True)
class PaperFindings:
    """The numbers of the paper job's report beyond its tables (module docstring).

    Attributes
    ----------
    claims, tuned_claims : Claims
        The paper's claims (:func:`claims`) for AROLC with the paper's gains, and with the
        tuned AROLC in its place (:func:`tuned_as_arolc`).
    stopped : DataFrame
        ``scenario, controller, status, t_stop`` of the runs that did not finish.
    off_path : int
        Runs off the path by the rule of the tuning and the robustness study: stopped, or a mean
        of AE-x and AE-y above :data:`~delaytrack.experiments.tuning.DIVERGED_AE_MM`.
    ae_x_range : dict
        ``"AROLC"``, ``"OuterLoop"``, ``"baseline"`` -> smallest and largest AE-x over S1–S4
        (mm).
    natural_frequency, damping : float
        The paper-gain outer loop's ``ω = √K1`` (rad/s) and ``ζ = K2 / (2 ω)``.
    c_hat_peak, c_hat_peak_scenario, c_hat_peak_time : float, str, float
        The largest adaptive gain ``ĉ`` of any AROLC run (paper gains), its scenario and time
        (s).
    c_hat_peak_at_end : bool
        Whether that peak is at the end of the run (ĉ may grow further in a longer one).
    switching_bound : float
        ``α ĉ`` at that peak: the bound on ``‖Δu‖``.
    wheel_rates : tuple of float
        Smallest and largest wheel rate of the consistent path (rad/s).
    wheel_friction : tuple of float
        Smallest and largest friction torque of the truth's wheels at those rates (N·m).
    inverse_mass_eigenvalue : float
        ``λ_max(M̂⁻¹)`` of the nominal model at the start of the path.
    stable_gain_product : float
        ``2 / (T_c λ_max(M̂⁻¹))``: the largest ``k_b c`` of a stable sampled predictor.
    tuning_spread : dict
        ``"PCON"``, ``"PCONf"`` -> smallest, median and largest worst-case objective (mm) of the
        grid points not excluded, for the gain set of S1 and S3.
    baseline_failures : tuple of BaselineFailure
    paper_arolc_tv : tuple of float
        Smallest and largest TV of AROLC in the paper's Table III.
    delay_ranges : dict
        Scenario -> smallest and largest delay over the run (s, sampled every ``dt``).
    delay_ranges_in_periods : dict
        The same divided by ``T_c``.
    largest_scenario_delay : float
        The largest ``h_max`` of S1–S4 (s).
    certified, tuned_certified : tuple of str
        The scenarios whose largest delay over the run Theorem 1 certifies, for the paper's
        gains and for the tuned AROLC.
    tuned_h_m : float
        Theorem 1's bound for the tuned AROLC: the smaller of its two class sets' (s).
    chosen_gains : DataFrame
        Every controller's chosen gain sets (``controller``, ``gain set``, in the gains file's
        order): objective (mm), certified ``h_m`` (ms, AROLC only).
    tuning_grids : dict
        ``(controller, gain set)`` -> :class:`TuningGrid`.
    heading_start, heading_rate : float
        The consistent path's heading at ``t = 0`` (rad) and its rate (rad/s).
    consistent_wheel_rates : tuple of float
        The consistent path's right and left wheel rates (rad/s).
    circle_speed : float
        The circle's speed (m/s).
    payload_placements : int
        How many times the payload is put on the robot in a run of the job's duration.
    literal_speed, literal_turn : float
        The forward speed (m/s) and turn rate (rad/s) the literal path's wheel references imply.
    controller_rate : float
        ``1 / T_c`` (Hz).
    half_dt : float
        The plant step of the dt-halving check (s).
    dt_within_tolerance : bool or None
        Whether halving ``dt`` moved every metric by less than the tolerance; None when not
        checked.
    mujoco_installed : bool
    floor_friction : float or None
        The sliding friction coefficient of the wheels on the floor in the model file of the
        robot with real wheels; None without contact runs.
    contact : ContactFindings or None
        What contacts changed; None without contact runs.
    """

    claims: Claims
    tuned_claims: Claims
    stopped: pd.DataFrame
    off_path: int
    ae_x_range: dict[str, tuple[float, float]]
    natural_frequency: float
    damping: float
    c_hat_peak: float
    c_hat_peak_scenario: str
    c_hat_peak_time: float
    c_hat_peak_at_end: bool
    switching_bound: float
    wheel_rates: tuple[float, float]
    wheel_friction: tuple[float, float]
    inverse_mass_eigenvalue: float
    stable_gain_product: float
    tuning_spread: dict[str, tuple[float, float, float]]
    baseline_failures: tuple[BaselineFailure, ...]
    paper_arolc_tv: tuple[float, float]
    delay_ranges: dict[str, tuple[float, float]]
    delay_ranges_in_periods: dict[str, tuple[float, float]]
    largest_scenario_delay: float
    certified: tuple[str, ...]
    tuned_h_m: float
    tuned_certified: tuple[str, ...]
    chosen_gains: pd.DataFrame
    tuning_grids: dict[tuple[str, str], TuningGrid]
    heading_start: float
    heading_rate: float
    consistent_wheel_rates: tuple[float, float]
    circle_speed: float
    payload_placements: int
    literal_speed: float
    literal_turn: float
    controller_rate: float
    half_dt: float
    dt_within_tolerance: bool | None
    mujoco_installed: bool
    floor_friction: float | None
    contact: ContactFindings | None


def summary_row(summary: pd.DataFrame, scenario: str, controller: str) -> pd.Series:
    """The row of ``summary`` (:data:`~delaytrack.experiments.paper_setup.SUMMARY_COLUMNS`) of
    one run."""
    return summary[(summary.scenario == scenario) & (summary.controller == controller)].iloc[0]


def _all_below(a: Sequence[float], b: Sequence[float]) -> bool | None:
    """Whether every ``a`` is below its ``b``; None when a value is not finite (its run left
    the path: staying on it is one question, accuracy another, and a run off the path has no
    accuracy to compare)."""
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        return None
    return bool(np.all(np.asarray(a) < np.asarray(b)))


def claims(summary: pd.DataFrame) -> Claims:
    """The paper's claims, case by case: ``ae`` (AROLC below the baseline in AE-x and AE-y),
    ``tv`` (AROLC below in TV), and ``growth`` (AROLC's AE-x and AE-y larger in S4 than in S3).
    A claim that compares a run that left the path (NaN) is None: not decided by this run, whichever
    run it was (the report says which stayed on the path)."""
    ae: dict[str, bool | None] = {}
    tv: dict[str, bool | None] = {}
    for case in SCENARIOS:
        a, b = summary_row(summary, case, "AROLC"), summary_row(summary, case, BASELINE[case])
        ae[case] = _all_below([a.ae_x_mm, a.ae_y_mm], [b.ae_x_mm, b.ae_y_mm])
        tv[case] = _all_below([a.tv_Nm], [b.tv_Nm])
    s3, s4 = summary_row(summary, "S3", "AROLC"), summary_row(summary, "S4", "AROLC")
    growth = {"S3->S4": _all_below([s3.ae_x_mm, s3.ae_y_mm], [s4.ae_x_mm, s4.ae_y_mm])}
    return {"ae": ae, "tv": tv, "growth": growth}


def tuned_as_arolc(summary: pd.DataFrame, tuned_summary: pd.DataFrame) -> pd.DataFrame:
    """``summary`` with the paper-gain AROLC rows replaced by the tuned AROLC's (named
    ``AROLC``), so that :func:`claims` checks the claims for the tuned AROLC."""
    tuned = tuned_summary.assign(controller="AROLC")
    rest = summary[summary.controller != "AROLC"]
    return pd.concat([tuned, rest], ignore_index=True)


def certified_scenarios(h_m: float, largest: Mapping[str, float]) -> tuple[str, ...]:
    """The scenarios Theorem 1 certifies with bound ``h_m``: those whose largest delay over the
    run (``largest``, s) is at most ``h_m``."""
    return tuple(case for case, value in largest.items() if value <= h_m)


def _delay_samples(scenario: str, duration: float) -> tuple[np.ndarray, np.ndarray]:
    """Times (s, every ``DT`` over ``[0, duration]``) and the scenario's delay (s) at them."""
    t = np.linspace(0.0, duration, int(round(duration / DT)) + 1)
    return t, SCENARIOS[scenario].h(t)


def _delay_range(scenario: str, duration: float) -> tuple[float, float]:
    """Smallest and largest delay (s) of a scenario over ``[0, duration]``."""
    h = _delay_samples(scenario, duration)[1]
    return float(h.min()), float(h.max())


def _dwells(scenario: str, duration: float, level: float) -> list[tuple[float, float]]:
    """``(start, end)`` (s) of the stretches where the scenario's delay exceeds ``level`` (s)."""
    t, h = _delay_samples(scenario, duration)
    above = np.concatenate([[False], h > level, [False]])
    edges = np.flatnonzero(np.diff(above.astype(int)))
    return [(float(t[a]), float(t[b - 1])) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def _stability_number(kind: str, gains: Mapping[str, float]) -> float:
    """``T_c k_b λ_max(ϑ) = T_c k_b c λ_max(ϑ₀)`` of a predictor's gains: the sampled law is
    stable only for about ``< 2`` (docs/decisions.md D23)."""
    lam = float(np.linalg.eigvalsh(tuning.vartheta_base(kind)).max())
    return T_C * gains["k_b"] * gains["c"] * lam


def _wheel_friction_torques() -> tuple[np.ndarray, np.ndarray]:
    """The consistent path's wheel rates (rad/s) and the truth's friction torque at them (N·m),
    from the truth plant's own friction law."""
    rates = wheel_rates("consistent")
    qdot = np.concatenate([np.zeros(3), rates])
    return rates, WheeledRobot().reduced_terms(qdot)[2][0]


def _inverse_mass_eigenvalue(reference: str) -> float:
    """``λ_max(M̂⁻¹)`` of the nominal model at the start of the path ``reference``."""
    start = initial_state(paper_reference(reference))[:5]
    return float(np.linalg.eigvalsh(np.linalg.inv(NominalRobot().mass_matrix(start)[0])).max())


def _floor_friction() -> float:
    """The sliding friction coefficient of the wheels on the floor in the shipped model file."""
    mujoco = import_mujoco()
    model = mujoco.MjModel.from_xml_path(str(P3DX_MJCF))
    tyre = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "tyre_r")
    floor = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "floor")
    return float(max(model.geom_friction[tyre, 0], model.geom_friction[floor, 0]))


def _baseline_failures(
    status: pd.DataFrame,
    gains: Mapping[str, Mapping[str, Mapping[str, float]]],
    record: Mapping[str, Any],
    duration: float,
) -> tuple[BaselineFailure, ...]:
    bad = status[status.controller.isin(["PCON", "PCONf"]) & (status.status != "ok")]
    if not len(bad):
        return ()
    conditions = tuning.draw_conditions(record["condition_seed"])
    failures = []
    for r in bad.itertuples():
        delay_class = DELAY_CLASS[r.scenario]
        reached = SCENARIOS[r.scenario].h_max
        level = _DWELL_SHARE * reached
        longest = max(
            (end - start for start, end in _dwells(r.scenario, duration, level)), default=0.0
        )
        failures.append(
            BaselineFailure(
                scenario=r.scenario,
                controller=r.controller,
                delay_class=delay_class,
                t_stop=r.t_stop,
                largest_delay=reached,
                dwell_level=level,
                longest_dwell=longest if 0.0 < longest < duration else None,
                tuning_largest_delay=max(
                    c.delay.h_max for c in conditions if c.delay_class == delay_class
                ),
                stability_number=_stability_number(r.controller, gains[r.controller][delay_class]),
            )
        )
    return tuple(failures)


def _chosen_gains(gains: Mapping[str, Mapping[str, Mapping[str, float]]]) -> pd.DataFrame:
    """Every controller's chosen gain sets: the objective (worst mean AE over the set's tuning
    conditions, mm) and, for AROLC, Theorem 1's certified ``h_m`` (ms)."""
    rows = []
    for kind, sets in gains.items():
        for gain_set, g in sets.items():
            rows.append(
                {
                    "controller": kind,
                    "gain set": gain_set,
                    "objective_mm": g["objective"],
                    "certified_h_m_ms": 1e3 * g["h_m"] if "h_m" in g else float("nan"),
                }
            )
    return pd.DataFrame(rows)


def _off_path(summary: pd.DataFrame, status: pd.DataFrame) -> int:
    """How many runs of ``summary`` are off the path by the tuning's rule
    (:func:`~delaytrack.experiments.tuning.off_path`; their ``status`` from ``status``, their
    mean AE of x and y)."""
    keys = ["scenario", "controller"]
    frame = summary[keys].merge(status, on=keys, how="left", validate="one_to_one")
    ok = frame.status.eq("ok").to_numpy()
    return int(tuning.off_path(ok, (summary.ae_x_mm + summary.ae_y_mm) / 2).sum())


def _ae_x_range(summary: pd.DataFrame, controllers: list[str]) -> tuple[float, float]:
    """Smallest and largest AE-x (mm) of ``controllers`` over S1–S4 (finished runs)."""
    ae_x = summary[summary.controller.isin(controllers)].ae_x_mm
    return float(ae_x.min()), float(ae_x.max())


def _tuning_grid(kind: str, gain_set: str, record: Mapping[str, Any]) -> TuningGrid:
    table = tuning.grid_table(kind, gain_set, record)
    best = table.drop(columns="status").sort_values("objective").head(_BEST_POINTS)
    return TuningGrid(best=best, excluded=int(table.objective.isna().sum()), points=len(table))


def _objective_spread(
    kind: str, gain_set: str, record: Mapping[str, Any]
) -> tuple[float, float, float]:
    objective = tuning.grid_table(kind, gain_set, record).objective
    return float(objective.min()), float(objective.median()), float(objective.max())


def paper_findings(
    *,
    reference: str,
    duration: float,
    results: Mapping[str, SimResult],
    summary: pd.DataFrame,
    status: pd.DataFrame,
    tuned_summary: pd.DataFrame,
    gains: Mapping[str, Mapping[str, Mapping[str, float]]],
    record: Mapping[str, Any],
    bound: RazumikhinBound,
    dt_check: pd.DataFrame | None,
    contact: pd.DataFrame | None,
    mujoco_installed: bool,
) -> PaperFindings:
    """The findings of a paper study (the arguments are the study's parts,
    :class:`~delaytrack.experiments.paper.PaperStudy`)."""
    scenarios = list(SCENARIOS)
    c_hat = {
        case: results["AROLC"][i].controller_state[0, :, 0] for i, case in enumerate(scenarios)
    }
    c_case = max(c_hat, key=lambda case: float(np.nanmax(c_hat[case])))
    c_max = float(np.nanmax(c_hat[c_case]))
    c_time = float(results["AROLC"][scenarios.index(c_case)].t[int(np.nanargmax(c_hat[c_case]))])
    omega = math.sqrt(AROLC_GAINS["K1"])
    rates, friction = _wheel_friction_torques()
    lam_max = _inverse_mass_eigenvalue(reference)
    delay_ranges = {case: _delay_range(case, duration) for case in scenarios}
    largest = {case: value for case, (_, value) in delay_ranges.items()}
    tuned_h_m = min(gains["AROLC"][c]["h_m"] for c in tuning.DELAY_CLASSES)
    qd, qd_dot, _ = paper_reference("consistent").evaluate(np.array([0.0]))
    right, left = wheel_rates("consistent")
    literal_right, literal_left = wheel_rates("literal")
    families = {"AROLC": ["AROLC"], "OuterLoop": ["OuterLoop"], "baseline": ["PCON", "PCONf"]}
    paper_tv = [values[4] for (_, name), values in PAPER_TABLE.items() if name == "AROLC"]
    verdict = dt_check_verdict(dt_check)
    return PaperFindings(
        claims=claims(summary),
        tuned_claims=claims(tuned_as_arolc(summary, tuned_summary)),
        stopped=status[status.status != "ok"],
        off_path=_off_path(summary, status),
        ae_x_range={family: _ae_x_range(summary, names) for family, names in families.items()},
        natural_frequency=omega,
        damping=AROLC_GAINS["K2"] / (2.0 * omega),
        c_hat_peak=c_max,
        c_hat_peak_scenario=c_case,
        c_hat_peak_time=c_time,
        c_hat_peak_at_end=c_time >= duration,
        switching_bound=AROLC_GAINS["alpha"] * c_max,
        wheel_rates=(float(rates.min()), float(rates.max())),
        wheel_friction=(float(friction.min()), float(friction.max())),
        inverse_mass_eigenvalue=lam_max,
        stable_gain_product=2.0 / (T_C * lam_max),
        tuning_spread={
            BASELINE[case]: _objective_spread(BASELINE[case], DELAY_CLASS[case], record)
            for case in ("S1", "S3")
        },
        baseline_failures=_baseline_failures(status, gains, record, duration),
        paper_arolc_tv=(min(paper_tv), max(paper_tv)),
        delay_ranges=delay_ranges,
        delay_ranges_in_periods={
            case: (smallest / T_C, value / T_C) for case, (smallest, value) in delay_ranges.items()
        },
        largest_scenario_delay=max(d.h_max for d in SCENARIOS.values()),
        certified=certified_scenarios(bound.h_m, largest),
        tuned_h_m=tuned_h_m,
        tuned_certified=certified_scenarios(tuned_h_m, largest),
        chosen_gains=_chosen_gains(gains),
        tuning_grids={
            (kind, gain_set): _tuning_grid(kind, gain_set, record)
            for kind in tuning.KINDS
            for gain_set in tuning.GAIN_SETS
        },
        heading_start=float(qd[0, 2]),
        heading_rate=float(qd_dot[0, 2]),
        consistent_wheel_rates=(float(right), float(left)),
        circle_speed=CIRCLE_RADIUS * CIRCLE_RATE,
        payload_placements=placement_count(
            duration, P3DX_PAYLOAD.first_on, P3DX_PAYLOAD.time_on, P3DX_PAYLOAD.time_off
        ),
        literal_speed=P3DX.wheel_radius * (literal_right + literal_left) / 2.0,
        literal_turn=P3DX.wheel_radius * (literal_right - literal_left) / (2.0 * P3DX.half_track),
        controller_rate=1 / T_C,
        half_dt=DT / 2,
        dt_within_tolerance=None if verdict is None else verdict.within_tolerance,
        mujoco_installed=mujoco_installed,
        floor_friction=_floor_friction() if contact is not None else None,
        contact=contact_findings(contact) if contact is not None else None,
    )
