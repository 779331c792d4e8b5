"""Theorem 1 (Razumikhin delay bound): reference values, independent oracles, refused inputs."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import scipy.linalg

from delaytrack.analysis import (
    RazumikhinBound,
    error_dynamics_matrices,
    lyapunov_matrix,
    razumikhin_bound,
)

# The paper's gains (Roy & Kar, Section III): K1 = K2 = Q = I, beta = 1, r = 1.1.
PAPER_H_M = 0.12487  # docs/decisions.md D8; the paper states "125 ms".


def random_spd(rng: np.random.Generator, n: int, shift: float = 0.5) -> np.ndarray:
    """A dense (non-diagonal) symmetric positive definite matrix."""
    M = rng.standard_normal((n, n))
    return M @ M.T + shift * np.eye(n)


def lyapunov_by_kronecker(A: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """Oracle for A^T P + P A = -Q, independent of scipy's Lyapunov solver.

    With column-major vec: vec(A^T P) = (I kron A^T) vec(P) and vec(P A) = (A^T kron I) vec(P).
    """
    m = A.shape[0]
    eye = np.eye(m)
    operator = np.kron(eye, A.T) + np.kron(A.T, eye)
    vec_P = np.linalg.solve(operator, -Q.reshape(-1, order="F"))
    return vec_P.reshape((m, m), order="F")


def E_by_hand(K1, K2, P, beta, r):
    """E of (delay cal) written out block by block, with P^-1 from a linear solve."""
    n = K1.shape[0]
    Z, I = np.zeros((n, n)), np.eye(n)
    A1 = np.block([[Z, I], [Z, Z]])
    B1 = np.block([[Z, Z], [-K1, -K2]])
    P_inv = np.linalg.solve(P, np.eye(2 * n))
    term_A1 = P @ B1 @ A1 @ P_inv @ A1.T @ B1.T @ P  # from (cond1)
    term_B1 = P @ B1 @ B1 @ P_inv @ B1.T @ B1.T @ P  # from (cond2)
    term_B = P @ B1 @ P_inv @ B1.T @ P  # from (cond3)
    return beta * (term_A1 + term_B1 + term_B) + 2.0 * (r / beta) * P


# --- the paper's reference value ------------------------------------------------------------


@pytest.mark.parametrize("n", [1, 5])
def test_paper_value_125_ms(n):
    bound = razumikhin_bound(np.eye(n), np.eye(n), np.eye(2 * n), beta=1.0, r=1.1)
    assert bound.h_m == pytest.approx(PAPER_H_M, abs=1e-5)
    assert bound.n == n


def test_paper_value_by_hand_n1():
    # Hand computation for k1 = k2 = 1, Q = I (closed form of P below):
    #   P = [[3/2, 1/2], [1/2, 1]],  P^-1 = [[0.8, -0.4], [-0.4, 1.2]],
    #   A1 P^-1 A1^T + B1 P^-1 B1^T + P^-1 = [[2.0, -0.4], [-0.4, 2.4]],
    #   P B1 = u [1, 1] with u = [-1/2, -1]^T, so the first term is 3.6 u u^T,
    #   E = [[0.9, 1.8], [1.8, 3.6]] + 2.2 P = [[4.2, 2.9], [2.9, 5.8]],
    #   ||E|| = 5 + sqrt(25 - 15.95) = 5 + sqrt(9.05)  (trace 10, determinant 15.95).
    bound = razumikhin_bound(1.0, 1.0, 1.0, beta=1.0, r=1.1)
    np.testing.assert_allclose(bound.P, [[1.5, 0.5], [0.5, 1.0]], rtol=0, atol=1e-14)
    np.testing.assert_allclose(bound.E, [[4.2, 2.9], [2.9, 5.8]], rtol=0, atol=1e-13)
    assert bound.h_m == pytest.approx(1.0 / (5.0 + math.sqrt(9.05)), rel=1e-13)


# --- the Lyapunov matrix ------------------------------------------------------------------


@pytest.mark.parametrize("k1, k2", [(1.0, 1.0), (2.0, 0.5), (0.3, 7.0), (25.0, 10.0)])
def test_lyapunov_closed_form_n1(k1, k2):
    # Derived by hand from A^T P + P A = -I with A = [[0, 1], [-k1, -k2]]:
    #   (1,1): -2 k1 p12 = -1;  (2,2): 2 p12 - 2 k2 p22 = -1;  (1,2): p11 - k2 p12 - k1 p22 = 0.
    p12 = 1.0 / (2.0 * k1)
    p22 = (k1 + 1.0) / (2.0 * k1 * k2)
    p11 = (k1**2 + k1 + k2**2) / (2.0 * k1 * k2)
    P = lyapunov_matrix(k1, k2, 1.0)
    np.testing.assert_allclose(P, [[p11, p12], [p12, p22]], rtol=1e-12)


@pytest.mark.parametrize("seed, n", [(0, 1), (1, 2), (2, 3), (3, 6)])
def test_lyapunov_residual_and_positive_definite(seed, n):
    rng = np.random.default_rng(seed)
    K1, K2, Q = random_spd(rng, n), random_spd(rng, n), random_spd(rng, 2 * n)
    P = lyapunov_matrix(K1, K2, Q)
    A = error_dynamics_matrices(K1, K2)[0]
    residual = A.T @ P + P @ A + Q
    # A backward-stable solver leaves a residual of a few eps * ||A|| ||P|| (measured: <= 1e-12).
    assert np.max(np.abs(residual)) <= 1e-13 * np.linalg.norm(A) * np.linalg.norm(P)
    np.testing.assert_array_equal(P, P.T)
    assert np.linalg.eigvalsh(P)[0] > 0.0
    np.testing.assert_allclose(P, lyapunov_by_kronecker(A, Q), rtol=1e-9, atol=1e-12)


def test_lyapunov_accepts_nonsymmetric_hurwitz_gains():
    # Only A Hurwitz is needed for the Lyapunov equation; A = [[0, I], [-K1, -K2]] with these
    # upper-triangular gains has the eigenvalues of s^2 + 2 s + 2 (twice): -1 +- 1j.
    K1 = np.array([[2.0, 1.0], [0.0, 2.0]])
    K2 = np.array([[2.0, 0.5], [0.0, 2.0]])
    Q = np.eye(4)
    P = lyapunov_matrix(K1, K2, Q)
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-K1, -K2]])
    np.testing.assert_allclose(P, lyapunov_by_kronecker(A, Q), rtol=1e-12, atol=1e-14)


def test_error_dynamics_matrices_blocks():
    # Non-symmetric gains (allowed here) so that a transposed block would show.
    K1 = np.array([[2.0, 0.3], [0.1, 1.0]])
    K2 = np.array([[4.0, 0.2], [0.0, 5.0]])
    A, A1, B1, B = error_dynamics_matrices(K1, K2)
    expected_A1 = np.array([[0, 0, 1, 0], [0, 0, 0, 1], [0, 0, 0, 0], [0, 0, 0, 0]], dtype=float)
    expected_B1 = np.array(
        [[0, 0, 0, 0], [0, 0, 0, 0], [-2.0, -0.3, -4.0, -0.2], [-0.1, -1.0, 0, -5.0]]
    )
    expected_B = np.array([[0, 0], [0, 0], [1, 0], [0, 1]], dtype=float)
    np.testing.assert_array_equal(A1, expected_A1)
    np.testing.assert_array_equal(B1, expected_B1)
    np.testing.assert_array_equal(A, expected_A1 + expected_B1)
    np.testing.assert_array_equal(B, expected_B)


def test_scalar_gain_expands_with_n():
    A, _, _, B = error_dynamics_matrices(3.0, 2.0, n=2)
    assert A.shape == (4, 4) and B.shape == (4, 2)
    np.testing.assert_array_equal(A[2:, :2], -3.0 * np.eye(2))
    bound = razumikhin_bound(1.0, 1.0, 1.0, beta=1.0, r=1.1, n=3)
    assert bound.n == 3 and bound.Q.shape == (6, 6)


# --- Theorem 1 against an independent computation -------------------------------------------


def test_h_m_independent_diagonal_gains():
    K1, K2 = np.diag([2.0, 3.0]), np.diag([1.5, 4.0])
    Q = np.diag([1.0, 2.0, 0.5, 3.0])
    beta, r = 0.7, 1.3
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-K1, -K2]])
    P = lyapunov_by_kronecker(A, Q)
    E = E_by_hand(K1, K2, P, beta, r)
    expected = 0.5 / np.max(np.abs(np.linalg.eigvals(E)))  # lambda_min(Q) = 0.5; E symmetric
    bound = razumikhin_bound(K1, K2, Q, beta=beta, r=r)
    assert bound.h_m == pytest.approx(expected, rel=1e-10)
    np.testing.assert_allclose(bound.E, E, rtol=1e-10)
    assert bound.lambda_min_Q == 0.5
    assert bound.E_norm == pytest.approx(0.5 / expected, rel=1e-10)


@pytest.mark.parametrize("seed", [10, 11, 12])
def test_h_m_independent_dense_gains(seed):
    rng = np.random.default_rng(seed)
    n = 3
    K1, K2, Q = random_spd(rng, n), random_spd(rng, n), random_spd(rng, 2 * n)
    beta, r = rng.uniform(0.2, 3.0), rng.uniform(1.05, 3.0)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-K1, -K2]])
    E = E_by_hand(K1, K2, lyapunov_by_kronecker(A, Q), beta, r)
    expected = np.min(np.linalg.eigvalsh(Q)) / np.linalg.svd(E, compute_uv=False)[0]
    assert razumikhin_bound(K1, K2, Q, beta=beta, r=r).h_m == pytest.approx(expected, rel=1e-9)


# --- structure: n, scaling of Q, monotonicity in r -----------------------------------------


def test_h_m_independent_of_n_for_identity_gains():
    # With K1 = K2 = Q = I every matrix is (2x2 block) kron I_n, so h_m cannot depend on n.
    values = [
        razumikhin_bound(np.eye(n), np.eye(n), np.eye(2 * n), beta=1.0, r=1.1).h_m
        for n in (1, 2, 3, 5)
    ]
    np.testing.assert_allclose(values, values[0], rtol=1e-12)


@pytest.mark.parametrize("factor", [1e-2, 3.0, 250.0])
def test_scaling_Q_leaves_h_m_unchanged(factor):
    # P scales with Q, P^-1 inversely, so E scales like lambda_min(Q): h_m is invariant.
    K1, K2 = np.array([[2.0, 0.4], [0.4, 1.0]]), np.diag([1.5, 0.8])
    Q = np.array([[2.0, 0.1, 0, 0], [0.1, 1.0, 0, 0], [0, 0, 1.5, 0.2], [0, 0, 0.2, 0.7]])
    base = razumikhin_bound(K1, K2, Q, beta=0.9, r=1.2)
    scaled = razumikhin_bound(K1, K2, factor * Q, beta=0.9, r=1.2)
    assert scaled.h_m == pytest.approx(base.h_m, rel=1e-10)
    np.testing.assert_allclose(scaled.P, factor * base.P, rtol=1e-10)
    np.testing.assert_allclose(scaled.E, factor * base.E, rtol=1e-9)


def test_h_m_decreases_with_r():
    # E grows by 2 (r/beta) P with P positive definite, so ||E|| increases strictly with r.
    rs = [1.001, 1.1, 1.5, 2.0, 5.0, 20.0]
    values = [razumikhin_bound(np.eye(2), np.eye(2), np.eye(4), beta=1.0, r=r).h_m for r in rs]
    assert all(later < earlier for earlier, later in zip(values, values[1:], strict=False))


# --- the result object ----------------------------------------------------------------------


def test_result_is_frozen_read_only_and_serialisable():
    bound = razumikhin_bound(np.eye(2), np.eye(2), np.eye(4), beta=1.0, r=1.1)
    assert isinstance(bound, RazumikhinBound)
    with pytest.raises(AttributeError):
        bound.h_m = 1.0  # type: ignore[misc]
    with pytest.raises(ValueError, match="read-only"):
        bound.P[0, 0] = 0.0
    data = json.loads(json.dumps(bound.to_dict()))
    assert data["h_m"] == bound.h_m
    assert data["n"] == 2
    assert data["beta"] == 1.0 and data["r"] == 1.1
    assert data["E_norm"] == bound.E_norm and data["lambda_min_Q"] == 1.0
    np.testing.assert_array_equal(np.array(data["P"]), bound.P)
    np.testing.assert_array_equal(np.array(data["E"]), bound.E)


# --- refused inputs -------------------------------------------------------------------------

I2, I4 = np.eye(2), np.eye(4)


@pytest.mark.parametrize("r", [1.0, 0.5, -2.0, float("nan")])
def test_refuses_r_not_above_one(r):
    with pytest.raises(ValueError, match=r"r must be > 1 \(Razumikhin condition .*got"):
        razumikhin_bound(I2, I2, I4, beta=1.0, r=r)


@pytest.mark.parametrize("beta, message", [(0.0, "beta must be > 0"), (-1.0, "beta must be > 0")])
def test_refuses_nonpositive_beta(beta, message):
    with pytest.raises(ValueError, match=message):
        razumikhin_bound(I2, I2, I4, beta=beta, r=1.1)


def test_refuses_nan_beta():
    with pytest.raises(ValueError, match="beta must be finite; got nan"):
        razumikhin_bound(I2, I2, I4, beta=float("nan"), r=1.1)


def test_refuses_nonsymmetric_K1():
    with pytest.raises(ValueError, match="K1 must be symmetric positive definite; it is not sym"):
        razumikhin_bound([[1.0, 0.5], [0.0, 1.0]], I2, I4, beta=1.0, r=1.1)


def test_refuses_indefinite_K1_and_gives_eigenvalues():
    with pytest.raises(ValueError, match=r"K1 must be .* eigenvalues are \[-1, 3\]"):
        razumikhin_bound([[1.0, 2.0], [2.0, 1.0]], I2, I4, beta=1.0, r=1.1)


def test_refuses_indefinite_K2_and_Q():
    with pytest.raises(ValueError, match=r"K2 must be symmetric positive definite.*\[-1, 1\]"):
        razumikhin_bound(I2, [1.0, -1.0], I4, beta=1.0, r=1.1)
    with pytest.raises(ValueError, match=r"Q must be symmetric positive definite.*\[0, 1, 1, 1\]"):
        razumikhin_bound(I2, I2, [1.0, 1.0, 0.0, 1.0], beta=1.0, r=1.1)


def test_refuses_wrong_Q_shape():
    with pytest.raises(ValueError, match=r"Q must be 2n x 2n = 4x4 for n = 2.*got shape \(2, 2\)"):
        razumikhin_bound(I2, I2, I2, beta=1.0, r=1.1)
    with pytest.raises(ValueError, match=r"Q must be 2n x 2n = 4x4 .*got shape \(3, 3\)"):
        lyapunov_matrix(I2, I2, [1.0, 1.0, 1.0])


def test_refuses_mismatched_K2_and_n():
    with pytest.raises(ValueError, match=r"K2 must be n x n = 2x2, the size of K1; got shape"):
        razumikhin_bound(I2, np.eye(3), I4, beta=1.0, r=1.1)
    with pytest.raises(ValueError, match=r"K1 must be n x n = 3x3 \(n = 3 given\)"):
        razumikhin_bound(I2, I2, I4, beta=1.0, r=1.1, n=3)
    with pytest.raises(ValueError, match="n must be a positive integer"):
        razumikhin_bound(1.0, 1.0, 1.0, beta=1.0, r=1.1, n=0)


def test_refuses_non_hurwitz_A():
    # K1 = -I is not positive definite; lyapunov_matrix takes any square gains and must catch the
    # unstable A. s^2 + s - 1 = 0 has the root (sqrt(5) - 1)/2 = 0.618034.
    with pytest.raises(ValueError, match=r"must be Hurwitz.*largest real part are \[0\.618034"):
        lyapunov_matrix(-I2, I2, I4)
    # K1 = K2 = 0: a double integrator, eigenvalues 0 (marginal, not Hurwitz).
    with pytest.raises(ValueError, match=r"must be Hurwitz.*largest real part are \[0, 0"):
        lyapunov_matrix(0.0, 0.0, 1.0)
    # The public bound refuses the same gains earlier, as not positive definite.
    with pytest.raises(ValueError, match=r"K1 must be symmetric positive definite.*\[-1, -1\]"):
        razumikhin_bound(-I2, I2, I4, beta=1.0, r=1.1)


def test_hurwitz_message_shows_complex_pair():
    # K2 = -1, K1 = 1: s^2 - s + 1 = 0, roots 0.5 +- 0.866025j.
    with pytest.raises(ValueError, match=r"\[0\.5\+0\.866025j, 0\.5-0\.866025j\]"):
        lyapunov_matrix(1.0, -1.0, 1.0)


def test_scipy_sign_convention_is_the_one_we_rely_on():
    # scipy solves M X + X M^H = C. Guard against a silent change: with M = A^T, C = -Q we must
    # get A^T P + P A = -Q for a non-symmetric A.
    A = np.array([[0.0, 1.0], [-2.0, -3.0]])
    P = scipy.linalg.solve_continuous_lyapunov(A.T, -np.eye(2))
    np.testing.assert_allclose(A.T @ P + P @ A, -np.eye(2), atol=1e-14)


def test_gains_too_ill_conditioned_for_an_accurate_lyapunov_solution_are_refused():
    # K1 = 1e8, K2 = 1: scipy returns an indefinite P with a residual of order ||Q|| (found in
    # review); the bound would be meaningless, so the solve is checked and refused.
    with pytest.raises(ValueError, match=r"cannot be solved accurately.*relative residual"):
        razumikhin_bound(1e8, 1.0, 1.0, 1.0, 1.1)
