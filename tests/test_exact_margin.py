"""Exact delay margin: closed forms, python-control as SISO oracle, spectral roots, bad input."""

from __future__ import annotations

import dataclasses
import math

import control
import numpy as np
import pytest

from delaytrack.analysis import ExactDelayMargin, exact_delay_margin

# K1 = K2 = I: omega_c^2 = (1 + sqrt 5) / 2 and h = atan(omega_c) / omega_c.
IDENTITY_MARGIN = 0.711118648715793


def random_spd(rng: np.random.Generator, n: int, shift: float = 0.5) -> np.ndarray:
    """A dense (non-diagonal) symmetric positive definite matrix."""
    M = rng.standard_normal((n, n))
    return M @ M.T + shift * np.eye(n)


def closed_form(k1: float, k2: float) -> tuple[float, float]:
    """(h, omega_c) of one decoupled axis: omega_c^4 = k1^2 + omega_c^2 k2^2."""
    omega = math.sqrt((k2**2 + math.sqrt(k2**4 + 4.0 * k1**2)) / 2.0)
    return math.atan(omega * k2 / k1) / omega, omega


def rightmost_root(K1: np.ndarray, K2: np.ndarray, h: float, N: int = 40) -> float:
    """Largest real part of the roots of det(s^2 I + (K2 s + K1) e^{-sh}), by spectral collocation.

    The DDE x' = A0 x(t) + A1 x(t - h), x = [e1, e1'], A0 = [[0, I], [0, 0]],
    A1 = [[0, 0], [-K1, -K2]], is written as the abstract ODE u' = A u on C([-h, 0]) whose
    generator A is d/dtheta with the boundary rule u'(0) = A0 u(0) + A1 u(-h). Collocating at the
    N + 1 Chebyshev points theta_j = h (cos(j pi / N) - 1) / 2 (theta_0 = 0, theta_N = -h) gives a
    matrix whose eigenvalues converge spectrally to the rightmost characteristic roots
    (Breda, Maset & Vermiglio, SIAM J. Sci. Comput. 27, 2005).
    """
    n = K1.shape[0]
    m = 2 * n
    A0 = np.block([[np.zeros((n, n)), np.eye(n)], [np.zeros((n, n)), np.zeros((n, n))]])
    A1 = np.block([[np.zeros((n, n)), np.zeros((n, n))], [-K1, -K2]])
    x = np.cos(np.pi * np.arange(N + 1) / N)
    c = np.hstack([2.0, np.ones(N - 1), 2.0]) * (-1.0) ** np.arange(N + 1)
    dx = x[:, None] - x[None, :]
    D = np.outer(c, 1.0 / c) / (dx + np.eye(N + 1))
    D -= np.diag(D.sum(axis=1))  # Trefethen's cheb: Chebyshev differentiation on [-1, 1]
    D *= 2.0 / h  # d/dtheta = (2/h) d/dx
    generator = np.kron(D, np.eye(m))
    generator[:m, :] = 0.0
    generator[:m, :m] = A0
    generator[:m, N * m :] = A1
    return float(np.max(np.linalg.eigvals(generator).real))


# --- reference values -----------------------------------------------------------------------


@pytest.mark.parametrize("n", [1, 3])
def test_identity_gains(n):
    margin = exact_delay_margin(np.eye(n), np.eye(n))
    assert margin.h == pytest.approx(IDENTITY_MARGIN, rel=1e-12)
    assert margin.omega == pytest.approx(math.sqrt((1.0 + math.sqrt(5.0)) / 2.0), rel=1e-12)
    assert margin.crossing_omegas == (margin.omega,), "identical axes are one crossing"


def test_closed_form_per_axis_for_random_diagonal_gains():
    rng = np.random.default_rng(5)
    for _ in range(20):
        n = int(rng.integers(1, 5))
        k1, k2 = np.exp(rng.uniform(-3, 3, n)), np.exp(rng.uniform(-3, 3, n))
        margin = exact_delay_margin(k1, k2)
        axes = sorted(closed_form(a, b) for a, b in zip(k1, k2, strict=True))
        assert margin.h == pytest.approx(axes[0][0], rel=1e-10)
        assert margin.omega == pytest.approx(axes[0][1], rel=1e-10)
        expected_omegas = sorted({round(w, 12) for _, w in axes})
        assert sorted(margin.crossing_omegas) == pytest.approx(expected_omegas, rel=1e-10)
        assert list(margin.crossing_delays) == sorted(margin.crossing_delays)


def test_two_axes_with_one_crossover_frequency_keep_both_delays():
    # omega^4 = k1^2 + omega^2 k2^2 has the same root for (1, 1) and (a, 0.5) with
    # a = sqrt(omega^4 - omega^2 / 4): one crossing frequency, two different delays.
    omega2 = (1.0 + math.sqrt(5.0)) / 2.0
    a = math.sqrt(omega2**2 - omega2 / 4.0)
    margin = exact_delay_margin([1.0, a], [1.0, 0.5])
    h_b, omega_b = closed_form(a, 0.5)
    assert omega_b == pytest.approx(math.sqrt(omega2), rel=1e-14)
    assert margin.h == pytest.approx(h_b, rel=1e-10) and h_b < 0.5 * IDENTITY_MARGIN
    assert margin.crossing_delays == pytest.approx([h_b, IDENTITY_MARGIN], rel=1e-10)


def test_siso_margin_is_phase_margin_over_crossover_from_python_control():
    # The loop (k2 s + k1) / s^2 under a delay e^{-sh} keeps its gain and loses phase omega h,
    # so the delay margin is the phase margin divided by the crossover frequency.
    rng = np.random.default_rng(11)
    for k1, k2 in np.exp(rng.uniform(-2.5, 2.5, (15, 2))):
        _, phase_margin_deg, _, crossover = control.margin(control.tf([k2, k1], [1.0, 0.0, 0.0]))
        margin = exact_delay_margin(k1, k2)
        assert margin.omega == pytest.approx(crossover, rel=1e-8)
        assert margin.h == pytest.approx(math.radians(phase_margin_deg) / crossover, rel=1e-8)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_non_diagonal_gains_against_spectral_roots(seed):
    rng = np.random.default_rng(seed)
    n = 3
    K1, K2 = random_spd(rng, n), random_spd(rng, n)
    margin = exact_delay_margin(K1, K2)
    assert len(margin.crossing_omegas) >= 1
    assert rightmost_root(K1, K2, 0.99 * margin.h) < 0.0 < rightmost_root(K1, K2, 1.01 * margin.h)
    # Every reported crossing is a root on the imaginary axis: det(-w^2 I + (K1 + jwK2)e^{-jwh}).
    for omega, h in zip(margin.crossing_omegas, margin.crossing_delays, strict=True):
        matrix = -(omega**2) * np.eye(n) + (K1 + 1j * omega * K2) * np.exp(-1j * omega * h)
        assert np.min(np.linalg.svd(matrix, compute_uv=False)) < 1e-9 * omega**2


def test_spectral_oracle_reproduces_the_scalar_margin():
    # The oracle itself: the scalar case crosses at the closed-form delay.
    h, _ = closed_form(1.0, 1.0)
    assert (
        rightmost_root(np.eye(1), np.eye(1), 0.99 * h)
        < 0.0
        < rightmost_root(np.eye(1), np.eye(1), 1.01 * h)
    )


def test_crossings_lie_in_the_documented_bracket():
    rng = np.random.default_rng(3)
    K1, K2 = random_spd(rng, 4), random_spd(rng, 4)
    margin = exact_delay_margin(K1, K2)
    low = closed_form(np.linalg.eigvalsh(K1)[0], np.linalg.eigvalsh(K2)[0])[1]
    high = closed_form(np.linalg.norm(K1, 2), np.linalg.norm(K2, 2))[1]
    assert all(low <= w <= high for w in margin.crossing_omegas)
    assert len(margin.crossing_omegas) >= 1


def test_result_is_frozen_and_serialisable():
    margin = exact_delay_margin(1.0, 1.0, n=2)
    assert isinstance(margin, ExactDelayMargin)
    with pytest.raises(dataclasses.FrozenInstanceError):
        margin.h = 1.0  # type: ignore[misc]
    assert margin.to_dict()["h"] == margin.h


# --- refused input --------------------------------------------------------------------------


@pytest.mark.parametrize(
    "K1, K2, error, words",
    [
        ([[1.0, 2.0], [2.0, 1.0]], np.eye(2), ValueError, "K1 must be symmetric positive definite"),
        (np.eye(2), [[1.0, 0.5], [0.0, 1.0]], ValueError, "K2 must be symmetric positive definite"),
        (1.0, -2.0, ValueError, "K2 must be symmetric positive definite; its eigenvalues are [-2]"),
        (np.nan, 1.0, ValueError, "K1 must be finite"),
        (np.eye(2), np.eye(3), ValueError, "K2 must be n x n = 2x2"),
        (np.ones((2, 3)), np.eye(2), ValueError, "K1 must be square"),
        ("fast", 1.0, TypeError, "K1 must be an array of real numbers; got 'fast'"),
        (1e300, 1.0, ValueError, "K1 and K2 are too large for the margin to be computed"),
        (1e-230, 1e-230, ValueError, "K1 and K2 are too small for the margin to be computed"),
    ],
)
def test_bad_gains_are_refused_with_a_clear_message(K1, K2, error, words):
    with pytest.raises(error) as raised:
        exact_delay_margin(K1, K2)
    assert words in str(raised.value)


# --- the scan's handling of touches and close pairs -----------------------------------------


def test_scan_counts_a_tangential_touch_and_splits_a_close_pair():
    from delaytrack.analysis.exact_margin import _crossings_of_column

    omegas = np.linspace(0.5, 1.5, 101)  # sample step 0.01
    touch = lambda w: -((w - 1.003) ** 2)  # noqa: E731  reaches zero, never changes sign
    found = _crossings_of_column(touch, omegas, touch(omegas))
    assert found == [pytest.approx(1.003, abs=1e-6)]
    pair = lambda w: (w - 1.003) ** 2 - 1e-6  # noqa: E731  roots 1.002 and 1.004, one step apart
    found = _crossings_of_column(pair, omegas, pair(omegas))
    assert sorted(found) == pytest.approx([1.002, 1.004], abs=1e-12)
    far = lambda w: (w - 1.003) ** 2 + 1e-6  # noqa: E731  a near miss is not a crossing
    assert _crossings_of_column(far, omegas, far(omegas)) == []
