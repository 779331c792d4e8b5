"""A plant's reduced form: the engine integrates ``(q, η)`` with ``q̇ = S(q) η`` instead of its
terms, the robot in its wheel-space form agrees with its constrained form, and a plant of the
user's can declare one."""

from __future__ import annotations

import dataclasses

import numba
import numpy as np
import pytest

from delaytrack import AROLC, ConstantDelay, SinusoidalReference, simulate
from delaytrack.components import ReducedForm
from delaytrack.delays import AbsSineDelay
from delaytrack.experiments.paper import AROLC_GAINS, DT, DURATION, PAYLOAD_SEED, T_C
from delaytrack.plants import CompiledPlant
from delaytrack.plants.robot import NominalRobot, PayloadRobot, initial_state, paper_reference
from delaytrack.sim._kernel_checks import REDUCED_START_TOLERANCE


@dataclasses.dataclass(frozen=True, eq=False)
class ConstrainedOnly(PayloadRobot):
    """The payload robot integrated in its constrained form (``M = I``, Baumgarte term), as
    before it declared its reduced form."""

    @property
    def reduced_form(self):
        return None


@pytest.mark.slow  # compiles the constrained form's integrator
def test_the_robot_in_wheel_space_agrees_with_its_constrained_form_over_the_paper_run():
    reference = paper_reference("consistent")
    plant = PayloadRobot(seed=PAYLOAD_SEED, duration=DURATION)
    controller = AROLC(NominalRobot(), **AROLC_GAINS)
    delay, x0 = AbsSineDelay.S1(), initial_state(reference)
    constrained = ConstrainedOnly(seed=PAYLOAD_SEED, duration=DURATION)
    assert np.array_equal(constrained.params, plant.params)
    runs = [
        simulate(p, controller, delay, x0, reference=reference, t1=DURATION, dt=DT, T_c=T_C)
        for p in (plant, constrained)
    ]
    assert [run.status_names for run in runs] == [["ok"], ["ok"]]
    reduced, full = (run.x[0] for run in runs)
    span = np.abs(full).max(axis=0)
    # Measured: positions within 6e-13 of their range, velocities within 1.5e-12 (the
    # constrained form's own velocity-constraint residual is of order 1e-11).
    assert np.all(np.abs(reduced[:, :5] - full[:, :5]).max(axis=0) <= 1e-12 * span[:5])
    assert np.all(np.abs(reduced[:, 5:] - full[:, 5:]).max(axis=0) <= 5e-12 * span[5:])
    # The reduced form keeps the velocity constraints to rounding; the constrained one to the
    # Baumgarte term's damping of RK4's truncation error.
    residual = np.abs(plant.constraint_residual(reduced)).max()
    assert residual < 1e-13 < np.abs(plant.constraint_residual(full)).max()


# ---- a plant of the user's: a disc of radius R rolling on a line, q = (x, θ), ẋ = R θ̇ --------

RADIUS, INERTIA, FRICTION = 0.2, 0.05, 0.1  # m, kg·m² (about the contact point), N·m·s


@numba.njit
def disc_terms(t, q, qdot, params, M, N, G):
    """``M = I``, ``N = -a``, ``G = b``: ``θ̈ = (u - c θ̇) / I``, ``ẍ = R θ̈``."""
    radius, inertia, friction = params[0], params[1], params[2]
    M[0, 0], M[0, 1], M[1, 0], M[1, 1] = 1.0, 0.0, 0.0, 1.0
    N[1] = friction * qdot[1] / inertia
    N[0] = radius * N[1]
    G[1, 0] = 1.0 / inertia
    G[0, 0] = radius * G[1, 0]


@numba.njit
def disc_velocities(q, eta, params, qdot):
    rate = eta[0]
    qdot[0] = params[0] * rate
    qdot[1] = rate


@numba.njit
def disc_dynamics(t, q, eta, u, params, eta_dot):
    eta_dot[0] = (u[0] - params[2] * eta[0]) / params[1]


@numba.njit
def disc_command(q, params, tau, command):
    """The torque whose accelerations ``G u`` are nearest ``τ`` (least squares, ``M = I``)."""
    radius, inertia = params[0], params[1]
    command[0] = inertia * (radius * tau[0] + tau[1]) / (radius * radius + 1.0)


@dataclasses.dataclass(frozen=True, eq=False)
class DiscModel(CompiledPlant):
    """The disc as a nominal model: one torque for two coordinates, mapped by least squares."""

    @property
    def command_map_kernel(self):
        return disc_command


def _disc(reduced: bool) -> CompiledPlant:
    form = ReducedForm(disc_velocities, disc_dynamics, 1) if reduced else None
    return CompiledPlant(2, 1, disc_terms, [RADIUS, INERTIA, FRICTION], reduced=form)


def _disc_run(plant, x0, engine="compiled"):
    model = DiscModel(2, 1, disc_terms, [RADIUS, INERTIA, 0.0])
    controller = AROLC(model, K1=4.0, K2=4.0, Q=1.0, alpha=1.0, epsilon=0.1, gamma=1e-3)
    reference = SinusoidalReference(offset=[0.0, 0.0], amplitude=[0.5, 2.5], frequency=[0.5, 0.5])
    return simulate(
        plant, controller, ConstantDelay(0.01), x0, reference=reference, t1=2.0, dt=1e-3,
        T_c=0.01, engine=engine,
    )  # fmt: skip


@pytest.mark.parametrize("engine", ["compiled", "python"])
def test_a_user_plant_declares_its_reduced_form_and_runs_in_it(engine):
    x0 = np.array([0.0, 0.0, RADIUS * 1.5, 1.5])
    reduced = _disc_run(_disc(True), x0, engine)
    full = _disc_run(_disc(False), x0, engine)
    assert reduced.status_names == full.status_names == ["ok"]
    # The same motion (the constraint is linear: both forms integrate it exactly up to rounding)
    np.testing.assert_allclose(reduced.x, full.x, rtol=0, atol=1e-12)
    x = reduced.x[0]
    np.testing.assert_array_equal(x[:, 2], RADIUS * x[:, 3])  # q̇ = S(q) η at every sample
    assert _disc(True).engine_kernel.key != _disc(False).engine_kernel.key


def test_a_start_off_the_constraints_is_refused_naming_x0():
    with pytest.raises(ValueError, match=r"x0 must satisfy the plant's velocity constraints"):
        _disc_run(_disc(True), np.array([0.0, 0.0, 1.0, 1.5]))


def test_a_reduced_form_is_checked_when_made():
    with pytest.raises(ValueError, match=r"size must be an integer r >= 1; got 0"):
        ReducedForm(disc_velocities, disc_dynamics, 0)
    with pytest.raises(TypeError, match=r"dynamics must be callable"):
        ReducedForm(disc_velocities, 3.0, 1)
    with pytest.raises(ValueError, match=r"reduced form of r = 3 velocities needs .* n >= r"):
        CompiledPlant(2, 1, disc_terms, [RADIUS, INERTIA, FRICTION],
                      reduced=ReducedForm(disc_velocities, disc_dynamics, 3))  # fmt: skip


def test_the_live_robot_node_steps_the_reduced_form_as_the_engine_does():
    """The robot node's compiled step of the P3-DX is the engine's reduced sub-step: the same
    numbers as the plain-Python engine's, and velocities on the constraints."""
    from delaytrack.live.robot import _compiled_step
    from delaytrack.plants.robot import consistent_state
    from delaytrack.sim.integrator import _reduced_rk4_substep, rk4_workspace

    plant = PayloadRobot(seed=PAYLOAD_SEED, duration=DURATION)
    entry, work = _compiled_step(plant, None)
    x = consistent_state([0.1, -0.2, 0.3, 1.0, 2.0], [3.0, 2.0], *plant.params[:3])
    python_x = x.copy()
    python_work = rk4_workspace(np.empty(10), 2)
    kernel, params, u = plant.engine_kernel, plant.params, np.array([0.4, -0.3])
    first_on = plant.first_on
    times = 0.1 * np.arange(100)  # across the first payload placement, on from first_on
    assert times[0] < first_on < times[-1]
    for t in times:
        outside, _ = entry(kernel, params, t, x, u, 1e-3, work, np.inf)
        assert not outside
        _reduced_rk4_substep.py_func(
            kernel.as_python(), params, t, python_x, u, 1e-3, python_work, np.inf
        )
    np.testing.assert_array_equal(x, python_x)
    # q̇ = S(q)η is set after each step, so the constraints hold to the rounding of that product.
    assert np.abs(plant.constraint_residual(x)).max() < 1e-15


def test_the_live_robot_starts_as_given_and_steps_from_its_start_on_the_constraints():
    """As the simulator: a start within the tolerance of the constraints is read as given at
    t = 0 and mapped onto them by the first step (the engine maps it before its first step)."""
    from delaytrack.live.robot import PlantStepper, SimulatedRobot
    from delaytrack.plants.robot import consistent_state

    plant = PayloadRobot(seed=PAYLOAD_SEED, duration=DURATION)
    on = consistent_state([0.1, -0.2, 0.3, 1.0, 2.0], [3.0, 2.0], *plant.params[:3])
    given = on.copy()
    # x's q̇ off S(q) η by a thousandth of what the start's check lets through
    given[5] += 1e-3 * REDUCED_START_TOLERANCE * (1.0 + np.abs(on[5:]).max())
    robot = SimulatedRobot(plant, 1e-3, given)  # its warm-up step is undone
    np.testing.assert_array_equal(np.concatenate(robot.read_state(0.0)), given)
    mapped = PlantStepper(plant, 1e-3, on)
    for stepper in (robot.stepper, mapped):
        stepper.u[:] = [0.4, -0.3]
        for j in range(5):
            assert stepper.step(j * 1e-3)
    np.testing.assert_array_equal(robot.stepper.x, mapped.x)


def test_the_twin_integrators_differ_only_in_their_sub_step():
    from delaytrack.live import _plant_step
    from delaytrack.sim import integrator

    pairs = [
        (integrator.integrate_tick, integrator.integrate_reduced_tick),
        (_plant_step.live_plant_step, _plant_step.live_reduced_plant_step),
    ]
    for plain, twin in pairs:
        assert twin.py_func.__code__ is plain.py_func.__code__
        names = set(plain.py_func.__code__.co_names)  # the globals the code reads
        for name in names - {"_rk4_substep"}:
            assert twin.py_func.__globals__.get(name) is plain.py_func.__globals__.get(name), name
        assert twin.py_func.__globals__["_rk4_substep"] is integrator._reduced_rk4_substep


@numba.njit
def careless_velocities(q, eta, params, qdot):
    qdot[:] = 0.0  # clears eta when eta is the tail of qdot ...
    qdot[0] = params[0] * eta[0]  # ... before reading it
    qdot[1] = eta[0]


def test_a_velocity_map_that_reads_eta_after_writing_it_is_refused():
    plant = CompiledPlant(
        2, 1, disc_terms, [RADIUS, INERTIA, FRICTION],
        reduced=ReducedForm(careless_velocities, disc_dynamics, 1),
    )  # fmt: skip
    with pytest.raises(ValueError, match=r"read every entry of eta before writing qdot"):
        _disc_run(plant, np.array([0.0, 0.0, RADIUS * 1.5, 1.5]))


def test_each_run_of_a_batch_starts_on_its_own_plants_constraints():
    """Two discs of other radii from one x0: the start fits the first, not the second."""
    other = dataclasses.replace(_disc(True), parameters=np.array([2 * RADIUS, INERTIA, FRICTION]))
    x0 = np.array([0.0, 0.0, RADIUS * 1.5, 1.5])
    with pytest.raises(ValueError, match=r"x0 \(run 1\) must satisfy"):
        _disc_run([_disc(True), other], x0)


def test_a_stepped_plant_cannot_also_have_a_reduced_form():
    from delaytrack.components import Kernel

    form = ReducedForm(disc_velocities, disc_dynamics, 1)
    with pytest.raises(ValueError, match=r"cannot also have a reduced form"):
        Kernel(disc_terms, sizes=(2, 1), stepper=disc_terms, reduced=form)


def test_a_scenario_starting_on_the_reference_starts_each_run_on_its_plants_constraints(
    tmp_path,
):
    """``x0 = "reference"``: ``robot_S1``'s start for the P3-DX, and for a robot of other wheels
    (in a sweep over the wheel radius) a start on that robot's constraints, run as given."""
    from delaytrack.scenario import Scenario, ScenarioError, load_builtin
    from delaytrack.sweeps import SweepSpec, run_sweep

    shipped = load_builtin("robot_S1")
    data = {**shipped.to_dict(), "duration": 0.5, "x0": "reference"}
    on_reference = Scenario.from_dict(data)
    # The same start up to rounding: the shipped x0 is q̇ = S(q)η through kinematic_map(q) @ η,
    # this one through the robot's velocity map (6.4e-18 apart in ẏ, measured).
    np.testing.assert_allclose(on_reference.build().x0, shipped.x0, rtol=0, atol=1e-15)
    path = tmp_path / "robot_on_reference.toml"
    path.write_text(on_reference.to_toml())
    assert Scenario.from_toml(path).x0 == "reference"
    assert isinstance(Scenario.from_toml(path).resolved().x0, tuple)  # as run: the numbers
    smaller = {**shipped.to_dict(), "plant": {**shipped.plant, "wheel_radius": 0.08}}
    with pytest.raises(ValueError, match=r"x0 must satisfy the plant's velocity constraints"):
        Scenario.from_dict({**smaller, "duration": 0.5}).run()
    spec = {
        "scenario": str(path), "unit_size": 2,
        "grid": {"plant.wheel_radius": [0.08, 0.11]},
    }  # fmt: skip
    outcome = run_sweep(
        SweepSpec.from_dict(spec, root=tmp_path), tmp_path / "sweep", progress=False
    )
    assert list(outcome.runs["status"]) == ["ok", "ok"]
    with pytest.raises(ScenarioError, match=r'must be a list of 2n numbers or "reference"'):
        Scenario.from_dict({**data, "x0": "on the path"})


def test_the_live_robot_node_steps_a_python_reduced_form_as_the_compiled_one():
    """A plant whose reduced form is plain Python: the live node's Python step integrates the
    reduced form, with the numbers of the compiled step."""
    from delaytrack.live.robot import PlantStepper
    from delaytrack.plants.base import ELPlant

    class PythonDisc(ELPlant):
        n, m = 2, 1
        params = np.array([RADIUS, INERTIA, FRICTION])
        terms_kernel = staticmethod(disc_terms.py_func)
        reduced_form = ReducedForm(disc_velocities.py_func, disc_dynamics.py_func, 1)

        def to_spec(self):
            return {"type": "python-disc"}

    x0 = np.array([0.0, 0.0, RADIUS * 1.5, 1.5])
    steppers = [PlantStepper(PythonDisc(), 1e-3, x0), PlantStepper(_disc(True), 1e-3, x0)]
    assert [stepper.compiled for stepper in steppers] == [False, True]
    for stepper in steppers:
        stepper.u[:] = 0.3
        for k in range(20):
            assert stepper.step(k * 1e-3)
    np.testing.assert_allclose(steppers[0].x, steppers[1].x, rtol=1e-14, atol=0)
    assert steppers[0].x[2] == RADIUS * steppers[0].x[3]  # on the constraint, exactly
