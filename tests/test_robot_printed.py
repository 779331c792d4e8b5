"""The paper's printed robot model ``M̄, V̄``: as printed, and what is wrong with it.

The printed formulas are re-typed here from the paper's Section 3 (``paper_mass``,
``paper_bias``) to check the kernel, then used to pin:

* ``λ_min(M̄) < 0`` at P3-DX values (m = 9, d = 0.05, r̄ = 0.0975, b = 0.165, Ī = 0.264,
  I_w = 0.01; docs/robot.md quotes ≈ -0.11, which is the K = m d case: -0.1068);
* the relation to the unconstrained Lagrangian found in ``delaytrack.plants.robot.printed``:
  rows 1–3 of ``M̄ q̈ + V̄`` vanish along every motion with ``q̇ = S_b(q) η`` (``S_b``: the kinematic
  map with ω = r̄ (θ̇_r - θ̇_l)/b), except the printed row 2, whose cos/sin are swapped.
"""

from __future__ import annotations

import numpy as np
import pytest

from delaytrack.plants.robot import PrintedRobotModel

m, d, r, b, I, Iw = 9.0, 0.05, 0.0975, 0.165, 0.264, 0.01


def paper_mass(phi, K):
    """M̄ with k1..k5 as printed in the paper."""
    s, c = np.sin(phi), np.cos(phi)
    k1 = s * (m * d * r - K * r) / b - m * r * c / 2
    k2 = s * (K * r - m * d * r) / b - m * r * c / 2
    k3 = c * (K * r - m * d * r) / b - m * r * s / 2
    k4 = c * (m * d * r - K * r) / b - m * r * s / 2
    k5 = r * (I - K * d) / b
    return np.array(
        [
            [m, 0, K * s, k1, k2],
            [0, m, -K * c, k3, k4],
            [K * s, -K * c, I, -k5, k5],
            [k1, k3, -k5, Iw, 0],
            [k2, k4, k5, 0, Iw],
        ]
    )


def paper_bias(phi, qdot, K):
    """V̄ as printed (row 2 included)."""
    s, c = np.sin(phi), np.cos(phi)
    phidot, wr, wl = qdot[2], qdot[3], qdot[4]
    wheels = (wr**2 - wl**2) / (2 * b)
    return np.array(
        [
            m * d * phidot**2 * c + m * r**2 * s * wheels,
            m * d * phidot**2 * c - m * r**2 * s * wheels,
            K * r**2 * wheels,
            -K * r * phidot**2 / 2,
            -K * r * phidot**2 / 2,
        ]
    )


def kinematics(phi, track):
    """S and ∂S/∂φ for ω = r̄ (θ̇_r - θ̇_l)/track and the look-ahead distance d."""
    s, c = np.sin(phi), np.cos(phi)
    a, w = r / 2, r / track
    S = np.array(
        [[a * c - d * w * s, a * c + d * w * s], [a * s + d * w * c, a * s - d * w * c], [w, -w]]
    )
    dS = np.array(
        [[-a * s - d * w * c, -a * s + d * w * c], [a * c - d * w * s, a * c + d * w * s], [0, 0]]
    )
    return np.vstack([S, np.eye(2)]), np.vstack([dS, np.zeros((2, 2))])


def full_track_kinematics(phi):
    """S_b: ω = r̄ (θ̇_r - θ̇_l)/b, b read as the full track."""
    return kinematics(phi, b)


KS = {"K=0": 0.0, "K=2 m_w d": 0.05, "K=m d": m * d}


@pytest.mark.parametrize("K", KS.values(), ids=KS.keys())
def test_kernel_is_the_printed_model(K):
    model = PrintedRobotModel(first_moment=K)
    rng = np.random.default_rng(30)
    for _ in range(5):
        q = np.array([0.1, 0.2, rng.uniform(-np.pi, np.pi), 0.0, 0.0])
        qdot = rng.normal(size=5) * 3
        mass, bias, input_map = model.terms(q, qdot)
        np.testing.assert_allclose(mass[0], paper_mass(q[2], K), rtol=1e-14, atol=1e-15)
        np.testing.assert_allclose(bias[0], paper_bias(q[2], qdot, K), rtol=1e-14, atol=1e-15)
        np.testing.assert_array_equal(input_map[0], np.vstack([np.zeros((3, 2)), np.eye(2)]))


@pytest.mark.parametrize(
    ("K", "lambda_min"), [(0.0, -0.12926), (0.05, -0.12664), (m * d, -0.10684)]
)
def test_printed_mass_matrix_is_not_positive_definite_at_p3_values(K, lambda_min):
    """λ_min(M̄) is negative and independent of φ (M̄'s spectrum is rotation invariant)."""
    model = PrintedRobotModel(first_moment=K)
    for phi in np.linspace(-np.pi, np.pi, 9):
        eigenvalues = np.linalg.eigvalsh(model.mass_matrix(np.array([0, 0, phi, 0, 0.0]))[0])
        assert eigenvalues.min() == pytest.approx(lambda_min, abs=1e-5)


@pytest.mark.parametrize(("K", "threshold"), [(0.05, 0.19658), (m * d, 0.16865)])
def test_printed_mass_matrix_needs_a_huge_wheel_inertia(K, threshold):
    """M̄ ≻ 0 iff I_w > λ_max(S_bᵀ M̂₁₁ S_b) (Schur complement): about 0.17–0.20 kg m², 17–20
    times the P3-DX wheel (docs/robot.md: 'I_w > 0.169 kg·m²' for K = m d)."""
    S, _ = full_track_kinematics(0.4)
    block = paper_mass(0.4, K)[:3, :3]
    exact = np.linalg.eigvalsh(S[:3].T @ block @ S[:3]).max()
    assert exact == pytest.approx(threshold, abs=1e-5)
    for factor, positive in ((0.999, False), (1.001, True)):
        model = PrintedRobotModel(first_moment=K, wheel_spin_inertia=factor * exact)
        smallest = np.linalg.eigvalsh(model.mass_matrix(np.zeros(5))[0]).min()
        assert bool(smallest > 0) is positive


@pytest.mark.parametrize("K", KS.values(), ids=KS.keys())
def test_printed_blocks_are_the_lagrangian_block_and_the_full_track_kinematics(K):
    """M̄ = [[M̂₁₁, -M̂₁₁ S_b], [-S_bᵀ M̂₁₁, I_w I]] and V̄₄:₅ = -S_bᵀ N̂₁:₃ exactly, with
    M̂₁₁ = [[m, 0, K sφ], [0, m, -K cφ], [K sφ, -K cφ, Ī]] and N̂₁:₃ = [K cφ φ̇², K sφ φ̇², 0]."""
    rng = np.random.default_rng(31)
    for phi in rng.uniform(-np.pi, np.pi, 5):
        s, c = np.sin(phi), np.cos(phi)
        block = np.array([[m, 0, K * s], [0, m, -K * c], [K * s, -K * c, I]])
        S, _ = full_track_kinematics(phi)
        mass = PrintedRobotModel(first_moment=K).mass_matrix(np.array([0, 0, phi, 0, 0]))[0]
        np.testing.assert_allclose(mass[:3, :3], block, atol=1e-15)
        np.testing.assert_allclose(mass[:3, 3:], -block @ S[:3], rtol=1e-13, atol=1e-15)
        np.testing.assert_allclose(mass[3:, 3:], Iw * np.eye(2))
        phidot = rng.normal()
        coriolis = np.array([K * c * phidot**2, K * s * phidot**2, 0.0])
        qdot = np.array([0.0, 0.0, phidot, 1.0, 2.0])
        bias = PrintedRobotModel(first_moment=K).nonlinear_terms(np.array([0, 0, phi, 0, 0]), qdot)
        np.testing.assert_allclose(bias[0, 3:], -S[:3].T @ coriolis, rtol=1e-13, atol=1e-15)


@pytest.mark.parametrize("K", KS.values(), ids=KS.keys())
def test_row_2_of_v_bar_has_cos_and_sin_swapped(K):
    """Along q̇ = S_b η, q̈ = S_b η̇ + Ṡ_b η: rows 1 and 3 of M̄ q̈ + V̄ vanish (they are M̂₁₁ times
    the differentiated constraints); the printed row 2 does not; the corrected row 2
    ``m d φ̇² sin φ - m r̄² cos φ (θ̇_r² - θ̇_l²)/(2b)`` does."""
    printed = PrintedRobotModel(first_moment=K)
    corrected = PrintedRobotModel(first_moment=K, corrected_row2=True)
    rng = np.random.default_rng(32)
    worst_printed_row_2 = 0.0
    for _ in range(20):
        phi = rng.uniform(-np.pi, np.pi)
        eta, eta_dot = rng.uniform(-6, 6, 2), rng.normal(size=2)
        S, dS = full_track_kinematics(phi)
        qdot = S @ eta
        qddot = S @ eta_dot + dS @ eta * qdot[2]
        q = np.array([0.5, -0.3, phi, 0.0, 0.0])
        for model, rows in ((printed, [0, 2]), (corrected, [0, 1, 2])):
            mass, bias, _ = model.terms(q, qdot)
            residual = mass[0] @ qddot + bias[0]
            np.testing.assert_allclose(residual[rows], 0.0, atol=1e-12)
        mass, bias, _ = printed.terms(q, qdot)
        worst_printed_row_2 = max(worst_printed_row_2, abs((mass[0] @ qddot + bias[0])[1]))
    assert worst_printed_row_2 > 1.0  # N; the printed row 2 is not a constraint identity


def test_half_track_kinematics_do_not_satisfy_the_printed_rows():
    """With ω = r̄ (θ̇_r - θ̇_l)/(2b) (b = 0.165 read as the half track, as in docs/robot.md)
    rows 1 and 3 do not vanish: the printed formulas use b where the half-track kinematics
    need 2b."""
    model = PrintedRobotModel(corrected_row2=True)
    rng = np.random.default_rng(33)
    phi, eta, eta_dot = 0.3, np.array([4.0, 5.0]), rng.normal(size=2)
    S, dS = kinematics(phi, 2 * b)
    qdot = S @ eta
    qddot = S @ eta_dot + dS @ eta * qdot[2]
    mass, bias, _ = model.terms(np.array([0, 0, phi, 0, 0.0]), qdot)
    residual = mass[0] @ qddot + bias[0]
    assert np.max(np.abs(residual[[0, 2]])) > 0.1
