"""The interim main job: AROLC vs the plain outer loop on the two-link arm under S1 and S3.

``delaytrack reproduce`` (and ``make reproduce``) runs :func:`reproduce`, which writes
``<out>/two-link/``:

- ``summary.csv``: one row per (scenario, controller): AE, RMS and max error per joint (rad), TV
  of the commanded torques (N·m), status;
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

This module is the job: it composes scenarios, metrics and the report package. The report package
itself never imports from here.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from delaytrack._io import write_frame
from delaytrack._output import (
    check_output_folder,
    check_results_root,
    claim_output_folder,
    record_outputs,
)
from delaytrack._version import __version__
from delaytrack.analysis import RazumikhinBound, razumikhin_bound
from delaytrack.experiments.convergence import dt_check_table, largest_change, write_dt_check
from delaytrack.experiments.scenario import Scenario, load_builtin, run_batched
from delaytrack.metrics import metrics_table
from delaytrack.report import (
    HtmlReport,
    c_hat_figure,
    delay_figure,
    error_figure,
    relative_change,
    save_figure,
    tracking_figure,
)
from delaytrack.sim import SimResult
from delaytrack.sim.compile_helper import ahead as compile_ahead
from delaytrack.sim.native_parts import step_parts

__all__ = ["CASES", "CONTROLLERS", "TwoLinkStudy", "reproduce", "run_study", "write_study"]

#: Delay scenarios of the paper used here.
CASES = ("S1", "S3")
#: Controllers compared: scenario-file type name -> label.
CONTROLLERS = {"arolc": "AROLC", "outer-loop": "outer loop"}
#: Razumikhin parameters for the certified bound (the paper's).
BETA, R = 1.0, 1.1
FOLDER = "two-link"
_COORDINATES = ("q1", "q2")
_CASE_TEXT = {
    "S1": "S1: h(t) = 20 + 80 |sin t| ms (time-varying, maximum 100 ms)",
    "S3": "S3: h = 60 ms (constant)",
}


def scenario_name(case: str, controller: str) -> str:
    """Name of the shipped scenario file for a delay case and a controller type."""
    return f"two_link_{case}" + ("" if controller == "arolc" else "_outer_loop")


@dataclass(frozen=True)
class TwoLinkStudy:
    """Everything the job computed.

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
    seconds : float
        Wall time of the simulations.
    """

    scenarios: dict[tuple[str, str], Scenario]
    results: dict[str, SimResult]
    summary: pd.DataFrame
    dt_check: pd.DataFrame | None
    undelayed: pd.DataFrame
    bound: RazumikhinBound
    seconds: float

    def run(self, case: str, controller: str) -> SimResult:
        """The single run of ``case`` (``"S1"``...) under ``controller`` (``"arolc"``...)."""
        return self.results[controller][CASES.index(case)]

    @property
    def dt_max_change(self) -> float:
        """Largest relative change of any metric when ``dt`` is halved (NaN if not checked)."""
        return largest_change(self.dt_check)


def _summary(results: dict[str, SimResult]) -> pd.DataFrame:
    frames = []
    for controller, result in results.items():
        table = metrics_table(result, coordinate_names=_COORDINATES)
        table.insert(0, "controller", controller)
        table.insert(0, "scenario", list(CASES))
        frames.append(table.drop(columns=["run"]))
    summary = pd.concat(frames, ignore_index=True)
    order = ["scenario", "controller"]
    metrics = [f"{p}_{c}" for p in ("ae", "rms", "max") for c in _COORDINATES] + ["tv"]
    summary = summary[order + metrics + ["status", "t_stop"]]
    return summary.sort_values(order, key=lambda s: s.map(_sort_key)).reset_index(drop=True)


def _sort_key(value: str) -> object:
    return list(CONTROLLERS).index(value) if value in CONTROLLERS else value


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
    scenarios = {}
    for case in CASES:
        for controller in CONTROLLERS:
            scenario = load_builtin(scenario_name(case, controller))
            if duration is not None:
                scenario = scenario.replace(duration=duration)
            scenarios[case, controller] = scenario.resolved()
    first = scenarios[CASES[0], "arolc"]
    controller_spec = dict(first.controller)
    bound = razumikhin_bound(
        controller_spec["K1"], controller_spec["K2"], controller_spec["Q"], BETA, R, n=2
    )
    steps = len(CONTROLLERS) * (3 if check_dt else 2)
    start = time.perf_counter()
    results: dict[str, SimResult] = {}
    halved: dict[str, SimResult] = {}
    # Every controller's step is compiled with the first run that compiles anything.
    built = [scenarios[CASES[0], controller].build() for controller in CONTROLLERS]
    named = step_parts([b.controller for b in built], built[0].plant.n, built[0].plant.m)
    with (
        tqdm(total=steps, desc="two-link", unit="batch", disable=not progress) as bar,
        compile_ahead(named),
    ):
        for controller in CONTROLLERS:
            batch = [scenarios[case, controller] for case in CASES]
            bar.set_postfix_str(f"{CONTROLLERS[controller]}, dt = {first.dt:g} s")
            results[controller] = run_batched(batch)
            bar.update()
        undelayed = {}
        for controller in CONTROLLERS:
            bar.set_postfix_str(f"{CONTROLLERS[controller]}, h = 0")
            base = scenarios[CASES[0], controller]
            no_delay = base.replace(
                name=f"{base.name}_no_delay", delay={"type": "constant", "h": 0.0}
            )
            undelayed[controller] = (
                metrics_table(
                    run_batched([no_delay]), coordinate_names=_COORDINATES, label=controller
                )
                .rename(columns={"label": "controller"})
                .drop(columns=["run"])
            )
            bar.update()
        if check_dt:
            for controller in CONTROLLERS:
                batch = [scenarios[case, controller].replace(dt=first.dt / 2) for case in CASES]
                bar.set_postfix_str(f"{CONTROLLERS[controller]}, dt = {first.dt / 2:g} s")
                halved[controller] = run_batched(batch)
                bar.update()
    seconds = time.perf_counter() - start
    summary = _summary(results)
    dt_check = None
    if check_dt:
        fine = _summary(halved)
        metrics = [c for c in summary.columns if c.startswith(("ae_", "rms_", "max_")) or c == "tv"]
        dt_check = dt_check_table(summary, fine[["scenario", "controller", *metrics]], metrics)
    undelayed_table = pd.concat(undelayed.values(), ignore_index=True)
    return TwoLinkStudy(scenarios, results, summary, dt_check, undelayed_table, bound, seconds)


# --------------------------------------------------------------------------------------------
# Writing


def _figures(study: TwoLinkStudy) -> dict[str, tuple[object, str]]:
    figures = {}
    for case in CASES:
        runs = {CONTROLLERS[c]: study.run(case, c) for c in CONTROLLERS}
        figures[f"error_{case}"] = (
            error_figure(runs, title=f"Tracking error under {case}"),
            f"|e1(t)| = |q_d - q| of both joints under {_CASE_TEXT[case]}, AROLC vs the outer "
            "loop.",
        )
        figures[f"tracking_{case}"] = (
            tracking_figure(runs, title=f"Joint angles under {case}"),
            f"q(t) of both controllers against q_d(t) under {case}.",
        )
    arolc = {case: study.run(case, "arolc") for case in CASES}
    figures["c_hat"] = (
        c_hat_figure(arolc, title="AROLC adaptive gain ĉ(t)"),
        "The adaptive gain ĉ(t) of AROLC under S1 and S3 (ĉ(0) = γ = 0.001).",
    )
    figures["delay"] = (
        delay_figure(arolc, h_m=study.bound.h_m, title="Input delay h(t)"),
        "The true input delays (unknown to both controllers) and AROLC's certified bound h_m.",
    )
    return figures


def _verdict(study: TwoLinkStudy) -> list[str]:
    """The outcome in words, computed from the summary (never hand-written)."""
    summary = study.summary
    lines = []
    not_ok = summary[summary["status"] != "ok"]
    for _, row in not_ok.iterrows():
        lines.append(
            f"{row['scenario']}, {CONTROLLERS[row['controller']]}: the run stopped with status "
            f"'{row['status']}' at t = {row['t_stop']:g} s; its metrics are NaN."
        )
    change = relative_change(
        summary, by="scenario", column="controller", baseline="outer-loop", candidate="arolc"
    )
    for _, row in change.iterrows():
        case = row["scenario"]
        base = summary[(summary.scenario == case) & (summary.controller == "outer-loop")].iloc[0]
        cand = summary[(summary.scenario == case) & (summary.controller == "arolc")].iloc[0]
        parts = []
        for metric, what in (
            ("ae_q1", "AE of q1"),
            ("ae_q2", "AE of q2"),
            ("max_q1", "max |e1| of q1"),
            ("max_q2", "max |e1| of q2"),
            ("tv", "TV"),
        ):
            pct = row[metric]
            if not np.isfinite(pct):
                parts.append(f"{what}: not comparable")
                continue
            word = "lower" if pct < 0 else "higher"
            unit = "N·m" if metric == "tv" else "rad"
            parts.append(
                f"{what} {abs(pct):.1f} % {word} ({cand[metric]:.4g} vs {base[metric]:.4g} {unit})"
            )
        wins = [m for m in ("ae_q1", "ae_q2") if np.isfinite(row[m]) and row[m] < 0]
        if len(wins) == 2:
            head = "AROLC tracks better on both joints"
        elif len(wins) == 1:
            head = f"AROLC tracks better on {wins[0][3:]} only"
        else:
            head = "AROLC does not track better than the outer loop"
        lines.append(f"{case}: {head}. AROLC vs outer loop: " + "; ".join(parts) + ".")
    return lines


def _context(study: TwoLinkStudy) -> str:
    """How large the errors are and how much the switching term acts, from the data."""
    summary = study.summary
    ae = summary[["ae_q1", "ae_q2"]].to_numpy(dtype=float)
    scenario = study.scenarios[CASES[0], "arolc"]
    alpha = float(dict(scenario.controller)["alpha"])
    plant = dict(scenario.plant)
    k1, k2 = float(dict(scenario.controller)["K1"]), float(dict(scenario.controller)["K2"])
    c_hat = {
        case: float(np.nanmax(study.run(case, "arolc").controller_state[0, :, 0])) for case in CASES
    }
    amplitude = ", ".join(f"{a:g}" for a in np.ravel(dict(scenario.reference)["amplitude"]))
    return (
        f"Size of the errors: AE lies between {np.nanmin(ae):.3g} and {np.nanmax(ae):.3g} rad over "
        f"all runs and joints, on references of amplitude {amplitude} rad. With K1 = {k1:g} I, "
        f"K2 = {k2:g} I the delay-free error dynamics are slow (natural frequency "
        f"{math.sqrt(k1):.3g} rad/s, damping {k2 / (2 * math.sqrt(k1)):.3g}), and the viscous "
        f"joint friction (fd1 = {plant['fd1']:g}, fd2 = {plant['fd2']:g} N·m·s) that the nominal "
        "model omits acts as a large unmodelled torque. AROLC's adaptive gain peaks at ĉ = "
        + ", ".join(f"{c_hat[c]:.3g} ({c})" for c in CASES)
        + ", so its switching term "
        f"Δu = α ĉ s / max(‖s‖, ε) never exceeds α max ĉ = {alpha * max(c_hat.values()):.3g} "
        "rad/s² in norm."
    )


def _delay_role(study: TwoLinkStudy) -> str:
    """How much of the error the delay causes: delayed runs against the h = 0 runs."""
    parts = []
    largest = 0.0
    for controller, label in CONTROLLERS.items():
        free = study.undelayed[study.undelayed.controller == controller].iloc[0]
        changes = []
        for case in CASES:
            row = study.summary[
                (study.summary.scenario == case) & (study.summary.controller == controller)
            ].iloc[0]
            for coordinate in _COORDINATES:
                metric = f"ae_{coordinate}"
                change = 100.0 * (row[metric] - free[metric]) / free[metric]
                largest = max(largest, abs(change))
                changes.append(f"{case} {coordinate} {change:+.1f} %")
        ae = ", ".join(f"{free[f'ae_{c}']:.4g}" for c in _COORDINATES)
        parts.append(
            f"{label}: AE without delay ({', '.join(_COORDINATES)}) = {ae} rad; with delay "
            + ", ".join(changes)
        )
    summary = (
        "so in this set-up the tracking error comes mostly from the model mismatch, not from the "
        "delay"
        if largest < 10.0
        else "so the delay is a large part of the tracking error"
    )
    return (
        "Role of the delay (context runs with h = 0, not part of the comparison): "
        + "; ".join(parts)
        + f". The delays change AE by at most {largest:.1f} %, {summary}."
    )


def _settings_rows(study: TwoLinkStudy) -> dict[str, str]:
    s = study.scenarios[CASES[0], "arolc"]
    plant, model = dict(s.plant), dict(s.model)
    ref = dict(s.reference)

    def params(spec: dict) -> str:
        return ", ".join(f"{k} = {spec[k]:g}" for k in ("p1", "p2", "p3", "fd1", "fd2"))

    terms = [
        f"{a:g} sin({w:g} t)"
        for a, w in zip(np.ravel(ref["amplitude"]), np.ravel(ref["frequency"]), strict=True)
    ]
    gains = dict(s.controller)
    return {
        "truth plant": f"two-link planar direct-drive arm, viscous friction: {params(plant)} "
        "(kg·m², N·m·s; Dixon et al. 2003)",
        "nominal model (M̂, N̂)": f"{params(model)}: p1, p2, p3 each 20 % below the truth, no "
        "friction. The friction and the inertia error are the uncertainty AROLC must absorb.",
        "reference q_d(t)": f"[{terms[0]}, {terms[1]}] rad. Frequencies below the 1 rad/s natural "
        "frequency of the outer loop with K1 = K2 = I (so the delay-free loop can follow them), "
        "incommensurate so the joints do not lock in phase, amplitudes well inside the planar "
        "workspace; q_d(0) = q(0) = 0 (no initial position error; q̇_d(0) ≠ 0).",
        "initial state x0": f"{list(s.x0)} ([q, q̇])",
        "AROLC": f"K1 = {gains['K1']:g} I, K2 = {gains['K2']:g} I, Q = {gains['Q']:g} I, "
        f"α = {gains['alpha']:g}, ε = {gains['epsilon']:g}, γ = {gains['gamma']:g}, ĉ(0) = γ "
        "(the paper's gains)",
        "outer loop": f"K1 = {gains['K1']:g} I, K2 = {gains['K2']:g} I (AROLC without Δu)",
        "delays": "; ".join(_CASE_TEXT[c] for c in CASES) + ". Unknown to both controllers.",
        "duration": f"{s.duration:g} s from t = 0",
        "plant step dt": f"{s.dt:g} s, fixed-step RK4 split at the instants the delayed input "
        "switches",
        "controller period T_c": f"{s.T_c:g} s with zero-order hold (500 Hz, a usual joint-"
        "controller rate; 10x below the smallest S1 delay; an integer multiple of dt)",
        "recording": f"every controller tick (record_every = {s.record_every}), so TV is the "
        "paper's TV over all ticks",
        "metrics": "AE = mean |e1| over the records, RMS, max |e1| (rad); TV = Σ |Δτ| over "
        "consecutive ticks summed over both joints (N·m). Whole run, no transient skipped.",
        "delaytrack": __version__,
    }


def write_study(study: TwoLinkStudy, folder: str | Path) -> list[Path]:
    """Write the study's files into ``folder`` (see the module docstring); return the paths."""
    folder = claim_output_folder(folder)
    files = [write_frame(study.summary, folder / "summary.csv")]
    if study.dt_check is not None:
        files.append(write_frame(study.dt_check, folder / "dt_check.csv"))
    for (case, controller), scenario in study.scenarios.items():
        files.append(folder / "scenarios" / f"{scenario.name}.toml")
        scenario.to_toml(files[-1])
        frame = study.run(case, controller).to_frame().drop(columns=["run"])
        files.append(write_frame(frame, folder / "trajectories" / f"{case}_{controller}.parquet"))
    figures = _figures(study)
    for name, (figure, _) in figures.items():
        files += save_figure(figure, folder / "figures" / name)
    files.append(_report(study, figures).write(folder / "report.html"))
    record_outputs(folder, files)
    return files


def _report(study: TwoLinkStudy, figures: dict[str, tuple[object, str]]) -> HtmlReport:
    bound = study.bound
    h_max = {case: study.run(case, "arolc").h[0].max() for case in CASES}
    report = HtmlReport("delaytrack: AROLC vs the plain outer loop on a two-link arm")
    report.paragraph(
        "Interim main job of delaytrack (the paper's robot experiment comes next). A simulated "
        "two-link arm tracks a sinusoidal joint reference while its torque command reaches the "
        "joints late by an unknown delay, with the paper's S1 and S3 delay profiles. AROLC (Roy & "
        "Kar) is compared with its own ablation, the plain outer loop (computed torque with the "
        "same K1, K2 and no switching term). All numbers below are computed by the simulation; "
        "nothing was tuned to favour either controller."
    )
    report.heading("Outcome")
    report.bullets(_verdict(study))
    report.paragraph(_context(study))
    report.paragraph(_delay_role(study))
    report.heading("Certified delay bound (Theorem 1)")
    report.paragraph(
        f"For K1 = K2 = Q = I, β = {bound.beta:g}, r = {bound.r:g} the Razumikhin bound is "
        f"h_m = λ_min(Q)/‖E‖₂ = {bound.lambda_min_Q:g}/{bound.E_norm:.5g} = {bound.h_m:.5f} s. "
        + " ".join(
            f"The largest delay of {case} is {h_max[case]:.3g} s, "
            f"{'below' if h_max[case] < bound.h_m else 'NOT below'} h_m."
            for case in CASES
        )
        + " Both cases are therefore inside the delay range the theorem certifies (the "
        "certificate concerns uniform ultimate boundedness, not the size of the error)."
    )
    report.heading("Summary")
    report.table(
        study.summary,
        "Metrics over the whole run. ae/rms/max in rad (per joint), tv in N·m; status 'ok' means "
        "the run reached the final time.",
    )
    report.table(study.undelayed, "Context: the same runs with no delay (h = 0).")
    write_dt_check(report, study.dt_check, study.scenarios[CASES[0], "arolc"].dt / 2)
    report.heading("Settings")
    report.settings(_settings_rows(study))
    report.heading("Figures")
    for figure, caption in figures.values():
        report.figure(figure, caption)
    report.heading("Scenario files as run")
    for scenario in study.scenarios.values():
        report.paragraph(f"{scenario.name}.toml")
        report.code(scenario.to_toml())
    report.paragraph(
        f"Simulation wall time: {study.seconds:.1f} s (per controller one batched simulate() call "
        f"over {', '.join(CASES)}, one with h = 0"
        + (", and one batched call at dt/2" if study.dt_check is not None else "")
        + "; numba-compiled)."
    )
    return report


def reproduce(
    out: str | Path = "results",
    *,
    duration: float | None = None,
    check_dt: bool = True,
    progress: bool = True,
) -> tuple[TwoLinkStudy, list[Path]]:
    """Run the job and write ``<out>/two-link/``; return the study and the files written."""
    folder = check_output_folder(check_results_root(out, "out") / FOLDER)
    study = run_study(duration=duration, check_dt=check_dt, progress=progress)
    files = write_study(study, folder)
    return study, files
