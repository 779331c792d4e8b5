"""A plant stepped by MuJoCo itself (``stepping = "mujoco"``) as the live robot.

dm_control's point mass, stepped by ``mj_step`` at its file's timestep: the robot node's states
must be MuJoCo's, step by step, for the inputs the node logged (no timing asserted). The session
runs with ``--quiet``, which is checked here too.
"""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("zenoh")
pytest.importorskip("mujoco")

from delaytrack.scenario import Scenario  # noqa: E402

SCENARIO = Path(__file__).resolve().parents[1] / "examples/dm_control_point_mass/point_mass_S1.toml"


def _rows(path):
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    out = tmp_path_factory.mktemp("mujoco") / "run"
    done = subprocess.run(
        [sys.executable, "-m", "delaytrack.live", "run", str(SCENARIO), "--duration", "1"]
        + ["--out", str(out), "--quiet"],
        capture_output=True,
        timeout=300,
    )
    return out, done


def test_a_mujoco_stepped_plant_runs_live_and_its_states_are_mujocos(session):
    out, done = session
    assert done.returncode == 0, done.stderr.decode()
    scenario = Scenario.from_toml(SCENARIO)
    plant = scenario.build().plant
    steps = _rows(out / "steps.csv")
    states = _rows(out / "states.csv")
    # 1 s at the file's timestep, 20 ms: 50 steps, and the states at their starts and the end.
    assert len(steps) == 50 and len(states) == 51
    inputs = list(steps[0])[-plant.m :]  # after j, t_s, lateness_ms, status, seq
    assert list(steps[0])[:5] == ["j", "t_s", "lateness_ms", "status", "seq"]
    columns = list(states[0])[2:]
    x = np.array([float(states[0][c]) for c in columns])
    params = np.ascontiguousarray(plant.params, dtype=np.float64)
    for j, step in enumerate(steps):
        u = np.array([float(step[c]) for c in inputs])
        plant.stepper_kernel(float(step["t_s"]), x, u, scenario.dt, params, j == 0)
        logged = np.array([float(states[j + 1][c]) for c in columns])
        np.testing.assert_array_equal(x, logged, err_msg=f"step {j}")


def test_live_run_quiet_prints_no_status(session):
    """``--quiet``: neither the launcher's status line nor its final summary."""
    _out, done = session
    assert done.returncode == 0, done.stderr.decode()
    assert not any(line.startswith("t=") for line in done.stderr.decode().splitlines())
    assert done.stdout == b""
