"""The report of a finished sweep (:mod:`delaytrack.sweeps`): summary table, figures and a
section of a self-contained report; the facts it states come from
:mod:`delaytrack.sweeps.summary`.

:func:`write_sweep_outputs` writes, next to the runs table of :func:`~delaytrack.sweeps.run_sweep`:

- ``summary.csv``: :func:`~delaytrack.sweeps.summary.summary_table` (per controller × delay
  class: runs, divergence rate, mean / median / 95th percentile / max of each metric);
- ``figures/distributions.{png,svg}``: per metric, a box plot per controller (runs that ended
  ``ok``; box = quartiles, whiskers = 5th and 95th percentiles);
- ``figures/ae_vs_h_max.{png,svg}``: each AE metric against the delay bound ``h_max`` of the run,
  one colour per controller;
- ``report.html``: one self-contained file with :func:`sweep_section`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from delaytrack import _result_columns as result_columns
from delaytrack._io import write_frame
from delaytrack._version import __version__
from delaytrack._words import counted
from delaytrack.report.figures import save_figure
from delaytrack.report.html import HtmlReport
from delaytrack.sweeps.runner import SweepOutcome, folder_lock
from delaytrack.sweeps.summary import (
    STATISTICS,
    TIE,
    controller_labels,
    default_metrics,
    divergence_per_controller,
    metric_units,
    smallest_medians,
    summary_table,
)
from delaytrack.units import coordinate_units, labelled, value_with_unit

__all__ = [
    "ae_vs_h_max_figure",
    "distribution_figure",
    "findings",
    "sweep_figures",
    "sweep_section",
    "with_units",
    "write_sweep_outputs",
]

_PANEL = (4.2, 3.4)


def _panels(count: int) -> tuple[Figure, list]:
    columns = min(3, count)
    rows = math.ceil(count / columns)
    figure = Figure(figsize=(_PANEL[0] * columns, _PANEL[1] * rows), layout="constrained")
    axes = figure.subplots(rows, columns, squeeze=False).ravel()
    for ax in axes[count:]:
        ax.set_visible(False)
    return figure, list(axes[:count])


def _log_scale_if_wide(ax, values: np.ndarray) -> None:
    """Log y-axis when the positive values span more than a factor of 20."""
    positive = values[np.isfinite(values) & (values > 0)]
    if positive.size == values[np.isfinite(values)].size and positive.size > 1:
        if positive.max() > 20.0 * positive.min():
            ax.set_yscale("log")


def _axis_label(metric: str, units: Mapping[str, str]) -> str:
    return labelled(metric, units.get(metric))


def distribution_figure(
    runs: pd.DataFrame,
    metrics: Sequence[str],
    label_keys: Sequence[str] | None = None,
    units: Mapping[str, str] | None = None,
) -> Figure:
    """Per metric, one box per controller over its ``ok`` runs; below it, how many of its runs
    were not ok (``2 of 12 not ok``, or ``all 12 ok``)."""
    labels = controller_labels(runs, label_keys)
    order = list(dict.fromkeys(labels))
    ok = runs["status"] == "ok"
    figure, axes = _panels(len(metrics))
    names = []
    for label in order:
        runs_of = int((labels == label).sum())
        not_ok = runs_of - int(ok[labels == label].sum())
        names.append(
            f"{label}\n{f'{not_ok} of {runs_of} not ok' if not_ok else f'all {runs_of} ok'}"
        )
    for ax, metric in zip(axes, metrics, strict=True):
        data = [runs.loc[ok & (labels == label), metric].to_numpy(float) for label in order]
        ax.boxplot(data, whis=(5, 95), flierprops={"markersize": 2})
        ax.set_xticks(range(1, len(order) + 1), names, fontsize="small")
        ax.set_title(metric)
        ax.set_ylabel(_axis_label(metric, units or {}))
        _log_scale_if_wide(ax, np.concatenate(data) if data else np.array([]))
        ax.grid(True, axis="y", alpha=0.3)
    return figure


def ae_vs_h_max_figure(
    runs: pd.DataFrame,
    metrics: Sequence[str],
    label_keys: Sequence[str] | None = None,
    units: Mapping[str, str] | None = None,
) -> Figure:
    """Each AE metric (or the first metric, if none is an AE) against ``h_max`` in ms."""
    shown = [metric for metric in metrics if metric.startswith("ae_")] or list(metrics[:1])
    labels = controller_labels(runs, label_keys)
    ok = runs["status"] == "ok"
    figure, axes = _panels(len(shown))
    for ax, metric in zip(axes, shown, strict=True):
        for label in dict.fromkeys(labels):
            chosen = ok & (labels == label)
            ax.scatter(
                1e3 * runs.loc[chosen, "h_max"],
                runs.loc[chosen, metric],
                s=6,
                alpha=0.5,
                label=label,
            )
        ax.set_xlabel("h_max (ms)")
        ax.set_ylabel(_axis_label(metric, units or {}))
        ax.set_title(metric)
        _log_scale_if_wide(ax, runs.loc[ok, metric].to_numpy(float))
        ax.grid(True, alpha=0.3)
    # Below the panels, not over a panel's points.
    handles, names = axes[0].get_legend_handles_labels()
    figure.legend(
        handles,
        names,
        fontsize="small",
        markerscale=2,
        loc="outside lower center",
        ncols=min(len(names), 4),
    )
    return figure


def _metric_table(summary: pd.DataFrame, metric: str, unit: str | None) -> pd.DataFrame:
    columns = {f"{metric}_{name}": labelled(name, unit) for name in STATISTICS}
    frame = summary[["controller", "delay_class", "runs", *columns]]
    return frame.rename(columns=columns)


def with_units(summary: pd.DataFrame, units: Mapping[str, str]) -> pd.DataFrame:
    """The summary with each metric statistic's unit in its column name (``ae_x_median_m``)."""
    return summary.rename(columns=result_columns.summary_columns(units))


def findings(summary: pd.DataFrame, metrics: Sequence[str], units: Mapping[str, str]) -> list[str]:
    """Sentences stating the summary's facts: divergence per controller
    (:func:`~delaytrack.sweeps.summary.divergence_per_controller`), and per delay class the
    controller with the smallest median of each metric, or every controller within
    :data:`~delaytrack.sweeps.summary.TIE` of the smallest, a tie
    (:func:`~delaytrack.sweeps.summary.smallest_medians`)."""
    parts = [
        f"{name} {int(row.diverged)} of {int(row.runs)}"
        + (f" ({int(row.failed)} more failed)" if row.failed else "")
        for name, row in divergence_per_controller(summary).iterrows()
    ]
    out = ["Runs that diverged or left the path, per controller: " + "; ".join(parts) + "."]
    for metric in metrics:
        unit = units.get(metric)
        best = []
        for smallest in smallest_medians(summary, metric):
            if len(smallest.controllers) > 1:
                names = " and ".join(smallest.controllers)
                medians = " and ".join(f"{value:.4g}" for value in smallest.medians)
                best.append(
                    f"{smallest.delay_class}: {names} within {TIE:.0%} of each other "
                    f"({value_with_unit(medians, unit)})"
                )
            else:
                best.append(
                    f"{smallest.delay_class}: {smallest.controllers[0]}, "
                    f"median {value_with_unit(f'{smallest.medians[0]:.3g}', unit)}"
                )
        if best:
            out.append(f"Smallest median {metric}, per delay class: " + "; ".join(best) + ".")
    return out


def sweep_section(
    report: HtmlReport,
    outcome: SweepOutcome,
    summary: pd.DataFrame,
    metrics: Sequence[str],
    figures: Mapping[str, tuple[Figure, str]],
    units: Mapping[str, str] | None = None,
) -> None:
    """Add the sweep's section to ``report``: set-up, findings, outcome counts, summary tables
    with units, figures.

    ``figures`` is :func:`sweep_figures`'s mapping; ``units`` is :func:`metric_units`'.
    """
    units = units or {}
    spec = outcome.spec
    report.heading(f"Sweep over {spec.base.name}")
    report.settings(
        {
            "base scenario": spec.base.name,
            "grid": "; ".join(f"{k}: {counted(len(v), 'value')}" for k, v in spec.grid.items())
            or "none",
            "random draws": (
                "; ".join(f"{k}: {v['dist']}" for k, v in spec.random.items())
                + f" ({spec.draws} draws, seed {spec.seed})"
                if spec.random
                else "none"
            ),
            "runs": f"{len(spec.runs)} in {len(spec.units())} units of up to {spec.unit_size}",
            "this call": (
                f"{counted(outcome.computed, 'unit')} computed, {outcome.resumed} found finished, "
                f"{outcome.seconds:.1f} s wall time"
            ),
            "executor": outcome.executor,
            "package": f"delaytrack {__version__}",
            "results folder": str(outcome.folder),
        }
    )
    if outcome.rejected:
        report.paragraph(
            "Part files found that did not count: a corrupt or altered part of this sweep was "
            "computed again; parts of another spec or code are left in place and ignored:",
            note=True,
        )
        report.bullets(f"{name}: {reason}" for name, reason in outcome.rejected.items())
    report.heading("Findings", level=3)
    report.bullets(findings(summary, metrics, units))
    report.heading("Outcomes", level=3)
    report.paragraph(
        "Divergence rate ('diverged'): share of runs whose state left the engine's bound or "
        "became non-finite (status 'diverged'), or whose tracking error passed the scenario's "
        f"error_bound (status 'left the path'; {_error_bound_text(spec.base)}). "
        "'failed': any other status that is not ok (a delay beyond the history buffer, a mass "
        "matrix that stopped being positive definite). Metric "
        "statistics are over the runs that ended ok, however far their errors grew within "
        "the bound."
    )
    outcomes = ["controller", "delay_class", "runs", "diverged", "divergence_rate", "failed"]
    report.table(summary[outcomes])
    for metric in metrics:
        report.heading(_axis_label(metric, units), level=3)
        report.table(_metric_table(summary, metric, units.get(metric)))
    report.heading("Figures", level=3)
    for figure, caption in figures.values():
        report.figure(figure, caption)


def _error_bound_text(scenario: Any) -> str:
    """The base scenario's ``error_bound`` per bounded coordinate, with units (``x 10 m, y
    10 m``), or that it sets none."""
    bound = scenario.error_bound
    if bound is None or not any(math.isfinite(b) for b in bound):
        return "the base scenario sets none"
    units = coordinate_units(scenario.build().plant)
    bounded = [
        value_with_unit(f"{name} {b:g}", unit)
        for (name, unit), b in zip(units.items(), bound, strict=True)
        if math.isfinite(b)
    ]
    return "the base scenario's: " + ", ".join(bounded)


def sweep_figures(
    runs: pd.DataFrame,
    metrics: Sequence[str],
    label_keys: Sequence[str] | None = None,
    units: Mapping[str, str] | None = None,
) -> dict[str, tuple[Figure, str]]:
    """File stem -> (figure, caption) of the sweep's figures."""
    return {
        "distributions": (
            distribution_figure(runs, metrics, label_keys, units),
            "Distribution per controller (runs that ended ok; box: quartiles, whiskers: 5th and "
            "95th percentiles).",
        ),
        "ae_vs_h_max": (
            ae_vs_h_max_figure(runs, metrics, label_keys, units),
            "Mean absolute tracking error against the delay bound h_max of each run (runs that "
            "ended ok).",
        ),
    }


def write_sweep_outputs(
    outcome: SweepOutcome, *, formats: Sequence[str] = ("png", "svg")
) -> list[Path]:
    """Write ``summary.csv``, the figures and ``report.html`` into the sweep's folder.

    The folder's lock (:func:`~delaytrack.sweeps.runner.folder_lock`) is held meanwhile, so a
    sweep started on the same folder cannot change the runs under the report.
    """
    with folder_lock(outcome.folder):
        return _write_outputs(outcome, formats)


def _write_outputs(outcome: SweepOutcome, formats: Sequence[str]) -> list[Path]:
    folder = outcome.folder
    metrics = list(outcome.spec.metrics or default_metrics(outcome.runs))
    keys = outcome.spec.label_keys
    summary = summary_table(outcome.runs, metrics, keys, outcome.spec.delay_label_keys)
    units = metric_units(outcome.spec)
    paths = [write_frame(with_units(summary, units), folder / "summary.csv")]
    figures = sweep_figures(outcome.runs, metrics, keys, units)
    for stem, (figure, _) in figures.items():
        paths += save_figure(figure, folder / "figures" / stem, formats)
    report = HtmlReport(f"delaytrack sweep: {outcome.spec.base.name}")
    sweep_section(report, outcome, summary, metrics, figures, units)
    paths.append(report.write(folder / "report.html"))
    return paths
