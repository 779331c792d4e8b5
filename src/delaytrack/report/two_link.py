"""The two-link job's report: the outcome in words, the settings, the figures and the HTML page,
made from a :class:`~delaytrack.experiments.two_link.TwoLinkStudy` that already holds every
number quoted here (this module computes none), and :func:`write_study`, which writes the job's
files."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from delaytrack._io import write_frame
from delaytrack._output import claim_output_folder, record_outputs
from delaytrack._version import __version__
from delaytrack.report.dt_check import write_dt_check
from delaytrack.report.figures import (
    c_hat_figure,
    delay_figure,
    error_figure,
    save_figure,
    tracking_figure,
)
from delaytrack.report.html import HtmlReport
from delaytrack.units import value_with_unit

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from delaytrack.experiments.two_link import TwoLinkStudy

__all__ = ["write_study"]

_CASE_TEXT = {
    "S1": "S1: h(t) = 20 + 80 |sin t| ms (time-varying, maximum 100 ms)",
    "S3": "S3: h = 60 ms (constant)",
}


def _figures(study: TwoLinkStudy) -> dict[str, tuple[Figure, str]]:
    figures = {}
    for case in study.cases:
        runs = {study.controllers[c]: study.run(case, c) for c in study.controllers}
        figures[f"error_{case}"] = (
            error_figure(runs, title=f"Tracking error under {case}"),
            f"|e1(t)| = |q_d - q| of both joints under {_CASE_TEXT[case]}, AROLC vs the outer "
            "loop.",
        )
        figures[f"tracking_{case}"] = (
            tracking_figure(runs, title=f"Joint angles under {case}"),
            f"q(t) of both controllers against q_d(t) under {case}.",
        )
    arolc = {case: study.run(case, "arolc") for case in study.cases}
    figures["c_hat"] = (
        c_hat_figure(arolc, title="AROLC adaptive gain ĉ(t)"),
        "The adaptive gain ĉ(t) of AROLC under S1 and S3 (ĉ(0) = γ = "
        f"{study.scenarios[study.cases[0], 'arolc'].controller['gamma']:g}).",
    )
    figures["delay"] = (
        delay_figure(arolc, h_m=study.bound.h_m, title="Input delay h(t)"),
        "The true input delays (unknown to both controllers) and AROLC's certified bound h_m.",
    )
    return figures


def _verdict(study: TwoLinkStudy) -> list[str]:
    """The outcome in words, from the summary and AROLC's change against the outer loop."""
    summary = study.summary
    lines = []
    not_ok = summary[summary["status"] != "ok"]
    for _, row in not_ok.iterrows():
        lines.append(
            f"{row['scenario']}, {study.controllers[row['controller']]}: the run stopped with "
            f"status '{row['status']}' at t = {row['t_stop']:g} s; it has no metrics (— in the "
            "tables)."
        )
    units = study.metric_units
    for _, row in study.changes.iterrows():
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
            values = value_with_unit(f"{cand[metric]:.4g} vs {base[metric]:.4g}", units[metric])
            parts.append(f"{what} {abs(pct):.1f} % {word} ({values})")
        wins = study.arolc_better[case]
        if not all(np.isfinite(row[f"ae_{name}"]) for name in study.coordinates):
            head = "in this one run, the mean errors cannot be compared (a run did not finish)"
        elif wins == study.coordinates:
            head = (
                "in this one run, AROLC's mean error is lower than the outer loop's on both joints"
            )
        elif wins:
            head = (
                "in this one run, AROLC's mean error is lower than the outer loop's on "
                f"{' and '.join(wins)} only"
            )
        else:
            head = "in this one run, AROLC's mean error is not lower than the outer loop's"
        lines.append(f"{case}: {head}. AROLC vs outer loop: " + "; ".join(parts) + ".")
    return lines


def _context(study: TwoLinkStudy) -> str:
    """How large the errors are and how much the switching term acts."""
    scenario = study.scenarios[study.cases[0], "arolc"]
    plant, gains = dict(scenario.plant), dict(scenario.controller)
    amplitude = ", ".join(f"{a:g}" for a in np.ravel(dict(scenario.reference)["amplitude"]))
    low, high = study.ae_range
    return (
        f"Size of the errors: AE lies between {low:.3g} and {high:.3g} rad over "
        f"all runs and joints, on references of amplitude {amplitude} rad. With "
        f"K1 = {float(gains['K1']):g} I, K2 = {float(gains['K2']):g} I the delay-free error "
        f"dynamics are slow (natural frequency {study.natural_frequency:.3g} rad/s, damping "
        f"{study.damping:.3g}), and the viscous joint friction (fd1 = {plant['fd1']:g}, "
        f"fd2 = {plant['fd2']:g} N·m·s) that the nominal model omits acts as a large unmodelled "
        "torque. AROLC's adaptive gain peaks at ĉ = "
        + ", ".join(f"{study.c_hat_peak[c]:.3g} ({c})" for c in study.cases)
        + ", so its switching term "
        f"Δu = α ĉ s / max(‖s‖, ε) never exceeds α max ĉ = {study.switching_bound:.3g} "
        "rad/s² in norm."
    )


def _delay_role(study: TwoLinkStudy) -> str:
    """How much of the error the delay causes: delayed runs against the h = 0 runs."""
    parts = []
    for controller, label in study.controllers.items():
        free = study.undelayed[study.undelayed.controller == controller].iloc[0]
        effect = study.delay_effect[study.delay_effect.controller == controller]
        changes = [
            f"{row.scenario} {row.coordinate} {row.ae_change_pct:+.1f} %"
            for row in effect.itertuples()
        ]
        ae = ", ".join(f"{free[f'ae_{c}']:.4g}" for c in study.coordinates)
        parts.append(
            f"{label}: AE without delay ({', '.join(study.coordinates)}) = {ae} rad; with delay "
            + ", ".join(changes)
        )
    largest = study.largest_delay_effect
    summary = (
        "so in this set-up the tracking error comes mostly from the model mismatch, not from the "
        "delay"
        if study.delay_effect_small
        else "so the delay is a large part of the tracking error"
    )
    return (
        "Role of the delay (context runs with h = 0, not part of the comparison): "
        + "; ".join(parts)
        + f". The delays change AE by at most {largest:.1f} %, {summary}."
    )


def _settings_rows(study: TwoLinkStudy) -> dict[str, str]:
    s = study.scenarios[study.cases[0], "arolc"]
    assert s.x0 is not None  # the study's scenarios are resolved, so they state x0
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
        "nominal model (M̂, N̂)": f"{params(model)}: p1, p2, p3 each "
        f"{100 * study.model_shortfall:.3g} % below the truth, no friction. The friction and "
        "the inertia error are the uncertainty AROLC must absorb.",
        "reference q_d(t)": f"[{terms[0]}, {terms[1]}] rad. Frequencies below the "
        f"{study.natural_frequency:g} rad/s natural frequency of the outer loop (so the "
        "delay-free loop can follow them), "
        "incommensurate so the joints do not lock in phase, amplitudes well inside the planar "
        "workspace; q_d(0) = q(0) = 0 (no initial position error; q̇_d(0) ≠ 0).",
        "initial state x0": f"{list(s.x0)} ([q, q̇])",
        "AROLC": f"K1 = {gains['K1']:g} I, K2 = {gains['K2']:g} I, Q = {gains['Q']:g} I, "
        f"α = {gains['alpha']:g}, ε = {gains['epsilon']:g}, γ = {gains['gamma']:g}, ĉ(0) = γ "
        "(the paper's gains)",
        "outer loop": f"K1 = {gains['K1']:g} I, K2 = {gains['K2']:g} I (AROLC without Δu)",
        "delays": "; ".join(_CASE_TEXT[c] for c in study.cases) + ". Unknown to both controllers.",
        "duration": f"{s.duration:g} s from t = 0",
        "plant step dt": f"{s.dt:g} s, fixed-step RK4 split at the instants the delayed input "
        "switches",
        "controller period T_c": f"{s.T_c:g} s with zero-order hold ({study.controller_rate:g} "
        "Hz, a usual joint-"
        f"controller rate; the smallest delay is {study.smallest_delay_periods:.3g} periods; an "
        "integer multiple of dt)",
        "recording": f"every controller tick (record_every = {s.record_every}), so TV is the "
        "paper's TV over all ticks",
        "metrics": "AE = mean |e1| over the records, RMS, max |e1| (rad); TV = Σ |Δτ| over "
        "consecutive ticks summed over both joints (N·m). Whole run, no transient skipped.",
        "delaytrack": __version__,
    }


def write_study(study: TwoLinkStudy, folder: str | Path) -> list[Path]:
    """Write the study's files into ``folder`` (see :mod:`delaytrack.experiments.two_link`);
    return the paths."""
    folder = claim_output_folder(folder)
    with_units = study.columns_with_units  # in the files' column names, as every table's
    files = [write_frame(study.summary.rename(columns=with_units), folder / "summary.csv")]
    if study.dt_check is not None:
        dt_check = study.dt_check.rename(columns=with_units)
        files.append(write_frame(dt_check, folder / "dt_check.csv"))
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


def _report(study: TwoLinkStudy, figures: dict[str, tuple[Figure, str]]) -> HtmlReport:
    bound = study.bound
    report = HtmlReport("delaytrack: AROLC vs the plain outer loop on a two-link arm")
    report.paragraph(
        "The two-link job of delaytrack (the paper's robot experiment is the main job). A "
        "simulated two-link arm tracks a sinusoidal joint reference while its torque command "
        "reaches the joints late by an unknown delay, with the paper's S1 and S3 delay "
        "profiles. AROLC (Roy & Kar) is compared with its own ablation, the plain outer loop "
        "(computed torque with the same K1, K2 and no switching term). All numbers below are "
        "computed by the simulation; nothing was tuned to favour either controller."
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
            f"The largest delay of {case} is {study.h_max[case]:.3g} s, "
            f"{'below' if study.below_bound[case] else 'NOT below'} h_m."
            for case in study.cases
        )
        + (
            " Both cases are therefore inside the delay range the theorem certifies"
            if study.all_below_bound
            else " Not every case is inside the delay range the theorem certifies"
        )
        + " (the certificate concerns uniform ultimate boundedness, not the size of the error)."
    )
    report.heading("Summary")
    with_units = study.columns_with_units
    report.table(
        study.summary.rename(columns=with_units),
        "Metrics over the whole run (summary.csv's columns): "
        "ae/rms/max per joint, tv; status 'ok' means the run reached the final time.",
    )
    report.table(
        study.undelayed.rename(columns=with_units), "Context: the same runs with no delay (h = 0)."
    )
    write_dt_check(report, study.dt_verdict, study.half_dt)
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
        f"over {', '.join(study.cases)}, one with h = 0"
        + (", and one batched call at dt/2" if study.dt_check is not None else "")
        + "; numba-compiled)."
    )
    return report
