"""The paper job's report (:mod:`delaytrack.experiments.paper`): ``summary.csv``,
``summary_tuned_arolc.csv``, ``summary_contact.csv``, ``tables.md`` (the paper's Tables I–III
with our numbers beside the paper's), ``dt_check.csv``, the figures and ``report.html``.

Every number comes from the study (:class:`~delaytrack.experiments.paper.PaperStudy`, its
:class:`~delaytrack.experiments.paper_findings.PaperFindings`) or from the set-up's constants;
nothing is computed or run here.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter, LogLocator

from delaytrack._io import write_frame, write_text
from delaytrack._output import claim_output_folder, record_outputs
from delaytrack._version import __version__
from delaytrack._words import counted, quantity_text, table_text
from delaytrack.experiments import tuning
from delaytrack.experiments.pairing import AROLC_GAINS, BASELINE, DELAY_CLASS
from delaytrack.experiments.paper_findings import summary_row
from delaytrack.experiments.paper_setup import (
    BETA,
    DIAMETER_MM,
    DT,
    PAPER_TABLE,
    PAYLOAD_SEED,
    SCENARIOS,
    SUMMARY_COLUMNS,
    T_C,
    TUNED,
    R,
    controller_name,
)
from delaytrack.plants.robot import P3DX, P3DX_PAYLOAD
from delaytrack.plants.robot.truth import DEFAULT_BAUMGARTE_GAIN
from delaytrack.report.contact import write_contact_section
from delaytrack.report.decision_study import decision_sentence, display_envelopes
from delaytrack.report.dt_check import write_dt_check
from delaytrack.report.figures import c_hat_figure, delay_figure, save_figure
from delaytrack.report.html import HtmlReport
from delaytrack.report.robustness import (
    display_attribution,
    display_knowledge,
    write_verdict_tables,
)
from delaytrack.report.robustness import findings as robustness_findings
from delaytrack.report.tuning import gains_text

if TYPE_CHECKING:
    from delaytrack.experiments.decision_study import DecisionStudy
    from delaytrack.experiments.paper import PaperStudy
    from delaytrack.experiments.paper_findings import BaselineFailure, Claims, PaperFindings
    from delaytrack.experiments.robustness import RobustnessStudy

__all__ = ["TABLES_NOTE", "paper_tables", "tables_markdown", "write_study"]

#: The delays S1–S4 as the paper writes them.
_SCENARIO_TEXT = {
    "S1": "h(t) = 20 + 80 |sin t| ms",
    "S2": "h(t) = 5 + 120 |sin 0.1t| ms",
    "S3": "h = 60 ms",
    "S4": "h = 120 ms",
}
#: The run kinds the figures draw, in their legends' order.
_KINDS = ("AROLC", "baseline", "OuterLoop")
TABLES_NOTE = (
    f"AE in mm, %AE = AE / {DIAMETER_MM:g} mm × 100, TV in N·m (commanded wheel torques at the "
    "controller ticks). Paper values from its Tables I–III; '—': not in the paper. Compare the "
    "pattern, not the digits."
)


def _fmt(value: float, digits: int = 2) -> str:
    """``value`` to ``digits`` decimals; a run's metric that is not a number is that of a run
    that left the path (the summary's metrics of runs that did not stay on it are NaN)."""
    return "left the path" if not np.isfinite(value) else f"{value:.{digits}f}"


def _ae_of(controller: str, row: pd.Series, digits: int = 2) -> str:
    """``AROLC 35.95 / 32.89 mm`` (AE x / y), or ``PCON left the path`` for a run without
    metrics."""
    if not (np.isfinite(row.ae_x_mm) and np.isfinite(row.ae_y_mm)):
        return f"{controller} left the path"
    return f"{controller} {_fmt(row.ae_x_mm, digits)} / {_fmt(row.ae_y_mm, digits)} mm"


def _tv_of(row: pd.Series) -> str:
    """``TV 9.94 N·m``, or nothing for a run without metrics (it left the path)."""
    return f", TV {_fmt(row.tv_Nm)} N·m" if np.isfinite(row.tv_Nm) else ""


def _one_run_verdict(
    check: bool | None, who: Mapping[str, pd.Series], compared: str = "accuracy"
) -> str:
    """``HOLDS``, ``FAILS``, or, for a claim one of whose runs left the path, that it is not
    decided and which runs left it (``who``: name -> summary row of each run compared;
    ``compared``: what the claim compares, which only runs on the path have)."""
    if check is not None:
        return "HOLDS" if check else "FAILS"
    gone = [name for name, row in who.items() if not np.isfinite(row.ae_x_mm)]
    stayed = [name for name in who if name not in gone]
    return (
        "is not decided ("
        + (f"{' and '.join(gone)} left the path" if len(gone) < len(who) else "both left the path")
        + (f", {' and '.join(stayed)} stayed on it" if stayed else "")
        + f": {compared} is compared between runs on the path)"
    )


def stopped_runs_text(stopped: pd.DataFrame) -> str:
    """The runs that did not finish (:attr:`PaperFindings.stopped`), each with its status and
    the time it stopped: ``"S2 PCON stopped as 'left the path' at t = 18.25 s; ..."``."""
    return "; ".join(
        f"{r.scenario} {r.controller} stopped as '{r.status}' at t = {r.t_stop:g} s"
        for r in stopped.itertuples()
    )


def summary_text(summary: pd.DataFrame, stopped: pd.DataFrame, reference: str) -> str:
    """The paper's summary as a terminal shows it: a line naming the path and the units, then
    scenario, controller, AE and %AE of x and y and TV (4 significant digits), "—" where a run
    has no metrics, and a line naming the runs of the table that did not finish (``stopped``:
    :attr:`PaperFindings.stopped`), and one for the tuned AROLC's (its own file), when any did
    not."""
    columns = [*SUMMARY_COLUMNS[:6], "tv_Nm"]
    text = (
        f"{reference} path: AE in mm, %AE of the {DIAMETER_MM:g} mm diameter, TV of the "
        "commanded wheel torques in N·m\n" + table_text(summary[columns])
    )
    shown = stopped.set_index(["scenario", "controller"]).index.isin(
        summary.set_index(["scenario", "controller"]).index
    )
    if shown.any():
        text += "\n—: no metrics, the run did not finish: " + stopped_runs_text(stopped[shown])
    if not shown.all():
        text += "\nin summary_tuned_arolc.csv, did not finish: " + stopped_runs_text(
            stopped[~shown]
        )
    return text


def with_status(summary: pd.DataFrame, status: pd.DataFrame) -> pd.DataFrame:
    """``summary`` with each run's ``status`` and ``t_stop_s`` (the time it stopped, s) from
    ``status`` (:attr:`PaperStudy.status`) as its last columns: what a file's empty metrics
    mean."""
    keys = ["scenario", "controller"]
    stops = status[[*keys, "status", "t_stop"]].rename(columns={"t_stop": "t_stop_s"})
    return summary.merge(stops, on=keys, how="left", validate="one_to_one")


def _ms(seconds: float, spec: str = "g") -> str:
    """Seconds written in milliseconds."""
    return f"{1e3 * seconds:{spec}}"


# --------------------------------------------------------------------------------------------
# Tables


def paper_tables(summary: pd.DataFrame) -> dict[str, pd.DataFrame]:
    """The paper's Tables I–III with our numbers beside the paper's: title -> table of text."""
    tables = {}
    for title, cases, baseline in (
        ("Table I: S1, S2 (time-varying delay) vs PCON", ("S1", "S2"), "PCON"),
        ("Table II: S3, S4 (constant delay) vs PCONf", ("S3", "S4"), "PCONf"),
    ):
        rows = []
        for case in cases:
            for controller in (baseline, "AROLC", "OuterLoop"):
                ours = summary_row(summary, case, controller)
                paper = PAPER_TABLE.get((case, controller))
                p = [_fmt(v) for v in paper] if paper else ["—"] * 5
                rows.append(
                    {
                        "case": case,
                        "controller": controller,
                        "AE-x ours (mm)": _fmt(ours.ae_x_mm),
                        "AE-x paper (mm)": p[0],
                        "%AE-x ours": _fmt(ours.pct_ae_x),
                        "%AE-x paper": p[1],
                        "AE-y ours (mm)": _fmt(ours.ae_y_mm),
                        "AE-y paper (mm)": p[2],
                        "%AE-y ours": _fmt(ours.pct_ae_y),
                        "%AE-y paper": p[3],
                    }
                )
        tables[title] = pd.DataFrame(rows)
    rows = []
    for case in SCENARIOS:
        baseline = BASELINE[case]
        rows.append(
            {
                "case": case,
                "baseline": baseline,
                "TV baseline ours (N·m)": _fmt(summary_row(summary, case, baseline).tv_Nm),
                "TV baseline paper": _fmt(PAPER_TABLE[case, baseline][4]),
                "TV AROLC ours (N·m)": _fmt(summary_row(summary, case, "AROLC").tv_Nm),
                "TV AROLC paper": _fmt(PAPER_TABLE[case, "AROLC"][4]),
                "TV OuterLoop ours (N·m)": _fmt(summary_row(summary, case, "OuterLoop").tv_Nm),
            }
        )
    tables["Table III: total variation of the control input"] = pd.DataFrame(rows)
    return tables


def tables_markdown(summary: pd.DataFrame, reference: str = "consistent") -> str:
    """:func:`paper_tables` as Markdown (``tables.md``)."""
    lines = [
        f"# The paper's Tables I–III: ours (simulation, `{reference}` path) beside the paper's "
        "(real robot)",
        "",
        TABLES_NOTE,
        "",
    ]
    for title, table in paper_tables(summary).items():
        lines += [f"## {title}", "", "| " + " | ".join(table.columns) + " |"]
        lines.append("|" + "---|" * len(table.columns))
        lines += ["| " + " | ".join(map(str, row)) + " |" for row in table.to_numpy()]
        lines.append("")
    return "\n".join(lines)


# --------------------------------------------------------------------------------------------
# Figures


def _path_figure(study: PaperStudy, scenario: str) -> Figure:
    figure = Figure(figsize=(6.4, 6.0), dpi=110, layout="constrained")
    ax = figure.subplots()
    first = study.run(scenario, "AROLC")
    ax.plot(first.reference[:, 0, 0], first.reference[:, 0, 1], "k--", lw=1.4, label="reference")
    for kind in _KINDS:
        run = study.run(scenario, kind)
        ax.plot(run.q[0, :, 0], run.q[0, :, 1], lw=1.0, label=controller_name(scenario, kind))
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.02, 1.0), frameon=False)
    ax.set_title(f"x–y path under {scenario} ({_SCENARIO_TEXT[scenario]})")
    return figure


def _decade(value: float, _position: int | None) -> str:
    """A log axis's tick label: ``10`` with the power as superscript digits at a power of
    ten, nothing between."""
    power = round(math.log10(value)) if value > 0 else None
    if power is None or not math.isclose(value, 10.0**power, rel_tol=1e-9):
        return ""
    return "10" + str(power).translate(_SUPERSCRIPTS)


_SUPERSCRIPTS = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def _error_figure(study: PaperStudy, cases: tuple[str, ...]) -> Figure:
    figure = Figure(figsize=(9.0, 2.3 * 2 * len(cases) + 0.6), dpi=110, layout="constrained")
    axes = figure.subplots(2 * len(cases), 1, sharex=True, squeeze=False)[:, 0]
    for i, case in enumerate(cases):
        for j, coordinate in enumerate(("x", "y")):
            ax = axes[2 * i + j]
            for kind in _KINDS:
                run = study.run(case, kind)
                ax.plot(
                    run.t,
                    1e3 * np.abs(run.e1[0, :, j]),
                    lw=0.9,
                    label=controller_name(case, kind),
                )
            ax.set_ylabel(f"{case} |e_{coordinate}| (mm)")
            # Log scale: the predictors' few-mm errors and the outer loop's 100 mm both show.
            # Minor ticks at 2 and 5 times each power of ten (a 1-2-5 grid): with all eight per
            # decade, matplotlib took about 1.6 times as long to draw the figure.
            ax.set_yscale("log")
            ax.yaxis.set_minor_locator(LogLocator(subs=(2.0, 5.0)))
            # Decades written as text (10⁻², not matplotlib's mathtext): the same look, without
            # parsing and laying out each label as a formula for each format. (matplotlib
            # labels minor ticks itself only on an axis of a decade or so.)
            ax.yaxis.set_major_formatter(FuncFormatter(_decade))
            ax.set_ylim(bottom=1e-2)
            ax.grid(True, alpha=0.3, which="both")
    axes[0].legend(
        loc="lower left", bbox_to_anchor=(0.0, 1.0), fontsize="small", ncols=3, frameon=False
    )
    axes[-1].set_xlabel("t (s)")
    return figure


def _figures(study: PaperStudy) -> dict[str, tuple[Figure, str]]:
    arolc = {case: study.run(case, "AROLC") for case in SCENARIOS}
    return {
        "path_S1": (
            _path_figure(study, "S1"),
            "S1: x–y path of the tracked point for each controller against the reference circle "
            "(the paper's Fig. 1).",
        ),
        "error_S1_S2": (
            _error_figure(study, ("S1", "S2")),
            "|e_x| and |e_y| over time under S1 and S2 (time-varying delays): AROLC, PCON, outer "
            "loop.",
        ),
        "error_S3_S4": (
            _error_figure(study, ("S3", "S4")),
            "|e_x| and |e_y| over time under S3 and S4 (constant delays): AROLC, PCONf, outer "
            "loop.",
        ),
        "c_hat": (
            c_hat_figure(arolc, title="AROLC adaptive gain ĉ(t)"),
            "AROLC's adaptive gain ĉ(t) in each scenario (ĉ(0) = γ = 0.001; dimensionless).",
        ),
        "delay": (
            delay_figure(arolc, h_m=study.bound.h_m, title="Input delay h(t)"),
            "The true delays h(t) of S1–S4 and AROLC's certified bound h_m (Theorem 1).",
        ),
    }


# --------------------------------------------------------------------------------------------
# Claims


def _verdict_word(verdict: str) -> str:
    """A distribution verdict without the reason of a "no decision"."""
    return "no decision" if verdict.startswith("no decision") else verdict


def _over_draws(
    robustness: RobustnessStudy | None,
    scenario: str,
    claim: str,
    controller: str,
    lead: str = "Over",
) -> str:
    """The robustness study's verdicts (without noise) of the claim a one-run statement makes,
    as a sentence starting with ``lead`` to set beside it; nothing without the study."""
    if robustness is None:
        return ""
    v = robustness.verdicts
    row = v[
        (v.scenario == scenario)
        & (v.noise == "off")
        & (v.claim == claim)
        & (v.controller == controller)
    ].iloc[0]
    return (
        f" {lead} {row.draws} drawn robots without noise: staying on the path "
        f"{row.survival_verdict}; accuracy where both stayed on the path ({row.both_stayed} "
        f"draws) {row.accuracy_verdict}."
    )


def _claims_text(study: PaperStudy, robustness: RobustnessStudy | None) -> list[str]:
    summary = study.summary
    checks = study.findings.claims
    who = "AROLC (paper gains)"
    lines = []
    for case in SCENARIOS:
        a, b = summary_row(summary, case, "AROLC"), summary_row(summary, case, BASELINE[case])
        verdict = _one_run_verdict(checks["ae"][case], {"AROLC": a, BASELINE[case]: b})
        lines.append(
            f"AE, {case}: {_ae_of('AROLC', a)} (x / y) vs {_ae_of(BASELINE[case], b)}: in this "
            f"one run the claim 'AROLC below the predictor baseline' {verdict}."
            + _over_draws(robustness, case, f"AE below {BASELINE[case]}", who)
        )
    for case in SCENARIOS:
        a, b = summary_row(summary, case, "AROLC"), summary_row(summary, case, BASELINE[case])
        verdict = _one_run_verdict(checks["tv"][case], {"AROLC": a, BASELINE[case]: b}, "TV")
        lines.append(
            f"TV, {case}: {_tv_value_of('AROLC', a)} vs {_tv_value_of(BASELINE[case], b)}: "
            f"in this one run the claim 'AROLC's TV is lower' {verdict}."
            + _over_draws(robustness, case, f"TV below {BASELINE[case]}", who)
        )
    s3, s4 = summary_row(summary, "S3", "AROLC"), summary_row(summary, "S4", "AROLC")
    verdict = _one_run_verdict(checks["growth"]["S3->S4"], {"AROLC in S3": s3, "AROLC in S4": s4})
    lines.append(
        f"Growth with the delay: AROLC's AE, S3 (60 ms): {_ae_of('AROLC', s3)}; S4 (120 ms): "
        f"{_ae_of('AROLC', s4)}: in this one run the claim 'AROLC's error grows from S3 to S4' "
        f"{verdict}." + _over_draws(robustness, "S3 -> S4", "AE grows from S3 to S4", who)
    )
    return lines


def _tv_value_of(controller: str, row: pd.Series) -> str:
    """``AROLC 9.94 N·m``, or ``PCON left the path``."""
    if not np.isfinite(row.tv_Nm):
        return f"{controller} left the path"
    return f"{controller} {_fmt(row.tv_Nm)} N·m"


def _verdicts(checks: Claims) -> str:
    def part(name: str, key: str) -> str:
        hold = [case for case, ok in checks[key].items() if ok]
        open_ = [case for case, ok in checks[key].items() if ok is None]
        return f"{name} holds in {', '.join(hold) if hold else 'no case'}" + (
            f" (not decided in {', '.join(open_)}: a run left the path)" if open_ else ""
        )

    growth = {True: "holds", False: "fails", None: "is not decided (a run left the path)"}
    return (
        f"{part('AE below the baseline', 'ae')}; {part('TV below the baseline', 'tv')}; "
        f"error growth S3 → S4 {growth[checks['growth']['S3->S4']]}"
    )


def _distribution_verdicts(robustness: RobustnessStudy | None, controller: str) -> str:
    """The robustness study's verdicts (without noise) of ``controller``'s claims, per claim
    and scenario: staying on the path, then accuracy; nothing without the study."""
    if robustness is None:
        return ""
    v = robustness.verdicts
    rows = v[(v.noise == "off") & (v.controller == controller)]
    parts = [
        f"{r.claim}{'' if r.scenario == 'S3 -> S4' else f' in {r.scenario}'}: path "
        f"{_verdict_word(r.survival_verdict)}, accuracy {_verdict_word(r.accuracy_verdict)}"
        for r in rows.itertuples()
    ]
    draws = int(rows.draws.iloc[0])
    return f" (over {draws} drawn robots without noise: {'; '.join(parts)})"


def _claims_summary(study: PaperStudy, robustness: RobustnessStudy | None) -> str:
    sets = "; ".join(
        f"{gain_set} delays: {gains_text('AROLC', g)}, certified up to h_m = "
        f"{quantity_text(g['h_m'], 's', 4)}"
        for gain_set, g in study.gains["AROLC"].items()
        if gain_set in tuning.DELAY_CLASSES
    )
    return (
        "Which conclusion holds for which AROLC, in this one run per case"
        + (
            ", with the robustness study's verdicts over draws beside it"
            if robustness is not None
            else ""
        )
        + ". With the paper's gains (certified by Theorem 1 up to h_m = "
        f"{quantity_text(study.bound.h_m, 's', 4)}): one run: {_verdicts(study.findings.claims)}"
        + _distribution_verdicts(robustness, "AROLC (paper gains)")
        + f". Tuned by the same protocol as the baselines, per delay class as they are ({sets}): "
        f"one run: {_verdicts(study.findings.tuned_claims)}"
        + _distribution_verdicts(robustness, "AROLC (tuned)")
        + ". The bullets above check the paper-gain AROLC; the section 'AROLC tuned by the same "
        "procedure' gives the tuned numbers."
    )


def _certified_text(largest: Mapping[str, float], certified: Sequence[str], who: str) -> str:
    """Which scenarios Theorem 1 certifies ``who`` for (``certified``), beside each scenario's
    largest delay over the run (``largest``, s)."""
    inside = [case for case in largest if case in certified]
    outside = [case for case in largest if case not in certified]
    maxima = ", ".join(f"{case} {_ms(value, '.0f')} ms" for case, value in largest.items())
    return (
        f"Largest delays over the run: {maxima}. "
        + (f"{who[0].upper()}{who[1:]} is certified")
        + (f" for {', '.join(inside)}" if inside else "")
        + (f" and NOT certified for {', '.join(outside)}." if inside and outside else "")
        + (f" for none of {', '.join(outside)}." if not inside else "")
        + ("." if inside and not outside else "")
    )


def _largest_delays(study: PaperStudy) -> dict[str, float]:
    return {case: largest for case, (_, largest) in study.findings.delay_ranges.items()}


def _explanation(study: PaperStudy) -> list[str]:
    """The paragraphs that explain the one run: why the AE claim fails (when it does), the
    baselines' failures (when any), what the predictor does on this robot, and TV."""
    found = study.findings
    out = []
    if any(holds is False for holds in found.claims["ae"].values()):
        out.append(_ae_failure_text(study))
    if found.baseline_failures:
        out.append(_baseline_failures_text(found.baseline_failures))
    out.append(_predictor_text(found))
    out.append(_tv_text(study))
    return out


def _ae_failure_text(study: PaperStudy) -> str:
    """Why the AE claim fails: AROLC at the paper's gains against tuned baselines."""
    found = study.findings
    return _arolc_error_text(found) + _tuned_baselines_text(study) + _tuning_spread_text(found)


def _arolc_error_text(found: PaperFindings) -> str:
    """AROLC's AE at the paper's gains, set by the model mismatch rather than by the delay."""
    arolc = found.ae_x_range["AROLC"]
    outer = found.ae_x_range["OuterLoop"]
    return (
        "Why the AE claim fails here. AROLC runs with the paper's gains "
        f"K1 = {AROLC_GAINS['K1']:g} I, K2 = {AROLC_GAINS['K2']:g} I: an outer loop with "
        f"natural frequency {found.natural_frequency:.3g} rad/s and damping "
        f"{found.damping:.3g}, in which an unmodelled "
        "acceleration a leaves a steady error of about a / K1. The wheel friction, which "
        "the nominal model leaves out (the truth's "
        f"{found.wheel_friction[0]:.2g}–{found.wheel_friction[1]:.2g} N·m per wheel at the "
        f"path's wheel rates of {found.wheel_rates[0]:.3g} and {found.wheel_rates[1]:.3g} "
        f"rad/s), and the {P3DX_PAYLOAD.mass:g} kg payload are such a mismatch. The error is "
        f"set by it, not by the delay: AROLC's AE spans {arolc[0]:.1f}–{arolc[1]:.1f} mm "
        "in x over the four delays, and the outer loop without Δu is at "
        f"{outer[0]:.1f}–{outer[1]:.1f} mm. The switching term helps "
        f"({_c_hat_peak_text(found)}; so ‖Δu‖ ≤ α ĉ = {found.switching_bound:.3g}) but cannot "
        "replace stiffer gains. "
    )


def _c_hat_peak_text(found: PaperFindings) -> str:
    """Where ĉ reaches its largest value, and whether that is at the end of the run."""
    text = (
        f"ĉ reaches {found.c_hat_peak:.3g}, its largest value in any run, in "
        f"{found.c_hat_peak_scenario} at t = {found.c_hat_peak_time:.3g} s"
    )
    if found.c_hat_peak_at_end:
        text += ", the end of the run: it may grow further in a longer one"
    return text


def _tuned_baselines_text(study: PaperStudy) -> str:
    """The baselines' tuned gains (stiff laws) and the AE they reach."""
    gains = {kind: study.gains[kind][DELAY_CLASS[case]] for case, kind in BASELINE.items()}
    base = study.findings.ae_x_range["baseline"]
    return (
        "The baselines were tuned (on conditions of their delay class, none of S1–S4) to "
        "minimise exactly this AE, and the optimum is a stiff law: "
        + "; ".join(_baseline_gains_text(kind, kind_gains) for kind, kind_gains in gains.items())
        + f", which reach AE of {base[0]:.1f}–{base[1]:.1f} mm in x. This table therefore "
        "compares tuned baselines with AROLC at the paper's gains; AROLC tuned by the same "
        "procedure is reported in its own section below. "
    )


def _baseline_gains_text(kind: str, gains: Mapping[str, float]) -> str:
    """A baseline's tuned gains κ, k_b and ϑ."""
    return f"{kind} κ = {gains['kappa']:g}, k_b = {gains['k_b']:g}, ϑ = {gains['c']:g} M̂⁻¹"


def _tuning_spread_text(found: PaperFindings) -> str:
    """How much tuning matters: the baselines' worst-case objective over the tuning grid."""
    return (
        "How much tuning matters: over the tuning grid's points that stayed on the path (did "
        f"not stop, mean AE at most {tuning.DIVERGED_AE_MM:g} mm) under every condition of the "
        "delay class a baseline is tuned for, the baselines' worst-case objective ranges "
        + " and ".join(_spread_text(kind, spread) for kind, spread in found.tuning_spread.items())
        + ". The paper does not say how its baselines were tuned; baselines tuned less well can "
        "land above AROLC."
    )


def _spread_text(kind: str, spread: Sequence[float]) -> str:
    """A baseline's worst-case objective over the grid (mm): its range and median."""
    low, median, high = spread
    delay_class = next(DELAY_CLASS[case] for case, baseline in BASELINE.items() if baseline == kind)
    return (
        f"from {low:.3g} to {high:.3g} mm (median {median:.3g} mm; {kind}, {delay_class}-delay "
        "conditions)"
    )


def _baseline_failures_text(failures: Sequence[BaselineFailure]) -> str:
    """The baselines' runs that left the path, and what that says of the claims."""
    return (
        "Baseline failures: "
        + "; ".join(_baseline_failure_text(failure) for failure in failures)
        + ". A delay longer, or longer-lasting, than any of the tuning conditions was never "
        "seen by the tuning. The gains were not re-tuned after this result. Where the "
        "baseline diverges the claim "
        "'holds' only by the baseline's failure; the robustness study's map shows where "
        "each predictor diverges."
    )


def _baseline_failure_text(failure: BaselineFailure) -> str:
    """One baseline run that left the path: when, the delay it met beside its tuning's, and
    its stability number."""
    return (
        f"{failure.controller} in {failure.scenario} left the path at t = "
        f"{failure.t_stop:.1f} s; {failure.scenario}'s delay reaches "
        f"{_ms(failure.largest_delay, '.0f')} ms"
        + (
            f" and stays above {_ms(failure.dwell_level, '.4g')} ms for up to "
            f"{failure.longest_dwell:.1f} s at a time"
            if failure.longest_dwell is not None
            else ""
        )
        + f", while the {failure.delay_class} tuning conditions reached at most "
        f"{_ms(failure.tuning_largest_delay, '.0f')} ms; its sampled-law stability number "
        f"T_c k_b λ_max(ϑ) is {failure.stability_number:.2g} (about 2 is the edge; ϑ = c ϑ₀, "
        "ϑ₀ the model's inverse mass matrix)"
    )


def _predictor_text(found: PaperFindings) -> str:
    """What the predictor does on this robot (docs/decisions.md, D23): partly effective, and
    stable only for a small enough gain product."""
    return (
        "What the predictor does on this robot. The law is applied in the five coordinates "
        "q = (x, y, φ, θ_r, θ_l) and its command is projected to the wheels by τ_w = S(q)ᵀ τ. "
        "The delayed input reaches ϱ̇ through S M_r⁻¹ S(q(t − h))ᵀ τ(t − h), a rank-2 map "
        "that turns with the heading, while ϑ e_z predicts ϑ τ(t − h). No constant symmetric "
        "positive definite ϑ cancels it, and e_z also integrates the components of τ "
        "that the constraints absorb. The predictor is thus only partly effective, and the "
        "sampled law is stable only for about T_c k_b λ_max(ϑ) < 2 (λ_max(M̂⁻¹) = "
        f"{found.inverse_mass_eigenvalue:.3g} at the start of the path, so k_b c < "
        f"{found.stable_gain_product:.3g} at T_c = {_ms(T_C)} ms). Near that boundary the "
        "commands can oscillate from tick "
        "to tick, which TV measures (TV is not part of the tuning objective; the worst-case "
        "objective keeps the chosen gains further from the boundary than an average-AE one)."
    )


def _tv_text(study: PaperStudy) -> str:
    """The TV of AROLC, the outer loop and the baselines, and where the one run's TV claim
    holds."""
    found = study.findings
    return (
        f"TV: AROLC's TV is {_tv_values(study.summary, 'AROLC')} N·m (S1–S4), against the "
        f"outer loop's {_tv_values(study.summary, 'OuterLoop')} N·m: its switching term Δu "
        f"(ĉ grows to {found.c_hat_peak:.3g}) adds most of it. The baselines' TV is "
        f"{_baseline_tv_values(study.summary)} N·m (S1–S4). "
        + _tv_verdict_text(found.claims["tv"])
        + f" The paper's TV values ({found.paper_arolc_tv[0]:g}–{found.paper_arolc_tv[1]:g} "
        "for AROLC) are smaller than ours because a real "
        "robot's torque commands and units differ; the comparison is within each row."
    )


def _tv_values(summary: pd.DataFrame, controller: str) -> str:
    """``controller``'s TV in S1–S4, comma-separated."""
    return ", ".join(f"{summary_row(summary, case, controller).tv_Nm:.3g}" for case in SCENARIOS)


def _baseline_tv_values(summary: pd.DataFrame) -> str:
    """Each scenario's baseline's TV in S1–S4, comma-separated, each with its baseline's name
    ("left the path" where not finite)."""
    values = {case: summary_row(summary, case, BASELINE[case]).tv_Nm for case in SCENARIOS}
    return ", ".join(
        f"{tv:.3g} ({BASELINE[case]})" if math.isfinite(tv) else f"left the path ({BASELINE[case]})"
        for case, tv in values.items()
    )


def _tv_verdict_text(tv_checks: Mapping[str, bool | None]) -> str:
    """Where the one run's TV claim holds, where it fails and where it is not decided."""
    holds = [case for case, ok in tv_checks.items() if ok]
    fails = [case for case, ok in tv_checks.items() if ok is False]
    open_ = [case for case, ok in tv_checks.items() if ok is None]
    return (
        (
            f"In this one run the claim holds in {', '.join(holds)}"
            if holds
            else "In this one run the claim holds nowhere"
        )
        + (f"; it fails in {', '.join(fails)}" if fails else "")
        + (f"; it is not decided in {', '.join(open_)}, where a run left the path" if open_ else "")
        + "."
    )


# --------------------------------------------------------------------------------------------
# Sections


#: The kinds of verdict as the paper report names them.
_KIND_NAMES = {"survival": "staying on the path", "accuracy": "accuracy where both stayed on it"}


def _distribution_section(report: HtmlReport, robustness: RobustnessStudy) -> None:
    """The claims over distributions of robots (the robustness study's verdicts)."""
    report.heading("The claims over distributions (robustness study)")
    counts = robustness.verdict_counts
    tallies = "; ".join(
        f"{_KIND_NAMES[r.kind]}: of {r.verdicts} verdicts {r.holds} hold, {r.fails} fail, "
        f"{r.undecided} are undecided and {r.no_decision} reach no decision"
        for r in counts[counts.noise == "all"].itertuples()
    )
    report.paragraph(
        "One run per case (the next section) can be a lucky or an unlucky draw. The robustness "
        "study (../robustness/"
        f"report.html) repeats every case over {robustness.size.claims} drawn robots (payload "
        "seed and wheel friction from their documented ranges), without and with measurement "
        "noise, and judges each claim twice on the same draws: staying on the path (per side "
        "the share of draws that stayed, McNemar's exact test on the draws where only one "
        "diverged) and accuracy over the draws where both stayed on the path (the share in "
        "which AROLC is below, the sign test, the paired median difference). Every verdict of "
        "the study is corrected together with Holm's method at "
        f"{100 * robustness.alpha:g} %: {tallies} at this size."
    )
    write_verdict_tables(report, robustness)
    report.bullets(robustness_findings(robustness))
    report.table(
        display_knowledge(robustness.knowledge_table),
        "What the predictors tolerate of a wrong delay (robustness/knowledge_table.csv): "
        "divergence rate, median time of leaving the path, median AE (mm) of the runs that "
        "stayed, beside AROLC with the paper's gains.",
    )
    report.table(
        display_attribution(robustness.attribution),
        "Attribution (robustness/attribution.csv): paired change of AE (mm) and TV (N·m) from "
        "the controller without the part to the one with it; medians over the draws where both "
        "stayed on the path, with bootstrap 95 % intervals, beside the draws in which each "
        "diverged.",
    )


def _decision_section(report: HtmlReport, decision: DecisionStudy) -> None:
    """Which controller and gains the decision rule chooses for each delay envelope."""
    report.heading("Which controller for which delay envelope")
    first = next(iter(decision.decisions.values()))
    tradeoff = decision.tradeoff
    report.paragraph(
        "The claims above compare fixed gain sets; a user choosing a controller also chooses "
        "its gains. The decision study (../decision/report.html) sweeps the outer-loop gains "
        f"K1 = ω_n² I, K2 = 2ζω_n I (ζ = {tradeoff.zeta:g}, ω_n from "
        f"{min(tradeoff.omegas):.3g} to {max(tradeoff.omegas):.3g} rad/s, "
        f"{len(tradeoff.omegas)} points) for AROLC, the outer loop and PCONf on "
        f"{tradeoff.scenario.name}, runs every candidate on {first.draws} drawn robots in each "
        "condition of an envelope (constant true delays; PCONf told the delay the envelope "
        "allows), and picks the smallest worst-case AE (the largest over the conditions of the "
        "median AE of the runs on the path) among the candidates that stay on the path in at "
        f"least {100 * first.required_share:g} % of drawn robots by the Wilson 95 % lower bound "
        "in every condition. The runner-up is the best qualifying candidate of another "
        "controller."
    )
    report.bullets(
        decision_sentence(decision.cases[name], chosen)
        for name, chosen in decision.decisions.items()
    )
    report.table(
        display_envelopes(decision),
        "decision/decision.csv: one row per envelope (—: no winner or no runner-up).",
    )


def _tuned_section(
    report: HtmlReport, study: PaperStudy, robustness: RobustnessStudy | None
) -> None:
    """The section 'AROLC tuned by the same procedure', with the robustness study's verdicts
    beside its one-run claims when the study is given."""
    found = study.findings
    who = "AROLC (tuned)"
    report.heading("AROLC tuned by the same procedure")
    per_class, grid, fixed = tuning.CONDITIONS_PER_CLASS, tuning.GRIDS["AROLC"], tuning.AROLC_FIXED
    sizes = {len(values) for values in grid.values()}
    report.paragraph(
        "Every controller is tuned by one protocol (delaytrack.experiments.tuning): the same "
        f"{per_class * len(tuning.DELAY_CLASSES)} conditions drawn from stated distributions "
        f"({per_class} time-varying and {per_class} constant delays, none of S1–S4), an initial "
        f"grid of {len(grid)} gains with {'/'.join(map(str, sorted(sizes)))} values each, the "
        "same rule for extending a grid whose optimum sits on its edge, and the same objective, "
        "the worst mean AE over a gain set's conditions with any divergence excluded. Each "
        "controller gets one gain set for all delays and one per delay class. AROLC's grid "
        "spans a gain scale k (K1 = k² I, K2 = 2 ζ k I), the damping ζ and the switching gain "
        f"α, with Q = {fixed['Q']:g} I, ε = {fixed['epsilon']:g}, γ = {fixed['gamma']:g} "
        "fixed. In the table below, AROLC-tuned and the "
        "baselines use their class's set (S1, S2: varying; S3, S4: constant). The chosen gains "
        "of every controller and set follow, with Theorem 1's certified bound where it applies "
        "(AROLC; the predictors have no certificate)."
    )
    chosen = found.chosen_gains.copy()
    chosen.insert(
        2,
        "gains",
        [
            gains_text(kind, study.gains[kind][gain_set])
            for kind, gain_set in zip(chosen["controller"], chosen["gain set"], strict=True)
        ],
    )
    report.table(
        chosen,
        "Chosen gains per controller and gain set (objective: worst mean AE over the set's "
        "tuning conditions, mm; certified h_m in ms, AROLC only).",
    )
    report.paragraph(
        f"Certification caveat: Theorem 1 certifies the tuned AROLC only up to h_m = "
        f"{found.tuned_h_m:.4f} s (β = {BETA:g}, r = {R:g}; the smaller of its two class sets), "
        f"against {study.bound.h_m:.4f} s for the paper's gains. "
        + _certified_text(_largest_delays(study), found.tuned_certified, "the tuned AROLC")
        + " Where it is not certified, its stability is an empirical finding of the simulation, "
        "like the baselines'. Theorem 1's bound is conservative (a sufficient condition), and "
        "stiffer gains shrink it quickly.",
        note=True,
    )
    base = study.summary[study.summary.controller.isin(["PCON", "PCONf"])]
    side = pd.concat([study.tuned_summary, base], ignore_index=True)
    side = side.sort_values(["scenario", "controller"], kind="stable").reset_index(drop=True)
    report.table(
        side,
        "AROLC-tuned beside the tuned baselines (mm, %, N·m; —: the run left the path).",
    )
    checks = found.tuned_claims
    lines = []
    for case in SCENARIOS:
        a = summary_row(study.tuned_summary, case, TUNED)
        b = summary_row(study.summary, case, BASELINE[case])
        runs = {"AROLC-tuned": a, BASELINE[case]: b}
        lines.append(
            f"{case}: {_ae_of('AROLC-tuned', a)}{_tv_of(a)} vs {_ae_of(BASELINE[case], b)}"
            f"{_tv_of(b)}: in this one run the AE claim "
            f"{_one_run_verdict(checks['ae'][case], runs)}, the TV claim "
            f"{_one_run_verdict(checks['tv'][case], runs, 'TV')}."
            + _over_draws(robustness, case, f"AE below {BASELINE[case]}", who, "AE claim over")
            + _over_draws(robustness, case, f"TV below {BASELINE[case]}", who, "TV claim over")
        )
    s3 = summary_row(study.tuned_summary, "S3", TUNED)
    s4 = summary_row(study.tuned_summary, "S4", TUNED)
    lines.append(
        "Growth S3 → S4 for AROLC-tuned, in this one run: "
        + _one_run_verdict(
            checks["growth"]["S3->S4"], {"AROLC-tuned in S3": s3, "AROLC-tuned in S4": s4}
        )
        + "."
        + _over_draws(robustness, "S3 -> S4", "AE grows from S3 to S4", who)
    )
    report.bullets(lines)


def _literal_paragraph(study: PaperStudy, literal_summary: pd.DataFrame | None) -> str:
    found = study.findings
    text = (
        "The literal path (the paper's Section III). The paper prints x_d = 1.25 sin(0.35t) + 0.1, "
        "y_d = 1.25 cos(0.35t) + 1.35, φ_d = 0.25t, θ_r,d = 3t, θ_l,d = 2t. These are not "
        "consistent for a nonholonomic robot: the circle is driven clockwise at "
        f"{found.circle_speed:.4g} m/s while φ_d turns counter-clockwise and the wheel "
        f"references imply {found.literal_speed:.3g} m/s and {found.literal_turn:.3g} rad/s "
        f"(R = {P3DX.wheel_radius:g} m, L = {P3DX.half_track:g} m). No motion satisfies all "
        "five, so every controller, which "
        "weighs all five coordinates, settles on a compromise between the x–y circle, the "
        "heading and the wheel angles, and the x–y errors grow to the order of the path itself. "
        "The main results (the report in paper/ beside this one's folder) use the "
        "'consistent' path (same circle, heading and wheel angles derived from the "
        "kinematics)."
    )
    if study.reference == "literal":
        frame = study.summary
        where = "this run"
    elif literal_summary is not None:
        frame = literal_summary
        where = "the sibling run ../paper-literal/report.html"
    else:
        return text + " The literal run is written by `delaytrack reproduce` to paper-literal/."
    rows = "; ".join(
        _ae_of(f"{r.scenario} {r.controller}", r, 0)
        for r in frame.itertuples()
        if r.scenario in ("S1", "S4")
    )
    return text + f" Measured in {where} (AE x / y): {rows}."


def _consistent_path_text(study: PaperStudy) -> str:
    """The consistent path's heading and wheel rates."""
    found = study.findings
    right, left = found.consistent_wheel_rates
    return (
        f"φ_d, θ_r,d, θ_l,d derived from the kinematics (φ_d = {found.heading_start:.6g} "
        f"{'+' if found.heading_rate >= 0 else '−'} {abs(found.heading_rate):.4g}t, "
        f"θ̇_r,d = {right:.5g}, θ̇_l,d = {left:.5g} rad/s; docs/robot.md)"
    )


def _settings(study: PaperStudy) -> dict[str, str]:
    g = study.gains
    found = study.findings
    record = study.tuning_record
    return {
        "reference path": f"'{study.reference}' (paper_reference): x_d = 1.25 sin(0.35t) + 0.1, "
        "y_d = 1.25 cos(0.35t) + 1.35 m; "
        + (
            _consistent_path_text(study)
            if study.reference == "consistent"
            else "φ_d = 0.25t, θ_r,d = 3t, θ_l,d = 2t as printed (kinematically inconsistent)"
        ),
        "initial state": "x0 = initial_state(reference): on the path's pose at t = 0, with the "
        "reference's wheel rates, on the constraint manifold",
        "truth plant": "PayloadRobot(robot=WheeledRobot()): constrained P3-DX dynamics, wheel "
        "friction "
        f"(viscous {P3DX.viscous_friction:g} N·m·s/rad + Coulomb {P3DX.coulomb_friction:g} N·m, "
        f"tanh-smoothed at {P3DX.friction_speed:g} rad/s; assumptions), "
        f"Baumgarte gain {DEFAULT_BAUMGARTE_GAIN:g} 1/s",
        "parameters": f"R = {P3DX.wheel_radius} m, L = {P3DX.half_track} m (half track), "
        f"d = {P3DX.d} m, m = {P3DX.mass} kg, I about the axle midpoint = "
        f"{P3DX.yaw_inertia} kg·m², I_w = {P3DX.wheel_spin_inertia} kg·m²; sources in "
        "delaytrack.plants.robot.P3DX_SOURCES and docs/robot.md",
        "payload": f"{P3DX_PAYLOAD.mass} kg, on {P3DX_PAYLOAD.time_on:g} s / off "
        f"{P3DX_PAYLOAD.time_off:g} s, first on at t = {P3DX_PAYLOAD.first_on:g} s (our "
        "choice: the robot starts as the nominal model), at a uniform random point of the "
        f"{P3DX_PAYLOAD.plate_length} × {P3DX_PAYLOAD.plate_width} m top plate; seed "
        f"{PAYLOAD_SEED}, the same for every controller and scenario",
        "nominal model": "NominalRobot(): the unconstrained Lagrangian M̂, N̂ of the robot without "
        "payload and friction; commands τ_w = S(q)ᵀ τ (all controllers)",
        "AROLC": ", ".join(
            f"{name} = {AROLC_GAINS[key]:g}{' I' if key in ('K1', 'K2', 'Q') else ''}"
            for key, name in (
                ("K1", "K1"),
                ("K2", "K2"),
                ("Q", "Q"),
                ("alpha", "α"),
                ("epsilon", "ε"),
                ("gamma", "γ"),
            )
        )
        + ", ĉ(0) = γ (the paper's gains)",
        "AROLC-tuned": "; ".join(
            f"{', '.join(c for c, k in DELAY_CLASS.items() if k == gain_set)}: "
            + gains_text("AROLC", g["AROLC"][gain_set])
            + f" (certified up to h_m = {quantity_text(g['AROLC'][gain_set]['h_m'], 's', 4)})"
            for gain_set in tuning.DELAY_CLASSES
        )
        + f"; Q = I, ε = {AROLC_GAINS['epsilon']:g}, γ = {AROLC_GAINS['gamma']:g}",
        "OuterLoop": f"K1 = {AROLC_GAINS['K1']:g} I, K2 = {AROLC_GAINS['K2']:g} I (AROLC "
        "without Δu; an ablation)",
        "PCON (S1, S2)": gains_text("PCON", g["PCON"]["varying"])
        + f" (q_d(0)), given the true h(t), history {tuning.HISTORY:g} s (≥ h_max = "
        f"{found.largest_scenario_delay:g} s)",
        "PCONf (S3, S4)": gains_text("PCONf", g["PCONf"]["constant"])
        + " (q_d(0)), h̄ = the scenario's constant delay",
        "tuning": "the same protocol for every controller (delaytrack tune-baselines; "
        "delaytrack/data/baseline_gains.toml): a grid of three gains per controller, each run "
        f"on the same {len(record['conditions'])} conditions drawn with seed "
        f"{record['condition_seed']} ("
        + "; ".join(record["conditions"])
        + f"), {record['duration']:g} s each; objective the worst mean(AE-x, AE-y) over a "
        "gain set's conditions, any divergence excluded; none of S1–S4",
        "delays": "; ".join(f"{k}: {v}" for k, v in _SCENARIO_TEXT.items())
        + " (unknown to AROLC and the outer loop)",
        "duration": f"{study.duration:g} s (not in the paper; "
        f"{counted(study.findings.payload_placements, 'payload placement')})",
        "plant step dt": f"{DT:g} s, RK4 split at the delayed input's switches; "
        + (
            "not checked at dt/2"
            if found.dt_within_tolerance is None
            else "the dt/2 check below shows the results do not hinge on it"
            if found.dt_within_tolerance
            else "the dt/2 check below names the runs whose metrics do depend on it"
        ),
        "controller period T_c": f"{T_C:g} s ({found.controller_rate:g} Hz), zero-order hold. "
        "Not in the paper: a plausible rate for a P3-DX control loop (its onboard server cycles "
        f"at 10–100 ms), {found.delay_ranges_in_periods['S1'][0]:.3g}× below the smallest S1 "
        f"delay and {found.delay_ranges_in_periods['S3'][1]:.3g}× below S3's",
        "metrics": "over the whole run, no transient skipped: AE = mean |e| of x and y (mm), "
        f"%AE = AE / {DIAMETER_MM:g} mm × 100, RMS, max; TV = Σ |Δu_r| + |Δu_l| over consecutive "
        "controller ticks of the commanded wheel torques (N·m)",
        "delaytrack": __version__,
    }


def _tuning_section(report: HtmlReport, study: PaperStudy) -> None:
    """The section 'Tuning': the objective, the conditions and each grid's best points."""
    report.heading("Tuning")
    record = study.tuning_record
    report.paragraph(
        "Objective, the same for every controller: every grid point is run under each tuning "
        "condition; per condition the mean of AE-x and AE-y (mm), ae_i_mm for condition i; a "
        "gain set's objective is the worst (largest) over its conditions, and a point that "
        "diverges under any of them is excluded. Conditions: "
        + "; ".join(
            f"({i}) {text} [{delay_class}]"
            for i, (text, delay_class) in enumerate(
                zip(record["conditions"], record["condition_classes"], strict=True), start=1
            )
        )
        + ". The grids' columns: AROLC's k (rad/s; K1 = k² I, K2 = 2ζk I), zeta (ζ) and alpha "
        "(α); a predictor's kappa (κ), k_b and c (ϑ = c M̂⁻¹). PCON-wheel is PCON with its "
        "law on the wheel torques it sends rather than on generalised forces (its ϑ = c M̂_r⁻¹, "
        "M̂_r = SᵀM̂S the nominal reduced mass matrix, and its integral of the commands sent)."
    )
    with report.folded("The five best grid points of each controller and gain set"):
        for (kind, gain_set), grid in study.findings.tuning_grids.items():
            chosen = record[kind][gain_set]
            report.paragraph(
                f"{kind}, gain set '{gain_set}': chosen {gains_text(kind, chosen)} "
                f"(objective {chosen['objective']:.3f} mm; "
                + ("inside its grid in every gain" if chosen["interior"] else "ON ITS GRID'S EDGE")
                + f"); {grid.excluded} of {grid.points} grid points diverged (stopped, or mean AE "
                f"above {tuning.DIVERGED_AE_MM:g} mm) under one of the set's conditions."
            )
            members = map(str, tuning.set_conditions(record["condition_classes"], gain_set))
            report.table(
                grid.best.rename(columns=_tuning_column),
                f"{kind} ({gain_set}): the five best grid points; the objective is the worst "
                f"ae_i_mm of conditions {', '.join(members)}; —: the point left the path under "
                "that condition.",
            )


def _tuning_column(name: str) -> str:
    """A tuning grid's column with its unit: ``ae_mm_3`` -> ``ae_3_mm``, ``tv_3`` ->
    ``tv_3_Nm``, ``h_m`` -> ``h_m_s``, ``objective`` -> ``objective_mm``; gains keep theirs."""
    if name.startswith("ae_mm_"):
        return f"ae_{name.removeprefix('ae_mm_')}_mm"
    if name.startswith("tv_"):
        return f"{name}_Nm"
    return {"h_m": "h_m_s", "objective": "objective_mm"}.get(name, name)


def _report(
    study: PaperStudy,
    figures: Mapping[str, tuple[Figure | bytes, str]],
    literal_summary: pd.DataFrame | None,
    robustness: RobustnessStudy | None = None,
    decision: DecisionStudy | None = None,
) -> HtmlReport:
    found = study.findings
    report = HtmlReport(f"delaytrack: the paper's robot experiment (S1–S4, {study.reference} path)")
    report.paragraph(
        "A simulated PIONEER-3 DX tracks the paper's circle while its wheel-torque commands "
        f"arrive late by the paper's delays S1–S4, with a {P3DX_PAYLOAD.mass:g} kg payload put "
        f"on for {P3DX_PAYLOAD.time_on:g} s and taken off for {P3DX_PAYLOAD.time_off:g} s. AROLC "
        "(Roy & Kar, the paper's gains) is compared with the predictor "
        "baselines PCON (S1, S2) and PCONf (S3, S4), tuned by a documented grid search on other "
        "conditions, and with the plain outer loop. AROLC tuned by the same procedure is "
        "reported beside them in its own section. Every number below is computed by the "
        "simulation; the paper's are from a real robot, so the pattern is compared, not the "
        "digits."
    )
    if len(found.stopped):
        report.paragraph(
            "Runs that left the path (no metrics: — in the tables, empty in the CSV files, "
            "whose status column says why): " + stopped_runs_text(found.stopped),
            note=True,
        )
    report.heading("Summary")
    report.table(
        study.summary,
        f"summary.csv: AE, RMS, max in mm; %AE of {DIAMETER_MM:g} mm; TV in N·m; —: the run "
        "left the path.",
    )
    report.heading("Figures")
    for figure, caption in figures.values():
        report.figure(figure, caption)
    if robustness is not None:
        _distribution_section(report, robustness)
    if decision is not None:
        _decision_section(report, decision)
    report.heading(f"Claims check, one run per case (payload seed {PAYLOAD_SEED})")
    if study.reference == "literal":
        report.paragraph(
            "This is the literal path, which no robot can follow (see 'Literal path' below): "
            f"{found.off_path} of {len(study.summary)} runs end with a mean AE above "
            f"{tuning.DIVERGED_AE_MM:g} mm or left the path, the rule by which the tuning and "
            "the robustness study count a run as off the path, so this claims check says little "
            "about the controllers. What sets the errors, and why each claim holds or fails, "
            "is explained for the consistent path (../paper/report.html).",
            note=True,
        )
    report.bullets(_claims_text(study, robustness))
    report.paragraph(_claims_summary(study, robustness))
    if study.reference != "literal":  # its mechanisms are the consistent path's
        for text in _explanation(study):
            report.paragraph(text)
    _tuned_section(report, study, robustness)
    write_contact_section(report, study)
    report.heading("Tables I–III beside the paper's")
    report.paragraph(TABLES_NOTE)
    for title, table in paper_tables(study.summary).items():
        report.table(table, title)
    report.heading("Literal path")
    report.paragraph(_literal_paragraph(study, literal_summary))
    report.heading("Settings and modelling decisions")
    report.settings(_settings(study))
    report.paragraph(
        f"Theorem 1's certified delay bound for AROLC's gains: h_m = {study.bound.h_m:.5f} s. "
        + _certified_text(_largest_delays(study), found.certified, "AROLC with the paper's gains")
    )
    write_dt_check(report, study.dt_verdict, found.half_dt)
    _tuning_section(report, study)
    report.paragraph(
        f"Simulation wall time: {study.seconds:.1f} s ({len(study.results)} batched simulate() "
        f"calls of {len(SCENARIOS)} runs each"
        + (", and as many at dt/2" if study.dt_check is not None else "")
        + "; numba-compiled)."
    )
    return report


def write_study(
    study: PaperStudy,
    folder: str | Path,
    *,
    literal_summary: pd.DataFrame | None = None,
    robustness: RobustnessStudy | None = None,
    decision: DecisionStudy | None = None,
) -> list[Path]:
    """Write ``summary.csv``, ``tables.md``, ``dt_check.csv``, figures and ``report.html`` (with
    the robustness study's verdicts when it is given, the decision rule's choice per delay
    envelope when the decision study is, and the literal run's AE when ``literal_summary``
    is)."""
    folder = claim_output_folder(folder)
    files = [write_frame(with_status(study.summary, study.status), folder / "summary.csv")]
    tuned = with_status(study.tuned_summary, study.status)
    files.append(write_frame(tuned, folder / "summary_tuned_arolc.csv"))
    if study.contact is not None:
        files.append(write_frame(study.contact, folder / "summary_contact.csv"))
    files.append(write_text(folder / "tables.md", tables_markdown(study.summary, study.reference)))
    if study.dt_check is not None:
        files.append(write_frame(study.dt_check, folder / "dt_check.csv"))
    images = {}
    for name, (figure, caption) in _figures(study).items():
        saved = save_figure(figure, folder / "figures" / name)
        files += saved
        # The report embeds the PNG just written (rendering the figure again would double the
        # time spent drawing).
        images[name] = (next(p for p in saved if p.suffix == ".png").read_bytes(), caption)
    report = _report(study, images, literal_summary, robustness, decision)
    files.append(report.write(folder / "report.html"))
    record_outputs(folder, files)
    return files
