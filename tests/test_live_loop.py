"""The live loop end to end: three node processes over Zenoh on loopback (delaytrack.live).

Three sessions run at once (one module fixture, to keep the wall time down): a normal
``delaytrack live run`` (``live_run`` of tests/conftest.py); a controller and a robot started
with scenarios that differ in ``T_c``; and a session with packet loss whose robot node is killed
with SIGKILL in the middle. Nothing here asserts a timing: only order, completeness, the delay
rule, exit codes and readable logs.
"""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from ports import free_ports

pytest.importorskip("zenoh")
pytest.importorskip("mcap_ros2")

from mcap.exceptions import EndOfFile  # noqa: E402
from mcap.reader import NonSeekingReader, make_reader  # noqa: E402
from mcap_ros2.decoder import DecoderFactory  # noqa: E402

from delaytrack.scenario import load_builtin  # noqa: E402
from delaytrack.sim.packet_loss import packet_lost  # noqa: E402

SCENARIO = "two_link_S1"
PYTHON = [sys.executable, "-m", "delaytrack.live"]


def _node(role, scenario, out, session, listen, connect, *extra):
    command = [
        *PYTHON,
        role,
        str(scenario),
        "--out",
        str(out),
        "--session",
        session,
        "--listen",
        f"tcp/127.0.0.1:{listen}",
        "--handshake-timeout",
        "40",
        "--quiet",
    ]
    for port in connect:
        command += ["--connect", f"tcp/127.0.0.1:{port}"]
    return subprocess.Popen([*command, *extra], stdout=subprocess.PIPE, stderr=subprocess.PIPE)


def _rows(path):
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def _messages(path, *, finished=True):
    """Decoded messages of an MCAP file with the public readers: (topic, message)."""
    out = []
    with open(path, "rb") as handle:
        if finished:
            reader = make_reader(handle, decoder_factories=[DecoderFactory()])
            for _schema, channel, _message, decoded in reader.iter_decoded_messages():
                out.append((channel.topic, decoded))
        else:
            reader = NonSeekingReader(handle, decoder_factories=[DecoderFactory()])
            try:
                for _schema, channel, _message, decoded in reader.iter_decoded_messages(
                    log_time_order=False
                ):
                    out.append((channel.topic, decoded))
            except EndOfFile:  # the cut where the process was killed
                pass
    return out


@pytest.fixture(scope="module")
def sessions(live_run, tmp_path_factory):
    root = tmp_path_factory.mktemp("live")
    env_ports = free_ports(5)
    # 1. A normal session through the launcher (tests/conftest.py, shared with
    # test_live_status.py, which reads its status line).
    run_out, run = live_run
    # 2. Two nodes whose scenarios differ in T_c.
    other = root / "other_T_c.toml"
    load_builtin(SCENARIO).replace(T_c=0.004).to_toml(other)
    mismatch = [
        _node("robot", SCENARIO, root / "mismatch", "mm", env_ports[0], []),
        _node("controller", other, root / "mismatch", "mm", env_ports[1], [env_ports[0]]),
    ]
    # 3. A session with packet loss whose robot is killed in the middle.
    kill_out = root / "kill"
    p = env_ports[2:]
    kill = {
        "robot": _node("robot", SCENARIO, kill_out, "kill", p[0], [], "--duration", "3"),
        "delay": _node(
            "delay",
            SCENARIO,
            kill_out,
            "kill",
            p[1],
            [p[0]],
            "--duration",
            "3",
            "--loss",
            "0.2",
            "--loss-seed",
            "7",
        ),
        "controller": _node(
            "controller", SCENARIO, kill_out, "kill", p[2], [p[0], p[1]], "--duration", "3"
        ),
    }
    deadline = time.monotonic() + 90
    robot_log = kill_out / "robot.mcap"
    while time.monotonic() < deadline:  # kill once the robot has logged a while
        if robot_log.exists() and robot_log.stat().st_size > 40_000:
            break
        time.sleep(0.05)
    os.kill(kill["robot"].pid, signal.SIGKILL)
    stdout, stderr, run_code = run.outcome
    results = {
        "run": (run_out, (stdout, stderr)),
        "run_code": run_code,
        "mismatch": [(m.communicate(timeout=120), m.returncode) for m in mismatch],
        "kill": (
            kill_out,
            {r: (n.communicate(timeout=120), n.returncode) for r, n in kill.items()},
        ),
    }
    return results


def test_a_session_runs_and_every_node_exits_cleanly(sessions):
    folder, (stdout, stderr) = sessions["run"]
    assert sessions["run_code"] == 0, stderr.decode()
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["exit_codes"] == {"robot": 0, "delay": 0, "controller": 0}
    for name in ("controller.mcap", "delay.mcap", "robot.mcap", "ticks.csv", "delays.csv"):
        assert (folder / name).is_file(), name
    for name in ("summary.json", "controller.json", "delay.json", "robot.json"):
        json.loads((folder / name).read_text(), parse_constant=_not_json)  # strict JSON


def test_the_nodes_import_no_module_of_the_working_folder(sessions, live_run):
    # The launcher ran from a folder of files named like modules the nodes import
    # (tests/conftest.py): a file a user was sent beside a scenario must not run.
    folder, _ = live_run
    working = folder.parent / "working"
    assert sorted(working.glob("*.py"))  # the files were there
    assert not (working / "imported").exists(), (working / "imported").read_text()


def _not_json(constant: str) -> None:
    raise AssertionError(f"{constant} is not JSON")


def test_commands_keep_their_order_and_none_is_lost_without_packet_loss(sessions):
    folder, _ = sessions["run"]
    ticks = [int(r["k"]) for r in _rows(folder / "ticks.csv")]
    assert ticks == sorted(set(ticks))  # sequence numbers increase
    sent = {
        int(r["k"]): float(r["send_s"])
        for r in _rows(folder / "ticks.csv")
        if r["status"] != "no-state"
    }
    received = _rows(folder / "releases.csv")
    seqs = {int(r["seq"]) for r in received}
    assert seqs <= set(sent)
    # Every command sent while the delay node's loop ran reaches it; one sent after its end is
    # taken in only if it arrives within the node's last second (a loaded machine may miss it).
    delay_end = json.loads((folder / "delay.json").read_text())["session_s"]
    assert {k for k, send in sent.items() if send <= delay_end} <= seqs
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["not_received"] == 0
    # Every command is accounted for, once
    parts = ("applied", "lost", "not_received", "sent_after_listening", "never_applied")
    parts += ("superseded_on_the_step_grid", "due_after_the_end")
    assert summary["commands"] == sum(summary[name] for name in parts), summary
    assert summary["applied"] == len(
        {m.seq for t, m in _messages(folder / "robot.mcap") if t == "/applied"}
    )
    # Never applied before the rule allows it: no better than the rule on the step grid alone.
    rule = summary["realised_minus_h_abs_ms_p99_of_the_rule"]
    assert 0 < rule <= summary["realised_minus_h_abs_ms_p99"] + 1e-9
    assert all(r["lost"] == "0" for r in received)
    arrival = [float(r["received_s"]) for r in sorted(received, key=lambda r: int(r["seq"]))]
    assert arrival == sorted(arrival)
    applied = [m.seq for topic, m in _messages(folder / "robot.mcap") if topic == "/applied"]
    assert applied == sorted(applied) and applied  # S1 never makes t - h(t) run backwards


def test_every_applied_command_respects_the_delay_rule(sessions):
    """From the robot's MCAP log: each command is applied at a step t with t_k <= t - h(t)."""
    folder, _ = sessions["run"]
    delay = load_builtin(SCENARIO).build().delay
    dt = load_builtin(SCENARIO).dt
    applied = [m for topic, m in _messages(folder / "robot.mcap") if topic == "/applied"]
    t = np.array([m.apply_at for m in applied])
    t_k = np.array([m.sample_time for m in applied])
    assert np.all(t_k <= t - delay.h(t) + 1e-9 * dt)
    states = [m for topic, m in _messages(folder / "robot.mcap") if topic == "/state"]
    assert states and len(states[0].position) == 2


def test_scenarios_that_differ_are_refused_at_the_handshake(sessions):
    for (_stdout, stderr), code in sessions["mismatch"]:
        assert code == 2
        # One line of error (after a first compile's notice, when the cache was cold).
        lines = [x for x in stderr.decode().strip().splitlines() if "compiling" not in x]
        assert len(lines) == 1
        assert "runs another scenario" in lines[0] and "T_c" in lines[0]


def test_a_killed_node_leaves_a_readable_log_and_the_others_finish(sessions):
    folder, nodes = sessions["kill"]
    assert nodes["robot"][1] == -signal.SIGKILL
    assert nodes["controller"][1] == 0 and nodes["delay"][1] == 0
    states = [
        m for topic, m in _messages(folder / "robot.mcap", finished=False) if topic == "/state"
    ]
    assert states, "the killed robot's log holds no state"
    seqs = [s.header.stamp.sec * 10**9 + s.header.stamp.nanosec for s in states]
    assert seqs == sorted(seqs)


def test_the_summary_of_a_session_whose_robot_left_no_steps_counts_no_command_by_step(sessions):
    """The killed robot wrote no step table: the session's end on the step grid is unknown, so
    whether a command came due before it is too (every command was counted "not due before
    the end", the session taken to have ended at t = 0)."""
    from delaytrack.live.session import collect, format_summary

    folder, _ = sessions["kill"]
    assert not (folder / "steps.csv").exists()
    scenario = load_builtin(SCENARIO)
    summary = collect(folder, scenario, scenario.build())
    assert summary["commands"] > 0
    counts = ("never_applied", "superseded_on_the_step_grid", "due_after_the_end")
    assert [summary[name] for name in counts] == [None, None, None]
    text = format_summary(summary, folder)
    assert "commands never applied: n/a (the robot node logged no step table)" in text
    assert "not due before the end" not in text


def test_packet_loss_drops_the_commands_the_toolkit_draws(sessions):
    folder, _ = sessions["kill"]
    rows = _rows(folder / "releases.csv")
    assert rows
    loss = np.array([0.2, 7.0])
    for row in rows:
        assert row["lost"] == str(int(bool(packet_lost(int(row["seq"]), loss))))
        if row["lost"] == "1":
            assert row["released_s"] == "nan"
    assert any(r["lost"] == "1" for r in rows)


def test_the_compiled_robot_step_is_the_python_rk4_step():
    """The robot node's compiled step (the engine's RK4 sub-step) gives the plain-Python RK4
    step's numbers on random states (on the robot's constraints) and inputs."""
    from delaytrack.live.robot import PlantStepper
    from delaytrack.sim._kernel_checks import velocities_on_constraints

    scenario = load_builtin(SCENARIO)
    built = scenario.build()
    stepper = PlantStepper(built.plant, scenario.dt, built.x0)
    assert stepper.compiled
    rng = np.random.default_rng(36)
    for _ in range(5):
        x = built.x0 + 0.5 * rng.standard_normal(built.x0.size)
        if built.plant.engine_kernel.reduced is not None:  # a state the robot can have
            x[built.plant.n :] = velocities_on_constraints(built.plant, x)
        u = 3.0 * rng.standard_normal(built.plant.m)
        t = float(rng.uniform(0.0, 5.0))
        expected = stepper.python_step(t, x, u, scenario.dt)
        stepper.x[:], stepper.u[:] = x, u
        assert stepper.step(t)
        np.testing.assert_allclose(stepper.x, expected, rtol=1e-12, atol=1e-12)
    stepper.x[:] = np.nan
    assert not stepper.step(0.0)  # a non-finite state is reported


def test_the_delay_nodes_plan_is_the_rule_evaluated_step_by_step(tmp_path):
    """The delay node sleeps until the next step where the rule's pick changes: that step is
    the first one where the latest held command with t_k <= s - h(s) differs from the last
    released, as evaluating the rule at every step finds it (D42)."""
    from types import SimpleNamespace

    from delaytrack.live.delay import DelayNode
    from delaytrack.live.messages import CommandMessage

    scenario = load_builtin(SCENARIO)
    args = SimpleNamespace(duration=3.0, out=tmp_path, quiet=True, loss=None, lead=None)
    node = DelayNode(scenario, scenario.build(), args)
    dt, delay = scenario.dt, scenario.build().delay
    for k in range(0, 400, 3):  # some commands missing, as with losses
        node._held_times.append(k * scenario.T_c)
        node._held.append(CommandMessage(k, k * scenario.T_c, 0.0, 0.0, 0, np.zeros(2)))
    times, held = node._held_times, node._held
    last, start = None, 0
    for _ in range(60):
        change, reach = node._next_change(start, start + 100, last)
        expected = None
        for j in range(start, start + 100):
            s = j * dt
            i = int(np.searchsorted(times, s - float(delay.h(s)) + 1e-9 * dt, side="right")) - 1
            if i >= 0 and held[i].seq != last:
                expected = j
                break
        assert change == expected
        stop_at = start + 100 if change is None else change
        g = [j * dt - float(delay.h(j * dt)) for j in range(start, stop_at)]
        assert reach == (max(g) + 1e-9 * dt if g else -np.inf)
        if change is None:
            start += 100
        else:
            s = change * dt
            last = held[int(np.searchsorted(times, s - delay.h(s) + 1e-9 * dt, "right")) - 1].seq
            start = change + 1


def test_the_session_writes_metrics_figures_and_a_report(sessions):
    import pandas as pd

    folder, _ = sessions["run"]
    metrics = pd.read_csv(folder / "metrics.csv")
    assert list(metrics["label"]) == ["live"] and list(metrics["status"]) == ["ok"]
    for prefix in ("ae", "rms", "max"):  # the two-link arm's joints are in radians
        for joint in ("q1", "q2"):
            column = f"{prefix}_{joint}_rad"
            assert column in metrics.columns
            assert np.isfinite(metrics.loc[0, column]) and metrics.loc[0, column] >= 0
    assert "tv_Nm" in metrics.columns
    # The session's own tables name the joints and the torques with their units too.
    headers = {
        name: (folder / name).read_text().splitlines()[0].split(",")
        for name in ("states.csv", "ticks.csv", "steps.csv")
    }
    assert headers["states.csv"] == ["j", "t_s", "q1_rad", "q2_rad"] + [
        "q1_dot_rad_per_s",
        "q2_dot_rad_per_s",
    ]
    assert headers["ticks.csv"][-2:] == headers["steps.csv"][-2:] == ["u1_Nm", "u2_Nm"]
    # The commands' TV counts from the first command sent, not from zero before it (at the
    # ticks before the first state the controller sends nothing): the sum over the ticks the
    # robot logged, each holding the latest command sent by then.
    summary = json.loads((folder / "summary.json").read_text())
    steps_per_tick = round(summary["T_c_s"] / summary["dt_s"])
    logged = sorted(
        {
            int(r["j"]) // steps_per_tick
            for r in _rows(folder / "states.csv")
            if int(r["j"]) % steps_per_tick == 0
        }
    )
    sent = {
        int(r["k"]): (float(r["u1_Nm"]), float(r["u2_Nm"]))
        for r in _rows(folder / "ticks.csv")
        if r["status"] != "no-state"
    }
    held, series = None, []
    for k in logged:
        held = sent.get(k, held)
        if held is not None:
            series.append(held)
    expected = float(np.abs(np.diff(np.array(series), axis=0)).sum())
    assert metrics.loc[0, "tv_Nm"] == pytest.approx(expected, rel=1e-9)
    figures = ("tracking", "error", "commands", "delay", "timing")  # the report's figures
    for name in figures:
        assert (folder / "figures" / f"{name}.png").read_bytes().startswith(b"\x89PNG")
    html = (folder / "report.html").read_text()  # each figure embedded once
    assert html.count("data:image/png;base64,") == len(figures) and "realised delay" in html

    from delaytrack._output import MANIFEST

    listed = json.loads((folder / MANIFEST).read_text())["files"]
    assert "figures/delay.png" in listed and "report.html" in listed


def test_the_report_says_where_the_live_error_passed_the_scenarios_error_bound():
    """``simulate`` stops a run whose tracking error leaves ``error_bound`` ("left the path");
    a live session runs on, and says where it passed the bound."""
    from types import SimpleNamespace

    from delaytrack.live.report import error_bound_text

    plant = SimpleNamespace(n=2, coordinate_names=None, coordinate_units=("rad", "rad"))
    e1 = np.array([[[0.01, 0.0], [0.02, 0.02], [0.06, 0.3], [0.01, 0.0]]])
    live = SimpleNamespace(e1=e1, t=np.array([0.0, 0.002, 0.004, 0.006]))
    bounded = SimpleNamespace(simulated_error_bound=(0.05, 1.0))
    assert error_bound_text(live, bounded, plant) == (
        "the tracking error passed the scenario's error_bound (q1 0.05 rad) at t = 0.004 s, "
        "where simulate stops a run as 'left the path'; the live session is not stopped by it "
        "and ran on (its metrics cover the whole session)"
    )
    both = SimpleNamespace(simulated_error_bound=0.01)
    assert "(q1 0.01 rad, q2 0.01 rad) at t = 0.002 s" in error_bound_text(live, both, plant)
    unbounded = SimpleNamespace(simulated_error_bound=np.inf)
    assert error_bound_text(live, unbounded, plant) is None
