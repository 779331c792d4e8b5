"""Outcomes of runs over drawn robots: divergence rates and medians per group, and how far in the
true delay each controller stays on the path.

A run *diverged* when it stopped, left the path or its mean AE exceeds the tuning's limit (the
``diverged`` column of the per-run frames). Divergence rates ``k / n`` carry Wilson 95 %
intervals; medians of AE and TV over the runs that stayed on the path carry percentile-bootstrap
95 % intervals (:mod:`~delaytrack.experiments.intervals`).
"""

from __future__ import annotations

import math

import pandas as pd

from delaytrack.experiments.intervals import median_interval, wilson_interval

__all__ = ["delay_reach", "outcome_table"]


def outcome_table(frame: pd.DataFrame, by: list[str]) -> pd.DataFrame:
    """Per group: runs, divergence rate with its Wilson interval, median AE (mm) and TV (N·m)
    of the runs that stayed on the path with bootstrap intervals."""
    rows = []
    for key, group in frame.groupby(by, sort=False, dropna=False):
        kept = group[~group.diverged]
        k, n = int(group.diverged.sum()), len(group)
        low, high = wilson_interval(k, n)
        ae = median_interval(kept.ae_mm)
        tv = median_interval(kept.tv_Nm)
        rows.append(
            {
                **dict(zip(by, key if isinstance(key, tuple) else (key,), strict=True)),
                "runs": n,
                "diverged": k,
                "divergence_rate": k / n,
                "divergence_ci_low": low,
                "divergence_ci_high": high,
                "median_ae_mm": ae[0],
                "median_ae_ci_low_mm": ae[1],
                "median_ae_ci_high_mm": ae[2],
                "median_tv_Nm": tv[0],
                "median_tv_ci_low_Nm": tv[1],
                "median_tv_ci_high_Nm": tv[2],
                **_received(kept),
                "median_t_stop_of_diverged_s": (
                    float(group[group.diverged].t_stop_s.median()) if k else math.nan
                ),
            }
        )
    return pd.DataFrame(rows)


def _received(kept: pd.DataFrame) -> dict[str, float]:
    """Of the runs that stayed on the path: how many wound up (their commands ran away from
    what the wheels received) and the median TV (N·m) of what the wheels received, with its
    bootstrap interval, when the runs have it (``tv_received_Nm``)."""
    if "tv_received_Nm" not in kept:
        return {}
    median, low, high = median_interval(kept.tv_received_Nm)
    return {
        "wound_up": int(kept.wound_up.sum()),
        "median_tv_received_Nm": median,
        "median_tv_received_ci_low_Nm": low,
        "median_tv_received_ci_high_Nm": high,
    }


def delay_reach(table: pd.DataFrame) -> pd.DataFrame:
    """How far in the true delay each controller stays on the path, from an
    :func:`outcome_table` per (``delay_ms``, ``controller``, ``scale``).

    One row per (controller, scale), in the table's order: ``draws`` (runs at the smallest
    delay), ``smallest_delay_ms`` and ``largest_delay_ms`` tested, ``longest_clean_delay_ms``
    (the largest delay below the smallest one at which a run diverged: up to it no run
    diverged; NaN when runs diverged already at the smallest delay),
    ``half_diverged_from_ms`` (the smallest delay at which at least half of the runs diverged;
    NaN when there is none) and ``diverged`` (runs that diverged, over every delay).
    """
    rows = []
    for (controller, scale), group in table.groupby(
        ["controller", "scale"], sort=False, dropna=False
    ):
        group = group.sort_values("delay_ms")
        first_bad = group[group.diverged > 0].delay_ms.min()
        clean = group if not math.isfinite(first_bad) else group[group.delay_ms < first_bad]
        rows.append(
            {
                "controller": controller,
                "scale": scale,
                "draws": int(group.runs.iloc[0]),
                "smallest_delay_ms": float(group.delay_ms.min()),
                "largest_delay_ms": float(group.delay_ms.max()),
                "longest_clean_delay_ms": float(clean.delay_ms.max()),
                "half_diverged_from_ms": float(group[group.divergence_rate >= 0.5].delay_ms.min()),
                "diverged": int(group.diverged.sum()),
            }
        )
    return pd.DataFrame(rows)
