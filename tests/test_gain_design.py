"""Gain design for Theorem 1: reproducible, within its bound, beyond the paper, conservative."""

from __future__ import annotations

import math

import numpy as np
import pytest

from delaytrack.analysis import GainDesign, design_gains, exact_delay_margin, razumikhin_bound

PAPER_H_M = 0.12487  # K1 = K2 = Q = I, beta = 1, r = 1.1 (docs/decisions.md D8)


@pytest.fixture(scope="module")
def paper_bound_design() -> GainDesign:
    return design_gains(n=2, gain_bound=1.0, seed=0)


def test_same_seed_same_design(paper_bound_design):
    again = design_gains(n=2, gain_bound=1.0, seed=0)
    for name in ("K1", "K2", "Q"):
        np.testing.assert_array_equal(getattr(again, name), getattr(paper_bound_design, name))
    assert (again.beta, again.h_m, again.evaluations) == (
        paper_bound_design.beta,
        paper_bound_design.h_m,
        paper_bound_design.evaluations,
    )


def test_design_under_the_paper_bound(paper_bound_design):
    design = paper_bound_design
    assert design.n == 2
    assert np.all(np.diag(design.K1) <= 1.0) and np.all(np.diag(design.K2) <= 1.0)
    assert np.count_nonzero(design.K1 - np.diag(np.diag(design.K1))) == 0
    assert design.h_m >= PAPER_H_M
    assert design.reference_h_m == pytest.approx(PAPER_H_M, abs=1e-5)
    assert design.h_m == pytest.approx(0.12682, abs=1e-5)  # measured, docs/margins.md
    assert design.bound_active


def test_certified_value_is_theorem_1_of_the_returned_matrices(paper_bound_design):
    design = paper_bound_design
    again = razumikhin_bound(design.K1, design.K2, design.Q, design.beta, design.r)
    assert design.h_m == again.h_m == design.bound.h_m
    assert design.exact.h == exact_delay_margin(design.K1, design.K2).h


def test_certificate_is_conservative(paper_bound_design):
    assert paper_bound_design.exact.h >= paper_bound_design.h_m


def test_no_nearby_feasible_design_certifies_more(paper_bound_design):
    design = paper_bound_design
    rng = np.random.default_rng(0)
    k1, k2, q_v = design.K1[0, 0], design.K2[0, 0], design.Q[-1, -1]
    for factors in np.exp(rng.uniform(-0.05, 0.05, (200, 4))):
        trial_k1, trial_k2 = min(k1 * factors[0], 1.0), min(k2 * factors[1], 1.0)
        trial = razumikhin_bound(
            trial_k1, trial_k2, [1.0, q_v * factors[2]], design.beta * factors[3], design.r
        )
        assert trial.h_m <= design.h_m * (1.0 + 1e-9)


def test_looser_bound_is_inactive_and_the_optimum_is_interior():
    design = design_gains(n=1, gain_bound=10.0, seed=0)
    assert not design.bound_active
    assert design.h_m == pytest.approx(0.12684, abs=1e-5)  # measured, docs/margins.md
    assert design.exact.h >= design.h_m


def test_least_bandwidth_binds_and_costs_certified_delay():
    design = design_gains(gain_bound=100.0, min_bandwidth=2.0, seed=0)
    assert design.K1[0, 0] >= 4.0 and design.bandwidth_active and not design.bound_active
    assert design.h_m == pytest.approx(0.08879, abs=1e-5)  # measured, docs/margins.md
    assert design.h_m < PAPER_H_M  # a faster loop is certified for less
    assert design.exact.h >= design.h_m
    loose = design_gains(gain_bound=100.0, min_bandwidth=0.5, seed=0)
    assert not loose.bandwidth_active  # the unconstrained optimum has sqrt(k1) = 1.014
    assert loose.min_bandwidth == 0.5


def test_one_axis_design_serves_every_n(paper_bound_design):
    single = design_gains(n=1, gain_bound=1.0, seed=0)
    assert single.h_m == pytest.approx(paper_bound_design.h_m, rel=1e-12)


def test_h_m_scales_as_one_over_sqrt_r_with_beta_rescaled(paper_bound_design):
    design = paper_bound_design
    for r in (1.01, 2.0):
        scaled = razumikhin_bound(
            design.K1, design.K2, design.Q, design.beta * math.sqrt(r / design.r), r
        )
        assert scaled.h_m == pytest.approx(design.h_m * math.sqrt(design.r / r), rel=1e-12)


def test_h_m_does_not_depend_on_the_scale_of_Q(paper_bound_design):
    design = paper_bound_design
    scaled = razumikhin_bound(design.K1, design.K2, 37.0 * design.Q, design.beta, design.r)
    assert scaled.h_m == pytest.approx(design.h_m, rel=1e-12)


@pytest.mark.parametrize(
    "options, error, words",
    [
        ({"n": 0}, ValueError, "n must be a positive integer (the number of joints); got 0"),
        ({"gain_bound": 0.0}, ValueError, "gain_bound must be > 0; got 0"),
        ({"gain_bound": math.inf}, ValueError, "gain_bound must be finite"),
        ({"gain_bound": "1"}, TypeError, "gain_bound must be a real number; got '1'"),
        ({"r": 1.0}, ValueError, "r must be > 1"),
        (
            {"min_bandwidth": -1.0},
            ValueError,
            "min_bandwidth must be > 0 rad/s (the least natural frequency sqrt(k1)); got -1",
        ),
        (
            {"min_bandwidth": 2.0},
            ValueError,
            "min_bandwidth = 2 rad/s needs K1 entries >= 4, above gain_bound = 1",
        ),
        ({"seed": -1}, ValueError, "seed must be a non-negative integer; got -1"),
        ({"seed": 1.5}, ValueError, "seed must be a non-negative integer; got 1.5"),
    ],
)
def test_bad_options_are_refused_with_a_clear_message(options, error, words):
    with pytest.raises(error) as raised:
        design_gains(**options)
    assert words in str(raised.value)


def test_the_searched_closed_form_is_theorem_1_of_one_axis():
    # The search maximises a closed form of Theorem 1 for one axis; it must be razumikhin_bound.
    from delaytrack.analysis.gain_design import _closed_form_h_m

    # Within e^±3 razumikhin_bound's own error, measured against the closed form, stays below
    # 1.2e-12 (4.5e-15 within e^±1); 1e-10 leaves room for that and nothing more.
    rng = np.random.default_rng(3)
    for log_parameters in rng.uniform(-3.0, 3.0, (300, 4)):
        k1, k2, q_v, gamma = np.exp(log_parameters)
        r = 1.0 + np.exp(rng.uniform(-5.0, 5.0))
        expected = razumikhin_bound(k1, k2, [1.0, q_v], math.sqrt(r) * gamma, r).h_m
        assert _closed_form_h_m(log_parameters, r) == pytest.approx(expected, rel=1e-10)
    assert _closed_form_h_m(np.zeros(4), 1.0) > 0.0
    assert _closed_form_h_m(np.log([1.0, 1.0, 1.0, 1.0 / math.sqrt(1.1)]), 1.1) == pytest.approx(
        PAPER_H_M, abs=1e-5
    )
    # k1 = k2 = e^400 are doubles, but k1² and the terms of E overflow: refused as h_m = 0.
    assert _closed_form_h_m(np.array([400.0, 400.0, 0.0, 0.0]), 1.1) == 0.0
    assert _closed_form_h_m(np.array([800.0, 0.0, 0.0, 0.0]), 1.1) == 0.0  # exp overflows
