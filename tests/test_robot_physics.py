"""Physics of the robot truth plant: energy, power balance, constraints, payload, parameters.

Independent references used here (not the plant's own code):

* the reduced mass matrix of Dhaouadi & Abu Hatab (2013) for a centre of mass on the heading
  axis, re-typed here:
  ``M_r = [[I_w + R²(mL² + I)/(4L²), R²(mL² - I)/(4L²)], [R²(mL² - I)/(4L²), I_w + ...]]``;
* the power balance ``dT/dt = η·τ - η·f`` with ``f_i = b_v θ̇_i + f_c tanh(θ̇_i / v_s)``, which
  holds for any correct reduced dynamics (the Coriolis terms do no work);
* a payload's kinetic energy ``½ m_p |v_p|²`` with ``v_p = v e + ω k × p`` (rigid-body kinematics),
  and its mass properties computed by hand in the test's comments;
* a fixed-step RK4 written in this file.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from delaytrack.plants.robot import (
    P3DX,
    P3DX_PAYLOAD,
    P3DX_SOURCES,
    PayloadRobot,
    WheeledRobot,
    consistent_state,
)

R, L, D = P3DX.wheel_radius, P3DX.half_track, P3DX.d


def rk4_step(f, t, x, h):
    k1 = f(t, x)
    k2 = f(t + h / 2, x + h / 2 * k1)
    k3 = f(t + h / 2, x + h / 2 * k2)
    k4 = f(t + h, x + h * k3)
    return x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


def robot_notes_reduced_mass(mass, inertia, Iw=P3DX.wheel_spin_inertia, R=R, L=L):
    """Dhaouadi & Abu Hatab's M_r (module docstring), re-typed."""
    diagonal = Iw + R**2 * (mass * L**2 + inertia) / (4 * L**2)
    off = R**2 * (mass * L**2 - inertia) / (4 * L**2)
    return np.array([[diagonal, off], [off, diagonal]])


def friction(eta, b_v, f_c, v_s):
    return b_v * eta + f_c * np.tanh(eta / v_s)


def start(eta=(4.0, 5.5), q=(0.1, 0.2, 0.3, 0.0, 0.0)):
    return consistent_state(np.array(q), np.array(eta), R, L, D)


def test_p3dx_parameters_and_sources():
    # The values of docs/robot.md ("Parameters"); derived: m_c = 9 - 2*0.5 = 8 kg,
    # K = 2 m_w d = 0.05 kg m, I_c = 0.264 - 8*0.05² - 2*0.5*0.165² - 2*I_m > 0.
    assert (R, L, D, P3DX.mass, P3DX.yaw_inertia, P3DX.wheel_spin_inertia) == (
        0.0975,
        0.165,
        0.05,
        9.0,
        0.264,
        0.01,
    )
    assert P3DX.platform_mass == 8.0
    assert P3DX.first_moment == pytest.approx(0.05)
    assert 0.2 < P3DX.platform_inertia < 0.225
    fields = set(P3DX.__dataclass_fields__) | {"platform_mass", "platform_inertia"}
    assert fields <= set(P3DX_SOURCES)
    for key, text in P3DX_SOURCES.items():
        assert text.startswith(("[source]", "[chosen]", "[assumed]", "[derived]")), key


def test_reduced_mass_is_robot_notes_formula():
    """With the centre of mass on the heading axis, the kernel's ``G`` rows 4–5 are ``M_r⁻¹``."""
    robot = WheeledRobot()
    rng = np.random.default_rng(10)
    for phi in rng.uniform(-np.pi, np.pi, 5):
        input_map = robot.input_map(np.array([0.0, 0.0, phi, 0.0, 0.0]))[0]
        np.testing.assert_allclose(
            np.linalg.inv(input_map[3:]),
            robot_notes_reduced_mass(P3DX.mass, P3DX.yaw_inertia),
            rtol=1e-12,
        )


@pytest.mark.parametrize("com_lateral", [0.0, 0.03])
def test_kinetic_energy_conserved_without_torque_and_friction(com_lateral):
    """10 s at dt = 1 ms: T = ½ηᵀM_rη stays constant to integrator accuracy (measured ~1e-14
    relative), while the Coriolis terms trade energy between v and ω."""
    robot = WheeledRobot(viscous_friction=0.0, coulomb_friction=0.0, com_lateral=com_lateral)
    x = start()
    energy0 = robot.kinetic_energy(x)[0]
    torque = np.zeros(2)

    def f(t, state):
        return robot.state_derivative(state, torque, t)[0]

    dt = 1e-3
    eta0 = x[8:].copy()
    for k in range(10_000):
        x = rk4_step(f, k * dt, x, dt)
    assert abs(robot.kinetic_energy(x)[0] - energy0) < 1e-11 * energy0
    assert np.max(np.abs(x[8:] - eta0)) > 0.05  # the wheel rates did change


def test_power_balance_at_random_states():
    """ηᵀ M_r η̇ = η·τ - η·f exactly (M_r of Dhaouadi & Abu Hatab, η̇ from the plant)."""
    b_v, f_c, v_s = 0.03, 0.12, 0.05
    robot = WheeledRobot(viscous_friction=b_v, coulomb_friction=f_c, friction_speed=v_s)
    reduced_mass = robot_notes_reduced_mass(P3DX.mass, P3DX.yaw_inertia)
    rng = np.random.default_rng(11)
    for _ in range(20):
        eta = rng.uniform(-6, 6, 2)
        x = start(eta, (*rng.normal(size=2), rng.uniform(-np.pi, np.pi), 0.0, 0.0))
        torque = rng.uniform(-2, 2, 2)
        eta_dot = robot.state_derivative(x, torque)[0][8:]
        power = eta @ torque - eta @ friction(eta, b_v, f_c, v_s)
        assert eta @ reduced_mass @ eta_dot == pytest.approx(power, rel=1e-11, abs=1e-12)


def power_balance_error(dt, seconds=5.0, b_v=0.01, f_c=0.1, v_s=0.05):
    """(T(t) - T(0) - W(t), W(t)) after ``seconds`` of random torques held 10 ms, where the work
    ``W = ∫ η·(τ - f) dt`` is integrated alongside the state by the same RK4."""
    robot = WheeledRobot(viscous_friction=b_v, coulomb_friction=f_c, friction_speed=v_s)
    torques = np.random.default_rng(12).uniform(-0.6, 0.6, (int(seconds * 100), 2))
    x = np.concatenate([start((1.0, -0.5)), [0.0]])
    energy0 = robot.kinetic_energy(x[:10])[0]
    per_hold = int(round(0.01 / dt))
    for k in range(int(round(seconds / dt))):
        torque = torques[k // per_hold]

        def f(t, state, torque=torque):
            eta = state[8:10]
            work_rate = eta @ torque - eta @ friction(eta, b_v, f_c, v_s)
            return np.append(robot.state_derivative(state[:10], torque, t)[0], work_rate)

        x = rk4_step(f, k * dt, x, dt)
    return robot.kinetic_energy(x[:10])[0] - energy0 - x[10], x[10]


def test_power_balance_along_a_trajectory():
    """dT/dt = η·τ - η·f integrated over 5 s with torques and friction: the mismatch is RK4's
    truncation error (4th order: halving dt divides it by ~16; measured 6.4e-8 J at 2 ms and
    3.9e-9 J at 1 ms, for 0.035 J of work; the wheels pass through zero speed, where the tanh
    friction is steep)."""
    error_1ms, work = power_balance_error(1e-3)
    error_2ms, _ = power_balance_error(2e-3)
    assert abs(work) > 0.01  # torques and friction did work
    assert abs(error_1ms) < 1e-8
    assert abs(error_2ms) > 8 * abs(error_1ms)


def random_torque_run(plant, seconds, dt=1e-3, seed=13):
    """Max ``|Λ q̇|`` along an RK4 run with random torques held for 10 ms."""
    rng = np.random.default_rng(seed)
    torques = rng.uniform(-1.0, 1.0, (int(seconds * 100) + 1, 2))
    x = start()
    worst = 0.0
    for k in range(int(round(seconds / dt))):
        torque = torques[int(k * dt * 100)]

        def f(t, state, torque=torque):
            return plant.state_derivative(state, torque, t)[0]

        x = rk4_step(f, k * dt, x, dt)
        worst = max(worst, float(np.max(np.abs(plant.constraint_residual(x)))))
    return worst, x


@pytest.mark.parametrize(
    "plant",
    [
        WheeledRobot(),
        # Placements switch every 1 s at times that fall inside RK4 steps (0.5003 + k s).
        PayloadRobot(
            placements=[[0.2, 0.15], [-0.1, -0.19], [0.0, 0.19]],
            first_on=0.5003,
            time_on=1.0,
            time_off=1.0,
        ),
    ],
    ids=["no-payload", "payload-switching"],
)
def test_constraints_hold_along_random_torque_trajectories(plant):
    # Measured: ~1e-11 without payload, ~1e-10 with mid-step payload switches.
    worst, x = random_torque_run(plant, seconds=5.0)
    assert worst < 1e-9
    assert np.all(np.isfinite(x))


@pytest.mark.parametrize("gain", [0.0, 20.0])
def test_baumgarte_term_removes_an_inconsistent_velocity(gain):
    """ρ̇ = -k_b ρ: an initial violation of 1e-3 m/s is gone after 2 s with the default
    k_b = 20 1/s (e^-40 ≈ 4e-18), and stays without the term."""
    robot = WheeledRobot(baumgarte_gain=gain)
    x = start()
    x[5:8] += [1e-3, -1e-3, 1e-3]
    residual0 = np.max(np.abs(robot.constraint_residual(x)))
    torque = np.array([0.3, 0.2])

    def f(t, state):
        return robot.state_derivative(state, torque, t)[0]

    for k in range(2000):
        x = rk4_step(f, k * 1e-3, x, 1e-3)
    residual = np.max(np.abs(robot.constraint_residual(x)))
    if gain > 0:
        assert residual < 1e-9
    else:
        assert residual > 0.5 * residual0


def test_payload_mass_properties_by_hand():
    """One placement p = (0.15, 0.10) m from A (forward, left), 3.5 kg, on the P3-DX:

    mass        9 + 3.5                                   = 12.5 kg
    moment s    (m_c d + m_p p_x, m_p p_y) = (8·0.05 + 3.5·0.15, 3.5·0.10) = (0.925, 0.35) kg m
    CoM         s / 12.5                                  = (0.074, 0.028) m
    I about A   0.264 + 3.5 (0.15² + 0.10²) = 0.264 + 0.11375 = 0.37775 kg m²
    I about CoM 0.37775 - 12.5 (0.074² + 0.028²) = 0.37775 - 0.07825 = 0.2995 kg m²
    """
    plant = PayloadRobot(placements=[[0.15, 0.10]], first_on=5.0, time_on=5.0, time_off=5.0)
    loaded = plant.mass_properties(7.0)
    assert loaded["mass"] == pytest.approx(12.5)
    np.testing.assert_allclose(loaded["center_of_mass"], [0.074, 0.028], rtol=1e-12)
    assert loaded["yaw_inertia_about_axle"] == pytest.approx(0.37775)
    assert loaded["yaw_inertia_about_com"] == pytest.approx(0.2995)
    unloaded = plant.mass_properties(2.0)
    assert unloaded["mass"] == pytest.approx(9.0)
    np.testing.assert_allclose(unloaded["center_of_mass"], [8 * 0.05 / 9, 0.0], atol=1e-15)
    assert unloaded["yaw_inertia_about_axle"] == pytest.approx(0.264)


def test_payload_enters_the_dynamics_as_a_point_mass():
    """T(loaded) - T(unloaded) = ½ m_p |v_p|², v_p = (v - ω p_y) e + ω p_x n (body frame)."""
    p_x, p_y, m_p = 0.15, 0.10, 3.5
    plant = PayloadRobot(placements=[[p_x, p_y]], first_on=5.0, time_on=5.0, time_off=5.0)
    rng = np.random.default_rng(14)
    for _ in range(5):
        eta = rng.uniform(-5, 5, 2)
        x = start(eta, (0.0, 0.0, rng.uniform(-np.pi, np.pi), 0.0, 0.0))
        v = R * (eta[0] + eta[1]) / 2
        w = R * (eta[0] - eta[1]) / (2 * L)
        payload_energy = 0.5 * m_p * ((v - w * p_y) ** 2 + (w * p_x) ** 2)
        difference = plant.kinetic_energy(x, 7.0)[0] - plant.kinetic_energy(x, 2.0)[0]
        assert difference == pytest.approx(payload_energy, rel=1e-12)
        # And the unloaded plant is the robot itself.
        assert plant.kinetic_energy(x, 2.0)[0] == pytest.approx(
            plant.robot.kinetic_energy(x)[0], rel=1e-15
        )


def test_payload_schedule():
    plant = PayloadRobot(
        placements=[[0.1, 0.0], [0.0, 0.1]], first_on=5.0, time_on=5.0, time_off=5.0
    )
    expected = {0.0: None, 4.999: None, 5.0: 0, 9.999: 0, 10.0: None, 15.0: 1, 19.9: 1, 25.0: None}
    for t, k in expected.items():
        point = plant.placement_at(t)
        if k is None:
            assert point is None, t
        else:
            np.testing.assert_array_equal(point, plant.placements[k])


def test_random_placements_are_seeded_and_on_the_plate():
    a = PayloadRobot(seed=7, duration=60.0)
    b = PayloadRobot(seed=7, duration=60.0)
    c = PayloadRobot(seed=8, duration=60.0)
    # First on at 5 s, every 10 s: placements start at 5, 15, ..., 55 s -> 6 of them.
    assert a.placements.shape == (6, 2)
    np.testing.assert_array_equal(a.placements, b.placements)
    assert not np.array_equal(a.placements, c.placements)
    center, length, width = (
        P3DX_PAYLOAD.plate_center,
        P3DX_PAYLOAD.plate_length,
        P3DX_PAYLOAD.plate_width,
    )
    many = PayloadRobot(seed=1, duration=2000.0).placements
    assert np.all(np.abs(many[:, 0] - center) <= length / 2)
    assert np.all(np.abs(many[:, 1]) <= width / 2)
    assert many[:, 1].min() < -0.15 and many[:, 1].max() > 0.15  # sideways both ways
    assert PayloadRobot(seed=1, duration=5.0).placements.shape == (0, 2)


def test_payload_refusals():
    with pytest.raises(ValueError, match="either placements"):
        PayloadRobot()
    with pytest.raises(ValueError, match="either placements"):
        PayloadRobot(placements=[[0.0, 0.0]], seed=1, duration=10.0)
    with pytest.raises(ValueError, match="seed and duration"):
        PayloadRobot(seed=1)
    with pytest.raises(ValueError, match=r"shape \(k, 2\)"):
        PayloadRobot(placements=[0.1, 0.2, 0.3])
    with pytest.raises(ValueError, match="payload_mass"):
        PayloadRobot(seed=1, duration=10.0, payload_mass=0.0)


def test_friction_slows_a_coasting_robot():
    robot = WheeledRobot()  # P3-DX friction (assumed values)
    x = start()
    energies = [robot.kinetic_energy(x)[0]]
    torque = np.zeros(2)

    def f(t, state):
        return robot.state_derivative(state, torque, t)[0]

    for k in range(1000):
        x = rk4_step(f, k * 1e-3, x, 1e-3)
        energies.append(robot.kinetic_energy(x)[0])
    assert np.all(np.diff(energies) < 0)


def test_body_refusals():
    with pytest.raises(ValueError, match="wheel_mass"):
        WheeledRobot(wheel_mass=5.0)
    with pytest.raises(ValueError, match="yaw_inertia"):
        WheeledRobot(yaw_inertia=0.01)
    with pytest.raises(ValueError, match="friction_speed"):
        WheeledRobot(friction_speed=0.0)
    with pytest.raises(TypeError, match="d must be a real number"):
        WheeledRobot(d="0.05")
    assert math.isclose(WheeledRobot(com_forward=0.07).com_forward, 0.07)
