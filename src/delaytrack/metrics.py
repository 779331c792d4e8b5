"""Tracking and effort metrics of the paper's experiments: small pure functions on a result.

The result is a :class:`~delaytrack.sim.SimResult`.

Every function works on a batched result (``B`` runs) and returns one value per run (and per
coordinate where that applies). Units are those of the result: radians for a joint angle,
metres for a position, N·m for a torque. The definitions, over the controller ticks
``k = 0 .. K-1`` of the metric window:

    AE_j   = (1/K) Σ_k |e1_j(t_k)|                       mean absolute error of coordinate j
    RMS_j  = sqrt((1/K) Σ_k e1_j(t_k)²)                  root-mean-square error
    MAX_j  = max_k |e1_j(t_k)|                           largest absolute error
    TV     = Σ_k Σ_j |command_j(t_{k+1}) - command_j(t_k)|   total variation of the commands
    TV_applied = Σ_k Σ_j |ū_j(t_{k+1}) - ū_j(t_k)|          of the input the plant received

with ``e1 = q_d - q`` and ``ū(t_k)`` the input the plant receives just after tick ``k`` (the
delayed command saturated to the input limits, the record ``applied``): with input limits the
controller's commands and what the actuators deliver differ, and both TVs are reported.
The paper's %AE is :func:`percent_of` ``(AE, scale)``.

**Always every tick.** Without ``t_from`` the metrics are the simulator's running metrics
(:attr:`SimResult.metrics`; a result without them is measured on all its records),
accumulated inside the run at every controller tick of its window
(``simulate(metrics_from=...)``, the whole run by default), whatever was recorded. With
``t_from`` they are taken from the recorded trajectories, which must then hold every tick
(``record_every = 1``): a metric over every k-th sample would be another number (a TV over
sparse samples is smaller, an AE over one sample is that sample), so it is refused rather than
returned. Sums run tick by tick in time order, the order of the running metrics, so a run gives
the same bits alone or in any batch.

**Runs that did not finish give NaN.** A diverged run, one that left the path (a tracking error
beyond ``error_bound``) or one that stopped because the delay left the history describes a
different experiment — a shorter one, ending in a blow-up — so its averages are not comparable
with those of complete runs. Returning NaN keeps it out of any comparison; read its ``status``
and ``t_stop`` instead.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from delaytrack._validation import quoted
from delaytrack.units import default_names

if TYPE_CHECKING:
    import pandas as pd

    from delaytrack.sim.result import SimResult

__all__ = [
    "COORDINATE_METRICS",
    "max_abs_error",
    "mean_absolute_error",
    "metrics_table",
    "percent_of",
    "rms_error",
    "total_variation",
]

#: The metrics of every coordinate ``c``, columns ``<metric>_c`` of the tables: mean absolute
#: error, RMS error and largest absolute error (:func:`mean_absolute_error`, :func:`rms_error`,
#: :func:`max_abs_error`).
COORDINATE_METRICS = ("ae", "rms", "max")


def _sequential_sum(values: np.ndarray, axis: int) -> np.ndarray:
    """``Σ`` along ``axis`` in index order (``np.sum`` adds pairwise, in an order that depends
    on the array's shape; a running accumulation does not)."""
    if values.shape[axis] == 0:
        return np.zeros(np.delete(values.shape, axis))
    return np.take(np.add.accumulate(values, axis=axis), -1, axis=axis)


def _samples(result: SimResult, t_from: float) -> slice:
    """The recorded ticks at or after ``t_from``; every tick must have been recorded."""
    if isinstance(t_from, bool) or not isinstance(t_from, int | float | np.integer | np.floating):
        raise ValueError(f"t_from must be a time in seconds (a number); got {t_from!r}")
    start = float(t_from)
    if not np.isfinite(start):
        raise ValueError(f"t_from must be a finite time in seconds; got {t_from!r}")
    if not result.has_trajectories or result.settings.get("record_every", 1) != 1:
        raise ValueError(
            f"t_from = {start:g} s takes the metrics from the recorded trajectories, which must "
            "hold every controller tick (simulate(..., record_every=1)); this result has "
            + (
                "none"
                if not result.has_trajectories
                else f"every {result.settings['record_every']}-th"
            )
            + ". Give the window to simulate(..., metrics_from=...) instead: its running metrics "
            "count every tick"
        )
    first = int(np.searchsorted(result.t, start, side="left"))
    if first >= result.t.size:
        raise ValueError(
            f"t_from = {start:g} s leaves no records; the result ends at t = {result.t[-1]:g} s"
        )
    return slice(first, None)


def _check_result(result: object) -> None:
    """Raise a TypeError unless ``result`` looks like a :class:`~delaytrack.sim.SimResult`
    (what ``simulate`` returns, or one made by hand)."""
    if not all(hasattr(result, name) for name in ("metrics", "ok", "t", "n", "batch_size")):
        raise TypeError(
            f"result must be a SimResult (what delaytrack.simulate returns); got "
            f"{type(result).__name__} {quoted(result)}"
        )


def _metrics(result: SimResult, t_from: float | None) -> dict[str, np.ndarray]:
    """``{"ae", "rms", "max" (B, n), "tv", "tv_applied" (B,)}`` over the window (module
    docstring); a result made by hand may give its own metrics without ``"tv_applied"``, which
    is then taken from its records (:func:`_with_applied_variation`)."""
    _check_result(result)
    if t_from is None and result.metrics:
        return {name: values.copy() for name, values in result.metrics.items()}
    # A result without running metrics (one built by hand) is measured on its records.
    window = _samples(result, result.t[0] if t_from is None else t_from)
    errors = np.abs(result.e1[:, window, :])
    count = errors.shape[1]
    with np.errstate(over="ignore"):  # errors near the largest float: RMS and TV are inf
        metrics = {
            "ae": _sequential_sum(errors, axis=1) / count,
            "rms": np.sqrt(_sequential_sum(errors * errors, axis=1) / count),
            "max": np.max(errors, axis=1),
            "tv": _total_variation(result.commands[:, window, :]),
            "tv_applied": _total_variation(result.applied[:, window, :]),
        }
    for values in metrics.values():
        values[~result.ok] = np.nan
    return metrics


def _with_applied_variation(
    result: SimResult, t_from: float | None, metrics: dict[str, np.ndarray]
) -> dict[str, np.ndarray]:
    """``metrics`` with ``"tv_applied"``, from the records when the result did not give it."""
    if "tv_applied" not in metrics:
        metrics["tv_applied"] = _metrics(result, result.t[0] if t_from is None else t_from)[
            "tv_applied"
        ]
    return metrics


def _total_variation(inputs: np.ndarray) -> np.ndarray:
    """``Σ_k Σ_j |u_j(t_{k+1}) - u_j(t_k)|`` of ``inputs (B, K, m)``, tick by tick in time order
    (the order of the running metrics)."""
    variation = np.abs(np.diff(inputs, axis=1))
    return _sequential_sum(_sequential_sum(variation, axis=2), axis=1)


def mean_absolute_error(result: SimResult, *, t_from: float | None = None) -> np.ndarray:
    """Mean absolute tracking error per coordinate, ``AE_j = (1/K) Σ_k |e1_j(t_k)|``.

    The paper's AE (its Tables I-III, in mm for the robot).

    Parameters
    ----------
    result : SimResult
        A batched simulation result.
    t_from : float, optional
        Ignore ticks before this time (seconds), e.g. to skip a transient; needs trajectories
        recorded at every tick. By default: the running metrics' window.

    Returns
    -------
    ndarray, shape (B, n)
        In the unit of ``q``; NaN for runs whose status is not ``ok``
        (see :mod:`delaytrack.metrics`).
    """
    return _metrics(result, t_from)["ae"]


def rms_error(result: SimResult, *, t_from: float | None = None) -> np.ndarray:
    """Root-mean-square tracking error per coordinate, ``sqrt((1/K) Σ_k e1_j(t_k)²)``.

    Parameters
    ----------
    result : SimResult
    t_from : float, optional
        Ignore ticks before this time (seconds); see :func:`mean_absolute_error`.

    Returns
    -------
    ndarray, shape (B, n)
        NaN for runs whose status is not ``ok``.
    """
    return _metrics(result, t_from)["rms"]


def max_abs_error(result: SimResult, *, t_from: float | None = None) -> np.ndarray:
    """Largest absolute tracking error per coordinate, ``max_k |e1_j(t_k)|``.

    Parameters
    ----------
    result : SimResult
    t_from : float, optional
        Ignore ticks before this time (seconds); see :func:`mean_absolute_error`.

    Returns
    -------
    ndarray, shape (B, n)
        NaN for runs whose status is not ``ok``.
    """
    return _metrics(result, t_from)["max"]


def total_variation(
    result: SimResult, *, t_from: float | None = None, of: str = "commands"
) -> np.ndarray:
    """Total variation of the commands, ``TV = Σ_k Σ_j |command_j(t_{k+1}) - command_j(t_k)|``,
    or of the input the plant received.

    The paper's TV, over every controller tick of the window. With ``of="applied"``, the same
    sum over ``ū(t_k)``, the input the plant receives just after tick ``k`` (the delayed
    command saturated to the input limits, ``result.applied``): the effort the actuators
    delivered, beside the effort the controller asked for. Sampled at the ticks as the commands
    are, it counts each command the plant receives across a tick; under a time-varying delay a
    command in force only between two ticks is skipped, so it is then a lower bound of the
    variation of the continuous-time input.

    Parameters
    ----------
    result : SimResult
    t_from : float, optional
        Use only the ticks at ``t >= t_from`` (seconds); see :func:`mean_absolute_error`.
    of : {"commands", "applied"}
        The commands the controller issued (the paper's TV, the default) or the input the
        plant received.

    Returns
    -------
    ndarray, shape (B,)
        In the unit of the commands (N·m for torques); NaN for runs whose status is not ``ok``.
    """
    metric = {"commands": "tv", "applied": "tv_applied"}.get(of)
    if metric is None:
        raise ValueError(f'of must be "commands" or "applied"; got {of!r}')
    values = _metrics(result, t_from)
    if metric == "tv_applied":  # the commands' TV never needs the records
        values = _with_applied_variation(result, t_from, values)
    return values[metric]


def percent_of(value: np.ndarray | float, scale: float) -> np.ndarray | float:
    """``100 · value / scale``: the paper's %AE with ``scale`` the size of the path.

    Parameters
    ----------
    value : array_like or float
        A metric, e.g. AE in mm.
    scale : float
        The reference size in the same unit (the paper uses the circle's diameter, 2500 mm).
        Must be finite and > 0.

    Returns
    -------
    ndarray or float
        Percent; NaN stays NaN.
    """
    size = float(scale)
    if not np.isfinite(size) or size <= 0.0:
        raise ValueError(f"scale must be a finite number > 0; got {scale!r}")
    percent = 100.0 * np.asarray(value, dtype=float) / size
    return float(percent) if percent.ndim == 0 else percent


def metrics_table(
    result: SimResult,
    coordinate_names: Sequence[str] | None = None,
    label: str | None = None,
    *,
    t_from: float | None = None,
    tv_applied: bool = False,
) -> pd.DataFrame:
    """One row per batch element with status, stop time and every metric of this module.

    Parameters
    ----------
    result : SimResult
    coordinate_names : sequence of str, optional
        One name per coordinate, used in the column names; by default the plant's
        (``result.coordinate_names``), else ``q1 .. qn``.
    label : str, optional
        If given, a first column ``label`` holding it (handy when concatenating tables).
    t_from : float, optional
        Ignore ticks before this time (seconds); see :func:`mean_absolute_error`.
    tv_applied : bool
        Add the column ``tv_applied``, the TV of the input the plant received
        (:func:`total_variation` ``of="applied"``), e.g. for runs with input limits; asked for,
        not inferred from the runs, so that tables of runs with and without limits share their
        columns.

    Returns
    -------
    DataFrame
        Columns ``[label,] run, status, t_stop, ae_<c>.., rms_<c>.., max_<c>.., tv[,
        tv_applied]``; metric values are NaN for runs whose status is not ``ok``. Every
        metric counts every controller tick of the window (module docstring): the running
        metrics without ``t_from``, the recorded trajectories (every tick) with it.
    """
    import pandas as pd  # imported when a table is made: `import delaytrack` stays light

    _check_result(result)
    n = result.n
    if coordinate_names is None:
        coordinate_names = result.coordinate_names
    names = list(default_names(coordinate_names, n))
    if len(names) != n or len(set(names)) != n:
        raise ValueError(
            f"coordinate_names must have n = {n} different entries; got {len(names)}: {names}"
        )
    columns: dict[str, object] = {}
    if label is not None:
        columns["label"] = [label] * result.batch_size
    columns["run"] = np.arange(result.batch_size)
    columns["status"] = result.status_names
    columns["t_stop"] = np.asarray(result.t_stop, dtype=float)
    values = _metrics(result, t_from)
    for prefix in COORDINATE_METRICS:
        for j, name in enumerate(names):
            columns[f"{prefix}_{name}"] = values[prefix][:, j]
    columns["tv"] = values["tv"]
    if tv_applied:
        columns["tv_applied"] = _with_applied_variation(result, t_from, values)["tv_applied"]
    return pd.DataFrame(columns)
