"""The margins job: certified vs exact vs empirical delay margins over a grid of gains.

``delaytrack reproduce --job margins`` runs :func:`reproduce`, which writes ``<out>/margins/``:

- ``margins.csv``: one row per gain pair ``K1 = k1 I``, ``K2 = k2 I`` (:data:`GAINS`; columns
  ``k1_per_s2``, ``k2_per_s``): Theorem 1's certified ``h_m`` (AROLC with ``Q = I``, ``β = 1``,
  ``r = 1.1``), the exact constant-delay margin ``h_exact`` of the nominal error dynamics, and
  the empirical margins of AROLC and of the plain outer loop under a constant delay ``h`` and
  under ``h(t) = a |sin t|`` (the largest delay ``a``), in seconds (columns ending ``_s``), with
  ``h_m / h_exact`` and ``h_m`` over AROLC's empirical constant-delay margin;
- ``evaluated.csv``: every simulated (gains, controller, profile, delay ``delay_s``, the tracking
  metric of each joint in radians, status);
- ``figures/margins.png|svg``: the margins of each gain pair side by side, log scale;
- ``scenario.toml``: the scenario (two_link_margins) with the paper's gains;
- ``report.html``: settings, the table, the figure and what the gap means.

The empirical margins come from :func:`~delaytrack.experiments.empirical_margin.empirical_margin`
on the shipped scenario ``two_link_margins`` (true arm without friction, nominal model 20 %
light), with the tracking rule ``max_j mean |e1_j| <= 0.1 rad`` over the last 15 of 30 s. All
gain pairs of one controller and profile are searched in lockstep (one batched simulation per
round).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from delaytrack._io import write_frame
from delaytrack._output import (
    check_output_folder,
    check_results_root,
    claim_output_folder,
    record_outputs,
)
from delaytrack._validation import ArgumentError
from delaytrack._version import __version__
from delaytrack.analysis import exact_delay_margin, razumikhin_bound
from delaytrack.experiments.empirical_margin import EmpiricalMargin, empirical_margin
from delaytrack.experiments.scenario import Scenario, load_builtin
from delaytrack.report import HtmlReport, margins_figure, save_figure

__all__ = ["GAINS", "MarginStudy", "reproduce", "run_study", "write_study"]

FOLDER = "margins"
SCENARIO = "two_link_margins"
#: Values of k1 and of k2 (K1 = k1 I, K2 = k2 I); every pair is run.
GAINS = (0.5, 1.0, 2.0)
#: Search settings of every empirical margin.
SEARCH = {"threshold": 0.2, "metric": "ae", "resolution": 0.005, "upper": 2.0, "frequency": 1.0}
#: Razumikhin parameters of the certified bound (the paper's).
BETA, R = 1.0, 1.1
#: Controllers (scenario type -> column prefix) and delay families searched.
CONTROLLERS = {"arolc": "arolc", "outer-loop": "outer_loop"}
PROFILES = ("constant", "abs-sine")


@dataclass(frozen=True)
class MarginStudy:
    """What the job computed: the table, every search, the scenario and the wall time."""

    table: pd.DataFrame
    searches: dict[tuple[str, str], list[EmpiricalMargin]]
    scenario: Scenario
    seconds: float


def _column(controller: str, profile: str) -> str:
    return f"{CONTROLLERS[controller]}_{profile.replace('-', '_')}"


def run_study(*, duration: float | None = None, progress: bool = False) -> MarginStudy:
    """Compute every margin of every gain pair.

    ``duration`` overrides 30 s (for smoke tests); it must be at least twice the largest searched
    delay (4 s), else the search would see no effect of the delay and its margins would mean
    nothing.
    """
    start = time.perf_counter()
    scenario = load_builtin(SCENARIO)
    if duration is not None:
        shortest = 2.0 * SEARCH["upper"]
        if not duration >= shortest:
            raise ArgumentError(
                "duration",
                f"must be at least {shortest:g} s for the margins job, twice its largest "
                f"searched delay ({SEARCH['upper']:g} s), so that the metric window "
                f"[duration/2, duration] begins after the longest delay has passed; got "
                f"{duration:g}",
            )
        scenario = scenario.replace(duration=duration)
    pairs = [(k1, k2) for k1 in GAINS for k2 in GAINS]
    rows = []
    for k1, k2 in pairs:
        K1, K2 = k1 * np.eye(2), k2 * np.eye(2)
        h_m = razumikhin_bound(K1, K2, np.eye(4), BETA, R, n=2).h_m
        rows.append({"k1": k1, "k2": k2, "h_m": h_m, "h_exact": exact_delay_margin(K1, K2).h})
    searches = {}
    for controller in CONTROLLERS:
        base = scenario.controller if controller == "arolc" else {"type": controller}
        built = [
            scenario.replace(controller={**base, "K1": k1, "K2": k2}).build().controller
            for k1, k2 in pairs
        ]
        for profile in PROFILES:
            found = empirical_margin(scenario, built, profile=profile, progress=progress, **SEARCH)
            searches[controller, profile] = found
            for row, result in zip(rows, found, strict=True):
                row[_column(controller, profile)] = (
                    result.margin if result.failure_found else np.nan
                )
    table = pd.DataFrame(rows)
    table["h_m_over_h_exact"] = table["h_m"] / table["h_exact"]
    table["h_m_over_arolc_constant"] = table["h_m"] / table["arolc_constant"]
    return MarginStudy(table, searches, scenario, time.perf_counter() - start)


def _evaluated(study: MarginStudy) -> pd.DataFrame:
    frames = []
    for (controller, profile), results in study.searches.items():
        for (k1, k2), result in zip(study.table[["k1", "k2"]].to_numpy(), results, strict=True):
            frame = result.to_frame()
            for position, (name, value) in enumerate(
                {"k1": k1, "k2": k2, "controller": controller, "profile": profile}.items()
            ):
                frame.insert(position, name, value)
            frames.append(frame)
    return pd.concat(frames, ignore_index=True)


_LABELS = {
    "h_m": "certified h_m (Theorem 1)",
    "h_exact": "exact h_exact (constant delay, nominal)",
    "arolc_constant": "AROLC, empirical, constant h",
    "arolc_abs_sine": "AROLC, empirical, a |sin t|",
    "outer_loop_constant": "outer loop, empirical, constant h",
    "outer_loop_abs_sine": "outer loop, empirical, a |sin t|",
}


#: The gains' columns in the files, with their units (``e'' + K2 e' + K1 e = 0``).
_GAIN_COLUMNS = {"k1": "k1_per_s2", "k2": "k2_per_s"}


def write_study(study: MarginStudy, folder: str | Path) -> list[Path]:
    """Write the job's files into ``folder``; return their paths."""
    folder = claim_output_folder(folder)
    table = study.table
    delays = {column: f"{column}_s" for column in _LABELS}
    files = [write_frame(table.rename(columns={**_GAIN_COLUMNS, **delays}), folder / "margins.csv")]
    evaluated = _evaluated(study)
    metrics = {column: f"{column}_rad" for column in evaluated if column.startswith("metric")}
    evaluated = evaluated.rename(columns={**_GAIN_COLUMNS, "value": "delay_s", **metrics})
    files.append(write_frame(evaluated, folder / "evaluated.csv"))
    study.scenario.to_toml(folder / "scenario.toml")
    files.append(folder / "scenario.toml")
    labels = [f"k1={k1:g}, k2={k2:g}" for k1, k2 in table[["k1", "k2"]].to_numpy()]
    figure = margins_figure(
        {label: table[column].to_numpy() for column, label in _LABELS.items()},
        labels,
        title="Delay margins of K1 = k1 I, K2 = k2 I on the two-link arm",
    )
    files += save_figure(figure, folder / "figures" / "margins")
    files.append(_report(study, figure).write(folder / "report.html"))
    record_outputs(folder, files)
    return files


def _report(study: MarginStudy, figure) -> HtmlReport:
    table = study.table
    report = HtmlReport("Certified, exact and empirical delay margins")
    report.paragraph(
        "How conservative is Theorem 1? For each gain pair K1 = k1 I, K2 = k2 I this page "
        "compares three delay margins: the certified h_m (every time-varying delay below it, "
        "with uncertainty), the exact margin h_exact of the nominal error dynamics under a "
        "constant delay, and the empirical margin: the largest delay at which the simulated "
        "closed loop (true arm, 20 % light nominal model) still tracks."
    )
    search = SEARCH
    report.settings(
        {
            "scenario": f"{study.scenario.name} ({study.scenario.duration:g} s, dt = "
            f"{study.scenario.dt:g} s, T_c = {study.scenario.T_c:g} s)",
            "tracking rule": f"status ok and max over joints of mean |e1| <= "
            f"{search['threshold']:g} rad over [{study.scenario.duration / 2:g}, "
            f"{study.scenario.duration:g}] s",
            "delay families": "constant h; h(t) = a |sin(t)| (the margin is the amplitude a)",
            "search": f"coarse grid of 17 values over [0, {search['upper']:g}] s, then "
            f"multi-section (4 values a round) to a bracket of {search['resolution']:g} s",
            "certificate": f"Theorem 1 with Q = I, beta = {BETA:g}, r = {R:g}",
            "gains": f"k1, k2 in {list(GAINS)}; AROLC alpha = 2, epsilon = 0.1, gamma = 0.001",
            "version": f"delaytrack {__version__}; wall time {study.seconds:.1f} s",
        }
    )
    report.table(table, caption="Margins in seconds (NaN: no failure up to the upper limit).")
    report.figure(figure, "Margins per gain pair, log scale.")
    ratio, exact_ratio = table["h_m_over_arolc_constant"], table["h_m_over_h_exact"]
    below = (table["h_m"] < table[["arolc_constant", "arolc_abs_sine"]].min(axis=1)).sum()
    outer = table["outer_loop_constant"] / table["h_exact"] - 1.0
    close = (outer.abs() <= 0.15).sum()
    lower = [
        result
        for result, below_exact in zip(
            study.searches["outer-loop", "constant"], outer < -0.15, strict=True
        )
        if below_exact
    ]
    ended_ok = [r.metric_values[r.values == r.first_failure][0] for r in lower]
    ended_ok = [value for value in ended_ok if np.isfinite(value)]
    report.heading("What the gap means")
    report.bullets(
        [
            f"h_m is {exact_ratio.min():.3g} to {exact_ratio.max():.3g} of h_exact and "
            f"{ratio.min():.3g} to {ratio.max():.3g} of AROLC's empirical constant-delay "
            f"margin: on this arm the certificate is conservative by a factor "
            f"{1 / ratio.max():.3g} to {1 / ratio.min():.3g}.",
            f"h_m is sufficient only, so every delay below it must pass: in {below} of "
            f"{len(table)} gain pairs both empirical AROLC margins lie above h_m. Nothing "
            "follows from a delay above h_m.",
            f"The outer loop's empirical constant-delay margin is within 15 % of h_exact in "
            f"{close} of {len(table)} gain pairs (nominal dynamics up to the model error and the "
            f"arm's nonlinearity). It is lower in {len(lower)}; there the first failing run "
            f"ended without divergence in {len(ended_ok)}"
            + (f", with mean |e1| = {max(ended_ok):.3g} rad at most" if ended_ok else "")
            + ": there the tracking rule, not a divergence, sets the margin.",
            f"AROLC's empirical constant-delay margin stays within "
            f"{table['arolc_constant'].min():.3g}-{table['arolc_constant'].max():.3g} s while "
            f"h_exact spans {table['h_exact'].min():.3g}-{table['h_exact'].max():.3g} s: its "
            "switching term changes the loop that h_exact describes, in either direction.",
            "Empirical margins hold for this scenario, horizon and rule only: an instability "
            "that grows too slowly to show in the scored window passes.",
        ]
    )
    return report


def reproduce(
    out: str | Path = "results", *, duration: float | None = None, progress: bool = True
) -> tuple[MarginStudy, list[Path]]:
    """Run the job and write ``<out>/margins/``; return the study and the files written."""
    folder = check_output_folder(check_results_root(out, "out") / FOLDER)
    study = run_study(duration=duration, progress=progress)
    return study, write_study(study, folder)
