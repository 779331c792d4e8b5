"""dm_control's point mass (examples/dm_control_point_mass): the model file loads as it is
shipped, its scenario tracks the reference through the CLI with MuJoCo stepping the truth, and
its sweep runs."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")
pd = pytest.importorskip("pandas")

from delaytrack.cli import main  # noqa: E402
from delaytrack.plants import MujocoPlant  # noqa: E402
from delaytrack.scenario import Scenario  # noqa: E402
from delaytrack.sweeps import SweepSpec  # noqa: E402

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "dm_control_point_mass"
MODEL = EXAMPLE / "point_mass.xml"
#: The reference's amplitudes (m) in point_mass_S1.toml.
AMPLITUDE = np.array([0.15, 0.10])


@pytest.fixture
def folder(tmp_path):
    copy = tmp_path / "dm_control_point_mass"
    shutil.copytree(EXAMPLE, copy)
    return copy


def test_the_point_mass_file_loads_with_its_limits_and_timestep():
    plant = MujocoPlant(MODEL, actuator_limits="ignore", constraints="ignore")
    assert (plant.n, plant.m, plant.coordinate_names) == (2, 2, ("root_x", "root_y"))
    mass, nonlinear, input_map = plant.terms(np.zeros(2), np.array([0.2, -0.1]))
    # 0.3 kg on two slide joints, damping 1 N s/m, each motor drives one joint through a tendon
    # with gear 0.1.
    np.testing.assert_allclose(mass[0], 0.3 * np.eye(2))
    np.testing.assert_allclose(nonlinear[0], [0.2, -0.1])
    np.testing.assert_allclose(input_map[0], 0.1 * np.eye(2))
    with pytest.raises(ValueError, match="pass actuator_limits='ignore'"):
        MujocoPlant(MODEL)
    with pytest.raises(ValueError, match="'root_x' has limits"):
        MujocoPlant(MODEL, actuator_limits="ignore")
    built = Scenario.from_toml(EXAMPLE / "point_mass_S1.toml").build()
    assert built.plant.stepping == "mujoco" and built.model.stepping == "rk4"
    assert built.model.mass_scale == 0.8
    scenario = Scenario.from_toml(EXAMPLE / "point_mass_S1.toml")
    assert scenario.dt == mujoco.MjModel.from_xml_path(str(MODEL)).opt.timestep


def _free_motion(x0: np.ndarray, steps: int) -> np.ndarray:
    """Positions of the point mass left alone (zero controls) from ``x0``, by MuJoCo."""
    model = mujoco.MjModel.from_xml_path(str(MODEL))
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = x0[:2], x0[2:]
    positions = np.empty((steps, 2))
    for k in range(steps):
        positions[k] = data.qpos
        mujoco.mj_step(model, data)
    return positions


def test_the_scenario_tracks_the_reference_through_the_cli(folder):
    out = folder.parent / "run"
    scenario = folder / "point_mass_S1.toml"
    assert main(["simulate", str(scenario), "--out", str(out), "--format", "csv"]) == 0
    metrics = pd.read_csv(out / "metrics.csv")
    assert metrics["status"].tolist() == ["ok"]
    errors = metrics[["ae_root_x_m", "ae_root_y_m"]].to_numpy()[0]
    assert np.all(np.isfinite(errors))
    trajectory = pd.read_csv(out / "trajectories.csv")
    q = trajectory[["root_x_m", "root_y_m"]].to_numpy()
    qd = trajectory[["root_x_d_m", "root_y_d_m"]].to_numpy()
    # Left alone, the mass coasts a couple of centimetres and stops: its error is of the
    # order of the reference's amplitude. The controller's is far below both.
    x0 = np.array(Scenario.from_toml(scenario).x0)
    idle = np.mean(np.abs(qd - _free_motion(x0, len(qd))), axis=0)
    assert np.all(idle > 0.4 * AMPLITUDE)
    assert np.all(errors < 0.05 * AMPLITUDE) and np.all(errors < 0.1 * idle)
    # The reference stays inside the joint range and the commands inside the control range,
    # which MuJoCo would otherwise enforce.
    assert np.max(np.abs(q)) < 0.29
    commands = trajectory[["u1_sent", "u2_sent"]].to_numpy()
    assert np.max(np.abs(commands)) < 1.0


def test_the_sweep_runs_both_controllers_over_its_delays(folder):
    sweep = folder / "sweep_point_mass.toml"
    spec = SweepSpec.from_toml(sweep)  # every run of the shipped file is built and checked
    assert (len(spec.runs), len(spec.units()), spec.draws) == (32, 4, 4)
    scales = [run.values["model.mass_scale"] for run in spec.runs]
    assert 0.6 <= min(scales) and max(scales) <= 1.4
    # One draw per grid point: 2 controllers x 4 delays = 8 runs, one unit.
    sweep.write_text(sweep.read_text().replace("draws = 4", "draws = 1"))
    out = folder.parent / "sweep"
    assert main(["sweep", str(sweep), "--out", str(out), "--quiet"]) == 0
    summary = pd.read_csv(out / "summary.csv")
    assert set(summary["controller"]) == {"arolc", "outer-loop"}
    assert summary["runs"].sum() == 8 and (summary["diverged"] == 0).all()
    runs = pd.read_csv(out / "runs.csv")
    errors = runs[["ae_root_x", "ae_root_y"]].to_numpy()
    assert (runs["status"] == "ok").all() and np.all(np.isfinite(errors))
    assert np.all(errors < 0.2 * AMPLITUDE)
    # A longer delay leaves a larger error.
    by_delay = runs.groupby("h_max")["ae_root_x"].mean()
    assert by_delay.index.min() == 0.0 and by_delay.iloc[-1] > by_delay.iloc[0]
