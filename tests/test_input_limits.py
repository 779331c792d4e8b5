"""Actuator saturation: the plant receives the delayed command clipped to ``input_limits``; the
controller's commands and their TV stay what it issued, and the TV of what the plant received is
reported beside it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from delaytrack.controllers import OuterLoop
from delaytrack.delays import ConstantDelay
from delaytrack.metrics import metrics_table, total_variation
from delaytrack.plants import LinearPlant
from delaytrack.plants.robot import P3DX_SOURCES, P3DX_WHEEL_TORQUE_LIMIT
from delaytrack.references import SinusoidalReference
from delaytrack.scenario import Scenario, ScenarioError, load_builtin
from delaytrack.sim import simulate

# A damped point mass q̈ = -c q̇ + u under the sampled PD law u = -K1 q - K2 q̇ (q_d = 0), from
# q = 1: the first commands are -K1 = -20, so a limit of 5 bites, and a limit of 1e9 never does.
DAMPING, K1, K2 = 3.0, 20.0, 6.0
DT, T_C, T1 = 1e-3, 1e-2, 1.0
#: One and a half controller periods: the input switches in the middle of a tick interval.
DELAY = 0.015
BITING = 5.0


def point_mass_run(input_limits=math.inf, **options):
    plant = LinearPlant(mass=1.0, damping=DAMPING)
    controller = OuterLoop(LinearPlant(mass=1.0), K1=K1, K2=K2)
    settings = dict(reference=SinusoidalReference([0.0]), t1=T1, dt=DT, T_c=T_C)
    return simulate(
        plant,
        controller,
        options.pop("delay", ConstantDelay(DELAY)),
        options.pop("x0", np.array([1.0, 0.0])),
        input_limits=input_limits,
        **settings,
        **options,
    )


def hand_written_loop(limit: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The same closed loop written out: RK4 at ``DT``, the command of tick ``k`` received over
    ``[t_k + DELAY, t_{k+1} + DELAY)`` clipped to ``±limit``, zero before the first.

    Returns the states and commands at the ticks and the input received just after each tick.
    """
    steps_per_tick, ticks = round(T_C / DT), round(T1 / T_C)
    delay_steps = round(DELAY / DT)
    x = np.array([1.0, 0.0])
    states, commands, received = [], [], []
    issued: list[float] = []

    def slope(state: np.ndarray, u: float) -> np.ndarray:
        return np.array([state[1], -DAMPING * state[1] + u])

    def input_at(step: int) -> float:
        tick = (step - delay_steps) // steps_per_tick  # the latest tick <= t - h
        return 0.0 if tick < 0 else float(np.clip(issued[tick], -limit, limit))

    for k in range(ticks + 1):
        states.append(x.copy())
        issued.append(-K1 * x[0] - K2 * x[1])
        commands.append(issued[-1])
        received.append(input_at(k * steps_per_tick))
        if k == ticks:
            break
        for j in range(steps_per_tick):
            u = input_at(k * steps_per_tick + j)
            k1 = slope(x, u)
            k2 = slope(x + 0.5 * DT * k1, u)
            k3 = slope(x + 0.5 * DT * k2, u)
            k4 = slope(x + DT * k3, u)
            x = x + DT / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return np.array(states), np.array(commands), np.array(received)


def test_limits_that_never_bite_change_nothing() -> None:
    free = point_mass_run()
    wide = point_mass_run(input_limits=1e9)
    for name in ("x", "commands", "applied"):
        np.testing.assert_array_equal(getattr(wide, name), getattr(free, name))
    for name, values in free.metrics.items():
        np.testing.assert_array_equal(wide.metrics[name], values)


def test_a_biting_limit_clips_exactly_as_a_hand_written_loop() -> None:
    result = point_mass_run(input_limits=BITING)
    states, commands, received = hand_written_loop(BITING)
    assert np.abs(commands).max() > 3 * BITING  # not vacuous: the controller asks for more
    np.testing.assert_allclose(result.x[0], states, rtol=0, atol=1e-12)
    np.testing.assert_allclose(result.commands[0, :, 0], commands, rtol=0, atol=1e-11)
    # The plant received the clipped delayed commands; the controller's record stays unclipped.
    np.testing.assert_allclose(result.applied[0, :, 0], received, rtol=0, atol=1e-11)
    assert np.abs(result.applied).max() == BITING
    tv_received = np.abs(np.diff(received)).sum()
    tv_commanded = np.abs(np.diff(commands)).sum()
    assert total_variation(result, of="applied")[0] == pytest.approx(tv_received, abs=1e-10)
    assert total_variation(result)[0] == pytest.approx(tv_commanded, abs=1e-10)
    assert tv_received < tv_commanded


def test_the_compiled_engine_equals_the_python_one() -> None:
    compiled = point_mass_run(input_limits=BITING)
    python = point_mass_run(input_limits=BITING, engine="python")
    for name in ("x", "commands", "applied"):
        np.testing.assert_array_equal(getattr(python, name), getattr(compiled, name))
    for name, values in compiled.metrics.items():
        np.testing.assert_array_equal(python.metrics[name], values)


def test_a_batch_equals_its_runs_alone() -> None:
    limits = np.array([[BITING], [np.inf], [2.0]])
    batch = point_mass_run(input_limits=limits, x0=np.array([[1.0, 0.0]] * 3))
    for b, limit in enumerate(limits[:, 0]):
        alone = point_mass_run(input_limits=limit)
        for name in ("x", "commands", "applied"):
            np.testing.assert_array_equal(getattr(batch, name)[b], getattr(alone, name)[0])
        for name, values in alone.metrics.items():
            np.testing.assert_array_equal(batch.metrics[name][b], values[0])


def test_the_running_tv_received_equals_the_recorded_one() -> None:
    result = point_mass_run(input_limits=BITING)
    running = total_variation(result, of="applied")
    recorded = total_variation(result, t_from=0.0, of="applied")
    np.testing.assert_allclose(running, recorded, rtol=1e-14)
    unrecorded = point_mass_run(input_limits=BITING, trajectories=False)
    np.testing.assert_array_equal(unrecorded.metrics["tv_applied"], running)
    window = point_mass_run(input_limits=BITING, metrics_from=0.5)
    np.testing.assert_allclose(
        total_variation(window, of="applied"),
        total_variation(result, t_from=0.5, of="applied"),
        rtol=1e-14,
    )


def test_without_delay_or_limit_the_plant_receives_the_commands() -> None:
    result = point_mass_run(delay=ConstantDelay(0.0))
    np.testing.assert_array_equal(result.applied, result.commands)
    np.testing.assert_array_equal(result.metrics["tv_applied"], result.metrics["tv"])


def test_the_summary_shows_the_tv_received_only_with_limits() -> None:
    limited, free = point_mass_run(input_limits=BITING), point_mass_run()
    assert limited.input_limited and not free.input_limited
    assert "TV received" in limited.summary().columns
    assert list(free.summary().columns) == ["status", "t_stop (s)", "AE q1", "TV"]
    table = metrics_table(limited, tv_applied=True)
    assert table["tv_applied"].tolist() == limited.metrics["tv_applied"].tolist()
    assert "tv_applied" not in metrics_table(limited).columns  # asked for, never inferred


def test_a_result_without_the_running_tv_received_measures_its_records() -> None:
    result = point_mass_run(input_limits=BITING)
    by_hand = result.__class__(
        **{
            **{name: getattr(result, name) for name in result.__dataclass_fields__},
            "metrics": {"tv": result.metrics["tv"]},
        }
    )
    np.testing.assert_allclose(
        total_variation(by_hand, of="applied"), result.metrics["tv_applied"], rtol=1e-14
    )


def test_the_commands_tv_of_a_result_from_before_needs_no_records() -> None:
    """A result whose running metrics have no ``tv_applied`` (made before it existed) and no
    trajectories still gives its commands' TV, from its running metrics."""
    result = point_mass_run(trajectories=False)
    older = result.__class__(
        **{
            **{name: getattr(result, name) for name in result.__dataclass_fields__},
            "metrics": {k: v for k, v in result.metrics.items() if k != "tv_applied"},
        }
    )
    np.testing.assert_array_equal(total_variation(older), result.metrics["tv"])


def test_an_unknown_input_is_refused() -> None:
    with pytest.raises(ValueError, match='of must be "commands" or "applied"'):
        total_variation(point_mass_run(), of="received")


@pytest.mark.parametrize("limits", [0.0, -1.0, float("nan"), [1.0, 2.0], "high"])
def test_bad_limits_are_refused_naming_the_key(limits) -> None:
    with pytest.raises(ValueError, match="input_limits"):
        point_mass_run(input_limits=limits)


def _robot_scenario(**changes) -> Scenario:
    return load_builtin("robot_S1").replace(**changes)


@pytest.mark.parametrize("limits", [0.0, -2.0, float("nan"), [1.0, float("nan")], True])
def test_a_scenario_refuses_bad_limits_naming_the_key(limits) -> None:
    with pytest.raises(ScenarioError, match="'input_limits'"):
        _robot_scenario(input_limits=limits)


def test_a_scenario_refuses_limits_of_the_wrong_length_naming_the_key() -> None:
    with pytest.raises(ScenarioError, match="'input_limits'.*m = 2"):
        _robot_scenario(input_limits=[1.0, 2.0, 3.0]).build()


def test_the_p3dx_wheel_torque_limit_is_documented_and_opt_in() -> None:
    # The derivation docs/robot.md gives: gearbox efficiency 0.8 x gear ratio 38 x the motor's
    # stall torque K_M^2 w_NL = (1.88e-2 N·m/sqrt(W))^2 x 628 rad/s (Pittman 9233S013).
    stall = 1.88e-2**2 * 628
    assert P3DX_WHEEL_TORQUE_LIMIT == pytest.approx(0.8 * 38 * stall, abs=0.05)
    assert P3DX_SOURCES["wheel_torque_limit"].startswith(
        f"[derived] {P3DX_WHEEL_TORQUE_LIMIT:g} N·m"
    )
    assert load_builtin("robot_S1").input_limits is None  # the shipped scenario runs unlimited
    limited = _robot_scenario(input_limits=P3DX_WHEEL_TORQUE_LIMIT)
    assert limited.simulated_input_limits == P3DX_WHEEL_TORQUE_LIMIT
