"""The shipped robot_S1 scenario is exactly the paper job's AROLC / S1 run."""

import numpy as np
import pytest

from delaytrack.controllers import AROLC
from delaytrack.delays import AbsSineDelay
from delaytrack.experiments import paper
from delaytrack.plants.robot import NominalRobot, PayloadRobot, initial_state, paper_reference
from delaytrack.scenario import load_builtin
from delaytrack.sim import simulate


@pytest.fixture(scope="module")
def built():
    return load_builtin("robot_S1").build()


def test_robot_s1_builds_the_paper_set_up(built):
    scenario = load_builtin("robot_S1")
    assert (scenario.duration, scenario.dt, scenario.T_c) == (paper.DURATION, paper.DT, paper.T_C)
    assert isinstance(built.plant, PayloadRobot) and isinstance(built.model, NominalRobot)
    truth = PayloadRobot(seed=paper.PAYLOAD_SEED, duration=paper.DURATION)
    np.testing.assert_array_equal(built.plant.params, truth.params)
    np.testing.assert_array_equal(built.model.params, NominalRobot().params)
    assert isinstance(built.controller, AROLC)
    assert built.delay == AbsSineDelay.S1()
    reference = paper_reference("consistent")
    np.testing.assert_array_equal(built.x0, initial_state(reference))
    t = np.linspace(0.0, 60.0, 601)
    for ours, theirs in zip(built.reference.evaluate(t), reference.evaluate(t), strict=True):
        np.testing.assert_array_equal(ours, theirs)
    assert built.plant.coordinate_names[:2] == ("x", "y")


def test_robot_s1_runs_bit_for_bit_like_the_paper_job(built):
    """Two seconds of the scenario against the paper job's own objects (exact equality)."""
    kwargs = dict(reference=paper_reference("consistent"), t1=2.0, dt=paper.DT, T_c=paper.T_C)
    ours = simulate(built.plant, built.controller, built.delay, built.x0, **kwargs)
    theirs = simulate(
        PayloadRobot(seed=paper.PAYLOAD_SEED, duration=paper.DURATION),
        AROLC(NominalRobot(), **paper.AROLC_GAINS),
        AbsSineDelay.S1(),
        initial_state(paper_reference("consistent")),
        **kwargs,
    )
    np.testing.assert_array_equal(ours.q, theirs.q)
    np.testing.assert_array_equal(ours.x, theirs.x)
    np.testing.assert_array_equal(ours.commands, theirs.commands)
    assert ours.status_names == ["ok"]
