"""Robots from MuJoCo model files: the plant form checked against MuJoCo's own dynamics, in
every command, and the model files it refuses."""

from __future__ import annotations

import copy
import json
import os
import pickle
import shutil
from pathlib import Path

import mujoco
import numpy as np
import pandas as pd
import pytest

import delaytrack as dt
from delaytrack.cli import main
from delaytrack.plants import MujocoPlant
from delaytrack.scenario import Scenario, ScenarioError
from delaytrack.sweeps import SweepSpec
from delaytrack.sweeps.spec import engine_inputs

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "mujoco_arm"
ARM = EXAMPLE / "arm3.xml"
REFERENCE = dt.SinusoidalReference(
    [0.0, 0.3, 0.0], amplitude=[[0.5], [0.3], [0.2]], frequency=[[1.0], [1.3], [0.7]]
)


def test_the_plant_form_gives_mujocos_own_accelerations():
    plant = MujocoPlant(ARM)
    assert (plant.n, plant.m, plant.coordinate_names) == (3, 3, ("shoulder", "elbow", "wrist"))
    model = mujoco.MjModel.from_xml_path(str(ARM))
    data = mujoco.MjData(model)
    rng = np.random.default_rng(3)
    for _ in range(5):
        q, qdot, u = rng.normal(size=3), 3.0 * rng.normal(size=3), 5.0 * rng.normal(size=3)
        mass, nonlinear, input_map = (array[0] for array in plant.terms(q, qdot))
        data.qpos[:], data.qvel[:], data.ctrl[:] = q, qdot, u
        mujoco.mj_forward(model, data)
        qddot = np.linalg.solve(mass, input_map @ u - nonlinear)
        np.testing.assert_allclose(qddot, data.qacc, rtol=1e-12, atol=1e-11)
    np.testing.assert_allclose(np.diag(input_map), [10.0, 5.0, 2.0])  # the motors' gears


def test_terms_skip_contacts_and_constraints_and_are_mujocos_own_with_them():
    """A plant integrated by RK4 has MuJoCo skip contacts and constraints (only its M, N, G are
    read); the terms are bit for bit those of the model with both on, here on the P3-DX, whose
    wheels touch the ground."""
    path = Path(dt.__file__).parent / "data" / "p3dx.xml"
    plant = MujocoPlant(path, constraints="ignore")
    off = int(mujoco.mjtDisableBit.mjDSBL_CONTACT) | int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
    assert plant._model.opt.disableflags & off == off
    stepped = MujocoPlant(path, constraints="ignore", stepping="mujoco")
    assert stepped._model.opt.disableflags & off == 0
    rng = np.random.default_rng(5)
    found = 0
    for _ in range(20):
        q, qdot = rng.normal(size=plant.n), rng.normal(size=plant.n)
        for ours, theirs in zip(plant.terms(q, qdot), stepped.terms(q, qdot), strict=True):
            np.testing.assert_array_equal(ours, theirs)
        found += int(stepped._data.ncon > 0)
    assert found > 0  # the model with contacts on found some: they changed no term


def test_an_actuator_pushing_through_contacts_keeps_them(tmp_path):
    """An adhesion actuator's force arm comes from its body's contacts (as constraint rows):
    its model keeps contacts and constraints, and its column of G is MuJoCo's own."""
    path = tmp_path / "adhesion.xml"
    path.write_text(
        """<mujoco><option gravity="0 0 -9.81"/><worldbody><geom type="plane" size="5 5 0.1"/>
        <body name="b" pos="0 0 0.1"><joint name="x" type="slide" axis="1 0 0"/>
        <joint name="z" type="slide" axis="0 0 1"/>
        <geom type="box" size="0.1 0.1 0.1" mass="1" margin="0.05" gap="0"/></body></worldbody>
        <actuator><motor joint="x"/><motor joint="z"/>
        <adhesion body="b" ctrlrange="0 10" gain="1"/></actuator></mujoco>"""
    )
    plant = MujocoPlant(path, actuator_limits="ignore")
    off = int(mujoco.mjtDisableBit.mjDSBL_CONTACT) | int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
    assert plant._model.opt.disableflags & off == 0
    stepped = MujocoPlant(path, actuator_limits="ignore", stepping="mujoco")
    q, qdot = np.zeros(2), np.zeros(2)
    ours, theirs = plant.terms(q, qdot)[2], stepped.terms(q, qdot)[2]
    np.testing.assert_array_equal(ours, theirs)
    assert np.any(ours[0, :, 2] != 0.0)  # the box touches the floor: the adhesion pulls it


def test_a_lighter_model_scales_masses_and_inertias():
    full, light = MujocoPlant(ARM), MujocoPlant(ARM, mass_scale=0.8)
    q, qdot = np.array([0.3, -0.2, 0.5]), np.zeros(3)
    mass_full, gravity_full, _ = (array[0] for array in full.terms(q, qdot))
    mass_light, gravity_light, _ = (array[0] for array in light.terms(q, qdot))
    armature = 0.01 * np.eye(3)  # rotor inertia, not a body's
    np.testing.assert_allclose(mass_light - armature, 0.8 * (mass_full - armature), rtol=1e-12)
    np.testing.assert_allclose(gravity_light, 0.8 * gravity_full, rtol=1e-12)
    assert not np.array_equal(full.run_identity, light.run_identity)
    np.testing.assert_array_equal(full.run_identity, MujocoPlant(ARM).run_identity)


def test_it_runs_compiled_as_plant_and_model_the_same_as_plain_python():
    truth, model = MujocoPlant(ARM), MujocoPlant(ARM, mass_scale=0.8)
    controller = dt.AROLC(model, K1=16.0, K2=8.0, Q=1.0, alpha=2.0, epsilon=0.1, gamma=0.001)
    x0 = [0.0, 0.3, 0.0, 0.5, 0.39, 0.14]
    settings = dict(reference=REFERENCE, t1=0.5, dt=1e-3, T_c=2e-3)
    compiled = dt.simulate(truth, controller, dt.AbsSineDelay.S1(), x0, **settings)
    python = dt.simulate(truth, controller, dt.AbsSineDelay.S1(), x0, engine="python", **settings)
    assert compiled.settings["compiled"] and compiled.status_names == ["ok"]
    np.testing.assert_array_equal(python.x, compiled.x)
    # Two threads, each with its own copy of the plant's and the model's MuJoCo data: each run
    # as alone.
    delays = [dt.AbsSineDelay.S1(), dt.ConstantDelay(0.03)]
    batch = dt.simulate(truth, controller, delays, x0, workers=2, **settings)
    np.testing.assert_array_equal(batch.x[0], compiled.x[0])
    alone = dt.simulate(truth, controller, delays[1], x0, **settings)
    np.testing.assert_array_equal(batch.x[1], alone.x[0])
    assert truth.for_worker(1) is truth.for_worker(1) and truth.for_worker(1) is not truth


def test_a_copy_is_made_again_from_its_file():
    plant = MujocoPlant(ARM, mass_scale=0.9)
    for twin in (copy.deepcopy(plant), pickle.loads(pickle.dumps(plant))):
        assert twin.params[0] != plant.params[0]  # its own MuJoCo model, not a dangling address
        q = np.array([0.1, 0.2, 0.3])
        np.testing.assert_array_equal(twin.terms(q, q)[1], plant.terms(q, q)[1])


def test_scenario_simulate_empirical_and_sweep_take_a_model_file(tmp_path, capsys):
    folder = tmp_path / "mujoco_arm"
    shutil.copytree(EXAMPLE, folder)
    scenario = Scenario.from_toml(folder / "arm3_S1.toml")
    assert scenario.plant["path"] == str(folder / "arm3.xml")  # relative to the scenario file
    data = scenario.to_dict()
    data["duration"] = 1.0
    (folder / "short.toml").write_text(Scenario.from_dict(data).to_toml())
    out = tmp_path / "run"
    assert main(["simulate", str(folder / "short.toml"), "--out", str(out)]) == 0
    metrics = pd.read_csv(out / "metrics.csv")
    assert {"ae_shoulder_rad", "ae_elbow_rad", "ae_wrist_rad"} <= set(metrics.columns)
    sweep = folder / "sweep_arm3.toml"
    text = sweep.read_text().replace("draws = 4", "draws = 1")
    sweep.write_text(text.replace('scenario = "arm3_S1.toml"', 'scenario = "short.toml"'))
    assert main(["sweep", str(sweep), "--out", str(tmp_path / "sweep"), "--quiet"]) == 0
    summary = pd.read_csv(tmp_path / "sweep" / "summary.csv")
    assert set(summary["controller"]) == {"arolc", "outer-loop"} and (summary["runs"] > 0).all()
    # Unit hashes cover the compiled model, not the addresses of this process.
    built = Scenario.from_toml(folder / "short.toml").build()
    assert engine_inputs(built) == engine_inputs(Scenario.from_toml(folder / "short.toml").build())
    # The empirical delay margin of the model file's closed loop (its [delay] replaced): the
    # 1 s run keeps its error below 0.5 rad at no delay and leaves it (or diverges) by 0.4 s.
    capsys.readouterr()
    arguments = ["empirical", str(folder / "short.toml"), "--threshold", "0.5", "--json"]
    arguments += ["--upper", "0.4", "--resolution", "0.02", "--settle", "0.5"]
    assert main(arguments) == 0
    found = json.loads(capsys.readouterr().out)
    assert found["scenario"] == "arm3_S1" and found["controller"] == "arolc"
    assert found["evaluated"][0][0] == 0.0 and found["evaluated"][0][2] == 0
    assert 0.0 < found["margin"] <= 0.4

    assert [u.hash for u in SweepSpec.from_toml(sweep).units()] == [
        u.hash for u in SweepSpec.from_toml(sweep).units()
    ]


def _arm_with(tmp_path: Path, old: str, new: str) -> Path:
    path = tmp_path / "arm.xml"
    text = ARM.read_text()
    assert old in text
    path.write_text(text.replace(old, new))
    return path


@pytest.mark.parametrize(
    ("old", "new", "options", "message"),
    [
        (
            '<joint name="shoulder"/>',
            '<joint name="shoulder" type="ball"/>',
            {},
            "'shoulder' is a ball joint",
        ),
        (
            '<body name="upper" pos="0 0 1">',
            '<body name="base" pos="0 0 2"><freejoint name="base"/>'
            '<geom type="sphere" size="0.1" mass="1"/></body><body name="upper" pos="0 0 1">',
            {},
            "'base' is a free joint",
        ),
        (
            '<motor name="elbow" joint="elbow" gear="5"/>',
            '<position joint="elbow" kp="5"/>',
            {},
            "only direct actuators",
        ),
        ('gear="5"/>', 'gear="5" ctrlrange="-1 1"/>', {}, "pass actuator_limits='ignore'"),
        ('<joint name="wrist"/>', '<joint name="wrist" range="-1 1"/>', {}, "'wrist' has limits"),
        (
            '<joint name="wrist"/>',
            '<joint name="wrist" frictionloss="0.1"/>',
            {},
            "'wrist' has friction loss",
        ),
        ("<mujoco model", "<mujoco modle", {}, "MuJoCo could not read it"),
        ('gear="5"/>', 'gear="5" delay="0.01" nsample="12"/>', {}, "has a delay of its own"),
        (
            '<joint name="elbow"/>',
            '<joint name="elbow" actuatorgravcomp="true"/>',
            {},
            "gravity compensation through its actuators",
        ),
        (
            '<joint name="elbow"/>',
            '<joint name="elbow" actuatorfrcrange="-1 1"/>',
            {},
            "pass actuator_limits='ignore'",
        ),
        (
            "</worldbody>",
            '</worldbody><equality><joint joint1="elbow" joint2="wrist"/></equality>',
            {},
            "equality constraints",
        ),
        # MuJoCo reads a NaN and goes on: a mass from the density, a NaN timestep.
        ('mass="1.5"', 'mass="nan"', {}, "a number of the file is NaN"),
        ('timestep="0.001"', 'timestep="nan"', {"stepping": "mujoco"}, "is NaN"),
    ],
)
def test_model_files_it_cannot_represent_are_refused_naming_what(
    tmp_path, old, new, options, message
):
    with pytest.raises(ValueError, match=message):
        MujocoPlant(_arm_with(tmp_path, old, new), **options)


def test_limits_are_used_without_their_clamps_only_when_asked(tmp_path):
    path = _arm_with(tmp_path, 'gear="5"/>', 'gear="5" ctrlrange="-1 1"/>')
    plant = MujocoPlant(path, actuator_limits="ignore")
    np.testing.assert_allclose(np.diag(plant.terms(np.zeros(3), np.zeros(3))[2][0]), [10, 5, 2])


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"path": "missing.xml"}, r"'model.path' = '.*missing\.xml' does not exist"),
        ({"mass_scale": 0.0}, "model.mass_scale' must be > 0"),
        ({"mass_scale": "heavy"}, "model.mass_scale"),
        ({"constraints": "maybe"}, "model.constraints' must be 'refuse' or 'ignore'"),
    ],
)
def test_bad_model_keys_name_the_key(tmp_path, changes, message):
    shutil.copytree(EXAMPLE, tmp_path / "arm")
    data = Scenario.from_toml(tmp_path / "arm" / "arm3_S1.toml").to_dict()
    data["model"] = {**data["model"], **changes}
    with pytest.raises(ScenarioError, match=message):
        Scenario.from_dict(data).build()


def test_without_mujoco_the_error_says_how_to_install_it(monkeypatch, tmp_path, capsys):
    import importlib

    real = importlib.import_module

    def no_mujoco(name, *args):
        if name == "mujoco":
            raise ImportError("No module named 'mujoco'")
        return real(name, *args)

    monkeypatch.setattr(importlib, "import_module", no_mujoco)
    with pytest.raises(ImportError, match=r"pip install -e '\.\[mujoco\]'"):
        MujocoPlant(ARM)
    # On the command line: exit 2 and the same advice, no traceback.
    scenario = str(EXAMPLE / "arm3_S1.toml")
    assert main(["simulate", scenario, "--out", str(tmp_path / "out")]) == 2
    assert "pip install -e '.[mujoco]'" in capsys.readouterr().err


URDF = """<robot name="two">
  <link name="base"/>
  <link name="l1"><inertial><mass value="1.0"/>
    <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="l2"><inertial><origin xyz="0.2 0 0"/><mass value="0.5"/>
    <inertia ixx="0.005" iyy="0.005" izz="0.005" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="10" velocity="5"/></joint>
  <joint name="j2" type="continuous"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.4 0 0"/><axis xyz="0 0 1"/></joint>
</robot>"""


def test_a_urdf_file_gets_a_motor_on_every_joint_when_asked(tmp_path):
    path = tmp_path / "two.urdf"
    path.write_text(URDF)
    with pytest.raises(ValueError, match="no actuators .* pass add_motors=True"):
        MujocoPlant(path)
    # URDF's effort limit is a clamp on the joint's actuator force, its limits a constraint.
    with pytest.raises(ValueError, match="actuator 'j1' clamps its control or force"):
        MujocoPlant(path, add_motors=True)
    with pytest.raises(ValueError, match="joint 'j1' has limits"):
        MujocoPlant(path, add_motors=True, actuator_limits="ignore")
    plant = MujocoPlant(path, add_motors=True, actuator_limits="ignore", constraints="ignore")
    assert (plant.n, plant.m, plant.coordinate_names) == (2, 2, ("j1", "j2"))
    mass, nonlinear, input_map = (array[0] for array in plant.terms([0.3, 0.7], [1.0, -2.0]))
    np.testing.assert_array_equal(input_map, np.eye(2))
    # Two point-like links about parallel axes: M11 = I1 + I2 + m2 (l1² + c2² + 2 l1 c2 cos q2).
    expected = 0.01 + 0.005 + 0.5 * (0.4**2 + 0.2**2 + 2 * 0.4 * 0.2 * np.cos(0.7))
    assert mass[0, 0] == pytest.approx(expected, rel=1e-12)
    assert dt.plant_from_spec(plant.to_spec()).to_spec() == plant.to_spec()
    assert plant.input_units == ("N·m", "N·m")  # a motor of gear 1 on a hinge: a torque


#: A hinge and a ball joint, each driven by a motor of gear 1.
BALL_ARM = """<mujoco>
  <worldbody>
    <body name="upper" pos="0 0 1">
      <joint name="hinge" type="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.03" mass="1"/>
      <body name="fore" pos="0.4 0 0">
        <joint name="ball" type="ball"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor joint="hinge" gear="1"/>
    <motor joint="ball" gear="1 0 0"/>
  </actuator>
</mujoco>
"""


def test_a_control_has_a_unit_only_where_it_is_the_joint_force(tmp_path):
    """A motor of gear 1 on a hinge takes N·m, on a slide N; a gear g makes the control a g-th
    of the torque, which has no unit of its own: TV then has none."""
    assert MujocoPlant(ARM).input_units is None  # gears 10, 5 and 2
    geared = ARM.read_text().replace('gear="5"', 'gear="1"').replace('gear="2"', 'gear="1"')
    direct = geared.replace('gear="10"', 'gear="1"')
    slide = direct.replace('<joint name="wrist"/>', '<joint name="wrist" type="slide"/>')
    assert len({geared, direct, slide}) == 3
    reversed_gear = direct.replace(
        '<motor name="wrist" joint="wrist" gear="1"/>',
        '<motor name="wrist" joint="wrist" gear="-1"/>',
    )
    site = direct.replace(
        '<geom fromto="0 0 0 0.15 0 0" mass="0.4"/>',
        # three sites before it: its id, 3, is no joint's (the arm has joints 0 to 2)
        '<geom fromto="0 0 0 0.15 0 0" mass="0.4"/>'
        + "".join(f'<site name="s{i}"/>' for i in range(3))
        + '<site name="tip" pos="0.15 0 0"/>',
    ).replace(
        '<motor name="wrist" joint="wrist" gear="1"/>', '<motor site="tip" gear="0 0 1 0 0 0"/>'
    )
    assert reversed_gear != direct and site != direct
    (tmp_path / "ball.xml").write_text(BALL_ARM)  # stepped by MuJoCo, the ball joint left out
    ball = MujocoPlant(tmp_path / "ball.xml", stepping="mujoco", coordinates=("hinge",))
    assert ball.input_units is None  # a motor on a ball joint: no one unit, and no error
    for name, written, units in (
        ("geared.xml", geared, None),  # one geared motor: the controls have no one unit
        ("direct.xml", direct, ("N·m", "N·m", "N·m")),
        ("slide.xml", slide, ("N·m", "N·m", "N")),
        ("reversed.xml", reversed_gear, ("N·m", "N·m", "N·m")),  # gear -1: the torque's sign
        ("site.xml", site, None),  # a force at a site: not a joint's force
    ):
        (tmp_path / name).write_text(written)
        assert MujocoPlant(tmp_path / name).input_units == units


def test_the_figures_name_the_controls_by_their_actuators(tmp_path):
    """An actuator's name labels its panel; an unnamed one is ``u<j>``; a model with none
    named keeps ``u1 .. um`` (and its tables keep ``u1 .. um`` whatever the names)."""
    from delaytrack.report.figures import commands_figure

    assert MujocoPlant(ARM).input_names == ("shoulder", "elbow", "wrist")
    partly = ARM.read_text().replace('<motor name="elbow" ', "<motor ")
    unnamed = partly.replace('name="shoulder" joint', "joint").replace(
        'name="wrist" joint', "joint"
    )
    for name, written, names in (("partly.xml", partly, ("shoulder", "u2", "wrist")),
                                 ("unnamed.xml", unnamed, None)):  # fmt: skip
        (tmp_path / name).write_text(written)
        assert MujocoPlant(tmp_path / name).input_names == names
    result = dt.simulate(
        MujocoPlant(ARM),
        _arolc_on_the_light_arm(),
        dt.AbsSineDelay.S1(),
        X0,
        reference=REFERENCE,
        t1=0.02,
        dt=1e-3,
        T_c=2e-3,
    )
    assert result.input_names == ("shoulder", "elbow", "wrist") == result[0].input_names
    labels = {ax.get_ylabel() for ax in commands_figure(result).axes}
    assert labels == {"shoulder", "elbow", "wrist"}
    assert [c for c in result.to_frame().columns if c.startswith("u")] == [
        f"u{j}_{kind}" for j in (1, 2, 3) for kind in ("sent", "applied")
    ]


# ---- stepped by MuJoCo ----------------------------------------------------------------------

T_C, DT = 0.002, 0.001
X0 = np.array([0.0, 0.3, 0.0, 0.5, 0.39, 0.14])


def _native_delay_run(
    h: float, ticks: int, controller, exact_clock: bool, arm: Path = ARM
) -> np.ndarray:
    """The closed loop run by MuJoCo alone, the delay by its actuators' own ``delay``
    (independent of this toolkit's delay); the states at the ticks."""
    import re

    nsample = round(h / DT) + 3
    text = re.sub(r"(<motor [^/]*)/>", rf'\1 delay="{h!r}" nsample="{nsample}"/>', arm.read_text())
    model = mujoco.MjModel.from_xml_string(text)
    assert model.actuator_delay[0] == h
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = X0[:3], X0[3:]
    state = controller.initial_state()
    steps = round(T_C / DT)
    states = []
    for k in range(ticks):
        reference = tuple(array[0] for array in REFERENCE.evaluate(np.array([k * T_C])))
        states.append(np.concatenate([data.qpos, data.qvel]))
        command, state = controller.step(
            k * T_C, data.qpos.copy(), data.qvel.copy(), reference, state, T_c=T_C
        )
        data.ctrl[:] = command
        for j in range(steps):
            if exact_clock:
                data.time = (k * steps + j) * DT  # as this toolkit counts time
            mujoco.mj_step(model, data)
    return np.array(states)


def _arolc_on_the_light_arm():
    model = MujocoPlant(ARM, mass_scale=0.8)
    return dt.AROLC(model, K1=16.0, K2=8.0, Q=1.0, alpha=2.0, epsilon=0.1, gamma=0.001)


def _toolkit_delay_run(
    arm: Path, h: float, ticks: int, controller, delay=None, t_c: float = T_C
) -> np.ndarray:
    """The same loop run by :func:`simulate`, the arm stepped by MuJoCo, under a constant delay
    ``h`` (or the profile ``delay``); the states at the ticks."""
    return dt.simulate(
        MujocoPlant(arm, stepping="mujoco"),
        controller,
        dt.ConstantDelay(h) if delay is None else delay,
        X0,
        reference=REFERENCE,
        t1=ticks * t_c,
        dt=DT,
        T_c=t_c,
    ).x[0, :ticks]


@pytest.mark.parametrize("h", [0.0, DT, 0.03, 0.0305])
def test_the_delay_agrees_with_mujocos_own_actuator_delay(h):
    controller = _arolc_on_the_light_arm()
    ticks = 1000
    ours = _toolkit_delay_run(ARM, h, ticks, controller)
    np.testing.assert_array_equal(ours, _native_delay_run(h, ticks, controller, True))
    # MuJoCo's own clock adds dt at each step; a delay that is not a whole number of steps
    # never meets a tie, so even that clock agrees bit for bit.
    if round(h / DT) * DT != h:
        np.testing.assert_array_equal(ours, _native_delay_run(h, ticks, controller, False))


def test_under_a_time_varying_delay_each_step_holds_the_command_in_force_at_its_start():
    """The rule for a plant stepped by its own integrator, restated in plain Python: each step
    from ``t = i dt`` holds the command of the latest tick ``k T_c <= t - h(t) + 1e-9 dt``
    (``u_init = 0`` before the first), under S1 and the paper's ``T_c`` = 10 ms: the only
    independent check of the rule under a time-varying delay (MuJoCo's own actuator delay,
    above, is constant)."""
    import math

    controller, t_c, ticks = _arolc_on_the_light_arm(), 0.01, 150
    steps = round(t_c / DT)
    engine = _toolkit_delay_run(ARM, 0.0, ticks, controller, dt.AbsSineDelay.S1(), t_c)
    model = mujoco.MjModel.from_xml_path(str(ARM))
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = X0[:3], X0[3:]
    state, commands, states, held = controller.initial_state(), [], [], -1
    for i in range(ticks * steps):
        if i % steps == 0:
            k = i // steps
            reference = tuple(array[0] for array in REFERENCE.evaluate(np.array([k * steps * DT])))
            states.append(np.concatenate([data.qpos, data.qvel]))
            command, state = controller.step(
                k * steps * DT, data.qpos.copy(), data.qvel.copy(), reference, state, T_c=t_c
            )
            commands.append(command)
        t = i * DT
        g = t - (0.02 + 0.08 * abs(math.sin(t))) + 1e-9 * DT
        while (held + 1) * steps * DT <= g:
            held += 1
        data.ctrl[:] = commands[held] if held >= 0 else 0.0
        data.time = t
        mujoco.mj_step(model, data)
    np.testing.assert_array_equal(engine, np.array(states))


def test_mujocos_own_delay_differs_under_its_rk4_integrator(tmp_path):
    """MuJoCo's actuator delay is this toolkit's rule only with one force evaluation per step
    (Euler, implicit, implicitfast: the test above). Under ``integrator="RK4"``,
    ``mj_fwdActuation`` reads the delayed control at each stage's time while ``mj_advance``
    records the step's control only at its end, so the last stage (at ``t + dt``) already
    uses the command one step newer: the two loops part by millimetres of joint angle."""
    rk4 = _arm_with(
        tmp_path, '<option timestep="0.001"', '<option timestep="0.001" integrator="RK4"'
    )
    controller = _arolc_on_the_light_arm()
    ticks, h = 500, 0.03
    ours = _toolkit_delay_run(rk4, h, ticks, controller)
    native = _native_delay_run(h, ticks, controller, True, rk4)
    # Measured here: 4.0e-3 rad (h = 30 ms, 1 s), while the Euler arm above agrees bit for bit;
    # the threshold 1e-4 lies far above rounding (1e-12) and far below the measured part.
    assert np.max(np.abs(ours - native)) > 1e-4, np.max(np.abs(ours - native))
    # Without a delay there is no buffer to read at stage times: bit for bit again.
    np.testing.assert_array_equal(
        _toolkit_delay_run(rk4, 0.0, ticks, controller),
        _native_delay_run(0.0, ticks, controller, True, rk4),
    )


def test_stepped_by_mujoco_each_run_starts_afresh_and_dt_is_the_models(tmp_path):
    # A joint limit makes MuJoCo's solver warm-start from the step before: a run that did not
    # start from fresh data would differ from the same run alone.
    limited = _arm_with(tmp_path, '<joint name="wrist"/>', '<joint name="wrist" range="-0.1 0.1"/>')
    truth = MujocoPlant(limited, stepping="mujoco")
    controller = dt.OuterLoop(MujocoPlant(ARM, mass_scale=0.8), K1=16.0, K2=8.0)
    settings = dict(reference=REFERENCE, t1=0.4, dt=DT, T_c=T_C)
    alone = dt.simulate(truth, controller, dt.AbsSineDelay.S1(), X0, **settings)
    delays = [dt.ConstantDelay(0.05), dt.AbsSineDelay.S1()]
    batch = dt.simulate(truth, controller, delays, X0, workers=1, **settings)
    np.testing.assert_array_equal(batch.x[1], alone.x[0])
    python = dt.simulate(truth, controller, dt.AbsSineDelay.S1(), X0, engine="python", **settings)
    np.testing.assert_array_equal(python.x, alone.x)
    with pytest.raises(ValueError, match=r"dt = 0.0005 s disagrees with the timestep 0.001 s"):
        dt.simulate(truth, controller, dt.ConstantDelay(0.0), X0, **{**settings, "dt": 5e-4})
    assert dt.plant_from_spec(truth.to_spec()).stepping == "mujoco"


def test_stepped_by_mujoco_it_takes_what_the_plant_form_cannot(tmp_path):
    path = _arm_with(tmp_path, '<joint name="wrist"/>', '<joint name="wrist" range="-0.1 0.1"/>')
    with pytest.raises(ValueError, match="'wrist' has limits"):
        MujocoPlant(path)
    truth = MujocoPlant(path, stepping="mujoco")
    controller = dt.OuterLoop(MujocoPlant(ARM), K1=16.0, K2=8.0)
    result = dt.simulate(
        truth, controller, dt.ConstantDelay(0.0), X0, reference=REFERENCE, t1=2.0, dt=DT, T_c=T_C
    )
    # The reference swings the wrist by ±0.2 rad; the joint limit holds it near ±0.1 rad.
    wrist = result.x[0, :, 2]
    assert np.max(np.abs(wrist)) < 0.115 and result.status_names == ["ok"]


def test_the_urdf_example_runs_from_its_scenario_and_sweep(tmp_path):
    folder = tmp_path / "mujoco_urdf"
    shutil.copytree(EXAMPLE.parent / "mujoco_urdf", folder)
    scenario = Scenario.from_toml(folder / "two_link_S2.toml")
    built = scenario.build()
    assert built.plant.coordinate_names == ("shoulder", "elbow") and built.plant.m == 2
    data = scenario.to_dict()
    data["duration"] = 1.0
    data["reference"] = {**data["reference"], "times": [0.0, 0.5, 1.0]}
    data["reference"]["values"] = data["reference"]["values"][:3]
    (folder / "short.toml").write_text(Scenario.from_dict(data).to_toml())
    sweep = folder / "sweep_two_link.toml"
    text = sweep.read_text().replace("draws = 4", "draws = 1")
    sweep.write_text(text.replace('scenario = "two_link_S2.toml"', 'scenario = "short.toml"'))
    assert main(["sweep", str(sweep), "--out", str(tmp_path / "sweep"), "--quiet"]) == 0
    summary = pd.read_csv(tmp_path / "sweep" / "summary.csv")
    assert (summary["runs"] > 0).all() and (summary["diverged"] == 0).all()


def test_a_stepped_model_is_not_a_nominal_model_and_a_diverging_run_is_reported():
    stepped = MujocoPlant(ARM, stepping="mujoco")
    with pytest.raises(ValueError, match="nominal model must be a plant form"):
        dt.OuterLoop(stepped, K1=16.0, K2=8.0)
    # Gains far too high for the delay: the state grows until MuJoCo meets bad numbers, which
    # it would otherwise hide (a control beyond 1e10 set to zero, a bad state reset).
    wild = dt.OuterLoop(MujocoPlant(ARM), K1=4.0e4, K2=400.0)
    result = dt.simulate(
        stepped,
        wild,
        dt.ConstantDelay(0.05),
        X0,
        reference=REFERENCE,
        t1=4.0,
        dt=DT,
        T_c=T_C,
        divergence_bound=1e300,
    )
    assert result.status_names == ["diverged"] and result.t_stop[0] < 4.0


def _profiling_clock():
    """MuJoCo's ``mjcb_time`` slot, as an address."""
    import ctypes

    from delaytrack.plants.mujoco.capi import mujoco_library

    library = mujoco_library(os.path.dirname(mujoco.__file__))
    return ctypes.c_void_p.in_dll(library, "mjcb_time")


def _step_timer(plant: MujocoPlant) -> tuple[float, int]:
    """``(duration, number)`` of MuJoCo's profiler timer of ``mj_step`` in the plant's data."""
    timer = plant._data.timer[int(mujoco.mjtTimer.mjTIMER_STEP)]
    return float(timer.duration), int(timer.number)


def test_mujocos_profiling_clock_is_stopped_while_a_run_steps_it_and_given_back_after():
    """MuJoCo's Python bindings install a clock that MuJoCo reads twice a pipeline stage for its
    profiler; a run stops it (every step timed zero) and gives it back, on every thread of a
    batch and when a clock of the user's was installed."""
    clock = _profiling_clock()
    mujoco.MjData(mujoco.MjModel.from_xml_path(str(ARM)))  # the bindings install their clock
    bindings = clock.value
    assert bindings  # else there is nothing to stop
    truth = MujocoPlant(ARM, stepping="mujoco")
    controller = dt.OuterLoop(MujocoPlant(ARM, mass_scale=0.8), K1=16.0, K2=8.0)
    settings = dict(reference=REFERENCE, t1=0.2, dt=DT, T_c=T_C)
    delays = [dt.ConstantDelay(0.01), dt.ConstantDelay(0.02)]
    result = dt.simulate(truth, controller, delays, X0, workers=2, **settings)
    assert result.status_names == ["ok", "ok"]
    assert clock.value == bindings
    assert truth._copies  # the second thread stepped a copy of its own (a compiled batch)
    for plant in [truth, *truth._copies.values()]:
        duration, number = _step_timer(plant)
        assert number > 0 and duration == 0.0
    # The same steps outside a run are timed by the bindings' clock: what the run stopped.
    mujoco.mj_step(truth._model, truth._data)
    assert _step_timer(truth)[0] > 0.0
    # A clock of the user's, installed before a run, is theirs again after it.
    mujoco.set_mjcb_time(lambda: 1.0)
    try:
        yours = clock.value
        alone = dt.simulate(truth, controller, delays[0], X0, **settings)
        assert clock.value == yours
        np.testing.assert_array_equal(alone.x[0], result.x[0])
    finally:
        mujoco.set_mjcb_time(None)  # the bindings forget the user's clock, then get theirs back
        clock.value = bindings


_CONCURRENT = """
import ctypes, os, sys, threading
import mujoco
import numpy as np
import delaytrack as dt
from delaytrack.plants import MujocoPlant
from delaytrack.plants.mujoco.capi import mujoco_library

arm = sys.argv[1]
clock = ctypes.c_void_p.in_dll(mujoco_library(os.path.dirname(mujoco.__file__)), "mjcb_time")
plants = [MujocoPlant(arm, stepping="mujoco") for _ in range(2)]
bindings = clock.value
# each run its own model: a MuJoCo model's data is written by every evaluation
controllers = [dt.OuterLoop(MujocoPlant(arm, mass_scale=0.8), K1=16.0, K2=8.0) for _ in range(2)]
reference = dt.SinusoidalReference([0.0, 0.3, 0.0], amplitude=[[0.5], [0.3], [0.2]],
                                   frequency=[[1.0], [1.3], [0.7]])
start = threading.Barrier(2)
results = [None, None]

def run(i):
    start.wait()
    results[i] = dt.simulate(plants[i], controllers[i], dt.ConstantDelay(0.01 * (i + 1)),
                             np.zeros(6), reference=reference, t1=0.3, dt=1e-3, T_c=0.01,
                             workers=1, progress=False)

threads = [threading.Thread(target=run, args=(i,)) for i in range(2)]
for thread in threads:
    thread.start()
for thread in threads:
    thread.join()
print([r.status_names[0] for r in results], bool(bindings) and clock.value == bindings)
"""


def test_batches_on_two_threads_at_once_stop_the_clock_once_and_give_it_back(tmp_path):
    """Two simulations start together in a fresh process, where the stopped clock is not yet
    compiled: it is compiled once, both runs end, and the bindings' clock is back."""
    import subprocess
    import sys

    script = tmp_path / "two_batches.py"  # not concurrent.py: the module it would hide
    script.write_text(_CONCURRENT)
    for _ in range(3):  # a race: a few fresh processes
        done = subprocess.run(
            [sys.executable, str(script), str(ARM)],
            capture_output=True,
            text=True,
            timeout=600,
            env={**os.environ, "DELAYTRACK_INTERPRET_FIRST": "0"},
        )
        assert done.returncode == 0, done.stderr[-2000:]
        assert done.stdout.strip().splitlines()[-1] == "['ok', 'ok'] True", done.stdout


def test_mujocos_warnings_are_python_warnings_and_no_log_file_is_written(tmp_path, monkeypatch):
    """A diverging batch stepped by MuJoCo on two threads: MuJoCo's "unstable" warnings reach
    Python's warnings, and no ``MUJOCO_LOG.TXT`` appears in the current folder."""
    from delaytrack.sim.integrator import DIVERGED

    monkeypatch.chdir(tmp_path)
    controller = dt.OuterLoop(MujocoPlant(ARM, mass_scale=0.8), K1=1e9, K2=1e5)
    with pytest.warns(RuntimeWarning, match="MuJoCo: .*unstable") as caught:
        result = dt.simulate(
            MujocoPlant(ARM, stepping="mujoco"),
            controller,
            [dt.ConstantDelay(0.05), dt.ConstantDelay(0.06)],
            X0,
            reference=REFERENCE,
            t1=0.5,
            dt=DT,
            T_c=T_C,
            workers=2,
        )
    assert list(result.status) == [DIVERGED, DIVERGED]
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()
    # placed at MuJoCo: shown as one line, not under a line of the engine's code
    assert {(w.filename, w.lineno) for w in caught if "MuJoCo" in str(w.message)} == {("mujoco", 0)}
