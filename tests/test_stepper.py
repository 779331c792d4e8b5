"""A controller's stepper (``Controller.stepper``): the same commands and states as
``Controller.step`` and as the simulator, bit for bit; arguments checked once at its making;
its own state; the command it returns overwritten by the next tick."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from delaytrack.controllers import AROLC, PCON
from delaytrack.controllers.stepper import entry_point
from delaytrack.delays import AbsSineDelay
from delaytrack.experiments.paper import AROLC_GAINS
from delaytrack.plants.robot import NominalRobot, PayloadRobot, initial_state, paper_reference
from delaytrack.sim import simulate

T_C = 0.01
HISTORY = 0.15
REFERENCE = paper_reference("consistent")


def make(kind: str):
    if kind == "AROLC":
        return AROLC(NominalRobot(), **AROLC_GAINS)
    return PCON(NominalRobot(), kappa=1.0, vartheta=1.0, k_b=1.0, history=HISTORY, T_c=T_C)


def ticks(count: int, seed: int = 3):
    """``(t, q, q̇, reference, h)`` of ``count`` ticks near the paper's path, the delay |sin|."""
    rng = np.random.default_rng(seed)
    times = T_C * np.arange(count)
    qd, qd_dot, qd_ddot = REFERENCE.evaluate(times)
    for k, t in enumerate(times):
        q = qd[k] + 0.05 * rng.normal(size=5)
        qdot = qd_dot[k] + 0.05 * rng.normal(size=5)
        h = 0.02 + 0.08 * abs(np.sin(t))
        yield t, q, qdot, (qd[k], qd_dot[k], qd_ddot[k]), h


@pytest.mark.parametrize("kind", ["AROLC", "PCON"])
def test_the_stepper_and_controller_step_equal_the_kernel_called_directly(kind):
    """Both equal, bit for bit, the step kernel called through numba's dispatcher with the
    arguments the simulator passes (``step_arguments``), an independent path: no stepper."""
    controller = make(kind)
    stepper = controller.stepper(T_c=T_C, h_max=0.1)
    state = direct = controller.initial_state()
    for t, q, qdot, reference, h in ticks(300):
        arguments = controller.step_arguments(t, q, qdot, reference, direct, T_c=T_C, h=h)
        controller.step_callable(*arguments)
        *_, direct, _, _, expected, _ = arguments  # the state advanced in place, the command
        command, state = controller.step(t, q, qdot, reference, state, T_c=T_C, h=h)
        np.testing.assert_array_equal(command, expected)
        np.testing.assert_array_equal(state, direct)
        np.testing.assert_array_equal(stepper(t, q, qdot, reference, h=h), expected)
        np.testing.assert_array_equal(stepper.state, direct)
    assert np.all(np.isfinite(state))


@pytest.mark.parametrize("kind", ["AROLC", "PCON"])
def test_the_stepper_equals_the_simulator_bit_for_bit(kind):
    controller = make(kind)
    x0 = initial_state(REFERENCE)
    result = simulate(
        PayloadRobot(seed=1, duration=3.0),
        controller,
        AbsSineDelay.S1(),
        x0,
        reference=REFERENCE,
        t1=3.0,
        dt=T_C,
        T_c=T_C,
    )
    assert result.ok.all()
    qd, qd_dot, qd_ddot = REFERENCE.evaluate(result.t)
    stepper = controller.stepper(T_c=T_C, h_max=AbsSineDelay.S1().h_max)
    recorded = result.controller_state.shape[2]
    for k in range(result.t.size - 1):
        q, qdot = result.x[0, k, :5], result.x[0, k, 5:]
        reference = (qd[k], qd_dot[k], qd_ddot[k])
        command = stepper(result.t[k], q, qdot, reference, h=float(result.h[0, k]))
        np.testing.assert_array_equal(command, result.commands[0, k])
        np.testing.assert_array_equal(stepper.state[:recorded], result.controller_state[0, k + 1])


def test_tick_on_the_stepper_inputs_equals_a_call():
    controller = make("AROLC")
    called, ticked = controller.stepper(T_c=T_C), controller.stepper(T_c=T_C)
    for t, q, qdot, reference, _ in ticks(50):
        for own, value in zip(ticked.inputs, (q, qdot, *reference), strict=True):
            own[:] = value
        np.testing.assert_array_equal(ticked.tick(t), called(t, q, qdot, reference))
    np.testing.assert_array_equal(ticked.state, called.state)


def test_steppers_and_step_do_not_share_state():
    controller = make("AROLC")
    first, second = controller.stepper(T_c=T_C), controller.stepper(T_c=T_C)
    start = controller.initial_state()
    for t, q, qdot, reference, _ in ticks(20):
        first(t, q, qdot, reference)
    np.testing.assert_array_equal(second.state, start)
    assert not np.array_equal(first.state, start)
    advanced = first.state.copy()
    t, q, qdot, reference, _ = next(ticks(1, seed=9))
    given = controller.initial_state()
    controller.step(t, q, qdot, reference, given, T_c=T_C)  # neither stepper moves
    np.testing.assert_array_equal(given, start)  # nor the state given to step
    np.testing.assert_array_equal(first.state, advanced)
    np.testing.assert_array_equal(second.state, start)
    first.reset()
    np.testing.assert_array_equal(first.state, start)
    first.reset(advanced)
    np.testing.assert_array_equal(first.state, advanced)


def test_the_command_is_a_view_overwritten_by_the_next_tick():
    controller = make("AROLC")
    stepper = controller.stepper(T_c=T_C)
    (t0, *first), (t1, *second) = [(t, q, qdot, reference) for t, q, qdot, reference, _ in ticks(2)]
    command = stepper(t0, *first)
    kept = command.copy()
    with pytest.raises(ValueError, match="read-only"):
        command[0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        stepper.state[0] = 1.0
    again = stepper(t1, *second)
    assert again is command  # the same array, now holding the second tick's command
    assert not np.array_equal(command, kept)
    expected, _ = controller.step(t0, *first, controller.initial_state(), T_c=T_C)
    np.testing.assert_array_equal(kept, expected)


def test_controller_step_returns_arrays_of_its_own_that_a_next_call_leaves_alone():
    controller = make("AROLC")
    (t0, *first), (t1, *second) = [(t, q, qdot, reference) for t, q, qdot, reference, _ in ticks(2)]
    command, state = controller.step(t0, *first, controller.initial_state(), T_c=T_C)
    kept = command.copy(), state.copy()
    command[0] = state[0] = 7.0  # writable: the caller's own
    controller.step(t1, *second, kept[1], T_c=T_C)
    assert command[0] == state[0] == 7.0
    again = controller.step(t0, *first, controller.initial_state(), T_c=T_C)
    np.testing.assert_array_equal(again[0], kept[0])
    np.testing.assert_array_equal(again[1], kept[1])


@pytest.mark.parametrize(
    ("kind", "arguments", "error", "message"),
    [
        ("AROLC", dict(T_c=0.0), ValueError, "T_c must be > 0"),
        ("AROLC", dict(T_c="0.01"), TypeError, "T_c must be a real number"),
        ("AROLC", dict(T_c=T_C, h_max=-0.1), ValueError, "h_max must be >= 0"),
        ("AROLC", dict(T_c=T_C, state=np.zeros(3)), ValueError, r"state must have shape \(7,\)"),
        ("PCON", dict(T_c=0.02), ValueError, "differs from the period PCON was built for"),
        ("PCON", dict(T_c=T_C, h_max=0.2), ValueError, "exceeds history"),
    ],
)
def test_a_bad_argument_is_refused_at_the_making_naming_it(kind, arguments, error, message):
    with pytest.raises(error, match=message):
        make(kind).stepper(**arguments)


def test_a_tick_refuses_what_the_law_cannot_serve():
    stepper = make("PCON").stepper(T_c=T_C, h_max=0.05)
    t, q, qdot, reference, _ = next(ticks(1))
    with pytest.raises(ValueError, match="PCON needs the true delay"):
        stepper(t, q, qdot, reference)
    with pytest.raises(ValueError, match="h must be >= 0"):
        stepper(t, q, qdot, reference, h=-0.01)
    with pytest.raises(ValueError, match="exceeds history"):
        stepper(t, q, qdot, reference, h=0.2)
    stepper(t, q, qdot, reference, h=0.1)  # above h_max, accepted by the law: admitted
    assert stepper.h_max == 0.1
    qd, qd_dot, qd_ddot = reference
    with pytest.raises(ValueError, match=r"qdot must have shape \(5,\); got \(4,\)"):
        stepper(t, q, qdot[:4], reference, h=0.05)
    with pytest.raises(ValueError, match=r"qd_ddot must have shape \(5,\); got \(\)"):
        stepper(t, q, qdot, (qd, qd_dot, 1.0), h=0.05)
    with pytest.raises(ValueError, match=r"q must have shape \(5,\); got \(1, 5\)"):
        stepper(t, q[None, :], qdot, reference, h=0.05)


def test_a_list_input_is_taken_as_an_array():
    stepper = make("AROLC").stepper(T_c=T_C)
    twin = make("AROLC").stepper(T_c=T_C)
    t, q, qdot, reference, _ = next(ticks(1))
    listed = stepper(t, list(q), list(qdot), tuple(list(r) for r in reference))
    np.testing.assert_array_equal(listed, twin(t, q, qdot, reference))


def test_a_controller_that_has_stepped_is_pickled_and_steps_the_same():
    controller = make("PCON")
    t, q, qdot, reference, h = next(ticks(1))
    state = controller.initial_state()
    command, next_state = controller.step(t, q, qdot, reference, state, T_c=T_C, h=h)
    copy = pickle.loads(pickle.dumps(controller))
    again, again_state = copy.step(t, q, qdot, reference, state, T_c=T_C, h=h)
    np.testing.assert_array_equal(again, command)
    np.testing.assert_array_equal(again_state, next_state)


def test_entry_point_keeps_a_python_function():
    def python_step(*arguments):
        return None

    assert entry_point(python_step, (0.0,)) is python_step
