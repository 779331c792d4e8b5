"""The verdicts of the robustness study (``delaytrack.experiments.verdicts``) on hand-built draws
whose answer is known: survival and accuracy judged apart, every draw counted once, Holm's
correction against a hand computation."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from delaytrack.experiments.verdicts import (
    MIN_DECIDED,
    attribution,
    claim_verdicts,
    holm,
    survival_verdicts,
    verdict_counts,
)

INF = math.inf


def draws(arolc, baseline, *, scenario="S1", noise="off", baseline_name="PCON"):
    """Claims runs of one scenario: AE per draw (``inf``: the run diverged) for both AROLCs and
    the baseline; TV 1 N·m everywhere."""
    rows = []
    for draw, (a, b) in enumerate(zip(arolc, baseline, strict=True)):
        for name, ae in (("AROLC (paper gains)", a), (baseline_name, b), ("AROLC (tuned)", a)):
            rows.append(
                dict(
                    scenario=scenario,
                    noise=noise,
                    controller=name,
                    draw=draw,
                    ae_mm=ae,
                    tv_Nm=1.0,
                    diverged=not math.isfinite(ae),
                )
            )
    return pd.DataFrame(rows)


def ae_row(table, scenario="S1", controller="AROLC (paper gains)"):
    chosen = table[
        (table.scenario == scenario)
        & (table.controller == controller)
        & table.claim.str.startswith("AE below")
    ]
    assert len(chosen) == 1
    return chosen.iloc[0]


def test_staying_on_the_path_and_accuracy_get_separate_verdicts():
    # The baseline diverges in 30 of 40 draws; in the 10 where both stayed on the path AROLC's
    # AE is larger every time: better at staying on the path, worse in accuracy.
    arolc = [5.0] * 40
    baseline = [INF] * 30 + [2.0] * 10
    row = ae_row(claim_verdicts(draws(arolc, baseline)))
    assert row.survival_verdict == "holds"  # AROLC stays on the path more often
    assert row.accuracy_verdict == "fails"  # and is less accurate where both did
    assert (row.a_stayed, row.b_stayed) == (40, 10)
    assert (row.only_a_diverged, row.only_b_diverged, row.both_diverged) == (0, 30, 0)
    assert (row.both_stayed, row.a_lower, row.b_lower, row.ties) == (10, 0, 10, 0)
    assert row.a_lower_share == 0.0 and row.median_difference == 3.0
    assert row.survival_p == pytest.approx(stats.binomtest(30, 30).pvalue)
    assert row.accuracy_p == pytest.approx(2 * 0.5**10)
    low, high = stats.binomtest(10, 40).proportion_ci(method="wilson")
    assert (row.b_stayed_ci_low, row.b_stayed_ci_high) == pytest.approx((low, high))


def test_every_draw_is_in_exactly_one_category():
    rng = np.random.default_rng(3)
    arolc = np.where(rng.random(40) < 0.3, INF, rng.uniform(1, 3, 40))
    baseline = np.where(rng.random(40) < 0.4, INF, rng.uniform(1, 3, 40))
    table = claim_verdicts(draws(arolc, baseline))
    parts = table.both_stayed + table.only_a_diverged + table.only_b_diverged + table.both_diverged
    assert (parts == table.draws).all() and (table.draws == 40).all()
    assert ((table.a_lower + table.b_lower + table.ties) == table.both_stayed).all()
    assert (table.a_stayed == 40 - table.only_a_diverged - table.both_diverged).all()
    # The TV claims tie everywhere (1 N·m): no accuracy decision, and the reason says so.
    tv = table[table.claim.str.startswith("TV")]
    assert tv.accuracy_verdict.str.contains("tied").all()


def test_too_few_decided_draws_give_no_decision_with_the_reason():
    # Only one side diverged in 5 draws, both stayed in 5: an exact test cannot reach 5 %.
    arolc = [1.0] * 10
    baseline = [INF] * (MIN_DECIDED - 1) + [2.0] * (10 - MIN_DECIDED + 1)
    row = ae_row(claim_verdicts(draws(arolc, baseline)))
    assert row.survival_verdict.startswith("no decision (one side diverged in only 5 draws")
    assert row.accuracy_verdict.startswith("no decision (both stayed on the path and differed")
    assert math.isnan(row.survival_p) and math.isnan(row.survival_p_holm)
    none = ae_row(claim_verdicts(draws([INF] * 10, [INF] * 10)))
    assert none.survival_verdict == "no decision (both diverged in every draw)"
    assert none.accuracy_verdict == "no decision (in no draw did both stay on the path)"
    clean = ae_row(claim_verdicts(draws([1.0] * 10, [2.0] * 10)))
    assert clean.survival_verdict == "no decision (both stayed on the path in every draw)"
    assert clean.accuracy_verdict == "holds"


def test_holm_matches_a_hand_computation():
    p = [0.01, 0.04, math.nan, 0.03, 0.005]
    # Sorted: 0.005, 0.01, 0.03, 0.04 (m = 4): 4·0.005, 3·0.01, 2·0.03, 1·0.04, running max.
    expected = [0.03, 0.06, math.nan, 0.06, 0.02]
    np.testing.assert_allclose(holm(p), expected, rtol=1e-12)
    assert holm([0.5, 0.9]).tolist() == [1.0, 1.0]
    assert holm([]).size == 0


def test_the_correction_spans_every_verdict_of_the_study():
    # Two noise levels, two scenarios: every test in one family, each pair's survival test once.
    one = draws([1.0] * 14 + [INF] * 6, [2.0] * 8 + [INF] * 12)
    frames = [
        one.assign(scenario=case, noise=noise) for case in ("S1", "S2") for noise in ("off", "on")
    ]
    table = claim_verdicts(pd.concat(frames, ignore_index=True))
    survival = survival_verdicts(table)
    assert len(survival) == 2 * 2 * 2  # scenarios x noise levels x AROLCs; AE and TV share one
    assert "claim" not in survival
    assert not any(c.startswith(("accuracy", "a_lower", "b_lower")) for c in survival.columns)
    family = np.concatenate([survival.survival_p, table.accuracy_p])
    m = np.isfinite(family).sum()
    row = ae_row(table[table.noise == "on"], "S2", "AROLC (tuned)")
    adjusted = holm(family)
    position = np.flatnonzero(table.index == row.name)[0] + len(survival)
    assert row.accuracy_p_holm == pytest.approx(adjusted[position])
    assert row.accuracy_p_holm >= row.accuracy_p and m == len(survival) + 2 * 2 * 2
    counts = verdict_counts(table)
    every = counts[counts.noise == "all"].set_index("kind")
    assert every.loc["survival", "verdicts"] == len(survival)
    assert every.loc["accuracy", "verdicts"] == len(table)
    parts = counts[["holds", "fails", "undecided", "no_decision"]].sum(axis=1)
    assert (parts == counts.verdicts).all()


def test_the_growth_claim_pairs_s3_with_s4():
    s3 = draws([1.0] * 20, [1.0] * 20, scenario="S3", baseline_name="PCONf")
    s4 = draws([3.0] * 14 + [INF] * 6, [1.0] * 20, scenario="S4", baseline_name="PCONf")
    table = claim_verdicts(pd.concat([s3, s4], ignore_index=True))
    row = table[(table.claim == "AE grows from S3 to S4") & (table.controller == "AROLC (tuned)")]
    row = row.iloc[0]
    assert (row.side_a, row.side_b) == ("AROLC (tuned) in S3", "AROLC (tuned) in S4")
    assert (row.only_b_diverged, row.both_stayed, row.a_lower) == (6, 14, 14)
    assert row.median_difference == -2.0  # S3 minus S4
    assert row.accuracy_verdict == "holds"


def test_attribution_shows_what_the_part_costs_in_staying_on_the_path():
    rows = []
    for draw in range(10):
        for name, ae in (
            ("AROLC (tuned)", INF if draw < 4 else 2.0),
            ("outer loop (tuned gains)", 3.0),
        ):
            rows.append(
                dict(
                    scenario="S4",
                    noise="on",
                    controller=name,
                    draw=draw,
                    ae_mm=ae,
                    tv_Nm=1.0,
                    diverged=not math.isfinite(ae),
                )
            )
    frame = pd.DataFrame(rows)
    part = attribution_of(frame)
    assert (part.diverged_with, part.diverged_without, part.draws_compared) == (4, 0, 6)
    assert part.median_change_ae_mm == -1.0


def attribution_of(frame):
    """The 'Δu at the tuned gains' row of the attribution of ``frame`` (the other pairs' runs
    copied from the tuned ones)."""
    extra = []
    for name, source in (
        ("AROLC (paper gains)", "AROLC (tuned)"),
        ("outer loop (paper gains)", "outer loop (tuned gains)"),
    ):
        extra.append(frame[frame.controller == source].assign(controller=name))
    table = attribution(pd.concat([frame, *extra], ignore_index=True))
    return table[table.part == "Δu at the tuned gains"].iloc[0]


def test_wilson_interval_ends_exactly_at_zero_and_one():
    """At k = 0 the lower end is 0 and at k = n the upper end is 1 exactly (the formula's
    c - w and c + w round to 2.8e-17 and 0.9999999999999999 there)."""
    from delaytrack.experiments.intervals import wilson_interval

    for n in (1, 12, 80, 1001):
        assert wilson_interval(0, n)[0] == 0.0 and wilson_interval(n, n)[1] == 1.0
        if n > 1:
            low, high = wilson_interval(1, n)
            assert 0.0 < low < high < 1.0


@pytest.mark.parametrize("p_values", [[-0.5, 0.2], [0.1, 2.0], [0.1, math.inf]])
def test_holm_refuses_what_is_not_a_p_value(p_values):
    with pytest.raises(ValueError, match=r"p_values must be p-values in \[0, 1\]"):
        holm(p_values)
