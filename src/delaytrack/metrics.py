"""Tracking and effort metrics of SPEC §6: small pure functions on a simulation result.

The result is a :class:`~delaytrack.sim.SimResult`.

Every function works on a batched result (``B`` runs) and returns one value per run (and per
coordinate where that applies). Units are those of the result: radians for a joint angle,
metres for a position, N·m for a torque. The definitions, over the recorded samples
``i = 0 .. R-1`` with ``t_i >= t_from``:

    AE_j   = (1/R) Σ_i |e1_j(t_i)|                       mean absolute error of coordinate j
    RMS_j  = sqrt((1/R) Σ_i e1_j(t_i)²)                  root-mean-square error
    MAX_j  = max_i |e1_j(t_i)|                           largest absolute error
    TV     = Σ_i Σ_j |command_j(t_{i+1}) - command_j(t_i)|   total variation of the commands

with ``e1 = q_d - q``. The paper's %AE is :func:`percent_of` ``(AE, scale)``.

**Runs that did not finish give NaN.** A diverged run (or one that stopped because the delay left
the history) has NaN samples after its stop time, and its average over the part before the stop
describes a different experiment — a shorter one, ending in a blow-up — so it is not comparable
with the averages of complete runs. Returning NaN keeps it out of any comparison; read its
``status`` and ``t_stop`` instead.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

if TYPE_CHECKING:
    from delaytrack.sim.result import SimResult

__all__ = [
    "max_abs_error",
    "mean_absolute_error",
    "metrics_table",
    "percent_of",
    "rms_error",
    "total_variation",
]


def _window(result: SimResult, t_from: float | None) -> np.ndarray:
    """Boolean mask over the record times: ``t >= t_from`` (all records when ``t_from`` is None)."""
    if not result.has_trajectories:
        raise ValueError(
            "this result has no recorded trajectories (simulate(..., trajectories=False)); "
            "read its running metrics, result.metrics, or metrics_table(result)"
        )
    if t_from is None:
        return np.ones(result.t.size, dtype=bool)
    start = float(t_from)
    if not np.isfinite(start):
        raise ValueError(f"t_from must be a finite time in seconds; got {t_from!r}")
    mask = result.t >= start
    if not np.any(mask):
        raise ValueError(
            f"t_from = {start:g} s leaves no records; the result ends at t = {result.t[-1]:g} s"
        )
    return mask


def _errors(result: SimResult, t_from: float | None) -> np.ndarray:
    """``|e1|`` on the window, shape (B, R', n), with every sample of a not-ok run set to NaN."""
    absolute = np.abs(result.e1[:, _window(result, t_from), :])
    absolute[~result.ok] = np.nan
    return absolute


def mean_absolute_error(result: SimResult, *, t_from: float | None = None) -> np.ndarray:
    """Mean absolute tracking error per coordinate, ``AE_j = mean_i |e1_j(t_i)|`` (SPEC §6).

    Parameters
    ----------
    result : SimResult
        A batched simulation result.
    t_from : float, optional
        Ignore records before this time (seconds), e.g. to skip a transient.

    Returns
    -------
    ndarray, shape (B, n)
        In the unit of ``q``; NaN for runs whose status is not ``ok`` (see the module docstring).
    """
    return np.mean(_errors(result, t_from), axis=1)


def rms_error(result: SimResult, *, t_from: float | None = None) -> np.ndarray:
    """Root-mean-square tracking error per coordinate, ``sqrt(mean_i e1_j(t_i)²)``.

    Parameters
    ----------
    result : SimResult
    t_from : float, optional
        Ignore records before this time (seconds).

    Returns
    -------
    ndarray, shape (B, n)
        NaN for runs whose status is not ``ok``.
    """
    return np.sqrt(np.mean(_errors(result, t_from) ** 2, axis=1))


def max_abs_error(result: SimResult, *, t_from: float | None = None) -> np.ndarray:
    """Largest absolute tracking error per coordinate, ``max_i |e1_j(t_i)|``.

    Parameters
    ----------
    result : SimResult
    t_from : float, optional
        Ignore records before this time (seconds).

    Returns
    -------
    ndarray, shape (B, n)
        NaN for runs whose status is not ``ok``.
    """
    return np.max(_errors(result, t_from), axis=1)


def total_variation(result: SimResult, *, t_from: float | None = None) -> np.ndarray:
    """Total variation of the commands, ``TV = Σ_i Σ_j |command_j(t_{i+1}) - command_j(t_i)|``.

    The sum runs over consecutive *recorded* command samples. It equals the paper's TV (taken
    over every controller tick) only when the result was recorded with ``record_every = 1``; with
    coarser recording it is smaller, because changes between records cancel.

    Parameters
    ----------
    result : SimResult
    t_from : float, optional
        Use only the commands recorded at ``t >= t_from`` (seconds).

    Returns
    -------
    ndarray, shape (B,)
        In the unit of the commands (N·m for torques); NaN for runs whose status is not ``ok``.
    """
    commands = result.commands[:, _window(result, t_from), :]
    variation = np.sum(np.abs(np.diff(commands, axis=1)), axis=(1, 2))
    variation[~result.ok] = np.nan
    return variation


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
) -> pd.DataFrame:
    """One row per batch element with status, stop time and every metric of this module.

    Parameters
    ----------
    result : SimResult
    coordinate_names : sequence of str, optional
        One name per coordinate, used in the column names; ``q1 .. qn`` by default.
    label : str, optional
        If given, a first column ``label`` holding it (handy when concatenating tables).
    t_from : float, optional
        Ignore records before this time (seconds).

    Returns
    -------
    DataFrame
        Columns ``[label,] batch, status, t_stop, ae_<c>.., rms_<c>.., max_<c>.., tv``; metric
        values are NaN for runs whose status is not ``ok``. With trajectories, the metrics are
        taken over the recorded samples from ``t_from``; they equal the running metrics
        (``result.metrics``, every tick from ``simulate(metrics_from=...)``) when
        ``record_every = 1`` and ``t_from`` is that ``metrics_from``. A result without
        trajectories (``simulate(..., trajectories=False)``) gives its running metrics.
    """
    n = result.n
    names = [f"q{i + 1}" for i in range(n)] if coordinate_names is None else list(coordinate_names)
    if len(names) != n:
        raise ValueError(f"coordinate_names must have n = {n} entries; got {len(names)}: {names}")
    columns: dict[str, object] = {}
    if label is not None:
        columns["label"] = [label] * result.batch_size
    columns["batch"] = np.arange(result.batch_size)
    columns["status"] = result.status_names
    columns["t_stop"] = np.asarray(result.t_stop, dtype=float)
    if result.has_trajectories:
        values = {
            "ae": mean_absolute_error(result, t_from=t_from),
            "rms": rms_error(result, t_from=t_from),
            "max": max_abs_error(result, t_from=t_from),
            "tv": total_variation(result, t_from=t_from),
        }
    elif t_from is None:
        values = result.metrics
    else:
        raise ValueError(
            "t_from selects recorded samples, and this result has none; give the window to "
            "simulate(..., metrics_from=...) instead"
        )
    for prefix in ("ae", "rms", "max"):
        for j, name in enumerate(names):
            columns[f"{prefix}_{name}"] = values[prefix][:, j]
    columns["tv"] = values["tv"]
    return pd.DataFrame(columns)
