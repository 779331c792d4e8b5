"""The two-link job: AROLC vs the plain outer loop on the two-link arm under S1 and S3.

``delaytrack reproduce --job two-link`` runs :func:`delaytrack.jobs.two_link.reproduce`, which
writes ``<out>/two-link/``:

- ``summary.csv``: one row per (scenario, controller): AE, RMS and max error per joint (rad), TV
  of the commanded torques (N·m), status, each unit in its column's name (``ae_q1_rad``,
  ``tv_Nm``);
- ``dt_check.csv``: the same metrics with ``dt`` halved, and their relative change;
- ``trajectories/<S>_<controller>.parquet``: every recorded sample of each run;
- ``scenarios/*.toml``: the four scenarios as run;
- ``figures/*.png|svg``: ``|e1|`` over time per delay scenario (both controllers), ``ĉ(t)``,
  ``h(t)``, and ``q`` against ``q_d``;
- ``report.html``: every setting, the tables, the figures (embedded) and the outcome in words.

The four runs are the shipped scenario files ``two_link_S1``, ``two_link_S1_outer_loop``,
``two_link_S3`` and ``two_link_S3_outer_loop`` (``delaytrack/scenarios/``); the settings and why
they were chosen are stated in those files and in the report. Each controller's two delay cases
run as one batched simulation.

This module is the study: :func:`run_study` returns a :class:`TwoLinkStudy` holding every number
of the report, which :func:`~delaytrack.report.two_link.write_study` writes;
:func:`delaytrack.jobs.two_link.reproduce` does both.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from delaytrack._deprecated import moved_names
from delaytrack._result_columns import metric_columns_with_units, metric_units
from delaytrack.analysis import RazumikhinBound, razumikhin_bound
from delaytrack.analysis.razumikhin import PAPER_BETA as BETA
from delaytrack.analysis.razumikhin import PAPER_R as R
from delaytrack.experiments.convergence import (
    DtCheck,
    dt_check_table,
    dt_check_verdict,
    largest_change,
)
from delaytrack.experiments.relative_change import relative_change
from delaytrack.metrics import COORDINATE_METRICS, metrics_table
from delaytrack.scenario import Scenario, load_builtin, run_batched
from delaytrack.sim import SimResult, compile_ahead

__all__ = [
    "CASES",
    "CONTROLLERS",
    "FOLDER",
    "SMALL_DELAY_EFFECT_PCT",
    "TwoLinkStudy",
    "run_study",
]
#: Running the study and writing its report is a job (:mod:`delaytrack.jobs.two_link`).
__getattr__ = moved_names(
    __name__,
    {
        "reproduce": "delaytrack.jobs.two_link:reproduce",
        "write_study": "delaytrack.report.two_link:write_study",
    },
)

#: Delay scenarios of the paper used here.
CASES = ("S1", "S3")
#: Controllers compared: scenario-file type name -> label.
CONTROLLERS = {"arolc": "AROLC", "outer-loop": "outer loop"}
FOLDER = "two-link"
_COORDINATES = ("q1", "q2")
#: Percent: when the delays change AE by less than this (the largest ``|ae_change_pct|`` of
#: :attr:`TwoLinkStudy.delay_effect`, against the same runs with no delay), the tracking error
#: counts as coming mostly from the model mismatch, not from the delay.
SMALL_DELAY_EFFECT_PCT = 10.0


def scenario_name(case: str, controller: str) -> str:
    """Name of the shipped scenario file for a delay case and a controller type."""
    return f"two_link_{case}" + ("" if controller == "arolc" else "_outer_loop")


@dataclass(frozen=True)
class TwoLinkStudy:
    """Everything the job computed: every number of its report.

    Attributes
    ----------
    scenarios : dict
        ``(case, controller) -> Scenario`` as run.
    results : dict
        ``controller -> SimResult`` batched over :data:`CASES` (element ``i`` is ``CASES[i]``).
    summary : DataFrame
        One row per (scenario, controller): metrics and status.
    dt_check : DataFrame or None
        Metrics at ``dt/2`` with the relative change against ``summary`` (None if not run).
    undelayed : DataFrame
        Context, not part of the comparison: the same runs with no delay (``h = 0``), one row
        per controller, to show how much of the error the delay causes.
    bound : RazumikhinBound
        Theorem 1's certified delay bound for the AROLC gains.
    changes : DataFrame
        AROLC against the outer loop per scenario: ``100 (AROLC - outer loop) / outer loop``
        per metric (percent; :func:`~delaytrack.experiments.relative_change.relative_change`).
    arolc_better : dict
        Case -> the joints (of ``coordinates``, in their order) on which AROLC's AE is lower
        than the outer loop's (a finite change in ``changes`` below 0).
    ae_range : tuple of float
        The smallest and the largest AE (rad) over every run and joint.
    natural_frequency, damping : float
        ``√k1`` (rad/s) and ``k2 / (2 √k1)`` of the delay-free error dynamics
        ``ë + k2 ė + k1 e = 0`` at AROLC's ``K1 = k1 I``, ``K2 = k2 I``.
    c_hat_peak : dict
        Case -> the largest adaptive gain ĉ of AROLC's run.
    switching_bound : float
        ``α max ĉ`` (rad/s²): the largest norm of AROLC's switching term
        ``Δu = α ĉ s / max(‖s‖, ε)`` over both runs.
    delay_effect : DataFrame
        Per (controller, scenario, coordinate): ``ae_change_pct = 100 (AE - AE₀) / AE₀``, the
        change of AE against the same run with no delay (``undelayed``).
    largest_delay_effect : float
        The largest ``|ae_change_pct|`` (percent; 0 when none is finite).
    h_max : dict
        Case -> the largest true delay of the run (s).
    half_dt : float
        The plant step of the dt check (s).
    model_shortfall : float
        How far below the truth's the nominal model's ``p1, p2, p3`` are (the largest of
        ``1 - p̂ / p``).
    controller_rate : float
        ``1 / T_c`` (Hz).
    smallest_delay_periods : float
        The smallest true delay of any run, in controller periods ``T_c``.
    seconds : float
        Wall time of the simulations.

    The design travels with every study as class attributes: ``cases`` (:data:`CASES`),
    ``controllers`` (:data:`CONTROLLERS`) and ``coordinates`` (the joints' names).
    """

    cases: ClassVar[tuple[str, ...]] = CASES
    controllers: ClassVar[dict[str, str]] = CONTROLLERS
    coordinates: ClassVar[tuple[str, ...]] = _COORDINATES

    scenarios: dict[tuple[str, str], Scenario]
    results: dict[str, SimResult]
    summary: pd.DataFrame
    dt_check: pd.DataFrame | None
    undelayed: pd.DataFrame
    bound: RazumikhinBound
    changes: pd.DataFrame
    arolc_better: dict[str, tuple[str, ...]]
    ae_range: tuple[float, float]
    natural_frequency: float
    damping: float
    c_hat_peak: dict[str, float]
    switching_bound: float
    delay_effect: pd.DataFrame
    largest_delay_effect: float
    h_max: dict[str, float]
    half_dt: float
    model_shortfall: float
    controller_rate: float
    smallest_delay_periods: float
    seconds: float

    def run(self, case: str, controller: str) -> SimResult:
        """The single run of ``case`` (``"S1"``...) under ``controller`` (``"arolc"``...)."""
        return self.results[controller][CASES.index(case)]

    @property
    def delay_effect_small(self) -> bool:
        """Whether ``largest_delay_effect`` is below :data:`SMALL_DELAY_EFFECT_PCT`: the tracking
        error comes mostly from the model mismatch, not from the delay."""
        return bool(self.largest_delay_effect < SMALL_DELAY_EFFECT_PCT)

    @property
    def below_bound(self) -> dict[str, bool]:
        """Case -> whether ``h_max`` is below the certified bound ``bound.h_m``."""
        return {case: bool(h < self.bound.h_m) for case, h in self.h_max.items()}

    @property
    def all_below_bound(self) -> bool:
        """Whether every case's largest delay is below the certified bound ``bound.h_m``."""
        return all(self.below_bound.values())

    @property
    def dt_max_change(self) -> float:
        """Largest relative change of any metric when ``dt`` is halved (NaN if not checked)."""
        return largest_change(self.dt_check)

    @property
    def dt_verdict(self) -> DtCheck | None:
        """The dt-halving check's verdict (None if not checked)."""
        return dt_check_verdict(self.dt_check)

    @property
    def metric_units(self) -> dict[str, str | None]:
        """Each metric of :attr:`summary` (``ae_q1``, ..., ``tv``) with its unit, as the arm's
        runs give it: the joints' in rad, the torques' TV in N·m."""
        result = next(iter(self.results.values()))
        return metric_units(
            result.coordinate_names, result.coordinate_units, result.n, result.input_units
        )

    @property
    def columns_with_units(self) -> dict[str, str]:
        """The metric columns of :attr:`summary` renamed with the arm's units, as its runs
        give them (every controller's runs are of the one arm): ``ae_q1`` -> ``ae_q1_rad``."""
        return metric_columns_with_units(next(iter(self.results.values())))


def _summary(results: dict[str, SimResult]) -> pd.DataFrame:
    frames = []
    for controller, result in results.items():
        table = metrics_table(result, coordinate_names=_COORDINATES)
        table.insert(0, "controller", controller)
        table.insert(0, "scenario", list(CASES))
        frames.append(table.drop(columns=["run"]))
    summary = pd.concat(frames, ignore_index=True)
    order = ["scenario", "controller"]
    metrics = [f"{p}_{c}" for p in COORDINATE_METRICS for c in _COORDINATES] + ["tv"]
    summary = summary[order + metrics + ["status", "t_stop"]]
    return summary.sort_values(order, key=lambda s: s.map(_sort_key)).reset_index(drop=True)


def _sort_key(value: str) -> object:
    return list(CONTROLLERS).index(value) if value in CONTROLLERS else value


def _delay_effect(summary: pd.DataFrame, undelayed: pd.DataFrame) -> pd.DataFrame:
    """Per controller, scenario and coordinate: ``100 (AE - AE₀) / AE₀``, the change (percent)
    of the AE of the delayed run against the AE₀ of the same controller's run with no delay."""
    rows = []
    for controller in CONTROLLERS:
        free = undelayed[undelayed.controller == controller].iloc[0]
        for case in CASES:
            row = summary[(summary.scenario == case) & (summary.controller == controller)].iloc[0]
            for coordinate in _COORDINATES:
                metric = f"ae_{coordinate}"
                rows.append(
                    {
                        "controller": controller,
                        "scenario": case,
                        "coordinate": coordinate,
                        "ae_change_pct": 100.0 * (row[metric] - free[metric]) / free[metric],
                    }
                )
    return pd.DataFrame(rows)


def _arolc_better(changes: pd.DataFrame) -> dict[str, tuple[str, ...]]:
    """Per scenario of ``changes``: the joints on which AROLC's AE change against the outer
    loop is finite and below 0."""
    return {
        row["scenario"]: tuple(
            c for c in _COORDINATES if np.isfinite(row[f"ae_{c}"]) and row[f"ae_{c}"] < 0
        )
        for _, row in changes.iterrows()
    }


def _scenarios(duration: float | None) -> dict[tuple[str, str], Scenario]:
    """The four shipped scenarios, resolved, by ``(case, controller)`` (``duration`` overrides
    theirs when given)."""
    scenarios = {}
    for case in CASES:
        for controller in CONTROLLERS:
            scenario = load_builtin(scenario_name(case, controller))
            if duration is not None:
                scenario = scenario.replace(duration=duration)
            scenarios[case, controller] = scenario.resolved()
    return scenarios


def _simulate(
    scenarios: dict[tuple[str, str], Scenario], check_dt: bool, progress: bool
) -> tuple[dict[str, SimResult], dict[str, SimResult], dict[str, SimResult]]:
    """Per controller: its cases batched, its first case with no delay and, if ``check_dt``,
    its cases at ``dt/2`` (else none), under one progress bar."""
    dt = scenarios[CASES[0], "arolc"].dt
    steps = len(CONTROLLERS) * (3 if check_dt else 2)
    # Every controller's step is compiled with the first run that compiles anything.
    built = [scenarios[CASES[0], controller].build() for controller in CONTROLLERS]
    with (
        tqdm(total=steps, desc="two-link", unit="batch", disable=not progress) as bar,
        compile_ahead([b.controller for b in built], built[0].plant.n, built[0].plant.m),
    ):
        delayed = {c: [scenarios[case, c] for case in CASES] for c in CONTROLLERS}
        results = _run_batches(delayed, bar, f"dt = {dt:g} s")
        no_delay = {c: [_without_delay(scenarios[CASES[0], c])] for c in CONTROLLERS}
        undelayed = _run_batches(no_delay, bar, "h = 0")
        halved: dict[str, SimResult] = {}
        if check_dt:
            fine = {
                c: [scenarios[case, c].replace(dt=dt / 2) for case in CASES] for c in CONTROLLERS
            }
            halved = _run_batches(fine, bar, f"dt = {dt / 2:g} s")
    return results, undelayed, halved


def _run_batches(
    batches: dict[str, list[Scenario]], bar: Any, setting: str
) -> dict[str, SimResult]:
    """Each controller's scenarios as one batched simulation, shown on ``bar`` with its label
    and ``setting``."""
    results = {}
    for controller, batch in batches.items():
        bar.set_postfix_str(f"{CONTROLLERS[controller]}, {setting}")
        results[controller] = run_batched(batch)
        bar.update()
    return results


def _without_delay(scenario: Scenario) -> Scenario:
    """``scenario`` with no delay (``h = 0``), named ``<name>_no_delay``."""
    return scenario.replace(name=f"{scenario.name}_no_delay", delay={"type": "constant", "h": 0.0})


def _dt_check(summary: pd.DataFrame, fine: pd.DataFrame) -> pd.DataFrame:
    """The metrics of ``fine`` (the runs at ``dt/2``) against ``summary``'s
    (:func:`~delaytrack.experiments.convergence.dt_check_table`)."""
    metrics = [c for c in summary.columns if c.startswith(("ae_", "rms_", "max_")) or c == "tv"]
    return dt_check_table(summary, fine[["scenario", "controller", *metrics]], metrics)


def _undelayed_table(results: dict[str, SimResult]) -> pd.DataFrame:
    """One row of metrics per controller's run with no delay."""
    tables = [
        metrics_table(result, coordinate_names=_COORDINATES, label=controller)
        .rename(columns={"label": "controller"})
        .drop(columns=["run"])
        for controller, result in results.items()
    ]
    return pd.concat(tables, ignore_index=True)


def _c_hat_peak(arolc: dict[str, SimResult]) -> dict[str, float]:
    """Case -> the largest adaptive gain ĉ of AROLC's run."""
    return {case: float(np.nanmax(run.controller_state[0, :, 0])) for case, run in arolc.items()}


def run_study(
    *, duration: float | None = None, check_dt: bool = True, progress: bool = False
) -> TwoLinkStudy:
    """Run the four scenarios (and, if ``check_dt``, again at ``dt/2``).

    Parameters
    ----------
    duration : float, optional
        Override the scenarios' 30 s (a multiple of ``T_c``; for smoke tests).
    check_dt : bool
        Also run every scenario with ``dt`` halved (``T_c`` unchanged) and tabulate the change.
    progress : bool
        Show a progress bar over the simulations.
    """
    scenarios = _scenarios(duration)
    first = scenarios[CASES[0], "arolc"]
    controller_spec = dict(first.controller)
    bound = razumikhin_bound(
        controller_spec["K1"], controller_spec["K2"], controller_spec["Q"], BETA, R, n=2
    )
    start = time.perf_counter()
    results, undelayed, halved = _simulate(scenarios, check_dt, progress)
    seconds = time.perf_counter() - start
    summary = _summary(results)
    dt_check = _dt_check(summary, _summary(halved)) if check_dt else None
    undelayed_table = _undelayed_table(undelayed)
    arolc = {case: results["arolc"][CASES.index(case)] for case in CASES}
    c_hat_peak = _c_hat_peak(arolc)
    k1, k2 = float(controller_spec["K1"]), float(controller_spec["K2"])
    ae = summary[[f"ae_{c}" for c in _COORDINATES]].to_numpy(dtype=float)
    delay_effect = _delay_effect(summary, undelayed_table)
    changes = relative_change(
        summary, by="scenario", column="controller", baseline="outer-loop", candidate="arolc"
    )
    # max(0, NaN) is 0: a change that is not finite is left out.
    largest_delay_effect = max(0.0, delay_effect.ae_change_pct.abs().max())
    h_max = {case: float(run.h[0].max()) for case, run in arolc.items()}
    return TwoLinkStudy(
        scenarios=scenarios,
        results=results,
        summary=summary,
        dt_check=dt_check,
        undelayed=undelayed_table,
        bound=bound,
        changes=changes,
        arolc_better=_arolc_better(changes),
        ae_range=(float(np.nanmin(ae)), float(np.nanmax(ae))),
        natural_frequency=math.sqrt(k1),
        damping=k2 / (2 * math.sqrt(k1)),
        c_hat_peak=c_hat_peak,
        switching_bound=float(controller_spec["alpha"]) * max(c_hat_peak.values()),
        delay_effect=delay_effect,
        largest_delay_effect=largest_delay_effect,
        h_max=h_max,
        half_dt=first.dt / 2,
        model_shortfall=max(1.0 - first.model[p] / first.plant[p] for p in ("p1", "p2", "p3")),
        controller_rate=1.0 / first.T_c,
        smallest_delay_periods=min(float(run.h[0].min()) for run in arolc.values()) / first.T_c,
        seconds=seconds,
    )
