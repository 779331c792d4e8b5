"""The engine's fast paths agree with the plain ones.

* running metrics (accumulated at every tick) == :func:`metrics_table` of a full record;
* ``trajectories=False`` gives the same metrics without any trajectory;
* threads: a batch split over workers == the same batch on one thread, bit for bit;
* a user's numba-compiled plant (:class:`CompiledPlant`) == the built-in plant it re-implements,
  and a plant of Python callables runs the same engine with a :class:`PythonFallbackWarning`;
* the reference path (``engine="python"``: the engine and kernels as plain Python) == compiled.
"""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from delaytrack.controllers import AROLC, OuterLoop
from delaytrack.delays import AbsSineDelay, ConstantDelay, RandomDelay
from delaytrack.experiments.paper import AROLC_GAINS
from delaytrack.metrics import mean_absolute_error, metrics_table
from delaytrack.plants import CallablePlant, CompiledPlant, TwoLinkArm
from delaytrack.plants.robot import NominalRobot, PayloadRobot, initial_state, paper_reference
from delaytrack.plants.two_link_arm import two_link_terms
from delaytrack.references import SinusoidalReference
from delaytrack.scenario import Scenario
from delaytrack.sim import simulate
from delaytrack.sim.fallback import PythonFallbackWarning
from test_golden import golden
from test_scenario import base_dict

ARM_REFERENCE = SinusoidalReference([0.0, 0.0], amplitude=[0.8, 0.5], frequency=[0.5, 0.7])
METRIC_COLUMNS = ["ae_q1", "ae_q2", "rms_q1", "rms_q2", "max_q1", "max_q2", "tv"]


def arm_controller(plant: TwoLinkArm | None = None) -> AROLC:
    nominal = plant or TwoLinkArm(p1=2.8, p2=0.16, p3=0.19, fd1=0.0, fd2=0.0)
    return AROLC(nominal, K1=4.0, K2=4.0, Q=1.0, alpha=2.0, epsilon=0.1, gamma=0.001)


def robot_batch(size: int) -> dict:
    """``size`` robot runs that differ in delay profile and payload placements."""
    reference = paper_reference("consistent")
    return dict(
        plant=[PayloadRobot(seed=seed, duration=3.0) for seed in range(size)],
        controller=AROLC(NominalRobot(), **AROLC_GAINS),
        delay=[
            RandomDelay(0.02, 0.13, max_rate=0.5, duration=3.0, seed=seed) for seed in range(size)
        ],
        x0=initial_state(reference),
        reference=reference,
        t1=3.0,
        dt=1e-3,
        T_c=1e-2,
    )


def test_running_metrics_equal_the_metrics_of_the_full_record() -> None:
    settings = robot_batch(3)
    for start in (None, 1.25):
        result = simulate(**settings, metrics_from=start, workers=1)
        offline = metrics_table(result, ["x", "y", "phi", "r", "l"], t_from=start)
        for j, name in enumerate(["x", "y", "phi", "r", "l"]):
            for key in ("ae", "rms", "max"):
                np.testing.assert_allclose(
                    result.metrics[key][:, j], offline[f"{key}_{name}"], rtol=1e-12, atol=0
                )
        np.testing.assert_allclose(result.metrics["tv"], offline["tv"], rtol=1e-12, atol=0)
        assert np.all(result.metrics["ae"] > 0.0)


def test_metrics_from_counts_the_ticks_at_or_after_it() -> None:
    settings = robot_batch(1)
    whole = simulate(**settings, metrics_from=0.0)
    late = simulate(**settings, metrics_from=2.0)
    np.testing.assert_array_equal(whole.metrics["ae"], simulate(**settings).metrics["ae"])
    expected = mean_absolute_error(whole, t_from=2.0)
    np.testing.assert_allclose(late.metrics["ae"], expected, rtol=1e-12, atol=0)
    assert late.settings["metrics_from"] == 2.0


def test_without_trajectories_the_metrics_are_the_same_and_nothing_is_recorded() -> None:
    settings = robot_batch(2)
    full = simulate(**settings)
    lean = simulate(**settings, trajectories=False)
    assert not lean.has_trajectories and lean.x.shape == (2, 0, 10)
    for key in ("ae", "rms", "max", "tv"):
        np.testing.assert_array_equal(lean.metrics[key], full.metrics[key])
    np.testing.assert_array_equal(lean.status, full.status)
    table = metrics_table(lean, ["x", "y", "phi", "r", "l"])
    np.testing.assert_array_equal(table["ae_x"], full.metrics["ae"][:, 0])
    np.testing.assert_array_equal(mean_absolute_error(lean), full.metrics["ae"])
    with pytest.raises(ValueError, match="record_every=1"):
        mean_absolute_error(lean, t_from=1.0)
    with pytest.raises(ValueError, match="metrics_from"):
        metrics_table(lean, t_from=1.0)


def stiff_arm_pair(**options):
    """Stiff AROLC gains on the arm: stable without delay, diverging under h = 0.2 s."""
    arm = TwoLinkArm()
    unstable = AROLC(arm, K1=400.0, K2=40.0, Q=1.0, alpha=2.0, epsilon=0.1, gamma=0.001)
    return simulate(
        arm,
        unstable,
        [ConstantDelay(0.0), ConstantDelay(0.2)],
        np.zeros(4),
        reference=ARM_REFERENCE,
        t1=5.0,
        dt=1e-3,
        T_c=2e-3,
        trajectories=False,
        **options,
    )


def test_a_diverged_run_has_nan_running_metrics() -> None:
    result = stiff_arm_pair()
    assert result.status_names == ["ok", "diverged"]
    assert np.all(np.isfinite(result.metrics["ae"][0]))
    assert np.all(np.isnan(result.metrics["ae"][1])) and np.isnan(result.metrics["tv"][1])


@pytest.mark.parametrize("workers", [2, 3])
def test_threads_give_the_results_of_one_thread_bit_for_bit(workers: int) -> None:
    settings = robot_batch(5)
    single = simulate(**settings, workers=1)
    threaded = simulate(**settings, workers=workers, progress=True)
    for name in ("x", "commands", "applied", "controller_state", "status", "t_stop"):
        np.testing.assert_array_equal(getattr(threaded, name), getattr(single, name))
    for key in single.metrics:
        np.testing.assert_array_equal(threaded.metrics[key], single.metrics[key])


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ({"workers": 0}, r"workers must be a positive integer or None; got 0"),
        ({"workers": 1.5}, r"workers must be a positive integer"),
        ({"metrics_from": 3.5}, r"metrics_from must lie in \[t0, t1\] = \[0, 3\] s; got 3\.5"),
        ({"metrics_from": float("nan")}, r"metrics_from must be finite"),
    ],
)
def test_bad_speed_settings_are_refused(override: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        simulate(**{**robot_batch(1), **override})


def test_trajectories_must_be_a_bool() -> None:
    with pytest.raises(TypeError, match="trajectories must be True or False; got 'no'"):
        simulate(**robot_batch(1), trajectories="no")


# --- user plants ------------------------------------------------------------------------------


#: The built-in arm's terms function compiled anew, as a user's own kernel would be: the engine
#: receives it as a function, not as the built-in kernel id.
user_arm_terms = njit(two_link_terms.py_func)


def python_arm() -> CallablePlant:
    """The built-in arm as Python callables (the plain-Python path)."""
    arm = TwoLinkArm()
    return CallablePlant(
        2, lambda q: arm.mass_matrix(q)[0], lambda q, qdot: arm.nonlinear_terms(q, qdot)[0]
    )


@pytest.mark.slow  # compiles the engine around the user's kernel (about 25 s)
def test_a_compiled_user_plant_runs_compiled_and_equals_the_built_in_plant() -> None:
    arm = TwoLinkArm()
    user = CompiledPlant(2, 2, user_arm_terms, arm.params, name="user arm")
    settings = dict(reference=ARM_REFERENCE, t1=2.0, dt=1e-3, T_c=2e-3)
    delays = [AbsSineDelay.S1(), ConstantDelay(0.05)]
    built_in = simulate(arm, arm_controller(), delays, np.zeros(4), **settings)
    mine = simulate(user, arm_controller(), delays, np.zeros(4), **settings)
    assert mine.settings["compiled"]
    np.testing.assert_allclose(mine.x, built_in.x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(mine.commands, built_in.commands, rtol=0, atol=1e-12)


def test_a_compiled_user_plant_is_checked_at_rest() -> None:
    with pytest.raises(TypeError, match=r"decorate it with @numba.njit\); got function"):
        CompiledPlant(2, 2, user_arm_terms.py_func, TwoLinkArm().params)
    with pytest.raises(
        ValueError, match=r"the kernel's M\(0\) must be symmetric positive definite"
    ):
        CompiledPlant(2, 2, user_arm_terms, [-1.0, 0.1, 0.1, 0.0, 0.0])
    with pytest.raises(ValueError, match="m must be a positive integer; got 0"):
        CompiledPlant(2, 0, user_arm_terms, TwoLinkArm().params)


def simulate_python_arm(**options):
    """A short run of :func:`python_arm` under the outer loop."""
    return simulate(
        python_arm(),
        OuterLoop(TwoLinkArm(), K1=4.0, K2=4.0),
        ConstantDelay(0.01),
        np.zeros(4),
        reference=ARM_REFERENCE,
        t1=0.1,
        dt=1e-3,
        T_c=2e-3,
        **options,
    )


def test_a_python_plant_warns_that_it_runs_as_plain_python() -> None:
    with pytest.warns(PythonFallbackWarning, match=r"plant CallablePlant .*CompiledPlant") as seen:
        result = simulate_python_arm()
    assert not result.settings["compiled"]
    assert [w.filename for w in seen] == [__file__]  # the line of the caller


def test_the_plain_python_warning_names_each_python_part_in_a_sentence() -> None:
    one = PythonFallbackWarning.describe(python_arm(), OuterLoop(TwoLinkArm(), 4.0, 4.0), None)
    both = PythonFallbackWarning.describe(python_arm(), OuterLoop(python_arm(), 4.0, 4.0), None)
    assert "because the plant CallablePlant is given as Python callables" in str(one)
    assert "the plant CallablePlant and the nominal model CallablePlant are given" in str(both)


def test_the_plain_python_warning_points_at_the_users_line_through_a_scenario() -> None:
    scenario = Scenario.from_dict(
        {**base_dict(), "plant": {"type": "python:test_speed_paths:python_arm"}}
    )
    with pytest.warns(PythonFallbackWarning) as seen:
        scenario.run()
    assert [w.filename for w in seen] == [__file__], [w.filename for w in seen]


# --- the reference path ----------------------------------------------------------------------


@pytest.mark.parametrize("name", golden.CONTROLLERS)
def test_the_reference_python_engine_equals_the_compiled_one(name: str) -> None:
    """Every controller on the payload robot (the golden cases), through a payload switch."""
    case = golden.build_case(name)
    settings = dict(reference=case.pop("reference"), t1=1.5, dt=1e-3, T_c=golden.T_C)
    compiled = simulate(**case, **settings, engine="compiled")
    reference = simulate(**case, **settings, engine="python")
    assert compiled.settings["compiled"] and not reference.settings["compiled"]
    for key in ("x", "commands", "applied", "controller_state"):
        np.testing.assert_allclose(
            getattr(reference, key), getattr(compiled, key), rtol=0, atol=1e-12, err_msg=key
        )
    for key in compiled.metrics:
        np.testing.assert_allclose(reference.metrics[key], compiled.metrics[key], rtol=1e-12)


def test_engine_names_and_the_compiled_engine_without_compiled_kernels_are_refused() -> None:
    case = golden.build_case("outer_loop")
    settings = dict(reference=case.pop("reference"), t1=0.1, dt=1e-3, T_c=golden.T_C)
    with pytest.raises(ValueError, match=r"engine must be one of \['auto', 'compiled', 'python'\]"):
        simulate(**case, **settings, engine="fast")
    with pytest.raises(ValueError, match="engine='compiled' needs compiled kernels"):
        simulate_python_arm(engine="compiled")


def test_one_compiled_engine_serves_every_call() -> None:
    """Read-only or broadcast inputs must not make numba compile the engine again (minutes)."""
    from delaytrack.sim.engine import run_batch_compiled

    settings = robot_batch(2)
    simulate(**settings)
    compiled = set(run_batch_compiled.signatures)
    x0 = np.array(settings["x0"])
    x0.flags.writeable = False
    u_init = np.zeros(2)
    u_init.flags.writeable = False
    simulate(**{**settings, "x0": x0, "plant": settings["plant"][0], "delay": settings["delay"][0]})
    simulate(**{**settings, "x0": np.stack([x0, x0])}, u_init=u_init, trajectories=False)
    assert set(run_batch_compiled.signatures) == compiled


def test_a_run_that_stops_before_its_metrics_window_has_nan_metrics() -> None:
    result = stiff_arm_pair(metrics_from=4.5)
    assert result.status_names == ["ok", "diverged"] and result.t_stop[1] < 4.5
    assert np.all(np.isfinite(result.metrics["rms"][0]))
    for key in ("ae", "rms", "max"):
        assert np.all(np.isnan(result.metrics[key][1]))


def test_metrics_from_between_ticks_starts_at_the_next_tick_as_t_from_does() -> None:
    settings = robot_batch(1)
    for start in (1.234, 1.23, 1.2300000000000002):
        result = simulate(**settings, metrics_from=start)
        expected = mean_absolute_error(result, t_from=start)
        np.testing.assert_allclose(result.metrics["ae"], expected, rtol=1e-12, atol=0)
