"""The robot's numba kernels against the symbolic derivation (``scripts/derive_robot.py``).

The expressions in ``tests/data/robot_derivation.json`` were derived by sympy from the positions of
the platform, wheels and payload alone (regenerate: ``.venv/bin/python scripts/derive_robot.py``).
Every comparison is at random states, with a general centre of mass (off the heading axis), a
payload and friction, so that a wrong sign or a missing term in any kernel fails.
"""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

sympy = pytest.importorskip("sympy")

from delaytrack.plants.robot import (  # noqa: E402
    NominalRobot,
    PayloadRobot,
    WheeledRobot,
    constraint_matrix,
    kinematic_map,
)

DATA = Path(__file__).parent / "data" / "robot_derivation.json"
SCRIPT = Path(__file__).parent.parent / "scripts" / "derive_robot.py"

# Component values for the random cases (SI units); c = platform CoM, p = payload, from A.
COMPONENTS = {
    "R": 0.0975,
    "L": 0.165,
    "d": 0.05,
    "m_c": 8.0,
    "I_c": 0.21,
    "c_x": 0.07,
    "c_y": -0.03,
    "m_w": 0.5,
    "I_w": 0.01,
    "I_m": 0.0013,
    "m_p": 3.5,
    "p_x": 0.18,
    "p_y": 0.12,
    "b_v": 0.02,
    "f_c": 0.1,
    "v_s": 0.05,
}


def load(derivation: dict) -> dict:
    """Lambdified functions ``f(params, q, qdot, tau, alpha)`` of every matrix in the file."""
    names = (
        derivation["parameters"]
        + derivation["coordinates"]
        + derivation["velocities"]
        + derivation["inputs"]
        + derivation["accelerations"]
    )
    symbols = {name: sympy.Symbol(name, real=True) for name in names}
    arguments = [symbols[name] for name in names]
    functions = {}
    for key in (
        "mass_matrix",
        "coriolis",
        "constraint_matrix",
        "kinematic_map",
        "reduced_mass",
        "reduced_bias",
        "friction",
        "qddot_on_manifold",
    ):
        matrix = sympy.Matrix(
            [[sympy.sympify(entry, locals=symbols) for entry in row] for row in derivation[key]]
        )
        functions[key] = sympy.lambdify(arguments, matrix, "numpy")
    energy = sympy.sympify(derivation["kinetic_energy"], locals=symbols)
    functions["kinetic_energy"] = sympy.lambdify(arguments, energy, "numpy")
    return functions


@pytest.fixture(scope="module")
def derived():
    return load(json.loads(DATA.read_text()))


def evaluate(function, components, q, qdot, tau=(0.0, 0.0), alpha=(0.0, 0.0)):
    values = [components[name] for name in COMPONENTS]
    return np.array(function(*values, *q, *qdot, *tau, *alpha), dtype=float)


def body_keywords(components: dict) -> dict:
    """The plant's aggregate parameters from the components (by hand: m = m_c + 2 m_w,
    I_A = I_c + 2 I_m + 2 m_w L² + m_c |c|²)."""
    c = components
    return {
        "wheel_radius": c["R"],
        "half_track": c["L"],
        "d": c["d"],
        "mass": c["m_c"] + 2 * c["m_w"],
        "yaw_inertia": c["I_c"]
        + 2 * c["I_m"]
        + 2 * c["m_w"] * c["L"] ** 2
        + c["m_c"] * (c["c_x"] ** 2 + c["c_y"] ** 2),
        "wheel_mass": c["m_w"],
        "wheel_spin_inertia": c["I_w"],
        "com_forward": c["c_x"],
        "com_lateral": c["c_y"],
    }


def truth_plants(components: dict):
    """(plant, time, components seen by the plant at that time): without and with the payload."""
    robot = WheeledRobot(
        **body_keywords(components),
        viscous_friction=components["b_v"],
        coulomb_friction=components["f_c"],
        friction_speed=components["v_s"],
    )
    unloaded = {**components, "m_p": 0.0}
    loaded = PayloadRobot(
        robot=robot,
        placements=[[components["p_x"], components["p_y"]]],
        first_on=1.0,
        time_on=5.0,
        time_off=5.0,
    )
    return [(robot, 0.0, unloaded), (loaded, 3.0, components), (loaded, 7.0, unloaded)]


def random_state(rng):
    q = np.concatenate([rng.uniform(-2, 2, 2), rng.uniform(-np.pi, np.pi, 1), rng.normal(size=2)])
    eta = rng.uniform(-8, 8, 2)
    return q, eta


def test_kinematics_match(derived):
    rng = np.random.default_rng(1)
    for _ in range(10):
        q, _ = random_state(rng)
        qdot = np.zeros(5)
        args = (COMPONENTS["R"], COMPONENTS["L"], COMPONENTS["d"])
        np.testing.assert_allclose(
            kinematic_map(q, *args),
            evaluate(derived["kinematic_map"], COMPONENTS, q, qdot),
            atol=1e-14,
        )
        np.testing.assert_allclose(
            constraint_matrix(q, *args),
            evaluate(derived["constraint_matrix"], COMPONENTS, q, qdot),
            atol=1e-14,
        )


def test_truth_reduced_terms_match(derived):
    rng = np.random.default_rng(2)
    for plant, t, components in truth_plants(COMPONENTS):
        for _ in range(10):
            q, eta = random_state(rng)
            qdot = kinematic_map(q, COMPONENTS["R"], COMPONENTS["L"], COMPONENTS["d"]) @ eta
            reduced_mass, bias, friction = plant.reduced_terms(qdot, t)
            expected_mass = evaluate(derived["reduced_mass"], components, q, qdot)
            np.testing.assert_allclose(reduced_mass[0], expected_mass, rtol=1e-12)
            np.testing.assert_allclose(
                bias[0],
                evaluate(derived["reduced_bias"], components, q, qdot)[:, 0],
                rtol=1e-11,
                atol=1e-13,
            )
            np.testing.assert_allclose(
                friction[0],
                evaluate(derived["friction"], components, q, qdot)[:, 0],
                rtol=1e-12,
            )


def test_truth_accelerations_match(derived):
    """q̈ of the kernel (via ``state_derivative``) = S η̇ + Ṡ η with η̇ = M_r⁻¹ (τ - f - n_r)."""
    rng = np.random.default_rng(3)
    for plant, t, components in truth_plants(COMPONENTS):
        for _ in range(10):
            q, eta = random_state(rng)
            qdot = kinematic_map(q, COMPONENTS["R"], COMPONENTS["L"], COMPONENTS["d"]) @ eta
            tau = rng.uniform(-2, 2, 2)
            reduced_mass = evaluate(derived["reduced_mass"], components, q, qdot)
            rhs = (
                tau
                - evaluate(derived["friction"], components, q, qdot)[:, 0]
                - evaluate(derived["reduced_bias"], components, q, qdot)[:, 0]
            )
            alpha = np.linalg.solve(reduced_mass, rhs)
            expected = evaluate(derived["qddot_on_manifold"], components, q, qdot, tau, alpha)
            dx = plant.state_derivative(np.concatenate([q, qdot]), tau, t)[0]
            np.testing.assert_allclose(dx[:5], qdot, rtol=0, atol=0)
            np.testing.assert_allclose(dx[5:], expected[:, 0], rtol=1e-10, atol=1e-11)


def test_kinetic_energy_matches(derived):
    """½ ηᵀ M_r η (plant) = the sum of the bodies' kinetic energies at q̇ = S η (sympy)."""
    rng = np.random.default_rng(4)
    for plant, t, components in truth_plants(COMPONENTS):
        q, eta = random_state(rng)
        qdot = kinematic_map(q, COMPONENTS["R"], COMPONENTS["L"], COMPONENTS["d"]) @ eta
        energy = plant.kinetic_energy(np.concatenate([q, qdot]), t)[0]
        assert energy == pytest.approx(
            float(evaluate(derived["kinetic_energy"], components, q, qdot)), rel=1e-12
        )


def test_nominal_matches_unconstrained_lagrangian(derived):
    """M̂ and N̂ of the nominal model = ∂²T/∂q̇² and the Christoffel terms, without payload,
    for a general platform centre of mass."""
    components = {**COMPONENTS, "m_p": 0.0}
    model = NominalRobot(**body_keywords(components))
    rng = np.random.default_rng(5)
    for _ in range(10):
        q = random_state(rng)[0]
        qdot = rng.normal(size=5) * 3
        mass, nonlinear, input_map = model.terms(q, qdot)
        np.testing.assert_allclose(
            mass[0], evaluate(derived["mass_matrix"], components, q, qdot), rtol=1e-12, atol=1e-14
        )
        np.testing.assert_allclose(
            nonlinear[0],
            evaluate(derived["coriolis"], components, q, qdot)[:, 0],
            rtol=1e-12,
            atol=1e-14,
        )
        np.testing.assert_array_equal(input_map[0], np.vstack([np.zeros((3, 2)), np.eye(2)]))


@pytest.mark.slow
def test_checked_in_derivation_is_what_the_script_derives(derived):
    """Rerun the derivation (about 10 s) and compare numerically with the checked-in file (the
    printed form of sympy's expressions may differ between sympy versions; their values may not)."""
    spec = importlib.util.spec_from_file_location("derive_robot", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    fresh = load(module.derive())
    rng = np.random.default_rng(6)
    q, eta = random_state(rng)
    qdot = rng.normal(size=5)
    tau, alpha = rng.normal(size=2), rng.normal(size=2)
    for key, function in derived.items():
        np.testing.assert_allclose(
            evaluate(fresh[key], COMPONENTS, q, qdot, tau, alpha),
            evaluate(function, COMPONENTS, q, qdot, tau, alpha),
            rtol=1e-12,
            atol=1e-14,
            err_msg=key,
        )
