"""The paper's claims judged draw by draw, staying on the path apart from accuracy, and what each
part of AROLC contributes.

Every comparison pairs two sides, A and B, on the same drawn robots (common random numbers) and
puts every draw in exactly one of four categories: both stayed on the path, only A diverged, only
B diverged, both diverged. Two questions are then asked apart, each with its own verdict:

- **Survival**: does A stay on the path more often than B? Per side, the share of the draws that
  stayed on the path with its Wilson 95 % interval; the paired test is McNemar's exact test:
  under equal survival, the draws in which only B diverged are ``Binomial(n_d, 1/2)`` among the
  ``n_d`` draws in which only one side diverged.
- **Accuracy given both stayed on the path**: over the draws where both did, is ``a < b`` more
  often than not? The share of those draws with ``a < b`` (ties counted apart and left out of the
  share) with its Wilson interval, the sign test (``Binomial(n, 1/2)`` over the ``n`` untied
  draws), and the paired median of ``a − b`` with its percentile-bootstrap 95 % interval.

Each p-value is the exact two-sided binomial test against one half on the decided draws
(:func:`scipy.stats.binomtest`). Many verdicts are tested together, so every test of the study
(both kinds, every scenario and noise level) is corrected as one family with Holm's step-down
method (:func:`holm`): a verdict *holds* when its Holm-adjusted p is at most :data:`ALPHA` and A
wins more of the decided draws than B, *fails* when the adjusted p is at most :data:`ALPHA` and
B wins more, and is *undecided* otherwise. An exact two-sided test on ``n`` draws cannot give a p
below ``2^(1−n)``: with fewer than :data:`MIN_DECIDED` decided draws the verdict is
``"no decision (...)"`` with the reason, and that test is left out of the family (it can never be
rejected, so the family-wise error rate stays at most :data:`ALPHA`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd

from delaytrack._validation import ArgumentError
from delaytrack.experiments.intervals import median_interval, wilson_interval
from delaytrack.experiments.pairing import BASELINE

__all__ = [
    "ALPHA",
    "ATTRIBUTION",
    "MIN_DECIDED",
    "VERDICT_KINDS",
    "attribution",
    "attribution_ranges",
    "claim_verdicts",
    "holm",
    "survival_verdicts",
    "verdict_counts",
]

#: Family-wise error rate of the verdicts (Holm).
ALPHA = 0.05
#: Fewest decided draws with which an exact two-sided test can reach :data:`ALPHA`
#: (``2^(1−n) ≤ ALPHA``).
MIN_DECIDED = math.ceil(math.log2(2.0 / ALPHA))
#: The two kinds of verdict: staying on the path, and accuracy given both stayed on it.
VERDICT_KINDS = ("survival", "accuracy")
#: The controllers whose claims are judged: AROLC with the paper's and with the tuned gains.
_CLAIMANTS = ("AROLC (paper gains)", "AROLC (tuned)")
#: The columns that identify one survival comparison (the AE and TV claims of a pair share it).
_SURVIVAL_KEY = ["scenario", "noise", "side_a", "side_b"]
#: The claims' metrics and their columns of the claims runs (AE in mm, TV in N·m).
_METRICS = {"AE": "ae_mm", "TV": "tv_Nm"}


def _per_draw(frame: pd.DataFrame, who: str, column: str) -> pd.DataFrame:
    """``column`` (``value``) and ``diverged`` of controller ``who``, indexed by draw."""
    rows = frame[frame.controller == who]
    if rows.draw.duplicated().any():
        raise ValueError(f"{who!r} has more than one run per draw")
    return pd.DataFrame(
        {"value": rows[column].to_numpy(float), "diverged": rows.diverged.to_numpy(bool)},
        index=rows.draw.to_numpy(),
    ).sort_index()


def _paired(
    first: pd.DataFrame, a: str, second: pd.DataFrame, b: str, column: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``column`` and the divergence of controller ``a`` (in ``first``) and ``b`` (in
    ``second``) on the same draws: ``(a values, b values, a diverged, b diverged)``."""
    left, right = _per_draw(first, a, column), _per_draw(second, b, column)
    if not left.index.equals(right.index):
        raise ValueError(f"{a!r} and {b!r} were not run on the same draws")
    return (
        left.value.to_numpy(),
        right.value.to_numpy(),
        left.diverged.to_numpy(),
        right.diverged.to_numpy(),
    )


def _categories(a_diverged: np.ndarray, b_diverged: np.ndarray) -> tuple[int, int, int, int]:
    """Draws in which both stayed on the path, only A diverged, only B diverged, both diverged
    (every draw in exactly one)."""
    a, b = a_diverged, b_diverged
    return int((~a & ~b).sum()), int((a & ~b).sum()), int((~a & b).sum()), int((a & b).sum())


def _binomial_p(wins: int, losses: int) -> float:
    """Exact two-sided binomial test of ``wins`` among ``wins + losses`` draws against one half
    (:func:`scipy.stats.binomtest`); NaN with fewer than :data:`MIN_DECIDED` draws."""
    from scipy import stats  # imported here: 0.4 s that a command not testing verdicts skips

    n = wins + losses
    return float(stats.binomtest(wins, n, 0.5).pvalue) if n >= MIN_DECIDED else math.nan


def _too_few(n: int, what: str) -> str:
    return f"{what} in only {n} draws; an exact test needs {MIN_DECIDED} to reach {100 * ALPHA:g} %"


def _survival(a_diverged: np.ndarray, b_diverged: np.ndarray) -> dict[str, Any]:
    """Survival columns of one comparison (module docstring); ``survival_verdict`` is the
    "no decision" text or empty (decided after the family's correction)."""
    draws = len(a_diverged)
    both_stayed, only_a, only_b, both_diverged = _categories(a_diverged, b_diverged)
    out: dict[str, Any] = {"draws": draws}
    for side, diverged in (("a", a_diverged), ("b", b_diverged)):
        k = int((~diverged).sum())
        low, high = wilson_interval(k, draws)
        out[f"{side}_stayed"] = k
        out[f"{side}_stayed_share"] = k / draws if draws else math.nan
        out[f"{side}_stayed_ci_low"] = low
        out[f"{side}_stayed_ci_high"] = high
    out |= {
        "both_stayed": both_stayed,
        "only_a_diverged": only_a,
        "only_b_diverged": only_b,
        "both_diverged": both_diverged,
        "survival_p": _binomial_p(only_b, only_a),
    }
    discordant = only_a + only_b
    if discordant == 0:
        reason = (
            "both diverged in every draw"
            if both_diverged == draws
            else "both stayed on the path in every draw"
            if both_stayed == draws
            else "no draw in which only one side diverged"
        )
        out["survival_verdict"] = f"no decision ({reason})"
    elif discordant < MIN_DECIDED:
        out["survival_verdict"] = f"no decision ({_too_few(discordant, 'one side diverged')})"
    else:
        out["survival_verdict"] = ""
    return out


def _accuracy(
    a: np.ndarray, b: np.ndarray, a_diverged: np.ndarray, b_diverged: np.ndarray
) -> dict[str, Any]:
    """Accuracy columns of one claim over the draws where both stayed on the path (module
    docstring); ``accuracy_verdict`` as ``survival_verdict`` of :func:`_survival`."""
    kept = ~a_diverged & ~b_diverged
    x, y = a[kept], b[kept]
    lower, higher = int((x < y).sum()), int((x > y).sum())
    untied = lower + higher
    low, high = wilson_interval(lower, untied)
    median, d_low, d_high = median_interval(x - y, seed=2)
    if not kept.any():
        verdict = "no decision (in no draw did both stay on the path)"
    elif untied == 0:
        verdict = "no decision (the sides tied in every draw where both stayed on the path)"
    elif untied < MIN_DECIDED:
        verdict = f"no decision ({_too_few(untied, 'both stayed on the path and differed')})"
    else:
        verdict = ""
    return {
        "a_lower": lower,
        "b_lower": higher,
        "ties": len(x) - untied,
        "a_lower_share": lower / untied if untied else math.nan,
        "a_lower_ci_low": low,
        "a_lower_ci_high": high,
        "median_difference": median,
        "difference_ci_low": d_low,
        "difference_ci_high": d_high,
        "accuracy_p": _binomial_p(lower, higher),
        "accuracy_verdict": verdict,
    }


def holm(p_values: Sequence[float] | np.ndarray) -> np.ndarray:
    """Holm's step-down adjusted p-values of one family of tests.

    With the ``m`` finite p-values sorted, ``p_(1) ≤ … ≤ p_(m)``, the adjusted
    ``p̃_(i) = max_{j ≤ i} min(1, (m − j + 1) p_(j))``; rejecting where ``p̃ ≤ α`` keeps the
    probability of any false rejection in the family at most ``α``. NaN (no test) stays NaN and
    is not counted in ``m``; a p-value outside ``[0, 1]`` is refused.
    """
    p = np.asarray(p_values, dtype=float)
    outside = p[~np.isnan(p) & ~((p >= 0) & (p <= 1))]
    if outside.size:
        raise ArgumentError(
            "p_values", f"must be p-values in [0, 1] (NaN: no test); got {outside.tolist()}"
        )
    adjusted = np.full(p.shape, np.nan)
    tested = np.flatnonzero(np.isfinite(p))
    order = tested[np.argsort(p[tested], kind="stable")]
    m = len(order)
    adjusted[order] = np.maximum.accumulate(np.minimum(1.0, (m - np.arange(m)) * p[order]))
    return adjusted


def _decided(p_holm: float, wins: int, losses: int) -> str:
    """The verdict of a test with at least :data:`MIN_DECIDED` decided draws."""
    if p_holm <= ALPHA:
        return "holds" if wins > losses else "fails"
    return "undecided"


def _comparison(
    first: pd.DataFrame, second: pd.DataFrame, a: str, b: str, column: str
) -> dict[str, Any]:
    """The survival columns of one comparison (:func:`_survival`), then its accuracy columns
    (:func:`_accuracy`)."""
    values_a, values_b, diverged_a, diverged_b = _paired(first, a, second, b, column)
    return {
        **_survival(diverged_a, diverged_b),
        **_accuracy(values_a, values_b, diverged_a, diverged_b),
    }


def claim_verdicts(claims: pd.DataFrame) -> pd.DataFrame:
    """The paper's claims per scenario and noise level, for AROLC with the paper's and the
    tuned gains: AE below the baseline, TV below the baseline, and AROLC's AE larger in S4 than
    in S3 (side A: AROLC in S3, side B: in S4), each judged for survival and for accuracy given
    both stayed on the path (module docstring), corrected with Holm over every test of the
    table.

    One row per claim: ``side_a``, ``side_b`` and ``draws``; survival: per side the draws that
    stayed on the path (``a_stayed``, ``b_stayed``) with their shares and Wilson intervals, the
    draws where ``both_stayed``, ``only_a_diverged``, ``only_b_diverged`` and ``both_diverged``
    (summing to ``draws``), ``survival_p``, ``survival_p_holm`` and ``survival_verdict`` (holds:
    A stays on the path more often; the AE and TV claims of a pair share one survival test);
    accuracy over the ``both_stayed`` draws: ``a_lower``, ``b_lower``, ``ties``,
    ``a_lower_share`` with its Wilson interval, the paired ``median_difference`` ``a − b`` (mm
    for AE, N·m for TV) with its bootstrap interval, ``accuracy_p``, ``accuracy_p_holm`` and
    ``accuracy_verdict`` (holds: ``a < b`` in more draws).
    """
    rows = []
    for (case, noise), frame in claims.groupby(["scenario", "noise"], sort=False):
        baseline = BASELINE[case]
        for who in _CLAIMANTS:
            for metric, column in _METRICS.items():
                rows.append(
                    {
                        "scenario": case,
                        "noise": noise,
                        "claim": f"{metric} below {baseline}",
                        "controller": who,
                        "side_a": who,
                        "side_b": baseline,
                        **_comparison(frame, frame, who, baseline, column),
                    }
                )
    for noise in claims.noise.unique():
        s3 = claims[(claims.scenario == "S3") & (claims.noise == noise)]
        s4 = claims[(claims.scenario == "S4") & (claims.noise == noise)]
        if s3.empty or s4.empty:
            continue
        for who in _CLAIMANTS:
            rows.append(
                {
                    "scenario": "S3 -> S4",
                    "noise": noise,
                    "claim": "AE grows from S3 to S4",
                    "controller": who,
                    "side_a": f"{who} in S3",
                    "side_b": f"{who} in S4",
                    **_comparison(s3, s4, who, who, _METRICS["AE"]),
                }
            )
    table = pd.DataFrame(rows)
    # One family: each survival comparison once, every accuracy claim.
    pair = table.groupby(_SURVIVAL_KEY, sort=False).ngroup().to_numpy()
    survival_p = table.groupby(pair, sort=True).survival_p.first().to_numpy()
    adjusted = holm(np.concatenate([survival_p, table.accuracy_p.to_numpy()]))
    table.insert(
        table.columns.get_loc("survival_p") + 1,
        "survival_p_holm",
        adjusted[: len(survival_p)][pair],
    )
    table.insert(
        table.columns.get_loc("accuracy_p") + 1,
        "accuracy_p_holm",
        adjusted[len(survival_p) :],
    )
    for r in table.itertuples():
        if not r.survival_verdict:
            verdict = _decided(r.survival_p_holm, r.only_b_diverged, r.only_a_diverged)
            table.at[r.Index, "survival_verdict"] = verdict
        if not r.accuracy_verdict:
            verdict = _decided(r.accuracy_p_holm, r.a_lower, r.b_lower)
            table.at[r.Index, "accuracy_verdict"] = verdict
    return table


def survival_verdicts(verdicts: pd.DataFrame) -> pd.DataFrame:
    """The survival columns of a :func:`claim_verdicts` table, one row per comparison (the AE
    and TV claims of a pair share one): every column up to ``survival_verdict`` but ``claim``
    (the accuracy columns follow it, :func:`_comparison`)."""
    survival = verdicts.columns[: verdicts.columns.get_loc("survival_verdict") + 1]
    columns = [c for c in survival if c != "claim"]
    return verdicts.drop_duplicates(_SURVIVAL_KEY)[columns].reset_index(drop=True)


def verdict_counts(verdicts: pd.DataFrame) -> pd.DataFrame:
    """How many verdicts of a :func:`claim_verdicts` table hold, fail, are undecided or reach no
    decision, per kind (``survival``: one per comparison, :func:`survival_verdicts`;
    ``accuracy``: one per claim) and noise level, and over every noise level (``noise`` "all");
    ``verdicts`` is their total."""
    tables = {"survival": survival_verdicts(verdicts), "accuracy": verdicts}
    rows = []
    for kind in VERDICT_KINDS:
        table = tables[kind]
        for noise in [*table.noise.unique(), "all"]:
            chosen = table if noise == "all" else table[table.noise == noise]
            verdict = chosen[f"{kind}_verdict"]
            rows.append(
                {
                    "kind": kind,
                    "noise": noise,
                    "verdicts": len(verdict),
                    "holds": int((verdict == "holds").sum()),
                    "fails": int((verdict == "fails").sum()),
                    "undecided": int((verdict == "undecided").sum()),
                    "no_decision": int(verdict.str.startswith("no decision").sum()),
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
    """What each part contributes, per scenario and noise level, from the second controller of
    each :data:`ATTRIBUTION` pair to the first: the draws in which each diverged
    (``diverged_with``, ``diverged_without``: its cost or gain in staying on the path) and the
    four categories of :func:`claim_verdicts` (``draws_compared`` is ``both_stayed``), and over
    the draws where both stayed on the path the paired median change of AE and TV with bootstrap
    intervals."""
    rows = []
    for (case, noise), frame in claims.groupby(["scenario", "noise"], sort=False):
        for what, with_it, without in ATTRIBUTION:
            out: dict[str, Any] = {"scenario": case, "noise": noise, "part": what}
            for column in _METRICS.values():
                a, b, a_diverged, b_diverged = _paired(frame, with_it, frame, without, column)
                both = ~a_diverged & ~b_diverged
                median, low, high = median_interval(a[both] - b[both], seed=1)
                out[f"median_change_{column}"] = median
                out[f"change_ci_low_{column}"] = low
                out[f"change_ci_high_{column}"] = high
            both_stayed, only_with, only_without, both_diverged = _categories(
                a_diverged, b_diverged
            )
            out |= {
                "draws": len(a_diverged),
                "diverged_with": int(a_diverged.sum()),
                "diverged_without": int(b_diverged.sum()),
                "only_with_diverged": only_with,
                "only_without_diverged": only_without,
                "both_diverged": both_diverged,
                "draws_compared": both_stayed,
            }
            rows.append(out)
    return pd.DataFrame(rows)


def attribution_ranges(table: pd.DataFrame) -> pd.DataFrame:
    """Per noise level and part of an :func:`attribution` table: the range over scenarios of
    its median change of AE (mm) and TV (N·m), the draws in which the controller with the part
    and the one without it diverged, summed over scenarios (``diverged_with``,
    ``diverged_without``, of ``draws``), and the scenarios in which no draw could be compared
    (``not_compared``, a tuple: in no draw did both stay on the path)."""
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
                "draws": int(group.draws.sum()),
                "diverged_with": int(group.diverged_with.sum()),
                "diverged_without": int(group.diverged_without.sum()),
                "not_compared": tuple(group[group.draws_compared == 0].scenario),
            }
        )
    return pd.DataFrame(rows)
