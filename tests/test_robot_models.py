"""The robot's nominal model, its command map ``τ_w = S(q)ᵀ τ`` and the plant registry.

References: the published reduced mass matrix M_r (docs/robot.md; re-typed in
``robot_notes_reduced_mass``), the kinematic map ``S(q)`` of docs/robot.md and in
``delaytrack.plants.robot.kinematics`` (re-typed in ``kinematic_map_by_hand``), and the input map
``G = [0; 0; 0; I]`` as printed in Roy & Kar, Section III.
"""

from __future__ import annotations

import numpy as np
import pytest

from delaytrack import AROLC, OuterLoop, plant_from_spec
from delaytrack._spec import SpecError
from delaytrack.components import call_command_map
from delaytrack.plants import LinearPlant
from delaytrack.plants.robot import (
    P3DX,
    NominalRobot,
    PayloadRobot,
    PrintedRobotModel,
    WheeledRobot,
    consistent_state,
    kinematic_map,
    kinematic_map_rate,
)

R, L, D = P3DX.wheel_radius, P3DX.half_track, P3DX.d


def kinematic_map_by_hand(phi, R=R, L=L, d=D):
    c, s = np.cos(phi), np.sin(phi)
    return np.array(
        [
            [R / 2 * c - d * R / (2 * L) * s, R / 2 * c + d * R / (2 * L) * s],
            [R / 2 * s + d * R / (2 * L) * c, R / 2 * s - d * R / (2 * L) * c],
            [R / (2 * L), -R / (2 * L)],
            [1.0, 0.0],
            [0.0, 1.0],
        ]
    )


def robot_notes_reduced_mass(mass=P3DX.mass, inertia=P3DX.yaw_inertia, Iw=0.01):
    diagonal = Iw + R**2 * (mass * L**2 + inertia) / (4 * L**2)
    off = R**2 * (mass * L**2 - inertia) / (4 * L**2)
    return np.array([[diagonal, off], [off, diagonal]])


@pytest.fixture(scope="module")
def angles():
    return np.random.default_rng(20).uniform(-np.pi, np.pi, 12)


def test_kinematic_map_and_its_rate(angles):
    """S(q) as printed (re-typed), and Ṡ = dS/dt by central differences along φ(t) = φ + φ̇ t."""
    phidot, h = 0.7, 1e-6
    for phi in angles:
        q = np.array([0.0, 0.0, phi, 0.0, 0.0])
        qdot = np.array([0.0, 0.0, phidot, 0.0, 0.0])
        np.testing.assert_allclose(kinematic_map(q, R, L, D), kinematic_map_by_hand(phi))
        numeric = (
            kinematic_map_by_hand(phi + phidot * h) - kinematic_map_by_hand(phi - phidot * h)
        ) / (2 * h)
        np.testing.assert_allclose(kinematic_map_rate(q, qdot, R, L, D), numeric, atol=1e-9)


def test_nominal_mass_matrix_is_symmetric_positive_definite(angles):
    model = NominalRobot()
    for phi in angles:
        mass = model.mass_matrix(np.array([0.3, -0.1, phi, 1.0, 2.0]))[0]
        np.testing.assert_array_equal(mass, mass.T)
        assert np.linalg.eigvalsh(mass).min() > 0.0
    # also with the platform's centre of mass off the heading axis
    model = NominalRobot(com_lateral=0.04, com_forward=0.08)
    assert np.linalg.eigvalsh(model.mass_matrix(np.zeros(5))[0]).min() > 0.0


def test_nominal_closed_form_at_p3dx_values():
    """K = m d - m_c d = 2·0.5·0.05 = 0.05 kg m; I_P = I - 2 d m_c d + m d² = 0.264 - 0.04 + 0.0225
    = 0.2465 kg m² (hand computation)."""
    model = NominalRobot()
    assert model.first_moment == pytest.approx(0.05)
    assert model.inertia_about_point == pytest.approx(0.2465)
    phi, phidot = 0.7, 1.3
    mass, nonlinear, _ = model.terms(np.array([0, 0, phi, 0, 0.0]), np.array([0, 0, phidot, 0, 0]))
    assert mass[0, 0, 2] == pytest.approx(0.05 * np.sin(phi))
    assert mass[0, 1, 2] == pytest.approx(-0.05 * np.cos(phi))
    np.testing.assert_allclose(
        nonlinear[0], [0.05 * np.cos(phi) * phidot**2, 0.05 * np.sin(phi) * phidot**2, 0, 0, 0]
    )


def test_projected_nominal_mass_is_the_reduced_mass(angles):
    """Sᵀ M̂ S = the published M_r (docs/robot.md; nominal parameters, CoM on the heading axis), and
    SᵀG = I."""
    model = NominalRobot()
    for phi in angles:
        q = np.array([0.0, 0.0, phi, 0.0, 0.0])
        S = kinematic_map_by_hand(phi)
        mass, _, input_map = model.terms(q, np.zeros(5))
        np.testing.assert_allclose(S.T @ mass[0] @ S, robot_notes_reduced_mass(), rtol=1e-12)
        np.testing.assert_array_equal(S.T @ input_map[0], np.eye(2))


def test_projected_nominal_model_reproduces_the_frictionless_truth(angles):
    """Along constrained motions, Sᵀ (M̂ q̈ + N̂) = τ_w with q̈ the truth plant's (same parameters,
    no friction): the nominal model plus the projection is exact when nothing is uncertain."""
    truth = WheeledRobot(viscous_friction=0.0, coulomb_friction=0.0)
    model = NominalRobot()
    rng = np.random.default_rng(21)
    for phi in angles:
        x = consistent_state(np.array([0.2, 0.1, phi, 0.0, 0.0]), rng.uniform(-6, 6, 2), R, L, D)
        torque = rng.uniform(-1, 1, 2)
        qddot = truth.state_derivative(x, torque)[0][5:]
        mass, nonlinear, _ = model.terms(x[:5], x[5:])
        S = kinematic_map_by_hand(phi)
        np.testing.assert_allclose(
            S.T @ (mass[0] @ qddot + nonlinear[0]), torque, rtol=1e-10, atol=1e-12
        )


@pytest.mark.parametrize("model", [NominalRobot(), PrintedRobotModel()], ids=["nominal", "printed"])
def test_python_command_map_is_the_projection(model):
    rng = np.random.default_rng(22)
    q = np.array([0.0, 0.0, 0.9, 0.0, 0.0])
    tau = rng.normal(size=5)
    command = np.empty(2)
    call_command_map(model.engine_kernel, q, model.params, np.zeros((5, 2)), tau, command)
    np.testing.assert_allclose(command, kinematic_map_by_hand(0.9).T @ tau, rtol=1e-14)


def test_python_command_map_default_solves_the_input_map():
    tau = np.array([1.0, 2.0])
    command = np.empty(2)
    model = LinearPlant(np.eye(2), input_map_matrix=np.diag([2.0, 4.0]))
    call_command_map(
        model.engine_kernel, np.zeros(2), model.params, np.diag([2.0, 4.0]), tau, command
    )
    np.testing.assert_allclose(command, [0.5, 0.5])


@pytest.mark.parametrize("model", [NominalRobot(), PrintedRobotModel()], ids=["nominal", "printed"])
def test_compiled_controller_step_uses_the_projection(model):
    """OuterLoop's compiled step with the robot model id: command = S(q)ᵀ (M̂ û + N̂)."""
    controller = OuterLoop(model, K1=1.0, K2=2.0)
    rng = np.random.default_rng(23)
    q, qdot = rng.normal(size=5), rng.normal(size=5)
    qd, qd_dot, qd_ddot = rng.normal(size=5), rng.normal(size=5), rng.normal(size=5)
    command, _ = controller.step(
        0.0, q, qdot, (qd, qd_dot, qd_ddot), controller.initial_state(), T_c=0.01
    )
    u = qd_ddot + 2.0 * (qd_dot - qdot) + 1.0 * (qd - q)
    mass, nonlinear, _ = model.terms(q, qdot)
    expected = kinematic_map_by_hand(q[2]).T @ (mass[0] @ u + nonlinear[0])
    np.testing.assert_allclose(command, expected, rtol=1e-12)


def test_controllers_accept_the_robot_models_and_refuse_the_truth():
    gains = dict(K1=1.0, K2=1.0, Q=1.0, alpha=2.0, epsilon=0.1, gamma=0.001)
    assert AROLC(NominalRobot(), **gains).m == 2
    assert AROLC(PrintedRobotModel(), **gains).n == 5
    with pytest.raises(ValueError, match="own command map"):
        AROLC(WheeledRobot(), **gains)


@pytest.mark.parametrize(
    "plant",
    [
        WheeledRobot(viscous_friction=0.02, com_lateral=0.01),
        PayloadRobot(seed=3, duration=30.0),
        PayloadRobot(placements=[[0.1, 0.05]], payload_mass=2.0),
        NominalRobot(d=0.06),
        PrintedRobotModel(first_moment=0.45, corrected_row2=True),
    ],
    ids=["truth", "payload-seed", "payload-placements", "nominal", "printed"],
)
def test_spec_round_trip(plant):
    rebuilt = plant_from_spec(plant.to_spec())
    assert type(rebuilt) is type(plant)
    np.testing.assert_array_equal(rebuilt.params, plant.params)
    assert rebuilt.engine_kernel == plant.engine_kernel


def test_spec_refusals_name_the_key():
    with pytest.raises(SpecError, match="'plant.mass'"):
        plant_from_spec({"type": "wheeled-robot", "mass": "nine"})
    with pytest.raises(SpecError, match="'plant.seed' must be an integer"):
        plant_from_spec({"type": "wheeled-robot-payload", "seed": 1.5, "duration": 10.0})
    with pytest.raises(SpecError, match="either"):
        plant_from_spec(
            {"type": "wheeled-robot-payload", "seed": 1, "duration": 10.0, "placements": [[0, 0]]}
        )
    with pytest.raises(SpecError, match="corrected_row2"):
        plant_from_spec({"type": "wheeled-robot-printed", "corrected_row2": 1})
    plant = plant_from_spec({"type": "wheeled-robot-payload", "seed": 1, "duration": 20.0})
    assert isinstance(plant, PayloadRobot) and plant.placements.shape == (2, 2)
