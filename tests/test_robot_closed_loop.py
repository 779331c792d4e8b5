"""The robot in the compiled simulator: AROLC on the nominal model drives the truth plants.

Settings: the paper's S1 delay ``h = 20 + 80 |sin t|`` ms and robot gains ``K1 = K2 = Q = I``,
``α = 2``, ``ε = 0.1``, ``γ = 0.001``; the ``consistent`` path started on it; ``dt`` = 1 ms,
``T_c`` = 10 ms (our choices; the paper gives neither).
"""

from __future__ import annotations

import numpy as np
import pytest

import delaytrack as dt
from delaytrack.plants.robot import (
    NominalRobot,
    PayloadRobot,
    PrintedRobotModel,
    WheeledRobot,
    initial_state,
    paper_reference,
)

GAINS = dict(K1=1.0, K2=1.0, Q=1.0, alpha=2.0, epsilon=0.1, gamma=0.001)
S1 = dt.AbsSineDelay(offset=0.02, amplitude=0.08, frequency=1.0)
REFERENCE = paper_reference()
X0 = initial_state(REFERENCE)


FAST_SCHEDULE = dict(seed=5, duration=2.0, first_on=0.5, time_on=0.5, time_off=0.5)


def fast_payload(**overrides):
    """Placements switching every 0.5 s, so that a 2 s run sees several."""
    return PayloadRobot(**{**FAST_SCHEDULE, **overrides})


class PythonPayloadRobot(PayloadRobot):
    """The same plant with its kernel as plain Python: ``simulate`` then runs as Python."""

    @property
    def terms_kernel(self):
        return super().terms_kernel.py_func


def run(plant, model=None, t1=2.0):
    controller = dt.AROLC(NominalRobot() if model is None else model, **GAINS)
    return dt.simulate(plant, controller, S1, X0, reference=REFERENCE, t1=t1, dt=1e-3, T_c=0.01)


@pytest.mark.parametrize(
    "plant", [WheeledRobot(), fast_payload()], ids=["truth", "truth-with-payload"]
)
def test_arolc_drives_the_robot(plant):
    result = run(plant)
    assert result.settings["compiled"]
    assert result.status.tolist() == [0]
    assert np.all(np.isfinite(result.x)) and np.all(np.isfinite(result.commands))
    # Started on the path; friction (unknown to the model) pulls it off by centimetres.
    assert np.max(np.abs(result.e1[0, :, :2])) < 0.3
    residual = plant.constraint_residual(result.x[0])
    assert np.max(np.abs(residual)) < 1e-9


def test_compiled_and_python_engines_agree():
    compiled = run(fast_payload(), t1=1.0)
    python = run(PythonPayloadRobot(**FAST_SCHEDULE), t1=1.0)
    assert compiled.settings["compiled"] and not python.settings["compiled"]
    np.testing.assert_allclose(python.x, compiled.x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(python.commands, compiled.commands, rtol=0, atol=1e-12)


def test_payload_changes_the_closed_loop():
    """The payload is felt: the same loop with and without it differs."""
    with_payload = run(fast_payload())
    without = run(fast_payload(payload_mass=1e-9))
    assert np.max(np.abs(with_payload.x - without.x)) > 1e-4


def test_printed_model_runs_as_a_nominal_model():
    result = run(fast_payload(), model=PrintedRobotModel())
    assert result.status.tolist() == [0]
    assert np.all(np.isfinite(result.commands))
