"""The paper's robot path: ``literal`` as printed, ``consistent`` derived from the kinematics.

Printed (paper, Section 3): x_d = 1.25 sin(0.35t) + 0.1, y_d = 1.25 cos(0.35t) + 1.35,
φ_d = 0.25t, θ_r,d = 3t, θ_l,d = 2t. Hand values for ``consistent`` with the P3-DX geometry
(R = 0.0975, L = 0.165, d = 0.05, ρ = 1.25, Ω = 0.35):

    φ_d(0) = asin(d/ρ) = asin(0.04) = 0.0400107 rad
    v_d    = Ω √(ρ² - d²) = 0.35 × 1.2489996 = 0.4371499 m/s
    θ̇_r,d = (v_d - L Ω)/R = (0.4371499 - 0.05775)/0.0975 = 3.891281 rad/s
    θ̇_l,d = (v_d + L Ω)/R = (0.4371499 + 0.05775)/0.0975 = 5.075897 rad/s
"""

from __future__ import annotations

import numpy as np
import pytest

from delaytrack.plants.robot import (
    P3DX,
    WheeledRobot,
    constraint_matrix,
    constraint_residual,
    initial_state,
    paper_reference,
    wheel_rates,
)

R, L, D = P3DX.wheel_radius, P3DX.half_track, P3DX.d
TIMES = np.linspace(0.0, 40.0, 81)


def test_literal_is_the_printed_path():
    qd, qd_dot, qd_ddot = paper_reference("literal").evaluate(TIMES)
    t = TIMES
    expected = np.column_stack(
        [1.25 * np.sin(0.35 * t) + 0.1, 1.25 * np.cos(0.35 * t) + 1.35, 0.25 * t, 3 * t, 2 * t]
    )
    np.testing.assert_allclose(qd, expected, atol=1e-12)
    expected_dot = np.column_stack(
        [
            1.25 * 0.35 * np.cos(0.35 * t),
            -1.25 * 0.35 * np.sin(0.35 * t),
            np.full_like(t, 0.25),
            np.full_like(t, 3.0),
            np.full_like(t, 2.0),
        ]
    )
    np.testing.assert_allclose(qd_dot, expected_dot, atol=1e-12)
    np.testing.assert_allclose(qd_ddot[:, :2], -(0.35**2) * (expected[:, :2] - [0.1, 1.35]))


def test_literal_is_not_feasible():
    """The printed five violate the constraints: the wheels give v = R(3 + 2)/2 = 0.244 m/s along
    the heading, the circle needs 0.4375 m/s; the wheels' ω = R/(2L) = 0.295 rad/s ≠ φ̇_d = 0.25."""
    qd, qd_dot, _ = paper_reference("literal").evaluate(TIMES)
    residual = constraint_residual(np.concatenate([qd, qd_dot], axis=1), R, L, D)
    assert np.max(np.abs(residual)) > 0.1
    assert R * (3 - 2) / (2 * L) == pytest.approx(0.2955, abs=1e-4)


def test_consistent_keeps_the_circle_and_has_the_hand_values():
    consistent = paper_reference().evaluate(TIMES)
    literal = paper_reference("literal").evaluate(TIMES)
    for k in range(3):
        np.testing.assert_allclose(consistent[k][:, :2], literal[k][:, :2], atol=1e-12)
    qd, qd_dot, qd_ddot = consistent
    assert qd[0, 2] == pytest.approx(0.0400107, abs=1e-7)
    np.testing.assert_allclose(qd_dot[:, 2], -0.35)
    np.testing.assert_allclose(wheel_rates(), [3.891281, 5.075897], atol=1e-6)
    np.testing.assert_allclose(qd_dot[:, 3:], np.broadcast_to(wheel_rates(), (TIMES.size, 2)))
    np.testing.assert_allclose(qd_ddot[:, 2:], 0.0)


def test_consistent_satisfies_the_constraints_to_second_order():
    """Λ(q_d) q̇_d = 0 and d/dt(Λ q̇_d) = Λ q̈_d + (∂Λ/∂φ φ̇_d) q̇_d = 0 along the path."""
    qd, qd_dot, qd_ddot = paper_reference().evaluate(TIMES)
    lam = constraint_matrix(qd, R, L, D)
    np.testing.assert_allclose(np.einsum("tij,tj->ti", lam, qd_dot), 0.0, atol=1e-14)
    phi, phidot = qd[:, 2], qd_dot[:, 2]
    zero = np.zeros_like(phi)
    dlam = np.moveaxis(
        np.array(
            [
                [-np.cos(phi), -np.sin(phi), zero, zero, zero],
                [-np.sin(phi), np.cos(phi), zero, zero, zero],
                [-np.sin(phi), np.cos(phi), zero, zero, zero],
            ]
        ),
        (0, 1),
        (-2, -1),
    )
    second = np.einsum("tij,tj->ti", lam, qd_ddot) + phidot[:, None] * np.einsum(
        "tij,tj->ti", dlam, qd_dot
    )
    np.testing.assert_allclose(second, 0.0, atol=1e-13)
    # The holonomic part: φ - R(θ_r - θ_l)/(2L) stays at its initial value asin(d/ρ).
    np.testing.assert_allclose(qd[:, 2] - R * (qd[:, 3] - qd[:, 4]) / (2 * L), np.arcsin(0.04))


def test_consistent_axle_runs_forward_on_the_inner_circle():
    qd, qd_dot, _ = paper_reference().evaluate(TIMES)
    heading = np.column_stack([np.cos(qd[:, 2]), np.sin(qd[:, 2])])
    axle = qd[:, :2] - D * heading
    np.testing.assert_allclose(
        np.linalg.norm(axle - [0.1, 1.35], axis=1), np.sqrt(1.25**2 - D**2), rtol=1e-12
    )
    axle_speed = np.einsum("ti,ti->t", qd_dot[:, :2], heading)  # + d φ̇ (n·e = 0)
    np.testing.assert_allclose(axle_speed, 0.35 * np.sqrt(1.25**2 - D**2), rtol=1e-12)


def test_consistent_heading_is_the_attracting_solution():
    """The look-ahead point's heading dynamics φ̇ = (ẋ_d (-sin φ) + ẏ_d cos φ)/d, started 0.5 rad
    off, converge to φ_d: the forward-driving branch attracts (the reversing one,
    φ_d + π - 2 asin(d/ρ), repels)."""
    reference = paper_reference()
    phi, dt = reference.evaluate(np.array([0.0]))[0][0, 2] + 0.5, 1e-3

    def rate(t, phi):
        qd_dot = reference.evaluate(np.array([t]))[1][0]
        return (-qd_dot[0] * np.sin(phi) + qd_dot[1] * np.cos(phi)) / D

    for k in range(2000):  # 2 s; the time constant is d/(V cos β) = 0.11 s
        t = k * dt
        k1 = rate(t, phi)
        k2 = rate(t + dt / 2, phi + dt / 2 * k1)
        k3 = rate(t + dt / 2, phi + dt / 2 * k2)
        k4 = rate(t + dt, phi + dt * k3)
        phi += dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    assert phi == pytest.approx(reference.evaluate(np.array([2.0]))[0][0, 2], abs=1e-6)


@pytest.mark.parametrize("kind", ["consistent", "literal"])
def test_initial_state_is_on_the_constraint_manifold(kind):
    reference = paper_reference(kind)
    x0 = initial_state(reference)
    qd, qd_dot, _ = reference.evaluate(np.array([0.0]))
    np.testing.assert_array_equal(x0[:5], qd[0])
    np.testing.assert_array_equal(x0[8:], qd_dot[0, 3:])
    assert np.max(np.abs(WheeledRobot().constraint_residual(x0))) < 1e-15
    if kind == "consistent":
        np.testing.assert_allclose(x0[5:], qd_dot[0], atol=1e-15)


def test_reference_refusals():
    with pytest.raises(ValueError, match="kind"):
        paper_reference("circle")
    with pytest.raises(ValueError, match="shorter than"):
        paper_reference(d=2.0)
