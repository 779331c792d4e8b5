"""The robustness study's report: findings in words, display tables, the robustness map and the
HTML page, made from a :class:`~delaytrack.experiments.robustness.RobustnessStudy` that already
holds every number quoted here (this module computes none)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from delaytrack._io import write_frame
from delaytrack._output import record_outputs
from delaytrack._words import counted
from delaytrack.experiments.robustness import repeated_in
from delaytrack.report.figures import save_figure
from delaytrack.report.html import HtmlReport

if TYPE_CHECKING:
    from delaytrack.experiments.robustness import RobustnessStudy

__all__ = [
    "MAP_CONTROLLERS",
    "display_attribution",
    "display_knowledge",
    "display_outcomes",
    "display_survival",
    "display_verdicts",
    "findings",
    "robustness_map",
    "write_robustness",
    "write_verdict_tables",
]

#: The map's controllers, in panel order.
MAP_CONTROLLERS = (
    "PCON",
    "PCON-wheel",
    "PCONf",
    "AROLC (paper gains)",
    "AROLC (tuned)",
    "outer loop (paper gains)",
)
#: The controllers at the paper's gains, with and without the switching term Δu.
_PAPER_GAINS = ("AROLC (paper gains)", "outer loop (paper gains)")


def _reach(study: RobustnessStudy, controller: str, scale: float | None) -> pd.Series:
    """The row of ``study.reach`` of ``controller`` told ``scale`` (None: not told)."""
    reach = study.reach
    told = reach.scale.isna() if scale is None else reach.scale == scale
    return reach[(reach.controller == controller) & told].iloc[0]


def findings(study: RobustnessStudy) -> list[str]:
    """The study's findings as sentences, every number taken from its tables."""
    out = []
    for name in MAP_CONTROLLERS:
        told = name in study.predictors
        row = _reach(study, name, 1.0 if told else None)
        text = f"{name}{' (told the true delay)' if told else ''}: " + (
            f"no run diverged up to {row.longest_clean_delay_ms:g} ms"
            if math.isfinite(row.longest_clean_delay_ms)
            else f"runs diverged already at {row.smallest_delay_ms:g} ms"
        )
        if math.isfinite(row.half_diverged_from_ms):
            text += f"; at least half of the runs diverged from {row.half_diverged_from_ms:g} ms on"
        text += f" ({row.draws} draws per delay; tested up to {row.largest_delay_ms:g} ms)."
        out.append(text)
    for name in study.predictors:
        parts = []
        for scale in study.scales:
            clean = _reach(study, name, scale).longest_clean_delay_ms
            parts.append(f"told {scale:g}·h: {f'{clean:g} ms' if math.isfinite(clean) else 'none'}")
        out.append(
            f"{name}, largest true delay up to which no run diverged, by what it is told: "
            + "; ".join(parts)
            + "."
        )
    paper_gains = [_reach(study, name, None) for name in _PAPER_GAINS]
    if all(row.diverged == 0 for row in paper_gains):
        out.append(
            "At the paper's gains AROLC and the plain outer loop both stay on the path at every "
            f"tested delay up to {paper_gains[0].largest_delay_ms:g} ms: the robustness to the "
            "delay observed here does not come from the switching term Δu, since the outer loop "
            "without it is as robust in this test."
        )
    if study.edges:
        out.append(
            "Tuned gain sets still on an edge of their grid after the extensions, so possibly "
            "not fully tuned: "
            + ", ".join(f"{kind} ({gain_set})" for kind, gain_set in study.edges)
            + " (their chosen value of some gain lies on the grid's edge: 'interior = false' in "
            "the gains file)."
        )
    ranges = study.attribution_ranges
    for row in ranges.itertuples():
        out.append(
            f"{row.part} (noise {row.noise}, S1–S4, median paired change over the draws where "
            f"both stayed on the path): AE {row.ae_change_min_mm:+.4g} to "
            f"{row.ae_change_max_mm:+.4g} mm, TV {row.tv_change_min_Nm:+.4g} to "
            f"{row.tv_change_max_Nm:+.4g} N·m; diverged in {row.diverged_with} of {row.draws} "
            f"draws with it and in {row.diverged_without} without it"
            + (
                f"; in {', '.join(row.not_compared)} no draw could be compared (in no draw did "
                "both stay on the path)"
                if row.not_compared
                else ""
            )
            + "."
        )
    out.append(
        "The tuning conditions covered delays of "
        + "; ".join(
            f"{_range_text(low, high)} ms ({delay_class} class)"
            for delay_class, (low, high) in study.tuning_envelope.items()
        )
        + ". A verdict whose scenario reaches delays outside its class's range is marked with "
        "both ranges."
    )
    counts = study.verdict_counts
    for noise in counts.noise.unique():
        if noise == "all":
            continue
        for kind, table, describe in (
            ("survival", study.survival_verdicts, _survival_name),
            ("accuracy", study.verdicts, _accuracy_name),
        ):
            count = counts[(counts.kind == kind) & (counts.noise == noise)].iloc[0]
            rows = table[table.noise == noise]
            verdict = rows[f"{kind}_verdict"]
            groups = [
                f"{label.upper()} ({number}): "
                + ("; ".join(describe(r) for r in rows[chosen].itertuples()) or "none")
                for label, number, chosen in (
                    ("holds", count.holds, verdict == "holds"),
                    ("fails", count.fails, verdict == "fails"),
                    ("undecided", count.undecided, verdict == "undecided"),
                    ("no decision", count.no_decision, verdict.str.startswith("no decision")),
                )
            ]
            out.append(
                f"{_KIND_TEXT[kind]}, measurement noise {noise}, {count.verdicts} verdicts. "
                + ". ".join(groups)
                + "."
            )
    return out


#: What each kind of verdict judges, as the findings introduce it.
_KIND_TEXT = {
    "survival": (
        "Staying on the path (holds: A stays on the path in more draws than B; one verdict per "
        "pair compared, which a pair's AE and TV claims share)"
    ),
    "accuracy": (
        "Accuracy where both stayed on the path (holds: A's value is below B's in more of "
        "those draws)"
    ),
}


def _range_text(low: float, high: float) -> str:
    """``low–high`` (one number when they agree to three digits)."""
    low_text, high_text = f"{low:.3g}", f"{high:.3g}"
    return low_text if low_text == high_text else f"{low_text}–{high_text}"


def _delay_ranges(row: Any) -> tuple[str, str]:
    """The delays (ms) of a verdict's scenario and those its tuning conditions covered."""
    return (
        _range_text(row.scenario_delay_min_ms, row.scenario_delay_max_ms),
        _range_text(row.tuning_delay_min_ms, row.tuning_delay_max_ms),
    )


def _outside_text(row: Any) -> str:
    """The delays of a verdict's scenario beside the tuning's, when they leave them."""
    if not row.outside_tuning:
        return ""
    scenario, tuned = _delay_ranges(row)
    return f" [delays {scenario} ms; tuned on {tuned} ms]"


def _no_decision_text(verdict: str) -> str:
    """The reason of a "no decision" verdict, in parentheses, or nothing."""
    return f" ({verdict[len('no decision (') : -1]})" if verdict.startswith("no decision") else ""


def _verdict_name(row: Any, name: str, verdict: str) -> str:
    """A verdict as the findings list it: its name, its scenario, why it was not decided and
    the delays it leaves the tuning's for."""
    where = "" if row.scenario == "S3 -> S4" else f" in {row.scenario}"
    return f"{name}{where}" + _no_decision_text(verdict) + _outside_text(row)


def _survival_name(row: Any) -> str:
    return _verdict_name(row, f"{row.side_a} vs {row.side_b}", row.survival_verdict)


def _accuracy_name(row: Any) -> str:
    return _verdict_name(row, f"{row.controller}: {row.claim}", row.accuracy_verdict)


def _interval_text(value: float, low: float, high: float, scale: float = 1.0) -> str:
    """``value (low to high)`` in the unit ``scale`` times the given one (100: percent), or a
    dash when the value is missing."""
    if not math.isfinite(value):
        return "—"
    if not (math.isfinite(low) and math.isfinite(high)):
        return f"{scale * value:.3g}"
    return f"{scale * value:.3g} ({scale * low:.3g} to {scale * high:.3g})"


def _p_text(p: float, p_holm: float) -> str:
    """``p (Holm-adjusted p)``, or a dash when no test was made."""
    return "—" if not math.isfinite(p) else f"{p:.2g} ({p_holm:.2g})"


def _tuning_text(row: Any) -> str:
    """The delays of a verdict's scenario and of the tuning, when they differ in range."""
    if not row.outside_tuning:
        return "inside"
    scenario, tuned = _delay_ranges(row)
    return f"{scenario} (tuned on {tuned})"


def display_survival(table: pd.DataFrame) -> pd.DataFrame:
    """:func:`~delaytrack.experiments.verdicts.survival_verdicts` for reading: per side the
    share of draws that stayed on the path, the four categories of draws, the p-values and the
    Holm-corrected verdict."""
    rows = list(table.itertuples())
    return pd.DataFrame(
        {
            "scenario": table.scenario,
            "noise": table.noise,
            "A": table.side_a,
            "B": table.side_b,
            "A stayed, % (95 % CI)": [
                _interval_text(r.a_stayed_share, r.a_stayed_ci_low, r.a_stayed_ci_high, 100.0)
                for r in rows
            ],
            "B stayed, % (95 % CI)": [
                _interval_text(r.b_stayed_share, r.b_stayed_ci_low, r.b_stayed_ci_high, 100.0)
                for r in rows
            ],
            "draws: both stayed / only A diverged / only B diverged / both diverged": [
                f"{r.both_stayed} / {r.only_a_diverged} / {r.only_b_diverged} / {r.both_diverged}"
                for r in rows
            ],
            "p (Holm)": [_p_text(r.survival_p, r.survival_p_holm) for r in rows],
            "verdict (A stays on the path more often)": table.survival_verdict,
            "delays, ms, outside the tuning": [_tuning_text(r) for r in rows],
        }
    )


def display_verdicts(verdicts: pd.DataFrame) -> pd.DataFrame:
    """:func:`~delaytrack.experiments.verdicts.claim_verdicts` for reading: per claim its
    survival verdict, and its accuracy over the draws where both stayed on the path (the share
    with A below B, the paired median difference, the p-values and the Holm-corrected
    verdict)."""
    rows = list(verdicts.itertuples())
    return pd.DataFrame(
        {
            "scenario": verdicts.scenario,
            "noise": verdicts.noise,
            "controller": verdicts.controller,
            "claim": verdicts.claim,
            "survival verdict": verdicts.survival_verdict,
            "both stayed / draws": [f"{r.both_stayed} / {r.draws}" for r in rows],
            "A below B, % of those (95 % CI)": [
                _interval_text(r.a_lower_share, r.a_lower_ci_low, r.a_lower_ci_high, 100.0)
                for r in rows
            ],
            "median A − B (95 % CI)": [
                _interval_text(r.median_difference, r.difference_ci_low, r.difference_ci_high)
                + (" N·m" if r.claim.startswith("TV") else " mm")
                if math.isfinite(r.median_difference)
                else "—"
                for r in rows
            ],
            "p (Holm)": [_p_text(r.accuracy_p, r.accuracy_p_holm) for r in rows],
            "accuracy verdict": verdicts.accuracy_verdict,
            "delays, ms, outside the tuning": [_tuning_text(r) for r in rows],
        }
    )


def display_attribution(table: pd.DataFrame) -> pd.DataFrame:
    """:func:`~delaytrack.experiments.verdicts.attribution` for reading: each median change with
    its interval in one column, beside the draws in which each controller diverged."""
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
            "diverged with / without it, of draws": [
                f"{w} / {wo} of {n}"
                for w, wo, n in zip(
                    table.diverged_with, table.diverged_without, table.draws, strict=True
                )
            ],
            "draws compared (both stayed)": table.draws_compared,
        }
    )


def display_knowledge(table: pd.DataFrame) -> pd.DataFrame:
    """:func:`~delaytrack.experiments.robustness.knowledge_table` for reading: shares in %,
    times in s, AE in mm."""

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
    """:func:`~delaytrack.experiments.outcomes.outcome_table` for reading: divergence and
    medians with their intervals; the scale of what a predictor is told as "told / true delay",
    "not told" for a controller told nothing."""
    ae = zip(table.median_ae_mm, table.median_ae_ci_low_mm, table.median_ae_ci_high_mm, strict=True)
    tv = zip(table.median_tv_Nm, table.median_tv_ci_low_Nm, table.median_tv_ci_high_Nm, strict=True)
    columns: dict[str, Any] = {
        _TOLD if key == "scale" else key: _told_text(table[key]) if key == "scale" else table[key]
        for key in by
    }
    columns["diverged / runs"] = [
        f"{k} / {n}" for k, n in zip(table.diverged, table.runs, strict=True)
    ]
    columns["median AE, mm (95 % CI)"] = [_interval_text(*values) for values in ae]
    columns["median TV, N·m (95 % CI)"] = [_interval_text(*values) for values in tv]
    if "median_tv_received_Nm" in table:  # runs on torque-limited wheels
        received = zip(
            table.median_tv_received_Nm,
            table.median_tv_received_ci_low_Nm,
            table.median_tv_received_ci_high_Nm,
            strict=True,
        )
        columns["median TV received, N·m (95 % CI)"] = [
            _interval_text(*values) for values in received
        ]
        columns["wound up / on the path"] = [
            f"{w} / {n - k}"
            for w, n, k in zip(table.wound_up, table.runs, table.diverged, strict=True)
        ]
    return pd.DataFrame(columns)


#: The header of the scale of what a predictor is told.
_TOLD = "told / true delay"


def _told_text(scales: pd.Series) -> list[str]:
    """Each scale of what a predictor is told, or "not told" (NaN: the controller is told
    nothing)."""
    return [f"{scale:.4g}" if math.isfinite(scale) else "not told" for scale in scales]


def robustness_map(study: RobustnessStudy) -> Figure:
    """Per controller: divergence rate (colour) and median AE in mm of the runs that stayed on
    the path (text) against the true constant delay and the scale of what it is told."""
    table = study.map
    figure = Figure(figsize=(12.0, 7.5), layout="constrained")
    axes = figure.subplots(2, 3, sharey=True)
    delays = sorted(table.delay_ms.unique())
    image = None
    for ax, name in zip(axes.ravel(), MAP_CONTROLLERS, strict=True):
        rows = table[table.controller == name]
        told = name in study.predictors
        columns = list(study.scales) if told else [math.nan]
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
    assert image is not None  # MAP_CONTROLLERS is not empty: every panel drew an image
    figure.colorbar(image, ax=axes, label="divergence rate (share of draws)", shrink=0.8)
    figure.suptitle("Robustness map: colour = divergence rate, text = median AE (mm)")
    return figure


def write_verdict_tables(report: HtmlReport, study: RobustnessStudy) -> None:
    """The verdict tables (staying on the path per pair compared, accuracy per claim) with
    their captions, as the study's report and the paper job's report show them."""
    report.table(
        display_survival(study.survival_verdicts),
        "Staying on the path, per pair compared on the same draws (verdicts.csv; the AE and TV "
        "claims of a pair share it): share of draws each side stayed on the path with its "
        "Wilson 95 % interval, the four categories of draws, McNemar's exact p with its "
        "Holm-adjusted value, and the verdict after the correction; the delays the scenario "
        "reaches beside those the tuning covered, when they leave them.",
    )
    report.table(
        display_verdicts(study.verdicts),
        "Accuracy per claim over the draws where both stayed on the path (verdicts.csv): the "
        "share in which A is below B with its Wilson 95 % interval, the paired median "
        "difference with its bootstrap 95 % interval, the sign test's p with its Holm-adjusted "
        "value, and the verdict after the correction.",
    )


def write_robustness(study: RobustnessStudy, out: str | Path) -> list[Path]:
    """Write ``runs.csv`` (every run), ``map.csv``, ``knowledge.csv``, ``claims.csv``,
    ``actuators.csv``, ``verdicts.csv``, ``attribution.csv``, ``knowledge_table.csv``, the map
    figure and ``report.html`` into ``out``; return their paths."""
    out = Path(out)
    files = []
    repeated = repeated_in(study.runs)
    marked = {**study.runs, "map": study.runs["map"].assign(repeated_in=repeated)}
    every = pd.concat(
        [frame.assign(sweep=name) for name, frame in marked.items()], ignore_index=True
    ).fillna({"repeated_in": ""})
    files.append(write_frame(every, out / "runs.csv"))
    tables = ("map", "knowledge", "claims", "actuators", "verdicts", "attribution")
    for name in (*tables, "knowledge_table"):
        files.append(write_frame(getattr(study, name), out / f"{name}.csv"))
    saved = save_figure(robustness_map(study), out / "figures" / "robustness_map")
    files += saved
    image = next(path for path in saved if path.suffix == ".png").read_bytes()
    files.append(_report(study, image, int((repeated != "").sum())).write(out / "report.html"))
    record_outputs(out, files)
    return files


def _report(study: RobustnessStudy, image: bytes, repeats: int) -> HtmlReport:
    """The study's ``report.html``: its method and size (``repeats``: the map's runs its edge
    sweeps ran again), the findings, the map, the verdicts and the tables behind them."""
    report = HtmlReport("delaytrack: robustness study (which controller when the delay is unknown)")
    report.paragraph(_method_text(study))
    report.paragraph(_size_text(study, repeats))
    report.heading("Findings")
    report.bullets(findings(study))
    report.figure(
        image,
        "Robustness map: divergence rate (colour) and median AE in mm of the "
        "runs that stayed on the path (text), per controller, against the true "
        "constant delay and what the predictors are told of it.",
    )
    report.heading("The paper's claims over draws")
    write_verdict_tables(report, study)
    _attribution_section(report, study)
    _knowledge_section(report, study)
    _outcome_sections(report, study)
    _actuator_section(report, study)
    return report


def _method_text(study: RobustnessStudy) -> str:
    """The study's method: the runs, its three parts and how a claim is judged."""
    return _runs_text(study) + _parts_text(study) + _judgement_text(study)


def _runs_text(study: RobustnessStudy) -> str:
    """What the study asks, and what every run is: the paper job's robot run on a drawn robot."""
    base = study.scenario
    viscous = study.friction["plant.viscous_friction"]
    coulomb = study.friction["plant.coulomb_friction"]
    return (
        "The paper's case for AROLC is that it needs no knowledge of the delay, while its "
        "predictor baselines assume they know it. This study asks which controller to use over "
        "distributions of robots rather than one run: every run is the paper job's robot run "
        f"({base.duration:g} s, the consistent circle, dt = {1e3 * base.dt:g} ms, T_c = "
        f"{1e3 * base.T_c:g} ms) with a drawn payload seed and wheel friction drawn uniformly "
        f"from its documented ranges (viscous {viscous['low']:g}–{viscous['high']:g} N·m·s/rad, "
        f"Coulomb {coulomb['low']:g}–{coulomb['high']:g} N·m); draw i is the same robot for "
        "every controller and condition, and each draw has its own noise seed. "
    )


def _parts_text(study: RobustnessStudy) -> str:
    """The study's three parts (map, delay knowledge, claims cases) and when a run diverged."""
    return (
        "Three parts: a robustness map (constant true delays "
        + ", ".join(f"{1e3 * h:g}" for h in study.true_delays)
        + " ms against what the predictors are told, "
        + ", ".join(f"{s:g}" for s in study.scales)
        + " times the delay; gain sets tuned for all delays), the paper's S1 and S2 with wrong "
        "delay estimates (gain sets for time-varying delays), and S1–S4 as in the paper job "
        "(class gain sets), without and with measurement noise (encoder quantisation and white "
        "noise). A run diverged when it stopped or its mean AE exceeded "
        f"{study.diverged_ae_mm:g} mm. "
    )


def _judgement_text(study: RobustnessStudy) -> str:
    """How a claim is judged over the draws: the two kinds of verdict, the tests and Holm's
    correction."""
    return (
        "Each claim 'A below B' is judged twice on the same "
        "draws, and every draw is counted in exactly one of four categories (both stayed on the "
        "path, only A diverged, only B diverged, both diverged). Staying on the path: per side "
        "the share of draws that stayed, with its Wilson 95 % interval, and McNemar's exact "
        "test on the draws where only one side diverged. Accuracy where both stayed on the "
        "path: the share of those draws in which A is below B, with its Wilson 95 % interval, "
        "the sign test, and the paired median difference A − B with its percentile-bootstrap "
        "95 % interval. Every p-value is an exact binomial test against one half; since many "
        "verdicts are tested together, all of them (both kinds, both noise levels) are "
        "corrected as one family with Holm's method: a verdict holds (or fails) when its "
        f"Holm-adjusted p is at most {100 * study.alpha:g} % and A (or B) wins more of the "
        "decided draws, and is undecided otherwise; with fewer than "
        f"{study.min_decided} decided draws no exact test can reach {100 * study.alpha:g} % "
        "and the verdict is 'no decision', with the reason."
    )


def _size_text(study: RobustnessStudy, repeats: int) -> str:
    """The study's size: its runs (``repeats`` of them run again, :func:`repeated_in`), draws
    per case, work units and time."""
    return (
        f"Size: {study.run_count} runs of {study.scenario.duration:g} s"
        + (
            f", {study.run_count - repeats} distinct: the refined cells' edge sweeps ran the "
            f"{repeats} draws of their first pass again (runs.csv marks these in repeated_in) "
            if repeats
            else " "
        )
        + f"({study.size.map} draws per map cell"
        + (
            f"; the {study.refined_cells} cells at a controller's divergence edge again with "
            f"{study.size.map_edge}"
            if study.refined_cells
            else ""
        )
        + f"; {study.size.knowledge} per delay-knowledge case, {study.size.claims} per claims "
        "case); "
        f"{counted(study.computed, 'work unit')} computed and {study.resumed} resumed in "
        f"{study.seconds:.1f} s."
    )


def _attribution_section(report: HtmlReport, study: RobustnessStudy) -> None:
    """The section 'Attribution': the paired changes of the outer loop, Δu and tuning."""
    report.heading("Attribution: outer loop, Δu, tuning")
    report.table(
        display_attribution(study.attribution),
        "Paired change of AE (mm) and TV (N·m) per draw, median with bootstrap 95 % interval.",
    )


def _knowledge_section(report: HtmlReport, study: RobustnessStudy) -> None:
    """The section on what the predictors tolerate of a wrong delay, case by case."""
    report.heading("What the predictors tolerate of a wrong delay")
    report.table(
        display_knowledge(study.knowledge_table),
        "Case by case (knowledge_table.csv): divergence rate, median time of leaving the path of "
        "the runs that did, and median AE (mm) of those that did not, beside AROLC's.",
    )


def _outcome_sections(report: HtmlReport, study: RobustnessStudy) -> None:
    """The outcome tables of the map, the delay-knowledge cases and the claims cases, each
    folded."""
    _outcome_section(
        report,
        "Robustness map (table)",
        "Per true delay, controller and what it is told",
        display_outcomes(study.map, ["delay_ms", "controller", "scale"]),
        "Per true delay (ms), controller and the delay it is told as a multiple of the true "
        "one: divergence and medians (map.csv).",
    )
    _outcome_section(
        report,
        "Delay knowledge under S1 and S2",
        "Per scenario, predictor and what it is told",
        display_outcomes(study.knowledge, ["scenario", "controller", "scale"]),
        "Predictors told s·h(t) (PCON, PCON-wheel) or s times the profile's long-run mean (PCONf).",
    )
    _outcome_section(
        report,
        "S1–S4 per controller and noise level",
        "Per scenario, noise level and controller",
        display_outcomes(study.claims, ["scenario", "noise", "controller"]),
        "Outcomes per scenario, noise level and controller (claims.csv).",
    )


def _outcome_section(
    report: HtmlReport, heading: str, summary: str, table: pd.DataFrame, caption: str
) -> None:
    """A section of one outcome table, folded away under ``summary``."""
    report.heading(heading)
    with report.folded(summary):
        report.table(table, caption)


def _actuator_section(report: HtmlReport, study: RobustnessStudy) -> None:
    """The section on the claims cases again with torque-limited wheels."""
    report.heading("S1–S4 on the P3-DX's wheels: torque-limited actuators")
    report.paragraph(
        "The claims cases again, every wheel's torque clipped to "
        f"±{study.wheel_torque_limit:g} N·m where the wheels receive it (the P3-DX motor's peak "
        "torque through its gearbox, derived in the documentation's robot page, where its "
        "uncertainty is given). The verdicts above are those of unlimited actuators; here, "
        "beside each controller's TV of what it commanded, is the TV of what the wheels "
        f"received. A run wound up when its commanded TV exceeds {study.wound_up:g} times "
        "the TV its wheels received: its commands ran away while the limit held the wheels, a "
        "controller that a real drive would fault or a watchdog would stop, although the robot "
        "stayed on the path."
    )
    report.table(
        display_outcomes(study.actuators, ["scenario", "noise", "controller"]),
        "Outcomes on torque-limited wheels per scenario, noise level and controller "
        "(actuators.csv).",
    )
