"""The paper's claims decided draw by draw, and what each part of AROLC contributes.

Every comparison pairs two controllers on the same drawn robots (common random numbers): per
draw, a run that diverged counts as ``+inf``, so it loses. A claim "A below B" holds in a draw
when ``a < b``; draws where both diverged decide nothing and are counted apart. Its verdict
comes from the share ``k / n`` of decided draws in which it holds: *holds* when the Wilson 95 %
interval of that share lies above one half, *fails* when below, *undecided* otherwise. Sizes
are paired medians (``a − b`` over draws where both stayed on the path) with percentile-bootstrap
95 % intervals.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from delaytrack.experiments.intervals import median_interval, wilson_interval
from delaytrack.experiments.pairing import BASELINE

__all__ = ["ATTRIBUTION", "attribution", "attribution_ranges", "claim_verdicts"]

#: The controllers whose claims are judged: AROLC with the paper's and with the tuned gains.
_CLAIMANTS = ("AROLC (paper gains)", "AROLC (tuned)")


def _per_draw(frame: pd.DataFrame, who: str, column: str) -> pd.Series:
    """``column`` of controller ``who`` indexed by draw (diverged runs: +inf); each draw once."""
    rows = frame[frame.controller == who]
    if rows.draw.duplicated().any():
        raise ValueError(f"{who!r} has more than one run per draw")
    return pd.Series(np.where(rows.diverged, np.inf, rows[column]), index=rows.draw.to_numpy())


def _paired(frame: pd.DataFrame, a: str, b: str, column: str) -> tuple[np.ndarray, np.ndarray]:
    """``column`` of controllers ``a`` and ``b`` on the same draws (diverged runs: +inf)."""
    first, second = _per_draw(frame, a, column), _per_draw(frame, b, column)
    if set(first.index) != set(second.index):
        raise ValueError(f"{a!r} and {b!r} were not run on the same draws")
    draws = np.sort(first.index.to_numpy())
    return first[draws].to_numpy(float), second[draws].to_numpy(float)


def _verdict(a: np.ndarray, b: np.ndarray) -> dict[str, Any]:
    """Whether ``a < b`` draw by draw. Draws where both diverged decide nothing and are left
    out (counted); the share and its Wilson interval are over the decided draws. The paired
    median difference ``a − b`` over draws where both stayed on the path gives the size."""
    both = np.isinf(a) & np.isinf(b)
    holds = (a < b)[~both]
    k, n = int(holds.sum()), len(holds)
    low, high = wilson_interval(k, n)
    if n == 0:
        verdict = "no decision (both diverged in every draw)"
    else:
        verdict = "holds" if low > 0.5 else "fails" if high < 0.5 else "undecided"
    finite = np.isfinite(a) & np.isfinite(b)
    median, d_low, d_high = median_interval(a[finite] - b[finite], seed=2)
    return {
        "share_holds": k / n if n else math.nan,
        "ci_low": low,
        "ci_high": high,
        "verdict": verdict,
        "draws_decided": n,
        "draws_both_diverged": int(both.sum()),
        "median_difference": median,
        "difference_ci_low": d_low,
        "difference_ci_high": d_high,
    }


def claim_verdicts(claims: pd.DataFrame) -> pd.DataFrame:
    """The paper's claims per scenario and noise level, for AROLC with the paper's and the
    tuned gains: AE below the baseline, TV below the baseline, and AROLC's AE larger in S4 than
    in S3 — each decided draw by draw on the same robots (:func:`_verdict`: a diverged run
    loses, a draw where both diverged is left out). ``median_difference`` is in mm for AE and
    N·m for TV (AROLC minus the baseline; S4 minus S3)."""
    rows = []
    for (case, noise), frame in claims.groupby(["scenario", "noise"], sort=False):
        baseline = BASELINE[case]
        for who in _CLAIMANTS:
            for metric, column in (("AE", "ae_mm"), ("TV", "tv_Nm")):
                a, b = _paired(frame, who, baseline, column)
                rows.append(
                    {
                        "scenario": case,
                        "noise": noise,
                        "claim": f"{metric} below {baseline}",
                        "controller": who,
                        **_verdict(a, b),
                    }
                )
    for noise in claims.noise.unique():
        s3 = claims[(claims.scenario == "S3") & (claims.noise == noise)]
        s4 = claims[(claims.scenario == "S4") & (claims.noise == noise)]
        if s3.empty or s4.empty:
            continue
        for who in _CLAIMANTS:
            first, second = _per_draw(s3, who, "ae_mm"), _per_draw(s4, who, "ae_mm")
            draws = np.sort(first.index.to_numpy())
            # "AE grows": S3's AE below S4's, draw by draw.
            verdict = _verdict(first[draws].to_numpy(float), second[draws].to_numpy(float))
            for key in ("median_difference", "difference_ci_low", "difference_ci_high"):
                verdict[key] = -verdict[key]  # S4 minus S3
            low, high = verdict["difference_ci_low"], verdict["difference_ci_high"]
            verdict["difference_ci_low"], verdict["difference_ci_high"] = high, low
            rows.append(
                {
                    "scenario": "S3 -> S4",
                    "noise": noise,
                    "claim": "AE grows from S3 to S4",
                    "controller": who,
                    **verdict,
                }
            )
    return pd.DataFrame(rows)


#: Attribution pairs: (what, the controller with it, the controller without it).
ATTRIBUTION = (
    ("Δu at the paper's gains", "AROLC (paper gains)", "outer loop (paper gains)"),
    ("Δu at the tuned gains", "AROLC (tuned)", "outer loop (tuned gains)"),
    ("tuning (AROLC)", "AROLC (tuned)", "AROLC (paper gains)"),
)


def attribution(claims: pd.DataFrame) -> pd.DataFrame:
    """What each part contributes: the paired change of AE and TV from the second controller of
    each :data:`ATTRIBUTION` pair to the first (medians over draws with bootstrap intervals;
    draws where either diverged are left out and counted)."""
    rows = []
    for (case, noise), frame in claims.groupby(["scenario", "noise"], sort=False):
        for what, with_it, without in ATTRIBUTION:
            out = {"scenario": case, "noise": noise, "part": what}
            for metric, column in (("ae", "ae_mm"), ("tv", "tv_Nm")):
                a, b = _paired(frame, with_it, without, column)
                both = np.isfinite(a) & np.isfinite(b)
                median, low, high = median_interval(a[both] - b[both], seed=1)
                unit = "mm" if metric == "ae" else "Nm"
                out[f"median_change_{metric}_{unit}"] = median
                out[f"change_ci_low_{metric}_{unit}"] = low
                out[f"change_ci_high_{metric}_{unit}"] = high
            out["draws_compared"] = int(both.sum())
            rows.append(out)
    return pd.DataFrame(rows)


def attribution_ranges(table: pd.DataFrame) -> pd.DataFrame:
    """Per noise level and part of an :func:`attribution` table: the range over scenarios of
    its median change of AE (mm) and TV (N·m), and the scenarios in which no draw could be
    compared (``not_compared``, a tuple: in no draw did both stay on the path)."""
    rows = []
    for (noise, part), group in table.groupby(["noise", "part"], sort=False):
        ae, tv = group.median_change_ae_mm, group.median_change_tv_Nm
        rows.append(
            {
                "noise": noise,
                "part": part,
                "ae_change_min_mm": ae.min(),
                "ae_change_max_mm": ae.max(),
                "tv_change_min_Nm": tv.min(),
                "tv_change_max_Nm": tv.max(),
                "not_compared": tuple(group[group.draws_compared == 0].scenario),
            }
        )
    return pd.DataFrame(rows)
