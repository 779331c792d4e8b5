"""Confidence intervals of the studies over drawn robots: Wilson's score interval of a share and
the percentile bootstrap's interval of a median."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

__all__ = ["median_interval", "wilson_interval"]


#: The standard normal quantile of a two-sided 95 % interval.
Z95 = 1.959963984540054


def wilson_interval(k: int, n: int, z: float = Z95) -> tuple[float, float]:
    """Wilson score interval (95 % by default) of a proportion ``p = k / n``.

    ``(c - w, c + w)`` clipped to ``[0, 1]``, with ``c = (p + z²/2n) / (1 + z²/n)`` and
    ``w = z √(p (1 - p)/n + z²/4n²) / (1 + z²/n)``; ``(nan, nan)`` for ``n = 0``. At ``k = 0``
    the lower end is exactly 0 and at ``k = n`` the upper end exactly 1 (``c = w`` there; in
    floating point their difference is a rounding error such as 2.8e-17).
    """
    if n == 0:
        return math.nan, math.nan
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    low = 0.0 if k == 0 else max(0.0, centre - half)
    high = 1.0 if k == n else min(1.0, centre + half)
    return low, high


def median_interval(values: Sequence[float], seed: int = 0) -> tuple[float, float, float]:
    """Median and its percentile-bootstrap 95 % interval (:func:`scipy.stats.bootstrap`, 2000
    resamples); NaN where fewer than two values are given."""
    data = np.asarray(values, dtype=float)
    if len(data) == 0:
        return math.nan, math.nan, math.nan
    median = float(np.median(data))
    if len(data) < 2 or np.all(data == data[0]):
        return median, median if len(data) > 1 else math.nan, median if len(data) > 1 else math.nan
    from scipy import stats  # imported here: 0.4 s that a command not drawing intervals skips

    # The percentile interval needs only the resampled medians; SciPy's standard error of
    # them may overflow for huge values (a wound-up controller's TV), harmlessly.
    with np.errstate(over="ignore", invalid="ignore"):
        result = stats.bootstrap(
            (data,),
            np.median,
            n_resamples=2000,
            method="percentile",
            random_state=np.random.default_rng(seed),
        )
    return median, float(result.confidence_interval.low), float(result.confidence_interval.high)
