"""The shipped example sweeps load, and the robot one states the gains it claims."""

from pathlib import Path

import numpy as np
import pytest

from delaytrack.controllers import AROLC, OuterLoop
from delaytrack.experiments import paper, tuning
from delaytrack.plants.robot import NominalRobot
from delaytrack.sweeps import SweepSpec

EXAMPLES = Path(__file__).parents[1] / "examples"


@pytest.fixture(scope="module")
def robot():
    return SweepSpec.from_toml(EXAMPLES / "sweep_robot.toml")


def test_robot_example_is_1000_draws_of_three_controllers(robot):
    assert (len(robot.runs), len(robot.units()), robot.draws) == (3000, 30, 1000)
    kinds = [run.scenario.controller["type"] for run in robot.runs]
    assert kinds == ["arolc"] * 1000 + ["pcon"] * 1000 + ["outer-loop"] * 1000
    # Common random numbers: run i of each controller sees the same delay and payload draw.
    for key in ("delay.h_high", "delay.seed", "plant.seed"):
        column = [run.values[key] for run in robot.runs]
        assert column[:1000] == column[1000:2000] == column[2000:]
    h_high = np.array([run.values["delay.h_high"] for run in robot.runs[:1000]])
    assert 0.05 <= h_high.min() and h_high.max() <= 0.2
    # 1000 integers drawn from 0..10^6 share a value about 0.5 times on average (birthdays).
    assert len({run.values["plant.seed"] for run in robot.runs[:1000]}) > 990


def test_robot_example_gains_are_the_papers_and_the_tuned_ones(robot):
    arolc, pcon, outer = (robot.runs[i].scenario.build().controller for i in (0, 1000, 2000))
    expected = AROLC(NominalRobot(), **paper.AROLC_GAINS)
    np.testing.assert_array_equal(arolc.params, expected.params)
    gains = tuning.load_gains()["PCON"]["varying"]
    tuned = tuning.make_controller("PCON", gains, history=0.25)
    np.testing.assert_array_equal(pcon.params, tuned.params)
    expected = OuterLoop(NominalRobot(), K1=paper.AROLC_GAINS["K1"], K2=paper.AROLC_GAINS["K2"])
    np.testing.assert_array_equal(outer.params, expected.params)


def test_small_example_loads():
    spec = SweepSpec.from_toml(EXAMPLES / "sweep_small.toml")
    assert (len(spec.runs), len(spec.units())) == (24, 3)
