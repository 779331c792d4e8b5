"""Relative changes between metric tables: a candidate against a baseline (percent), and the
same runs computed twice (the dt check)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

__all__ = ["metric_columns", "relative_change", "relative_difference"]

_METRIC_PREFIXES = ("ae_", "rms_", "max_")


def metric_columns(frame: pd.DataFrame) -> list[str]:
    """The metric columns of a metrics table: ``ae_*``, ``rms_*``, ``max_*`` and ``tv``."""
    return [c for c in frame.columns if c.startswith(_METRIC_PREFIXES) or c == "tv"]


def relative_change(
    frame: pd.DataFrame,
    *,
    by: str,
    column: str,
    baseline: str,
    candidate: str,
    metrics: Sequence[str] | None = None,
) -> pd.DataFrame:
    """Percent change of ``candidate`` against ``baseline``: ``100 (cand - base) / base``.

    Parameters
    ----------
    frame : DataFrame
        One row per (``by``, ``column``) pair, e.g. per (scenario, controller).
    by : str
        Column identifying the cases compared separately (e.g. ``"scenario"``).
    column : str
        Column naming the two contenders (e.g. ``"controller"``).
    baseline, candidate : str
        Values of ``column`` to compare.
    metrics : sequence of str, optional
        Columns to compare; every metric column by default.

    Returns
    -------
    DataFrame
        One row per case, column ``by`` plus one percent column per metric. Negative means the
        candidate's value is lower (for errors and TV: better).
    """
    metrics = metric_columns(frame) if metrics is None else list(metrics)
    rows = []
    for case, group in frame.groupby(by, sort=False):
        base = group[group[column] == baseline]
        cand = group[group[column] == candidate]
        if len(base) != 1 or len(cand) != 1:
            raise ValueError(
                f"case {case!r} needs exactly one {baseline!r} and one {candidate!r} row in "
                f"column {column!r}; got {len(base)} and {len(cand)}"
            )
        row = {by: case}
        for metric in metrics:
            b = float(base[metric].iloc[0])
            c = float(cand[metric].iloc[0])
            row[metric] = 100.0 * (c - b) / b if b != 0.0 else np.nan
        rows.append(row)
    return pd.DataFrame(rows)


def relative_difference(
    reference: pd.DataFrame, other: pd.DataFrame, metrics: Sequence[str] | None = None
) -> pd.DataFrame:
    """``|other - reference| / |reference|`` per row and metric, for two tables of equal shape.

    Used for numerical checks (e.g. the same runs at ``dt`` and ``dt/2``). NaN where the
    reference is zero or either value is NaN.
    """
    metrics = metric_columns(reference) if metrics is None else list(metrics)
    if len(reference) != len(other):
        raise ValueError(f"tables must have the same rows; got {len(reference)} and {len(other)}")
    base = reference[metrics].to_numpy(dtype=float)
    alt = other[metrics].to_numpy(dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(base != 0.0, np.abs(alt - base) / np.abs(base), np.nan)
    return pd.DataFrame(ratio, columns=metrics, index=reference.index)
