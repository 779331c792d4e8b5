"""The robot bridge of the live loop (delaytrack.live.bridge): a robot of the user's in the robot
node instead of the simulated plant.

Three sessions run at once through ``delaytrack live run --bridge`` (one module fixture): the
example bridge (MuJoCo stepping the arm in a thread of its own) wrapped to record every call; the
same bridge whose ``read_state`` raises in the middle; and a factory that returns no bridge. Two
more commands are refused before any session starts. Nothing here asserts a timing: only exit
codes, one-line errors, the delay rule, order, and that what the node publishes and applies is
what the bridge read and was written.
"""

from __future__ import annotations

import csv
import html
import json
import re
import subprocess
import sys
import textwrap
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

pytest.importorskip("zenoh")
pytest.importorskip("mcap_ros2")
pytest.importorskip("mujoco")

from mcap.reader import make_reader  # noqa: E402
from mcap_ros2.decoder import DecoderFactory  # noqa: E402

from delaytrack.live.bridge import BridgeError, bridge_factory, load_bridge  # noqa: E402
from delaytrack.scenario import Scenario  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "examples" / "mujoco_arm" / "arm3_S1.toml"
EXAMPLE = ROOT / "examples" / "live" / "mujoco_bridge.py"
PYTHON = [sys.executable, "-m", "delaytrack.live"]

#: Bridges of the tests: the example recording every call, the example failing at 0.3 s, and
#: factories that return no bridge or a bridge of the wrong size. Each records what it was
#: called with in a JSON file beside this one when it is closed.
BRIDGES = f"""
import importlib.util
import json
from pathlib import Path

import numpy as np

from delaytrack.live.bridge import RobotBridge

_spec = importlib.util.spec_from_file_location("mujoco_bridge_example", {str(EXAMPLE)!r})
example = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(example)
HERE = Path(__file__).parent


class Recorded(RobotBridge):
    def __init__(self, inner, name, fail_at=None):
        self.inner, self.name, self.fail_at = inner, name, fail_at
        self.reads, self.writes = [], []

    def start(self):
        self.inner.start()

    def read_state(self, t):
        if self.fail_at is not None and t >= self.fail_at:
            raise ConnectionError("encoder link lost")
        q, qdot = self.inner.read_state(t)
        self.reads.append([t, *q.tolist(), *qdot.tolist()])
        return q, qdot

    def write_command(self, t, u):
        self.inner.write_command(t, u)
        self.writes.append([t, *u.tolist()])

    def close(self):
        self.inner.close()
        (HERE / self.name).write_text(json.dumps({{"reads": self.reads, "writes": self.writes}}))


def recorded(scenario, dt):
    return Recorded(example.make_bridge(scenario, dt), "recorded.json")


class JammedBrakes(Recorded):
    def close(self):
        super().close()
        raise RuntimeError("brakes jammed")


def jammed_brakes(scenario, dt):
    return JammedBrakes(example.make_bridge(scenario, dt), "jammed.json")


def failing(scenario, dt):
    return Recorded(example.make_bridge(scenario, dt), "failing.json", fail_at=0.3)


def not_a_bridge(scenario, dt):
    return 42


class TwoJoints(RobotBridge):
    closed = False

    def read_state(self, t):
        return np.zeros(2), np.zeros(2)

    def write_command(self, t, u):
        pass

    def close(self):
        TwoJoints.closed = True


def wrong_shapes(scenario, dt):
    return TwoJoints()


def not_finite(scenario, dt):
    bridge = TwoJoints()
    bridge.read_state = lambda t: (np.full(3, np.nan), np.zeros(3))
    return bridge


def raises(scenario, dt):
    raise RuntimeError("no robot on /dev/ttyUSB0")


def exits(scenario, dt):  # as a vendor's SDK may, when no device answers
    raise SystemExit("no device found")
"""


def _live(*arguments):
    return subprocess.Popen(
        [*PYTHON, *map(str, arguments)], stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )


def _rows(path):
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def _messages(path):
    """(topic, MCAP sequence, decoded message) of a finished MCAP file, with the public reader."""
    with open(path, "rb") as handle:
        reader = make_reader(handle, decoder_factories=[DecoderFactory()])
        return [
            (channel.topic, message.sequence, decoded)
            for _schema, channel, message, decoded in reader.iter_decoded_messages()
        ]


def _errors(stderr):
    return [line for line in stderr.decode().splitlines() if line.startswith("error:")]


@pytest.fixture(scope="module")
def bridges_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("bridge") / "bridges.py"
    path.write_text(textwrap.dedent(BRIDGES))
    return path


@pytest.fixture(scope="module")
def sessions(bridges_file):
    root = bridges_file.parent
    # The controller's step for this arm, compiled here: on a cold cache the three sessions'
    # controller nodes would each compile it at once; they load it instead.
    from delaytrack.live.controller import ControllerNode

    scenario = Scenario.from_toml(SCENARIO)
    options = SimpleNamespace(
        duration=1.0, out=root, quiet=True, phase=None, state_timeout=None, stale="hold"
    )
    ControllerNode(scenario, scenario.build(), options)
    bridge = f"{root / 'bridges.py'}:"
    running = {
        "good": _live("run", SCENARIO, "--duration", "1.5", "--bridge", f"{bridge}recorded",
                      "--out", root / "good", "--quiet"),
        "failing": _live("run", SCENARIO, "--duration", "3", "--bridge", f"{bridge}failing",
                         "--out", root / "failing", "--quiet"),
        "jammed_brakes": _live("run", SCENARIO, "--duration", "1", "--bridge",
                               f"{bridge}jammed_brakes", "--out", root / "jammed", "--quiet"),
        "not_a_bridge": _live("run", SCENARIO, "--duration", "3", "--bridge",
                              f"{bridge}not_a_bridge", "--out", root / "none", "--quiet"),
        "no_file": _live("run", SCENARIO, "--bridge", f"{root}/nothing.py:make",
                         "--out", root / "no_file"),
        "wrong_shapes": _live("robot", SCENARIO, "--bridge", f"{bridge}wrong_shapes",
                              "--out", root / "shapes"),
    }  # fmt: skip
    results = {name: (*p.communicate(timeout=300), p.returncode) for name, p in running.items()}
    return root, results


def test_a_session_with_the_example_bridge_runs_and_every_node_exits_cleanly(sessions):
    root, results = sessions
    _stdout, stderr, code = results["good"]
    assert code == 0, stderr.decode()
    summary = json.loads((root / "good" / "summary.json").read_text())
    assert summary["exit_codes"] == {"robot": 0, "delay": 0, "controller": 0}
    robot = json.loads((root / "good" / "robot.json").read_text())
    assert robot["bridge"].endswith("bridges.py:recorded") and robot["failure"] is None


def test_a_bridge_whose_close_raises_fails_the_node_in_one_line_with_its_tables_written(
    sessions,
):
    root, results = sessions
    _stdout, stderr, code = results["jammed_brakes"]
    folder = root / "jammed"
    assert code == 1 and "Traceback" not in stderr.decode(), stderr.decode()
    assert [line for line in _errors(stderr) if "close()" in line] == [
        "error: JammedBrakes.close() raised RuntimeError: brakes jammed; the robot may still "
        "hold its last input"
    ]
    robot = json.loads((folder / "robot.json").read_text())
    assert robot["stopped_by"] == "failure" and "brakes jammed" in robot["failure"]
    assert len(_rows(folder / "states.csv")) > 0 and (folder / "report.html").is_file()
    # After the session's end: said so, not that it stopped the session early, and the
    # tracking measured over the whole session.
    assert robot["failed_when_closed"] is True and robot["steps"] == 1000
    stdout = _stdout.decode()
    assert "its bridge failed when closed, after the session: JammedBrakes.close()" in stdout
    assert "stopped the session early" not in stdout
    assert [r["status"] for r in _rows(folder / "metrics.csv")] == ["ok"]


def test_the_bridge_is_written_the_released_commands_under_the_delay_rule_in_order(sessions):
    """Every step the node woke for is written once (a missed one is not), with the command the
    delay node released for it or zeros; each applied command satisfies t_k <= t - h(t)."""
    root, _ = sessions
    scenario = Scenario.from_toml(SCENARIO)
    delay, dt = scenario.build().delay, scenario.dt
    writes = json.loads((root / "recorded.json").read_text())["writes"]
    times = [w[0] for w in writes]
    assert times == sorted(set(times)) and times
    steps = _rows(root / "good" / "steps.csv")
    assert times == [float(r["t_s"]) for r in steps if r["status"] != "missed"]
    applied = [m for topic, _, m in _messages(root / "good" / "robot.mcap") if topic == "/applied"]
    seqs = [m.seq for m in applied]
    assert seqs == sorted(set(seqs)) and seqs  # S1 never makes t - h(t) run backwards
    t = np.array([m.apply_at for m in applied])
    t_k = np.array([m.sample_time for m in applied])
    assert np.all(t_k <= t - delay.h(t) + 1e-9 * dt)
    status = {float(r["t_s"]): r["status"] for r in steps}
    in_force = None
    by_step = {m.apply_at: m for m in applied}
    for time, *u in writes:
        in_force = by_step.get(time, in_force)
        if status[time] == "ok":
            assert u == list(in_force.command)  # arm3 has no input limits
        else:
            assert status[time] in ("no-command", "timeout-zero") and not any(u)


def test_the_state_the_controller_received_is_what_the_bridge_read(sessions):
    root, _ = sessions
    dt = Scenario.from_toml(SCENARIO).dt
    reads = json.loads((root / "recorded.json").read_text())["reads"]
    read_at = {round(r[0] / dt): r[1:] for r in reads}
    published = [
        (j, [*m.position, *m.velocity])
        for topic, j, m in _messages(root / "good" / "robot.mcap")
        if topic == "/state"
    ]
    assert published and all(x == read_at[j] for j, x in published)
    controller = _messages(root / "good" / "controller.mcap")
    read_values = {tuple(x) for x in read_at.values()}
    received = [tuple([*m.position, *m.velocity]) for t, _, m in controller if t == "/received"]
    assert received and set(received) <= read_values
    used = {round(m.state_time / dt) for t, _, m in controller if t == "/command"}
    assert used and used <= set(read_at)


def test_a_bridge_that_fails_mid_session_stops_the_robot_node_cleanly(sessions):
    """Its read_state raises from t = 0.3 s on (at the first step the node wakes for then)."""
    root, results = sessions
    _stdout, stderr, code = results["failing"]
    folder = root / "failing"
    summary = json.loads((folder / "summary.json").read_text())
    assert code == 1 and summary["exit_codes"] == {"robot": 1, "delay": 0, "controller": 0}
    robot_error = [line for line in _errors(stderr) if "the robot failed" in line]
    assert len(robot_error) == 1, stderr.decode()
    found = re.fullmatch(
        r"error: the robot failed at t = \S+ s \(step (\d+)\): Recorded\.read_state raised "
        r"ConnectionError: encoder link lost; the robot node stops \(exit code 1\), its log "
        r"and tables up to there are written",
        robot_error[0],
    )
    assert found, robot_error
    failed_at = int(found[1])
    robot = json.loads((folder / "robot.json").read_text())
    assert robot["stopped_by"] == "failure" and "encoder link lost" in robot["failure"]
    # The report says so: the metrics are the tracking up to the failure, not an "ok" run.
    assert [r["status"] for r in _rows(folder / "metrics.csv")] == ["robot failed"]
    report = html.unescape((folder / "report.html").read_text())
    assert "robot: failure: Recorded.read_state raised ConnectionError: encoder link lost" in report
    steps = _rows(folder / "steps.csv")
    assert [int(r["j"]) for r in steps] == list(range(failed_at)) and failed_at >= 300
    woken = [int(r["j"]) for r in steps if r["status"] != "missed"]
    states = [j for topic, j, _ in _messages(folder / "robot.mcap") if topic == "/state"]
    assert states == [j for j in woken if j % 2 == 0]  # the finished log, up to the failure
    calls = json.loads((root / "failing.json").read_text())  # written by close()
    assert len(calls["reads"]) == len(woken) + 1  # and the read that checked the bridge
    assert [w[0] for w in calls["writes"]] == [j * 0.001 for j in woken]


@pytest.mark.parametrize("name", ["not_a_bridge", "no_file", "wrong_shapes"])
def test_a_bad_bridge_is_refused_in_one_line_with_exit_code_2(sessions, name):
    _root, results = sessions
    _stdout, stderr, code = results[name]
    errors = _errors(stderr)
    assert code == 2 and len(errors) == 1, stderr.decode()
    assert errors[0].startswith("error: --bridge '") and "Traceback" not in stderr.decode()


@pytest.mark.parametrize(
    ("function", "expected"),
    [
        ("not_a_bridge", "not_a_bridge(scenario, dt) returned int, not a RobotBridge"),
        ("wrong_shapes", "read_state returned q of shape (2,) and q̇ of shape (2,)"),
        ("not_finite", "read_state returned a state that is not finite"),
        ("raises", "raises(scenario, dt) raised RuntimeError: no robot on /dev/ttyUSB0"),
        ("exits", "exits(scenario, dt) raised SystemExit: no device found"),
        (
            "missing",
            "has no function 'missing' (its functions: exits, failing, jammed_brakes, not_a",
        ),
    ],
)
def test_bridge_errors_name_the_option_the_value_and_what_is_valid(
    bridges_file, function, expected
):
    scenario = Scenario.from_toml(SCENARIO)
    value = f"{bridges_file}:{function}"
    with pytest.raises(BridgeError) as raised:
        load_bridge(value, scenario, scenario.dt, 3)
    message = str(raised.value)
    assert message.startswith(f"--bridge {value!r}: ") and expected in message
    assert "\n" not in message


def test_a_refused_bridge_is_closed(bridges_file):
    from delaytrack._spec import module_from_file

    module = module_from_file(bridges_file)
    module.TwoJoints.closed = False
    scenario = Scenario.from_toml(SCENARIO)
    with pytest.raises(BridgeError):
        load_bridge(f"{bridges_file}:wrong_shapes", scenario, scenario.dt, 3)
    assert module.TwoJoints.closed


@pytest.mark.parametrize("value", ["bridges.py", "bridges:make", "bridges.py:2make", ":make"])
def test_a_bridge_value_of_another_form_is_refused(value):
    with pytest.raises(BridgeError, match=r"^--bridge .* must be FILE\.py:FUNCTION"):
        bridge_factory(value)


def test_the_example_bridge_refuses_a_scenario_of_another_robot():
    from delaytrack.scenario import load_builtin

    with pytest.raises(BridgeError, match="drives the joints shoulder, elbow, wrist; the "):
        load_bridge(f"{EXAMPLE}:make_bridge", load_builtin("two_link_S1"), 0.001, 2)


def test_the_simulated_robot_stops_on_a_state_that_is_not_finite():
    """The default bridge raises (and the node stops with exit code 1) instead of going on."""
    from delaytrack.live.robot import SimulatedRobot, SimulatedRobotDiverged
    from delaytrack.scenario import load_builtin

    scenario = load_builtin("two_link_S1")
    built = scenario.build()
    robot = SimulatedRobot(built.plant, scenario.dt, built.x0)
    robot.write_command(0.0, np.array([1.0, -1.0]))
    q, qdot = robot.read_state(0.001)
    assert np.all(np.isfinite(q)) and np.any(qdot != 0.0)
    # The loop's divergence, told apart from a driver's fault (the node says "diverged").
    with pytest.raises(SimulatedRobotDiverged, match="not finite .* in the step from t = 0.001 s"):
        robot.write_command(0.001, np.array([np.inf, 0.0]))


def test_the_summary_says_when_the_robot_stopped_the_session_early():
    from delaytrack.live.session import _robot_stop_text

    assert _robot_stop_text({"failure": None, "diverged": False}) == ""
    assert _robot_stop_text({"failure": "its state is not finite", "diverged": True}) == (
        "; it diverged and stopped the session early: its state is not finite"
    )
    assert _robot_stop_text({"failure": "Recorded.read_state raised ConnectionError: x"}) == (
        "; it failed and stopped the session early: Recorded.read_state raised ConnectionError: x"
    )
