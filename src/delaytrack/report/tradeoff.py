"""The trade-off's report: ``tradeoff.csv`` (units in the column names), ``runs.csv``,
``evaluated.csv``, the Pareto front as a figure and ``report.html``, made from a
:class:`~delaytrack.experiments.tradeoff.TradeoffStudy` that already holds every number shown
(this module computes none); with a :class:`~delaytrack.experiments.decision.Decision`, also
``decision.csv``, ``decision-runs.csv`` and the decision's section of the page."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from matplotlib.figure import Figure

from delaytrack._io import write_frame
from delaytrack._output import claim_output_folder, record_outputs
from delaytrack._version import __version__
from delaytrack.experiments.drawn_robots import drawn_columns
from delaytrack.experiments.empirical_margin import resolved_texts
from delaytrack.experiments.tradeoff import LOWER_BOUND, MARGIN_SEARCHES
from delaytrack.report.decision import (
    ae_text,
    candidates_table,
    conditions_text,
    decision_columns,
    decision_table,
    edge_text,
    gains_text,
    ratio_text,
    refusal_text,
)
from delaytrack.report.figures import save_figure
from delaytrack.report.html import HtmlReport
from delaytrack.units import coordinate_units, labelled, value_with_unit, with_unit

if TYPE_CHECKING:
    import pandas as pd

    from delaytrack.experiments.decision import Choice, Decision
    from delaytrack.experiments.tradeoff import TradeoffStudy

__all__ = ["decision_lines", "pareto_figure", "threshold_text", "write_tradeoff"]

#: The families as the report names them.
_NAMES = {
    "arolc": "AROLC",
    "outer-loop": "outer loop (AROLC without Δu)",
    "pcon": "PCON (told the true delay)",
    "pconf": "PCONf (told h̄)",
}


def _shown(study: TradeoffStudy, frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` (the study's table or its front) as the page shows it: its columns with their
    units, the empirical margin rounded down to the decimals of the search's resolution (as
    ``delaytrack empirical`` shows it; tradeoff.csv has it in full), None where there is none."""
    margins = resolved_texts(frame.empirical_margin, study.resolution)
    return frame.assign(empirical_margin=margins).rename(columns=_columns(study))


def _columns(study: TradeoffStudy) -> dict[str, str]:
    """The table's columns with their units (``e'' + K2 e' + K1 e = 0``)."""
    return {
        "omega_n": "omega_n_rad_per_s",
        "k1": "k1_per_s2",
        "k2": "k2_per_s",
        "h_m": "h_m_s",
        "h_exact": "h_exact_s",
        "empirical_margin": "empirical_margin_s",
        "ae_median": with_unit("ae_median", study.ae_unit),
        "tv_median": with_unit("tv_median", study.tv_unit),
    }


def threshold_text(study: TradeoffStudy) -> str:
    """The rule's bound on each scored coordinate's mean ``|e1|``, in its unit: ``x <= 1 m,
    y <= 1 m``."""
    units = coordinate_units(study.scenario.build().plant)
    return ", ".join(
        value_with_unit(f"{name} <= {bound:g}", units.get(name))
        for name, bound in study.threshold.items()
    )


def pareto_figure(study: TradeoffStudy) -> Figure:
    """Median AE against the empirical constant-delay margin, one marker per point and family
    labelled with its ω_n (an open triangle where the margin is only a lower bound: no failure
    up to the search limit), the Pareto front joined by a line; a family with no margin to
    place is named in the legend with the reason. The AE axis is logarithmic where the AEs
    span more than a decade."""
    figure = Figure(figsize=(7.5, 4.5), dpi=120, layout="constrained")
    ax = figure.add_subplot()
    table = study.table
    for family in study.families:
        rows = table[table.controller == family]
        exact = rows[rows.margin_found]
        bounded = rows[rows.margin_search == LOWER_BOUND]
        if exact.empty and bounded.empty:  # PCONf: not searched; or missed at zero delay
            reasons = "; ".join(MARGIN_SEARCHES[key] for key in dict.fromkeys(rows.margin_search))
            ax.plot([], [], " ", label=f"{_NAMES[family]}: not shown, {reasons or 'no runs'}")
            continue
        (marker,) = ax.plot(exact.empirical_margin, exact.ae_median, "o", alpha=0.8)
        ax.plot(
            bounded.empirical_margin, bounded.ae_median, ">", mfc="none", alpha=0.8,
            color=marker.get_color(),
        )  # fmt: skip
        marker.set_label(_NAMES[family])
        for row in (*exact.itertuples(), *bounded.itertuples()):
            ax.annotate(
                f"{row.omega_n:.4g}",
                (row.empirical_margin, row.ae_median),
                xytext=(3, 3),
                textcoords="offset points",
                fontsize="x-small",
                color=marker.get_color(),
            )
    if (table.margin_search == LOWER_BOUND).any():
        ax.plot([], [], ">", mfc="none", color="grey", label="no failure up to the search limit")
    if ax.texts:
        ax.plot([], [], " ", label="numbers: ω_n (rad/s)")
    front = study.front
    ax.plot(front.empirical_margin, front.ae_median, "k--", lw=1, label="Pareto front")
    placed = table.ae_median[table.margin_found | (table.margin_search == LOWER_BOUND)]
    if placed.max() > 10 * placed.min() > 0:
        ax.set_yscale("log")
    ax.set_xlabel("empirical delay margin, constant delay (s)")
    ax.set_ylabel(labelled("median AE of the runs on the path", study.ae_unit))
    ax.set_title(f"{study.scenario.name}: K1 = ω_n² I, K2 = 2ζω_n I, ζ = {study.zeta:g}")
    ax.grid(which="both", alpha=0.3)
    ax.legend(fontsize="small")
    return figure


def _choice_text(choice: Choice, decision: Decision) -> str:
    return (
        f"{_NAMES[choice.controller]} at omega_n = {choice.omega_n:.4g} rad/s "
        f"({gains_text(choice)}){edge_text(choice)}: worst-case AE "
        f"{ae_text(decision, choice.worst_ae, 4)}, worst Wilson lower bound "
        f"{choice.worst_share_low:.3f}"
    )


def decision_lines(decision: Decision) -> list[str]:
    """The decision in a few lines of text: the envelope and rule, then the winner, the
    runner-up and the margin, or why no candidate was chosen."""
    lines = [
        f"decision for {decision.envelope.text}: smallest worst-case AE among the candidates on "
        f"the path in >= {100 * decision.required_share:g} % of {decision.draws} drawn robots "
        "by the Wilson lower bound, in every condition"
    ]
    if decision.winner is None:
        return [*lines, f"  {refusal_text(decision)}"]
    lines.append(f"  winner: {_choice_text(decision.winner, decision)}")
    if decision.runner_up is None:
        lines.append("  runner-up: none (no other controller qualifies)")
    else:
        lines.append(f"  runner-up: {_choice_text(decision.runner_up, decision)}")
        lines.append(
            f"  wins by {ae_text(decision, decision.ae_difference, 4)} of worst-case AE"
            + ratio_text(decision, " (the runner-up's is {:.3g} times the winner's)")
        )
    return lines


def write_tradeoff(
    study: TradeoffStudy, folder: str | Path, decision: Decision | None = None
) -> list[Path]:
    """Write the study's files (and the decision's, when given) into ``folder``; return their
    paths."""
    folder = claim_output_folder(folder)
    columns = _columns(study)
    files = [write_frame(study.table.rename(columns=columns), folder / "tradeoff.csv")]
    drawn_names = drawn_columns(study.scenario)
    runs = study.runs.rename(
        columns={
            **drawn_names,
            "omega_n": columns["omega_n"],
            "ae": with_unit("ae", study.ae_unit),
            "tv": with_unit("tv", study.tv_unit),
        }
    )
    files.append(write_frame(runs, folder / "runs.csv"))
    evaluated = study.evaluated.rename(columns={"omega_n": columns["omega_n"], "value": "delay_s"})
    files.append(write_frame(evaluated, folder / "evaluated.csv"))
    if decision is not None:
        named = decision_columns(decision.ae_unit)
        files.append(
            write_frame(decision_table(decision).rename(columns=named), folder / "decision.csv")
        )
        drawn = decision.runs.rename(
            columns={
                **drawn_names,
                **named,
                "ae": with_unit("ae", study.ae_unit),
                "tv": with_unit("tv", study.tv_unit),
            }
        )
        files.append(write_frame(drawn, folder / "decision-runs.csv"))
    study.scenario.to_toml(folder / "scenario.toml")
    files.append(folder / "scenario.toml")
    figure = pareto_figure(study)
    files += save_figure(figure, folder / "figures" / "pareto")
    files.append(_report(study, figure, decision).write(folder / "report.html"))
    record_outputs(folder, files)
    return files


def _decision_section(report: HtmlReport, decision: Decision) -> None:
    report.heading("Decision for a delay envelope")
    conditions = conditions_text(decision.envelope, "predictor")
    report.settings(
        {
            "envelope": decision.envelope.text,
            "conditions": f"{conditions} (constant true delays; AROLC and the outer loop are "
            "told nothing; under a constant delay h, PCON told a delay (s h, s the told "
            "ratio) is PCONf's law told h̄ = s h, run as PCONf)",
            "rule": "smallest worst-case AE (the largest over the conditions of the median AE "
            "of the runs on the path) among the candidates whose share of drawn robots on the "
            f"path has a Wilson 95 % lower bound >= {decision.required_share:g} in every "
            "condition; the runner-up is the best qualifying candidate of another controller",
            "draws": f"{decision.draws} per candidate and condition; the lower bound can reach "
            f"{decision.required_share:g} only from {decision.draws_needed} draws on",
            "not candidates": "; ".join(f"{f}: {why}" for f, why in decision.excluded.items())
            or "none",
        }
    )
    report.bullets(line.strip() for line in decision_lines(decision)[1:])
    report.table(
        candidates_table(decision).rename(columns=decision_columns(decision.ae_unit)),
        caption="One row per candidate, best first: its worst (smallest) Wilson lower bound "
        "over the conditions, worst-case AE, and why it was not chosen.",
    )
    # Each candidate's worst values and why it was not chosen are in the table above: here only
    # what differs from condition to condition (decision.csv has both).
    keys = ("controller", "omega_n", "k1", "k2", "status")
    repeated = [c for c in decision.candidates.columns if c not in keys and c in decision.table]
    report.table(
        decision.table.drop(columns=repeated).rename(columns=decision_columns(decision.ae_unit)),
        caption="One row per candidate and condition (decision.csv, which also repeats each "
        "candidate's row above): robots on the path of those drawn, share with its Wilson 95 % "
        "interval, median AE of the runs on the path; told_s —: told no delay (AROLC and the "
        "outer loop).",
    )


def _report(study: TradeoffStudy, figure: Figure, decision: Decision | None) -> HtmlReport:
    report = HtmlReport(f"Accuracy against delay margin: {study.scenario.name}")
    report.paragraph(
        "Raising the outer-loop gains buys accuracy and costs delay margin. This page sweeps "
        "the gains along one family, K1 = ω_n² I, K2 = 2ζω_n I (the delay-free error dynamics "
        "ë1 = −K2 ė1 − K1 e1 of the paper with natural frequency ω_n and damping ζ), and for "
        "each point and controller reports Theorem 1's certified bound h_m (AROLC), the exact "
        "constant-delay margin h_exact of the linear outer loop, the empirical margin of the "
        "simulated closed loop, and, at the scenario's own delay, the share of drawn robots "
        "that stay on the path with median AE and TV."
    )
    scenario = study.scenario
    scored = threshold_text(study)
    drawn = (
        ", ".join(study.random) + f"; {study.draws} draws, seed {study.seed}"
        if study.random
        else "nothing: the scenario has no uncertain parameter to draw, so each point is one run "
        "and each share is 0 or 1 of 1"
    )
    report.settings(
        {
            "scenario": f"{scenario.name} ({scenario.duration:g} s, dt = {scenario.dt:g} s, "
            f"T_c = {scenario.T_c:g} s, delay {scenario.delay['type']})",
            "gain family": f"ζ = {study.zeta:g}; ω_n in "
            + ", ".join(f"{w:.4g}" for w in study.omegas)
            + " rad/s",
            "controllers": "; ".join(_NAMES[f] for f in study.families)
            + "".join(f"; {f} left out: {why}" for f, why in study.left_out.items()),
            "predictor gains": "κ = ω_n/(2ζ), k_b = 2ζω_n M̂(q0): the same delay-free nominal loop",
            "on the path": f"run ok and mean |e1| over the whole run: {scored}",
            "AE": f"mean over {', '.join(study.threshold)} of mean |e1|",
            "drawn": drawn,
            "empirical margin": f"constant delay, up to {study.upper:g} s, bracket "
            f"{study.resolution:g} s, same rule; not for PCONf (its window is fixed at h̄; told "
            "a constant delay exactly it is PCON's law)",
            "certificate": f"Theorem 1 with the AROLC controller's Q, β = {study.beta:g}, "
            f"r = {study.r:g}",
            "version": f"delaytrack {__version__}; wall time {study.seconds:.1f} s; work units "
            f"of the draws: {study.computed} computed, {study.resumed} resumed from an earlier "
            "run",
        }
    )
    # tradeoff.csv in two tables (a point's margins, then its runs at the scenario's delay),
    # each narrow enough to read without scrolling sideways
    table = _shown(study, study.table)
    point = ["omega_n_rad_per_s", "k1_per_s2", "k2_per_s", "controller"]
    margins = ["h_m_s", "h_exact_s", "empirical_margin_s", "margin_search"]
    report.table(
        table[point + margins],
        caption="tradeoff.csv (1 of 2), one row per point and controller: the margins (s; —: "
        "not defined, h_m being AROLC's and PCONf not searched; the empirical one rounded down "
        "to the decimals of the search's resolution, in full in the file). margin_search says "
        "what the "
        "empirical margin is: "
        + "; ".join(f"{key}: {meaning}" for key, meaning in MARGIN_SEARCHES.items())
        + ".",
    )
    runs = [c for c in table.columns if c not in (*point, *margins, "margin_found")]
    report.table(
        table[[point[0], point[3], *runs]],
        caption="tradeoff.csv (2 of 2), one row per point and controller: its drawn robots at "
        "the scenario's delay. Runs off the path by reason: stopped (diverged or beyond the "
        "scenario's error_bound) and over_threshold (ended ok, mean |e1| above the threshold). "
        "share_low/high: Wilson 95 % interval; —: no run on the path to take a median of.",
    )
    report.figure(
        figure,
        "Median AE against the empirical margin; the dashed line joins the "
        "Pareto front (no other point is known to be both more accurate and more "
        "delay-tolerant; a margin at the search limit is a lower bound, so such a point is on "
        "the front).",
    )
    report.heading("Pareto front")
    front = _shown(study, study.front)
    shown = [*point, "empirical_margin_s", "margin_search", "share_on_path", "share_low"]
    report.table(
        front[shown + [_columns(study)["ae_median"], _columns(study)["tv_median"]]],
        caption="The points on the front (their other columns in the tables above).",
    )
    report.paragraph(
        "Empirical margins hold for this scenario, horizon and rule only; a margin at the search "
        "limit is a lower bound. h_m is sufficient only; h_exact covers the nominal linear loop "
        "under a constant delay.",
        note=True,
    )
    if decision is not None:
        _decision_section(report, decision)
    return report
