"""Theorem 2 (ultimate bounds varpi_1..varpi_6): each bound re-derived independently."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
import scipy.linalg
import scipy.optimize

from delaytrack.analysis import UltimateBounds, psi_min, razumikhin_bound, ultimate_bounds

# The paper's gains K1 = K2 = Q = I, beta = 1, r = 1.1 (h_m = 0.12487 s) and its AROLC
# parameters alpha = 2, epsilon = 0.1, gamma = 0.001 (Section III). Gamma, Theta, c and c_hat are
# not in the paper; the values below are arbitrary but chosen so every coefficient is positive.
PAPER = razumikhin_bound(np.eye(2), np.eye(2), np.eye(4), beta=1.0, r=1.1)
B = np.vstack([np.zeros((2, 2)), np.eye(2)])
PAPER_BTP = float(np.linalg.norm(B.T @ PAPER.P, 2))

CASES = [
    dict(
        Psi_min=0.4, Gamma=0.3, Theta_norm=0.25, BtP_norm=1.1, c=2.0, c_hat=0.5, alpha=2.0,
        epsilon=0.1, gamma=0.001,
    ),
    dict(
        Psi_min=2.5, Gamma=0.01, Theta_norm=0.0, BtP_norm=0.3, c=0.7, c_hat=0.2, alpha=1.5,
        epsilon=0.05, gamma=0.1,
    ),
    dict(
        Psi_min=psi_min(PAPER, 0.06), Gamma=0.05, Theta_norm=0.4, BtP_norm=PAPER_BTP, c=1.5,
        c_hat=0.5, alpha=2.0, epsilon=0.1, gamma=0.001,
    ),
]  # fmt: skip


def derived_switching_bound(lmin, b, k, constant):
    """Cases (i)-(iii), re-derived: the smallest x with
    max over 0 <= ||s|| <= b x of (-1/2 lmin x^2 + k ||s|| + constant) = 0.
    The maximum sits at an end of the interval; found by root bracketing, not by the formula.
    """

    def worst_v_dot(x):
        return -0.5 * lmin * x**2 + max(0.0, k * b * x) + constant

    upper = 1.0
    while worst_v_dot(upper) >= 0.0:
        upper *= 2.0
    return scipy.optimize.brentq(worst_v_dot, 0.0, upper, xtol=1e-15, rtol=1e-14)


def derived_boundary_layer_bound(lmin, alpha, c_hat, epsilon, k, constant):
    """Cases (iv)-(vi), re-derived: maximise f(x) = -alpha c_hat x^2 / epsilon + k x over x >= 0
    numerically, then solve -1/2 lmin ||e||^2 + max f + constant = 0 for ||e||.
    """
    upper = 10.0 * epsilon * (abs(k) + 1.0) / (alpha * c_hat)
    result = scipy.optimize.minimize_scalar(
        lambda x: alpha * c_hat * x**2 / epsilon - k * x,
        bounds=(0.0, upper),
        method="bounded",
        options={"xatol": 1e-12},
    )
    return math.sqrt(2.0 * (max(-result.fun, 0.0) + constant) / lmin)


# --- each bound against the paper's inequality ---------------------------------------------


@pytest.mark.parametrize("p", CASES)
def test_varpi_1_is_root_of_case_i_quadratic(p):
    # Case (i), alpha >= 1: lmin ||e||^2 = 2 Gamma + 2 ||Theta|| ||B^T P|| ||e||.
    v = ultimate_bounds(**p).varpi_1
    lmin, theta, b, Gamma = p["Psi_min"], p["Theta_norm"], p["BtP_norm"], p["Gamma"]
    assert v > 0.0
    assert lmin * v**2 - 2.0 * theta * b * v - 2.0 * Gamma == pytest.approx(0.0, abs=1e-12)
    assert v == pytest.approx(derived_switching_bound(lmin, b, theta, Gamma), rel=1e-12)


@pytest.mark.parametrize("p", CASES)
def test_varpi_2_is_root_of_case_ii_quadratic(p):
    # Case (ii): k = 2c - (alpha + 1) c_hat + ||Theta|| (positive in all CASES).
    v = ultimate_bounds(**p).varpi_2
    k = 2 * p["c"] - (p["alpha"] + 1) * p["c_hat"] + p["Theta_norm"]
    assert k > 0.0
    lmin, b = p["Psi_min"], p["BtP_norm"]
    assert lmin * v**2 - 2.0 * k * b * v - 2.0 * p["Gamma"] == pytest.approx(0.0, abs=1e-12)
    assert v == pytest.approx(derived_switching_bound(lmin, b, k, p["Gamma"]), rel=1e-12)


@pytest.mark.parametrize("p", CASES)
def test_varpi_3_is_root_of_case_iii_quadratic_with_BtP(p):
    # Case (iii): k = c - alpha c_hat + ||Theta||, constant Gamma + gamma^2, and ||s|| <= b ||e||.
    v = ultimate_bounds(**p).varpi_3
    k = p["c"] - p["alpha"] * p["c_hat"] + p["Theta_norm"]
    assert k > 0.0
    lmin, b, constant = p["Psi_min"], p["BtP_norm"], p["Gamma"] + p["gamma"] ** 2
    assert lmin * v**2 - 2.0 * k * b * v - 2.0 * constant == pytest.approx(0.0, abs=1e-12)
    assert v == pytest.approx(derived_switching_bound(lmin, b, k, constant), rel=1e-12)


def test_printed_mu_3_without_BtP_is_not_certified():
    # The paper prints mu3 = (c - alpha c_hat + ||Theta||) / lmin. With ||B^T P|| = 2 the bound
    # from that mu3 is too small: at that ||e|| the paper's own V-dot bound is still positive.
    p = dict(CASES[0], BtP_norm=2.0)
    lmin, b, constant = p["Psi_min"], p["BtP_norm"], p["Gamma"] + p["gamma"] ** 2
    k = p["c"] - p["alpha"] * p["c_hat"] + p["Theta_norm"]
    mu3_printed = k / lmin
    printed = mu3_printed + math.sqrt(2.0 * constant / lmin + mu3_printed**2)
    assert -0.5 * lmin * printed**2 + k * b * printed + constant > 0.0
    assert ultimate_bounds(**p).varpi_3 > printed


@pytest.mark.parametrize("p", CASES)
def test_varpi_4_5_6_maximise_the_boundary_layer_quadratic(p):
    bounds = ultimate_bounds(**p)
    lmin, alpha, c_hat, eps = p["Psi_min"], p["alpha"], p["c_hat"], p["epsilon"]
    theta, c, Gamma, g = p["Theta_norm"], p["c"], p["Gamma"], p["gamma"]
    # k in case (iv): c_hat + ||Theta||; (v): 2c - c_hat + ||Theta||; (vi): c + ||Theta||,
    # with gamma^2 added to Gamma in case (vi).
    expected = [
        derived_boundary_layer_bound(lmin, alpha, c_hat, eps, c_hat + theta, Gamma),
        derived_boundary_layer_bound(lmin, alpha, c_hat, eps, 2 * c - c_hat + theta, Gamma),
        derived_boundary_layer_bound(lmin, alpha, c_hat, eps, c + theta, Gamma + g**2),
    ]
    actual = [bounds.varpi_4, bounds.varpi_5, bounds.varpi_6]
    np.testing.assert_allclose(actual, expected, rtol=1e-9)


def test_varpi_4_by_hand():
    # lmin = 2, Gamma = 1, Theta = 1, c_hat = 1, alpha = 2, epsilon = 0.5:
    #   (4*2*1*1 + 0.5*(1 + 1)^2) / (2*2*1*2) = 10/8,  varpi4 = sqrt(1.25).
    bounds = ultimate_bounds(
        Psi_min=2.0, Gamma=1.0, Theta_norm=1.0, BtP_norm=1.0, c=0.5, c_hat=1.0, alpha=2.0,
        epsilon=0.5, gamma=0.01,
    )  # fmt: skip
    assert bounds.varpi_4 == pytest.approx(math.sqrt(1.25), rel=1e-15)
    # Same inputs, case (vi): (4*2*1*(1 + 1e-4) + 0.5*(0.5 + 1)^2) / 8 = (8.0008 + 1.125)/8.
    assert bounds.varpi_6 == pytest.approx(math.sqrt(9.1258 / 8.0), rel=1e-15)


def test_as_tuple_order():
    bounds = ultimate_bounds(**CASES[0])
    assert isinstance(bounds, UltimateBounds)
    assert bounds.as_tuple() == (
        bounds.varpi_1,
        bounds.varpi_2,
        bounds.varpi_3,
        bounds.varpi_4,
        bounds.varpi_5,
        bounds.varpi_6,
    )


# --- where the printed formulas would under-estimate ---------------------------------------


def test_negative_mu_2_is_not_used():
    # k2 = 2c - (alpha + 1) c_hat + ||Theta|| = 0.2 - 3 + 0.1 = -2.7 < 0. The printed formula
    # would give mu2 < 0 and a bound below sqrt(2 Gamma / lmin); it is not certified, because
    # s = B^T P e is small for e near the null space of B^T P. Build such an e explicitly.
    h = 0.05
    lmin = psi_min(PAPER, h)
    p = dict(
        Psi_min=lmin, Gamma=1.0, Theta_norm=0.1, BtP_norm=PAPER_BTP, c=0.1, c_hat=1.0,
        alpha=2.0, epsilon=0.1, gamma=0.001,
    )  # fmt: skip
    k = 2 * p["c"] - (p["alpha"] + 1) * p["c_hat"] + p["Theta_norm"]
    mu2_printed = k * PAPER_BTP / lmin
    printed = mu2_printed + math.sqrt(2 * p["Gamma"] / lmin + mu2_printed**2)

    BtP = B.T @ PAPER.P
    null = scipy.linalg.null_space(BtP)  # (4, 2): e here gives s = 0
    along = BtP.T[:, 0] / np.linalg.norm(BtP.T[:, 0])  # in the row space, orthogonal to null
    e_norm = 0.5 * (printed + math.sqrt(2 * p["Gamma"] / lmin))  # between the two bounds
    s_part = p["epsilon"] / np.linalg.norm(BtP @ along)  # ||s|| = epsilon: still case (ii)
    e = s_part * along + math.sqrt(e_norm**2 - s_part**2) * null[:, 0]
    s = BtP @ e
    assert np.linalg.norm(e) == pytest.approx(e_norm) and e_norm > printed
    assert np.linalg.norm(s) == pytest.approx(p["epsilon"])
    # The paper's V-dot bound in case (ii) at this e, with e^T Psi e >= lmin ||e||^2:
    v_dot_bound = -0.5 * lmin * e_norm**2 + k * np.linalg.norm(s) + p["Gamma"]
    assert v_dot_bound > 0.0  # V may grow here although ||e|| exceeds the printed bound
    assert ultimate_bounds(**p).varpi_2 == pytest.approx(math.sqrt(2 * p["Gamma"] / lmin))


def test_negative_mu_3_is_not_used():
    # k3 = c - alpha c_hat + ||Theta|| = 0.1 - 2 + 0.1 < 0: only the constant term remains.
    p = dict(CASES[0], c=0.1, c_hat=1.0, Theta_norm=0.1)
    expected = math.sqrt(2 * (p["Gamma"] + p["gamma"] ** 2) / p["Psi_min"])
    assert ultimate_bounds(**p).varpi_3 == pytest.approx(expected, rel=1e-15)


def test_alpha_below_one_keeps_the_case_i_term():
    # For alpha < 1 the term -(alpha - 1) c_hat ||s|| that the paper drops is positive.
    p = dict(CASES[0], alpha=0.5)
    k = (1 - p["alpha"]) * p["c_hat"] + p["Theta_norm"]
    lmin, b = p["Psi_min"], p["BtP_norm"]
    v = ultimate_bounds(**p).varpi_1
    assert v == pytest.approx(derived_switching_bound(lmin, b, k, p["Gamma"]), rel=1e-12)
    assert v > ultimate_bounds(**dict(p, alpha=1.0)).varpi_1


def test_varpi_5_with_negative_coefficient_is_conservative():
    # 2c - c_hat + ||Theta|| < 0: the paper squares it, over-estimating the true maximum 0.
    p = dict(CASES[0], c=0.0, c_hat=1.0, Theta_norm=0.1)
    derived = derived_boundary_layer_bound(
        p["Psi_min"], p["alpha"], p["c_hat"], p["epsilon"], -0.9, p["Gamma"]
    )
    assert derived == pytest.approx(math.sqrt(2 * p["Gamma"] / p["Psi_min"]), rel=1e-12)
    assert ultimate_bounds(**p).varpi_5 > derived


# --- limits and monotonicity ---------------------------------------------------------------


def test_limits_theta_zero_and_Gammazero():
    p = dict(CASES[0], Theta_norm=0.0, Gamma=0.0)
    bounds = ultimate_bounds(**p)
    lmin, alpha, c_hat, eps = p["Psi_min"], p["alpha"], p["c_hat"], p["epsilon"]
    c, g = p["c"], p["gamma"]
    assert bounds.varpi_1 == 0.0  # nothing drives the error in case (i)
    assert bounds.varpi_4 == pytest.approx(math.sqrt(eps * c_hat / (2 * alpha * lmin)))
    expected_6 = math.sqrt((4 * alpha * c_hat * g**2 + eps * c**2) / (2 * alpha * c_hat * lmin))
    assert bounds.varpi_6 == pytest.approx(expected_6)
    # Gamma -> 0 is continuous.
    nearly = ultimate_bounds(**dict(p, Gamma=1e-14)).as_tuple()
    np.testing.assert_allclose(nearly, bounds.as_tuple(), rtol=1e-6, atol=1e-6)


def test_bounds_grow_with_delay():
    # Psi = Q - h E loses definiteness as h grows, so every varpi grows with h.
    hs = np.linspace(0.0, 0.99 * PAPER.h_m, 12)
    lmins = [psi_min(PAPER, h) for h in hs]
    assert all(b < a for a, b in zip(lmins, lmins[1:], strict=False))
    rows = np.array([ultimate_bounds(**dict(CASES[2], Psi_min=lmin)).as_tuple() for lmin in lmins])
    assert np.all(np.diff(rows, axis=0) > 0.0)


def test_psi_min_values():
    # Q = I: lambda_min(I - h E) = 1 - h ||E|| = 1 - h / h_m exactly.
    for h in (0.0, 0.03, 0.1, 0.12):
        assert psi_min(PAPER, h) == pytest.approx(1.0 - h / PAPER.h_m, abs=1e-14)
    # General Q: Theorem 1's inequality lambda_min(Q - h E) >= lambda_min(Q) - h ||E||.
    Q = np.diag([3.0, 1.0, 2.0, 0.5])
    bound = razumikhin_bound(np.diag([2.0, 1.0]), np.diag([1.0, 3.0]), Q, beta=0.8, r=1.2)
    for h in np.linspace(0.0, 0.999 * bound.h_m, 7):
        expected = float(np.min(np.linalg.eigvalsh(Q - h * bound.E)))
        assert psi_min(bound, h) == pytest.approx(expected, rel=1e-14, abs=1e-15)
        assert psi_min(bound, h) >= bound.lambda_min_Q - h * bound.E_norm - 1e-14


# --- refused inputs -------------------------------------------------------------------------


@pytest.mark.parametrize("h", [PAPER.h_m, 2 * PAPER.h_m])
def test_psi_min_refuses_h_at_or_above_h_m(h):
    with pytest.raises(ValueError, match=r"h must be < h_m = 0\.12487 s .*got h = "):
        psi_min(PAPER, h)


@pytest.mark.parametrize(
    "h, message", [(-0.01, "h must be >= 0; got -0.01"), (float("nan"), "h must be finite")]
)
def test_psi_min_refuses_negative_or_nan_h(h, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        psi_min(PAPER, h)


@pytest.mark.parametrize(
    "name, value, message",
    [
        ("Psi_min", 0.0, "Psi_min must be > 0; got 0"),
        ("Psi_min", -0.2, "Psi_min must be > 0; got -0.2"),
        ("Gamma", -1.0, "Gamma must be >= 0; got -1"),
        ("Theta_norm", -0.1, "Theta_norm must be >= 0; got -0.1"),
        ("BtP_norm", -2.0, "BtP_norm must be >= 0; got -2"),
        ("c", -0.5, "c must be >= 0; got -0.5"),
        ("c_hat", 0.0, "c_hat must be > 0; got 0"),
        ("alpha", -1.0, "alpha must be > 0; got -1"),
        ("epsilon", 0.0, "epsilon must be > 0; got 0"),
        ("gamma", 0.0, "gamma must be > 0; got 0"),
        ("gamma", float("inf"), "gamma must be finite; got inf"),
    ],
)
def test_ultimate_bounds_refuse_out_of_range(name, value, message):
    with pytest.raises(ValueError, match="^" + re.escape(message) + "$"):
        ultimate_bounds(**dict(CASES[0], **{name: value}))
