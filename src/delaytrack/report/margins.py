"""The margins job's report: the settings, the table, the figure and what the gap between the
margins means, made from a :class:`~delaytrack.experiments.margins.MarginStudy` that already
holds every number quoted here (this module computes none), and :func:`write_study`, which
writes the job's files."""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import TYPE_CHECKING

import pandas as pd
from matplotlib.figure import Figure

from delaytrack._io import write_frame
from delaytrack._output import claim_output_folder, record_outputs
from delaytrack._version import __version__
from delaytrack._words import table_text
from delaytrack.experiments.empirical_margin import resolved_text, resolved_texts
from delaytrack.report.figures import margins_figure, save_figure
from delaytrack.report.html import HtmlReport

if TYPE_CHECKING:
    from delaytrack.experiments.margins import MarginStudy

__all__ = ["margins_with_units", "terminal_text", "write_study"]

#: The margins' columns and their labels.
_LABELS = {
    "h_m": "certified h_m (Theorem 1)",
    "h_exact": "exact h_exact (constant delay, nominal)",
    "arolc_constant": "AROLC, empirical, constant h",
    "arolc_abs_sine": "AROLC, empirical, a |sin t|",
    "outer_loop_constant": "outer loop, empirical, constant h",
    "outer_loop_abs_sine": "outer loop, empirical, a |sin t|",
}
#: The empirical margins' columns (a search's result, shown to its resolution).
_EMPIRICAL = tuple(column for column in _LABELS if column not in ("h_m", "h_exact"))
#: The gains' columns in the files, with their units (``e'' + K2 e' + K1 e = 0``).
_GAIN_COLUMNS = {"k1": "k1_per_s2", "k2": "k2_per_s"}


def margins_with_units(table: pd.DataFrame) -> pd.DataFrame:
    """The study's ``table`` with its units in the column names, as ``margins.csv`` holds it:
    ``k1_per_s2``, ``k2_per_s`` and each margin in seconds (``h_m_s``, ...)."""
    delays = {column: f"{column}_s" for column in _LABELS}
    return table.rename(columns={**_GAIN_COLUMNS, **delays})


def _resolved(study: MarginStudy) -> pd.DataFrame:
    """:func:`margins_with_units` with the empirical margins as text to the decimals of the
    search's resolution, rounded down (as ``delaytrack empirical`` shows them: never above the
    value that passed), None where no failure was found."""
    resolution = study.search["resolution"]
    empirical = {column: resolved_texts(study.table[column], resolution) for column in _EMPIRICAL}
    return margins_with_units(study.table.assign(**empirical))


def terminal_text(study: MarginStudy) -> str:
    """The table of :func:`_resolved` for a terminal, below a legend of what its columns
    hold."""
    shown = _resolved(study)
    named = dict(zip(study.table.columns, shown.columns, strict=True))
    margins = "; ".join(f"{named[column]}: {label}" for column, label in _LABELS.items())
    legend = (
        f"K1 = k1 I, K2 = k2 I; margins in s: {margins}; the last two columns are ratios; "
        f"—: no failure found up to {study.search['upper']:g} s (the margin is at least that, "
        "and no ratio to it is given)"
    )
    return "\n".join([*textwrap.wrap(legend, 100), table_text(shown)])


def write_study(study: MarginStudy, folder: str | Path) -> list[Path]:
    """Write the job's files into ``folder`` (see :mod:`delaytrack.experiments.margins`);
    return their paths."""
    folder = claim_output_folder(folder)
    table = study.table
    files = [write_frame(margins_with_units(table), folder / "margins.csv")]
    evaluated = study.evaluated
    metrics = {column: f"{column}_rad" for column in evaluated if column.startswith("metric")}
    evaluated = evaluated.rename(columns={**_GAIN_COLUMNS, "value": "delay_s", **metrics})
    files.append(write_frame(evaluated, folder / "evaluated.csv"))
    study.scenario.to_toml(folder / "scenario.toml")
    files.append(folder / "scenario.toml")
    labels = [f"k1 = {k1:g}, k2 = {k2:g}" for k1, k2 in table[["k1", "k2"]].to_numpy()]
    figure = margins_figure(
        {label: table[column].to_numpy() for column, label in _LABELS.items()},
        labels,
        xlabel="outer-loop gains K1 = k1 I (k1 in 1/s²), K2 = k2 I (k2 in 1/s)",
        title="Delay margins of K1 = k1 I, K2 = k2 I on the two-link arm",
        at_least={_LABELS[column]: study.search["upper"] for column in _EMPIRICAL},
    )
    files += save_figure(figure, folder / "figures" / "margins")
    files.append(_report(study, figure).write(folder / "report.html"))
    record_outputs(folder, files)
    return files


def _report(study: MarginStudy, figure: Figure) -> HtmlReport:
    report = HtmlReport("Certified, exact and empirical delay margins")
    report.paragraph(
        "How conservative is Theorem 1? For each gain pair K1 = k1 I, K2 = k2 I this page "
        "compares three delay margins: the certified h_m (every time-varying delay below it, "
        "with uncertainty), the exact margin h_exact of the nominal error dynamics under a "
        "constant delay, and the empirical margin: the largest delay at which the simulated "
        "closed loop (true arm, 20 % light nominal model) still tracks."
    )
    search, scenario = study.search, study.scenario
    start, end = study.window
    report.settings(
        {
            "scenario": f"{scenario.name} ({scenario.duration:g} s, dt = "
            f"{scenario.dt:g} s, T_c = {scenario.T_c:g} s)",
            "tracking rule": f"status ok and max over joints of mean |e1| ≤ "
            f"{search['threshold']:g} rad over [{start:g}, {end:g}] s",
            "delay families": "constant h; h(t) = a |sin(t)| (the margin is the amplitude a)",
            "search": f"coarse grid of {search['grid'] + 1} values over [0, {search['upper']:g}] "
            f"s, then multi-section ({search['points']} values a round) to a bracket of "
            f"{search['resolution']:g} s",
            "certificate": f"Theorem 1 with Q = I, β = {study.beta:g}, r = {study.r:g}",
            "gains": f"k1, k2 in {list(study.gain_values)}; AROLC α = "
            f"{scenario.controller['alpha']:g}, ε = {scenario.controller['epsilon']:g}, "
            f"γ = {scenario.controller['gamma']:g}",
            "version": f"delaytrack {__version__}; wall time {study.seconds:.1f} s",
        }
    )
    report.table(
        _resolved(study),
        caption="Margins in seconds, the empirical ones rounded down to the decimals of the "
        f"search's resolution ({search['resolution']:g} s; margins.csv has them in full); —: "
        f"no failure up to the search limit (the margin is at least {search['upper']:g} s, "
        "and no ratio to it is given). The columns as margins.csv holds them.",
    )
    report.figure(figure, "Margins per gain pair, log scale.")
    gap = study.gap
    report.heading("What the gap means")
    report.bullets(
        [
            f"h_m is {gap.certified_over_exact[0]:.3g} to {gap.certified_over_exact[1]:.3g} of "
            f"h_exact and {gap.certified_over_arolc[0]:.3g} to "
            f"{gap.certified_over_arolc[1]:.3g} of AROLC's empirical constant-delay margin: on "
            f"this arm the certificate is conservative by a factor {gap.conservatism[0]:.3g} to "
            f"{gap.conservatism[1]:.3g}.",
            f"h_m is sufficient only, so every delay below it must pass: in "
            f"{gap.above_certified} of {gap.pairs} gain pairs both empirical AROLC margins lie "
            "above h_m. Nothing follows from a delay above h_m.",
            f"The outer loop's empirical constant-delay margin is within {study.close_percent:g} "
            f"% of h_exact in {gap.close_to_exact} of {gap.pairs} gain pairs (nominal dynamics "
            f"up to the model error and the arm's nonlinearity); higher in {gap.above_exact}"
            + (
                f"; no failure up to the search limit in {gap.outer_unbounded}"
                if gap.outer_unbounded
                else ""
            )
            + f". It is lower in {gap.below_exact}; there the first failing run ended without "
            "divergence in "
            f"{gap.ended_on_path}"
            + (
                f", with mean |e1| = {gap.largest_ended_error:.3g} rad at most"
                if gap.ended_on_path
                else ""
            )
            + ": there the tracking rule, not a divergence, sets the margin.",
            f"AROLC's empirical constant-delay margin stays within "
            f"{resolved_text(gap.arolc_constant[0], search['resolution'])}–"
            f"{resolved_text(gap.arolc_constant[1], search['resolution'])} s while h_exact spans "
            f"{gap.h_exact[0]:.3g}–{gap.h_exact[1]:.3g} s: its switching term changes the loop "
            "that h_exact describes, in either direction.",
            "Empirical margins hold for this scenario, horizon and rule only: an instability "
            "that grows too slowly to show in the scored window passes.",
        ]
    )
    return report
