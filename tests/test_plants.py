"""Euler–Lagrange plants: closed forms, energy balance, batching, user plants, refused inputs.

References: the two-link arm's closed form is the one printed in the module docstring of
``delaytrack.plants.two_link_arm`` (Dixon et al. 2003), re-typed here; the energy checks use the
EL identity dT/dt = q̇ᵀ(G u − F_d q̇) that holds for any correct Coriolis term (Ṁ − 2C skew).
"""

from __future__ import annotations

import numpy as np
import pytest

from arm_closed_form import FD1, FD2, P1, P2, P3, arm_mass, arm_mass_dot, arm_nonlinear
from delaytrack.plants import CallablePlant, LinearPlant, TwoLinkArm, plant_from_spec


def kinetic_energy(plant, x: np.ndarray) -> np.ndarray:
    """T = 1/2 q̇ᵀ M(q) q̇ for states x (batch, 2n)."""
    n = plant.n
    mass = plant.mass_matrix(x[:, :n])
    return 0.5 * np.einsum("bi,bij,bj->b", x[:, n:], mass, x[:, n:])


def rk4(f, x: np.ndarray, dt: float, steps: int) -> np.ndarray:
    """Classic fixed-step RK4, written here (independent of delaytrack.sim)."""
    for _ in range(steps):
        k1 = f(x)
        k2 = f(x + 0.5 * dt * k1)
        k3 = f(x + 0.5 * dt * k2)
        k4 = f(x + dt * k3)
        x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return x


@pytest.fixture(scope="module")
def rng():
    return np.random.default_rng(20240601)


# --------------------------------------------------------------------------------------------
# TwoLinkArm
# --------------------------------------------------------------------------------------------


def test_arm_matches_closed_form(rng):
    arm = TwoLinkArm()
    q = rng.uniform(-2 * np.pi, 2 * np.pi, (40, 2))
    qdot = rng.uniform(-3, 3, (40, 2))
    mass, nonlinear, input_map = arm.terms(q, qdot)
    for b in range(40):
        np.testing.assert_allclose(mass[b], arm_mass(q[b]), rtol=1e-15)
        np.testing.assert_allclose(
            nonlinear[b], arm_nonlinear(q[b], qdot[b]), rtol=1e-13, atol=1e-14
        )
        np.testing.assert_array_equal(input_map[b], np.eye(2))  # G = I
    np.testing.assert_array_equal(arm.params, [P1, P2, P3, FD1, FD2])


def test_arm_mass_symmetric_positive_definite(rng):
    arm = TwoLinkArm()
    q = rng.uniform(-10, 10, (200, 2))
    mass = arm.mass_matrix(q)
    np.testing.assert_array_equal(mass, np.swapaxes(mass, 1, 2))
    eigenvalues = np.linalg.eigvalsh(mass)
    # det M = p1 p2 - p2^2 - p3^2 cos^2 q2 >= p1 p2 - p2^2 - p3^2 = 0.0829 > 0 (docstring values).
    assert np.all(eigenvalues > 0.0)
    np.testing.assert_allclose(
        np.linalg.det(mass), P1 * P2 - P2**2 - P3**2 * np.cos(q[:, 1]) ** 2, rtol=1e-12
    )


def test_arm_mass_dot_by_finite_differences(rng):
    # Guards the hand-derived Ṁ used below: central differences along q̇.
    arm = TwoLinkArm()
    for _ in range(10):
        q, qdot = rng.uniform(-3, 3, 2), rng.uniform(-2, 2, 2)
        step = 1e-6
        fd = (arm.mass_matrix(q + step * qdot)[0] - arm.mass_matrix(q - step * qdot)[0]) / (
            2 * step
        )
        np.testing.assert_allclose(fd, arm_mass_dot(q, qdot), atol=1e-8)


@pytest.mark.parametrize("friction", [(0.0, 0.0), (FD1, FD2)], ids=["frictionless", "friction"])
def test_arm_power_balance(rng, friction):
    # EL power balance: dT/dt = q̇ᵀ M q̈ + 1/2 q̇ᵀ Ṁ q̇ = q̇ᵀ u − q̇ᵀ F_d q̇.
    arm = TwoLinkArm(fd1=friction[0], fd2=friction[1])
    friction_matrix = np.diag(friction)
    for _ in range(25):
        q, qdot, u = rng.uniform(-3, 3, 2), rng.uniform(-3, 3, 2), rng.uniform(-5, 5, 2)
        qdd = arm.state_derivative(np.concatenate([q, qdot]), u)[0, 2:]
        power = qdot @ (arm_mass(q) @ qdd + 0.5 * arm_mass_dot(q, qdot) @ qdot)
        expected = qdot @ u - qdot @ friction_matrix @ qdot
        assert power == pytest.approx(expected, abs=1e-10 * max(1.0, abs(expected)))


def christoffel_coriolis(plant, q, qdot, step=1e-5):
    """C(q, q̇) from Christoffel symbols of M, with ∂M/∂q_i by central differences.

    C_kj = Σ_i 1/2 (∂M_kj/∂q_i + ∂M_ki/∂q_j − ∂M_ij/∂q_k) q̇_i.
    """
    n = plant.n
    dM = np.empty((n, n, n))  # dM[i] = ∂M/∂q_i
    for i in range(n):
        e = np.zeros(n)
        e[i] = step
        dM[i] = (plant.mass_matrix(q + e)[0] - plant.mass_matrix(q - e)[0]) / (2 * step)
    C = np.zeros((n, n))
    for k in range(n):
        for j in range(n):
            C[k, j] = sum(
                0.5 * (dM[i][k, j] + dM[j][k, i] - dM[k][i, j]) * qdot[i] for i in range(n)
            )
    return C


def test_arm_coriolis_from_christoffel_symbols_and_skew_symmetry(rng):
    arm = TwoLinkArm(fd1=0.0, fd2=0.0)
    for _ in range(10):
        q, qdot = rng.uniform(-3, 3, 2), rng.uniform(-3, 3, 2)
        C = christoffel_coriolis(arm, q, qdot)
        # Frictionless N is exactly C q̇ (no gravity: horizontal plane).
        np.testing.assert_allclose(arm.nonlinear_terms(q, qdot)[0], C @ qdot, atol=1e-8)
        S = arm_mass_dot(q, qdot) - 2 * C
        np.testing.assert_allclose(S, -S.T, atol=1e-8)


def test_frictionless_arm_conserves_energy_rk4():
    # Zero torque, no friction: T is a first integral. RK4 at dt = 1 ms over 2 s keeps it to
    # ~3e-14 relative (measured; global error O(dt^4): 3e-10 at dt = 10 ms); a wrong Coriolis
    # term drifts by O(1).
    arm = TwoLinkArm(fd1=0.0, fd2=0.0)
    x0 = np.array([[0.3, -1.2, 1.5, -2.0], [2.0, 0.5, -0.7, 3.0], [0.0, 0.3, 1.0, 0.0]])
    u = np.zeros((1, 2))
    x1 = rk4(lambda x: arm.state_derivative(x, u), x0, 1e-3, 2000)
    T0, T1 = kinetic_energy(arm, x0), kinetic_energy(arm, x1)
    np.testing.assert_allclose(T1, T0, rtol=1e-11)
    assert np.all(np.abs(x1[:, :2] - x0[:, :2]) > 0.1)  # the arm did move


def test_arm_work_energy_balance_with_torque_and_friction_rk4():
    # T(t1) − T(0) = ∫ (q̇ᵀ u − q̇ᵀ F_d q̇) dt, integrated alongside the state by the same RK4.
    arm = TwoLinkArm()
    u = np.array([[1.5, -0.4]])
    friction_matrix = np.diag([FD1, FD2])

    def augmented(z):
        x = z[:, :4]
        qdot = x[:, 2:]
        work = qdot @ u[0] - np.einsum("bi,ij,bj->b", qdot, friction_matrix, qdot)
        return np.concatenate([arm.state_derivative(x, u), work[:, None]], axis=1)

    z0 = np.array([[0.1, 0.4, -1.0, 2.0, 0.0]])
    z1 = rk4(augmented, z0, 1e-3, 1000)
    delta_T = kinetic_energy(arm, z1[:, :4]) - kinetic_energy(arm, z0[:, :4])
    np.testing.assert_allclose(delta_T, z1[:, 4], atol=1e-9)
    assert abs(z1[0, 4]) > 0.1  # non-trivial work


def test_arm_batch_axis_equals_single_calls(rng):
    arm = TwoLinkArm()
    q = rng.uniform(-3, 3, (7, 2))
    qdot = rng.uniform(-3, 3, (7, 2))
    assert arm.mass_matrix(q).shape == (7, 2, 2)
    assert arm.nonlinear_terms(q, qdot).shape == (7, 2)
    assert arm.input_map(q).shape == (7, 2, 2)
    assert arm.mass_matrix(q[0]).shape == (1, 2, 2)  # a single (n,) is a batch of one
    for b in range(7):
        np.testing.assert_array_equal(arm.mass_matrix(q)[b], arm.mass_matrix(q[b])[0])
        np.testing.assert_array_equal(
            arm.nonlinear_terms(q, qdot)[b], arm.nonlinear_terms(q[b], qdot[b])[0]
        )
    x = np.concatenate([q, qdot], axis=1)
    u = rng.uniform(-1, 1, (7, 2))
    dx = arm.state_derivative(x, u)
    assert dx.shape == (7, 4)
    for b in range(7):
        np.testing.assert_array_equal(dx[b], arm.state_derivative(x[b], u[b])[0])
        qdd = np.linalg.solve(arm_mass(q[b]), u[b] - arm_nonlinear(q[b], qdot[b]))
        np.testing.assert_allclose(dx[b], np.concatenate([qdot[b], qdd]), rtol=1e-12, atol=1e-13)


def test_arm_wrong_shapes_refused():
    arm = TwoLinkArm()
    with pytest.raises(ValueError, match=r"q must have shape \(batch, 2\) or \(2,\); got \(3,\)"):
        arm.mass_matrix(np.zeros(3))
    with pytest.raises(
        ValueError, match=r"x must have shape \(batch, 4\) and u \(batch, 2\); got \(1, 3\)"
    ):
        arm.state_derivative(np.zeros(3), np.zeros(2))
    with pytest.raises(ValueError, match=r"same batch size; got 2 and 3"):
        arm.terms(np.zeros((2, 2)), np.zeros((3, 2)))


def test_state_derivative_broadcasts_a_single_input(rng):
    arm = TwoLinkArm()
    x = rng.uniform(-1, 1, (3, 4))
    u = np.array([[0.5, -2.0]])
    dx = arm.state_derivative(x, u)
    for b in range(3):
        np.testing.assert_array_equal(dx[b], arm.state_derivative(x[b], u[0])[0])


def test_state_derivative_refuses_mismatched_input_batch():
    arm = TwoLinkArm()
    with pytest.raises(ValueError, match=r"batch"):
        arm.state_derivative(np.zeros((3, 4)), np.ones((2, 2)))


@pytest.mark.parametrize(
    "kwargs, message",
    [
        # p1 p2 − p2² = 0.04 < p3² = 0.09.
        (dict(p1=0.5, p2=0.4, p3=0.3), r"p1\*p2 - p2\*\*2 > p3\*\*2.*p1=0\.5, p2=0\.4, p3=0\.3"),
        # Boundary: p1 p2 − p2² = p3² exactly (1·1 − 0.75 = 0.25 = 0.5²) is refused too.
        (dict(p1=1.0, p2=0.75, p3=0.5), r"p1\*p2 - p2\*\*2 > p3\*\*2"),
        # Terms beyond a float: refused, not an OverflowError from p3**2, nor inf - inf taken.
        (dict(p3=1e300), r"p1\*p2 - p2\*\*2 > p3\*\*2, a finite margin.*p3=1e\+300"),
        (dict(p1=1e300, p2=1e200), r"p1\*p2 - p2\*\*2 > p3\*\*2, a finite margin"),
        (dict(p1=-1.0), r"p1'? must be > 0; got -1"),
        (dict(fd2=-0.1), r"fd2'? must be >= 0; got -0\.1"),
    ],
)
def test_arm_bad_parameters_refused(kwargs, message):
    with pytest.raises(ValueError, match=message):
        TwoLinkArm(**kwargs)
    with pytest.raises(ValueError, match=message):
        plant_from_spec({"type": "two-link-arm", **kwargs})


def test_compiled_flags():
    assert TwoLinkArm().compiled is True
    assert LinearPlant(1.0).compiled is True
    plant = CallablePlant(1, lambda q: np.eye(1), lambda q, qdot: np.zeros(1))
    assert plant.compiled is False


# --------------------------------------------------------------------------------------------
# LinearPlant
# --------------------------------------------------------------------------------------------


def test_linear_plant_state_derivative(rng):
    n, m = 3, 2
    A = rng.standard_normal((n, n))
    mass = A @ A.T + n * np.eye(n)
    damping = rng.standard_normal((n, n))
    stiffness = rng.standard_normal((n, n))
    input_map = rng.standard_normal((n, m))
    plant = LinearPlant(mass, damping, stiffness, input_map)
    assert (plant.n, plant.m) == (3, 2)
    x = rng.standard_normal((5, 2 * n))
    u = rng.standard_normal((5, m))
    dx = plant.state_derivative(x, u)
    assert dx.shape == (5, 6)
    for b in range(5):
        q, qdot = x[b, :n], x[b, n:]
        qdd = np.linalg.solve(mass, input_map @ u[b] - damping @ qdot - stiffness @ q)
        np.testing.assert_allclose(dx[b], np.concatenate([qdot, qdd]), rtol=1e-12, atol=1e-12)
    mass_b, nonlinear_b, input_b = plant.terms(x[:, :n], x[:, n:])
    assert mass_b.shape == (5, 3, 3) and nonlinear_b.shape == (5, 3) and input_b.shape == (5, 3, 2)
    np.testing.assert_allclose(mass_b[0], mass, rtol=1e-15)
    np.testing.assert_allclose(input_b[4], input_map, rtol=1e-15)


def test_linear_plant_defaults_and_scalar_forms():
    plant = LinearPlant(2.0)
    assert (plant.n, plant.m) == (1, 1)
    # 2 q̈ = u with D = K = 0, G = 1.
    np.testing.assert_allclose(plant.state_derivative([1.0, -3.0], [4.0]), [[-3.0, 2.0]])
    diagonal = LinearPlant([1.0, 4.0], stiffness=[[1.0, 0.0], [0.0, 8.0]])
    np.testing.assert_array_equal(diagonal.mass, np.diag([1.0, 4.0]))
    np.testing.assert_allclose(
        diagonal.state_derivative([1.0, 1.0, 0.0, 0.0], [0.0, 0.0]), [[0, 0, -1, -2]]
    )


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (
            dict(mass=[[1.0, 2.0], [2.0, 1.0]]),
            r"mass must be symmetric positive definite; its eigenvalues are \[-1, 3\]",
        ),
        (
            dict(mass=[[1.0, 0.5], [0.0, 1.0]]),
            r"mass must be symmetric positive definite; it is not symmetric",
        ),
        (
            dict(mass=[1.0, 0.0]),
            r"mass must be symmetric positive definite; its eigenvalues are \[0, 1\]",
        ),
        (dict(mass=np.eye(2), damping=np.eye(3)), r"damping must be 2x2; got shape \(3, 3\)"),
        (
            dict(mass=np.eye(2), input_map_matrix=np.ones((3, 2))),
            r"input_map_matrix must have shape \(2, m\); got \(3, 2\)",
        ),
        (dict(mass=np.eye(2), stiffness=[[np.nan, 0], [0, 1]]), r"stiffness must be finite"),
    ],
)
def test_linear_plant_refused(kwargs, message):
    with pytest.raises(ValueError, match=message):
        LinearPlant(**kwargs)


# --------------------------------------------------------------------------------------------
# CallablePlant
# --------------------------------------------------------------------------------------------


def test_callable_plant_matches_two_link_arm(rng):
    arm = TwoLinkArm()
    user = CallablePlant(2, arm_mass, arm_nonlinear, name="arm-as-python")
    assert (user.n, user.m) == (2, 2)
    q = rng.uniform(-3, 3, (6, 2))
    qdot = rng.uniform(-3, 3, (6, 2))
    for got, want in zip(user.terms(q, qdot), arm.terms(q, qdot), strict=True):
        np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-14)
    x = np.concatenate([q, qdot], axis=1)
    u = rng.uniform(-2, 2, (6, 2))
    np.testing.assert_allclose(
        user.state_derivative(x, u), arm.state_derivative(x, u), rtol=1e-12, atol=1e-13
    )


def test_callable_plant_input_map_forms():
    mass, zero = (lambda q: np.diag([1.0, 2.0])), (lambda q, qdot: np.zeros(2))
    column = np.array([[1.0], [0.5]])
    constant = CallablePlant(2, mass, zero, input_map_fn=column)
    function = CallablePlant(2, mass, zero, input_map_fn=lambda q: column)
    for plant in (constant, function):
        assert plant.m == 1
        # q̈ = M⁻¹ G u = [3, 0.5 * 3 / 2].
        np.testing.assert_allclose(plant.state_derivative(np.zeros(4), [3.0]), [[0, 0, 3.0, 0.75]])


@pytest.mark.parametrize(
    "args, message",
    [
        (
            (2, lambda q: np.eye(3), lambda q, qd: np.zeros(2)),
            r"mass_matrix must return shape \(2, 2\); got \(3, 3\)",
        ),
        (
            (2, lambda q: np.eye(2), lambda q, qd: np.zeros(3)),
            r"nonlinear_terms must return shape \(2,\); got \(3,\)",
        ),
        (
            (2, lambda q: np.ones(2), lambda q, qd: np.zeros(2)),
            r"mass_matrix must return shape \(2, 2\); got \(2,\)",
        ),
        (
            (2, lambda q: [[1.0, 0.3], [0.0, 1.0]], lambda q, qd: np.zeros(2)),
            r"mass_matrix\(0\) must be symmetric",
        ),
        (
            (2, lambda q: np.diag([1.0, -2.0]), lambda q, qd: np.zeros(2)),
            r"mass_matrix\(0\) must be symmetric positive definite; its eigenvalues are \[-2, 1\]",
        ),
        (
            (2, lambda q: np.eye(2), lambda q, qd: np.full(2, np.nan)),
            r"nonlinear_terms returned non-finite values",
        ),
        (
            (0, lambda q: np.eye(0), lambda q, qd: np.zeros(0)),
            r"n must be a positive integer; got 0",
        ),
    ],
)
def test_callable_plant_refused(args, message):
    with pytest.raises(ValueError, match=message):
        CallablePlant(*args)


def test_callable_plant_not_callable_and_bad_input_map():
    with pytest.raises(TypeError, match=r"mass_matrix must be callable; got ndarray"):
        CallablePlant(2, np.eye(2), lambda q, qd: np.zeros(2))
    with pytest.raises(ValueError, match=r"input_map must have shape \(2, m\); got \(3, 1\)"):
        CallablePlant(
            2, lambda q: np.eye(2), lambda q, qd: np.zeros(2), input_map_fn=np.ones((3, 1))
        )
    with pytest.raises(ValueError, match=r"input_map must return shape \(2, m\); got \(2,\)"):
        CallablePlant(
            2, lambda q: np.eye(2), lambda q, qd: np.zeros(2), input_map_fn=lambda q: np.ones(2)
        )


# --------------------------------------------------------------------------------------------
# plant_from_spec
# --------------------------------------------------------------------------------------------


def test_plant_from_spec_builds_and_refuses():
    arm = plant_from_spec({"type": "two-link-arm", "p1": 3.0, "fd1": 0.0})
    assert isinstance(arm, TwoLinkArm) and arm.p1 == 3.0 and arm.fd1 == 0.0 and arm.p2 == P2
    assert plant_from_spec(arm.to_spec()) == arm
    linear = plant_from_spec({"type": "linear", "mass": 2.0, "input_map": [[1.0]]})
    assert isinstance(linear, LinearPlant) and linear.m == 1
    np.testing.assert_array_equal(plant_from_spec(linear.to_spec()).params, linear.params)
    with pytest.raises(
        ValueError,
        match=r"'plant\.type' must be one of \['linear', 'mujoco', 'two-link-arm', "
        r"'wheeled-robot', 'wheeled-robot-mujoco', 'wheeled-robot-nominal', "
        r"'wheeled-robot-payload', 'wheeled-robot-printed'\] or a factory of yours, "
        r"'python:<module>:<function>'; got 'scara'",
    ):
        plant_from_spec({"type": "scara"})
    with pytest.raises(ValueError, match=r"'plant\.type' is missing"):
        plant_from_spec({"p1": 1.0})
    with pytest.raises(ValueError, match=r"unknown key 'plant\.p4' .* type = 'two-link-arm'"):
        plant_from_spec({"type": "two-link-arm", "p4": 1.0})
    with pytest.raises(ValueError, match=r"unknown key 'plant\.input_map_matrix' .* 'linear'"):
        plant_from_spec({"type": "linear", "mass": 1.0, "input_map_matrix": [[1.0]]})
