"""A sweep's summary: per controller × delay class, the distribution of each metric.

Rows of the runs table (:func:`delaytrack.sweeps.run_unit`) are grouped by

- **controller**: the controller type (for a factory of yours, ``"python:<module>:<function>"``,
  the function's name, unless another type of the sweep has that name), followed by the
  values of swept ``controller.*`` keys (``arolc (K1=2)``; a sweep shows its grid and
  ``choice`` keys only); when a swept ``controller`` table list holds several tables of one
  type, they are told apart as ``pcon #1``, ``pcon #2`` in the order they first appear;
- **delay class**: when the sweep chooses its delays from lists (a grid, or ``choice`` draws),
  each delay of the lists is a class of its own: its family and bound (``constant, h_max 50
  ms``), then the values of swept ``delay.*`` keys (``abs-sine, h_max 100 ms (frequency=2)``;
  whole ``delay`` tables of one family and bound are told apart as ``#1``, ``#2``). When a
  delay key is drawn from a continuous distribution, the class is the family and the band its
  bound falls in (``random, h_max 100-150 ms``; bands at :data:`DELAY_BAND_EDGES`). A delay of
  the user's is named by its factory's function, as a controller is (``make_congested_link,
  h_max 120 ms``), unless another type of the sweep has that name: both then keep their full
  types.

Per group: ``runs``; ``diverged`` and ``divergence_rate`` (status ``diverged``: the state left
the engine's bound or became non-finite, or ``left the path``: a tracking error passed the
scenario's ``error_bound``); ``failed`` (any other status that is not ``ok``, such
as a delay beyond the history buffer or a mass matrix that stopped being positive definite);
then ``<metric>_mean``, ``_median``, ``_p95`` (95th
percentile, linear interpolation) and ``_max`` over the runs whose status is ``ok`` (NaN when
there is none). The statistic columns are named by
:func:`~delaytrack._result_columns.summary_columns`, which refuses two columns of one name (with
or without the metrics' units, :func:`~delaytrack.report.sweep.with_units`).

What the sweep's report states is computed here too: the divergence per controller
(:func:`divergence_per_controller`) and, per delay class, the smallest median of each metric or
the controllers tied for it (:func:`smallest_medians`).
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from delaytrack import _result_columns as result_columns
from delaytrack._result_columns import SUMMARY_STATISTICS, summary_columns
from delaytrack.metrics import COORDINATE_METRICS

if TYPE_CHECKING:
    from delaytrack.sweeps.spec import SweepSpec

__all__ = [
    "DELAY_BAND_EDGES",
    "DIVERGED_STATUSES",
    "STATISTICS",
    "TIE",
    "SmallestMedian",
    "controller_labels",
    "default_metrics",
    "delay_classes",
    "divergence_per_controller",
    "metric_units",
    "smallest_medians",
    "summary_table",
]

#: Statuses counted as divergence: the state blew up, or a tracking error passed the
#: scenario's ``error_bound`` (the run left the path).
DIVERGED_STATUSES = ("diverged", "left the path")
#: Upper edges (s) of the ``h_max`` bands of a delay class; above the last: ``> 1000 ms``.
DELAY_BAND_EDGES: tuple[float, ...] = (0.05, 0.1, 0.15, 0.2, 0.3, 0.5, 1.0)
#: Statistic suffix -> function of the ``ok`` runs' values.
STATISTICS: dict[str, Callable[[np.ndarray], float]] = dict(
    zip(
        SUMMARY_STATISTICS,
        (np.mean, np.median, lambda values: np.percentile(values, 95.0), np.max),
        strict=True,
    )
)


def _shown(value: object) -> str:
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def _band(h_max: float) -> str:
    lower = 0.0
    for upper in DELAY_BAND_EDGES:
        if h_max <= upper:
            return f"h_max {1e3 * lower:g}-{1e3 * upper:g} ms"
        lower = upper
    return f"h_max > {1e3 * lower:g} ms"


def delay_classes(runs: pd.DataFrame, keys: Sequence[str] | None = None) -> pd.Series:
    """The delay class of every run (module docstring).

    ``keys``: the swept delay keys (``delay`` or ``delay.*``) whose values were chosen from
    lists (:attr:`SweepSpec.delay_label_keys`): each delay is then a class of its own. None:
    some delay key was drawn continuously, and classes are bands of ``h_max``
    (:data:`DELAY_BAND_EDGES`, upper edge in).
    """
    kinds = _short_kinds(list(runs["delay_type"]))
    if keys is None:
        classes = [f"{kind}, {_band(h)}" for kind, h in zip(kinds, runs["h_max"], strict=True)]
        return pd.Series(classes, index=runs.index, name="delay_class")
    bounds = [f"h_max {1e3 * h:g} ms" for h in runs["h_max"]]
    if "delay" in keys:  # whole tables, told apart within a family and bound
        groups = [f"{kind}, {bound}" for kind, bound in zip(kinds, bounds, strict=True)]
        numbers = _numbers(groups, list(runs["delay"]))
        kinds = [k if i is None else f"{k} #{i}" for k, i in zip(kinds, numbers, strict=True)]
    classes = [f"{kind}, {bound}" for kind, bound in zip(kinds, bounds, strict=True)]
    classes = _with_swept(classes, runs, [key for key in keys if key.startswith("delay.")])
    return pd.Series(classes, index=runs.index, name="delay_class")


def _short_kinds(kinds: list[str]) -> list[str]:
    """Each ``type`` of ``kinds``, a factory of the user's (``python:<file or module>:<name>``)
    by its function's name alone where no other type of these shortens to the same name (two
    files' ``make_link``, or a factory named ``constant`` beside the built-in one, keep their
    full types)."""
    short = {kind: kind.rpartition(":")[2] for kind in set(kinds)}
    uses = Counter(short.values())
    return [short[kind] if uses[short[kind]] == 1 else kind for kind in kinds]


def _numbers(groups: list[str], tables: list[object]) -> list[int | None]:
    """For each run, the number (from 1, in order of first appearance) of its table among the
    different ``tables`` of its group, or None when the group has one table only."""
    seen: dict[str, list[object]] = {}
    for group, table in zip(groups, tables, strict=True):
        if table not in seen.setdefault(group, []):
            seen[group].append(table)
    return [
        seen[group].index(table) + 1 if len(seen[group]) > 1 else None
        for group, table in zip(groups, tables, strict=True)
    ]


def controller_labels(runs: pd.DataFrame, keys: Sequence[str] | None = None) -> pd.Series:
    """The controller label of every run (module docstring).

    ``keys``: the swept ``controller.*`` columns to show in labels (all of them by default;
    :attr:`SweepSpec.label_keys` leaves out continuous draws).
    """
    kinds = _short_kinds(list(runs["controller_type"]))
    labels = kinds
    if "controller" in runs:
        numbers = _numbers(kinds, list(runs["controller"]))
        labels = [
            kind if i is None else f"{kind} #{i}" for kind, i in zip(kinds, numbers, strict=True)
        ]
    if keys is None:
        keys = [column for column in runs.columns if column.startswith("controller.")]
    return pd.Series(_with_swept(labels, runs, list(keys)), index=runs.index, name="controller")


def _with_swept(labels: list[str], runs: pd.DataFrame, keys: list[str]) -> list[str]:
    """``labels`` followed by each run's values of the swept ``<table>.<name>`` columns
    ``keys``: ``arolc (K1=2)``."""
    if not keys:
        return labels
    names = [key.partition(".")[2] for key in keys]
    swept = [
        ", ".join(f"{name}={_shown(value)}" for name, value in zip(names, row, strict=True))
        for row in runs[keys].itertuples(index=False)
    ]
    return [f"{label} ({text})" for label, text in zip(labels, swept, strict=True)]


def default_metrics(runs: pd.DataFrame) -> list[str]:
    """Every ``ae_*`` column, then ``tv``."""
    return [column for column in runs.columns if column.startswith("ae_")] + ["tv"]


def summary_table(
    runs: pd.DataFrame,
    metrics: Sequence[str] | None = None,
    label_keys: Sequence[str] | None = None,
    delay_keys: Sequence[str] | None = None,
) -> pd.DataFrame:
    """The summary (module docstring), groups in order of first appearance.

    Parameters
    ----------
    runs : DataFrame
        The sweep's runs table (every part, one row per run).
    metrics : sequence of str, optional
        Metric columns to summarise; :func:`default_metrics` by default.
    label_keys : sequence of str, optional
        Swept ``controller.*`` columns shown in controller labels (:func:`controller_labels`).
    delay_keys : sequence of str, optional
        Swept delay keys chosen from lists (:func:`delay_classes`); by default, bands of
        ``h_max``.

    Raises
    ------
    ValueError
        For a metric that is not a numeric column of ``runs``, naming the valid ones, or
        metrics whose statistic columns would share a name.
    """
    metrics = default_metrics(runs) if metrics is None else list(metrics)
    valid = [
        column
        for column in runs.columns
        if column.split("_")[0] in COORDINATE_METRICS or column in ("tv", "tv_applied")
    ]
    unknown = [metric for metric in metrics if metric not in valid]
    if unknown:
        raise ValueError(f"summary metrics {unknown} are not columns of the runs; valid: {valid}")
    columns = summary_columns(dict.fromkeys(metrics))
    labels = controller_labels(runs, label_keys)
    frame = runs.assign(controller=labels, delay_class=delay_classes(runs, delay_keys))
    rows = []
    for (controller, delay_class), group in frame.groupby(
        ["controller", "delay_class"], sort=False
    ):
        ok = group[group["status"] == "ok"]
        diverged = int(group["status"].isin(DIVERGED_STATUSES).sum())
        row = {
            "controller": controller,
            "delay_class": delay_class,
            "runs": len(group),
            "diverged": diverged,
            "divergence_rate": diverged / len(group),
            "failed": len(group) - len(ok) - diverged,
        }
        for metric in metrics:
            values = ok[metric].to_numpy(dtype=float)
            for name, statistic in STATISTICS.items():
                column = columns[f"{metric}_{name}"]
                row[column] = float(statistic(values)) if values.size else math.nan
        rows.append(row)
    return pd.DataFrame(rows)


#: Relative difference of two medians under which :func:`smallest_medians` calls them a tie.
TIE = 0.01


@dataclass(frozen=True)
class SmallestMedian:
    """The controller with the smallest median of a metric in one delay class, or every
    controller within :data:`TIE` of the smallest (a tie), smallest first."""

    delay_class: str
    controllers: tuple[str, ...]
    medians: tuple[float, ...]


def divergence_per_controller(summary: pd.DataFrame) -> pd.DataFrame:
    """``runs``, ``diverged`` and ``failed`` of :func:`summary_table`'s rows summed per
    controller, in the summary's order."""
    return summary.groupby("controller", sort=False)[["runs", "diverged", "failed"]].sum()


def smallest_medians(summary: pd.DataFrame, metric: str) -> list[SmallestMedian]:
    """Per delay class of :func:`summary_table`'s rows with at least two finite medians of
    ``metric``, its smallest: the controllers whose median ``m`` is within :data:`TIE` of the
    smallest ``low`` (``m - low <= TIE max(|low|, |m|)``), in order (ties kept in row order)."""
    column = f"{metric}_median"
    found = []
    for delay_class, rows in summary.groupby("delay_class", sort=False):
        rows = rows[np.isfinite(rows[column].to_numpy(float))]
        if len(rows) < 2:
            continue
        ordered = rows.sort_values(column, kind="stable")
        values = ordered[column].to_numpy(float)
        low = values[0]
        tied = ordered[values - low <= TIE * np.maximum(abs(low), np.abs(values))]
        found.append(
            SmallestMedian(
                str(delay_class),
                tuple(str(name) for name in tied["controller"]),
                tuple(float(value) for value in tied[column]),
            )
        )
    return found


def metric_units(spec: SweepSpec) -> dict[str, str]:
    """Unit of each metric column a sweep's runs can have, from the base scenario's plant:
    ``ae_<c>``, ``rms_<c>``, ``max_<c>`` in the coordinate's unit, ``tv`` in the inputs' unit
    (when they share one); metrics whose unit the plant does not give are left out."""
    plant = spec.base.build().plant
    units = result_columns.metric_units(
        plant.coordinate_names, plant.coordinate_units, plant.n, plant.input_units
    )
    return {metric: unit for metric, unit in units.items() if unit}
