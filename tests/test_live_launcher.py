"""``delaytrack live run``'s launcher, without a session: what it removes of an earlier session,
how it stops a node that does not end, how its nodes end with it, and what its summary says of
a node that wrote no record."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from delaytrack._output import MANIFEST, claim_output_folder
from delaytrack.live import session as session_module
from delaytrack.live._node import EXIT_PORT_TAKEN, LAUNCHER_PID, StopFlag, end_with_launcher
from delaytrack.live._tables import ROLE_FILES
from delaytrack.live.cli import main as live_main
from delaytrack.live.session import (
    SESSION_FILES,
    _remove_earlier_session,
    _wait_for_nodes,
    format_summary,
)


def test_an_earlier_sessions_files_are_removed_before_a_session_starts(tmp_path):
    """The session's own files, recorded or not (a session cut short); nothing else the folder's
    record lists."""
    folder = claim_output_folder(tmp_path / "session")
    (folder / "figures").mkdir()
    recorded = ["summary.json", "figures/tracking.png", "robot.json", "notes.csv"]
    unrecorded = ["steps.csv", "replay.json", "release_events.csv"]
    for name in recorded + unrecorded:
        (folder / name).write_text("from the session before")
    (folder / MANIFEST).write_text(json.dumps({"files": recorded}))
    _remove_earlier_session(folder)
    left = sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file())
    assert left == [MANIFEST, "notes.csv"]
    every_file = {*SESSION_FILES, *(name for names in ROLE_FILES.values() for name in names)}
    assert set(unrecorded) <= every_file


def test_a_node_recording_the_folder_removes_no_table_another_node_wrote_meanwhile(
    tmp_path, monkeypatch
):
    """The folder's record lists an earlier session's ``steps.csv``; the robot node renames its
    own into place just after a node that finished first listed the folder: that node records
    what it listed and removes nothing (it removed the new table as the earlier one's, and the
    session ended with exit code 0 and no steps)."""
    from delaytrack.live import _node

    folder = claim_output_folder(tmp_path / "session")
    (folder / MANIFEST).write_text(json.dumps({"files": ["steps.csv", "delay.json"]}))
    (folder / "delay.json").write_text("{}")
    listed = _node.session_files(folder)  # before the robot's table is there
    (folder / "steps.csv").write_text("k,t_s\n0,0.0\n")  # renamed into place meanwhile
    monkeypatch.setattr(_node, "session_files", lambda _folder: listed)
    _node.record_node_files(folder)
    assert (folder / "steps.csv").read_text() == "k,t_s\n0,0.0\n"
    assert json.loads((folder / MANIFEST).read_text())["files"] == ["delay.json"]


def _child(code: str, **options) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", textwrap.dedent(code)], **options)


def test_a_node_still_running_after_its_peers_ended_is_stopped_and_named(tmp_path):
    deaf = "import signal, time\nsignal.signal(signal.SIGTERM, signal.SIG_IGN)\ntime.sleep(60)"
    processes = {"controller": _child("pass"), "robot": _child(deaf)}
    stuck, why = _wait_for_nodes(processes, tmp_path, None, time.monotonic() + 600, grace=0.5)
    assert stuck == {"robot": "SIGTERM, then SIGKILL 5 s on"}
    assert why == "0.5 s after the controller node ended"
    assert processes["robot"].wait(timeout=10) == -signal.SIGKILL  # SIGTERM ignored


def test_the_nodes_of_a_launcher_stop_when_it_is_killed(tmp_path):
    """A launcher (a process that starts a node-like child with :data:`LAUNCHER_PID`) killed
    with SIGKILL: its child's stop flag is set (SIGTERM from the kernel) and it ends."""
    done = tmp_path / "stopped"
    node = f"""
        import time
        from delaytrack.live._node import StopFlag, end_with_launcher
        stop = StopFlag()
        stop.install()
        end_with_launcher(stop)
        deadline = time.monotonic() + 60
        while not stop() and time.monotonic() < deadline:
            time.sleep(0.02)
        from pathlib import Path
        Path({str(done)!r}).write_text(str(stop.signal))
    """
    launcher = f"""
        import os, subprocess, sys
        env = {{**os.environ, {LAUNCHER_PID!r}: str(os.getpid())}}
        child = subprocess.Popen([sys.executable, "-c", {textwrap.dedent(node)!r}], env=env)
        print(child.pid, flush=True)
        child.wait()
    """
    parent = _child(launcher, stdout=subprocess.PIPE, text=True)
    child = int(parent.stdout.readline())
    time.sleep(1.0)  # time to set its parent-death signal
    parent.kill()
    parent.wait()
    parent.stdout.close()
    deadline = time.monotonic() + 30
    while not done.exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert done.read_text() == str(int(signal.SIGTERM))
    with pytest.raises(ProcessLookupError):
        for _ in range(100):
            os.kill(child, 0)
            time.sleep(0.05)


def test_a_node_whose_launcher_is_gone_already_stops_at_once(monkeypatch):
    monkeypatch.setenv(LAUNCHER_PID, str(os.getppid() + 1))
    stop = StopFlag()
    end_with_launcher(stop)
    assert stop() and stop.signal == signal.SIGTERM


def test_a_stop_signal_that_comes_inside_the_handler_of_another_does_not_hang_the_node():
    """SIGINT, then SIGTERM microseconds later (Ctrl-C under ``live run``, which forwards
    SIGTERM), to 300 forked nodes' stop flags: the second handler may run inside the first. A
    handler that took a lock hung such a node for good within a few hundred pairs (tried). A
    node still running 10 s after the pair is hung."""
    child = """
        import os, signal, time
        from delaytrack.live._node import StopFlag
        for pair in range(300):
            ready, told = os.pipe()
            pid = os.fork()
            if pid == 0:
                stop = StopFlag()
                stop.install()
                os.write(told, b"r")
                while not stop():
                    pass
                os._exit(0)
            os.read(ready, 1)
            os.kill(pid, signal.SIGINT)
            until = time.perf_counter() + (pair % 40) * 2e-6
            while time.perf_counter() < until:
                pass
            os.kill(pid, signal.SIGTERM)
            deadline = time.monotonic() + 10.0
            while not os.waitpid(pid, os.WNOHANG)[0]:
                if time.monotonic() > deadline:
                    os.kill(pid, signal.SIGKILL)
                    raise SystemExit(f"pair {pair}: the node hung")
                time.sleep(0.001)
        print("done")
    """
    done = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(child)], capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0 and done.stdout == "done\n", done.stderr


def test_the_summary_says_a_node_wrote_no_record_rather_than_zeros():
    summary = {
        "scenario": "two_link_S1",
        "T_c_s": 0.002,
        "dt_s": 0.001,
        "never_applied": 0,
        "realised_minus_h_ms_p50": float("nan"),
        "realised_minus_h_abs_ms_p99": float("nan"),
        "nodes": {"controller": {"ticks": 5}, "delay": {"received": 5}, "robot": None},
    }
    text = format_summary(summary, Path("out"))
    assert "  robot: no record (robot.json): the node did not finish; robot.mcap holds" in text
    assert "commands never applied: n/a" in text and "controller: 5 ticks" in text
    assert "links between the nodes: controller: n/a; delay: n/a; robot: n/a" in text


def test_a_session_interrupted_before_it_starts_says_so_and_writes_no_summary(tmp_path):
    pytest.importorskip("zenoh")
    out = tmp_path / "out"
    command = [sys.executable, "-m", "delaytrack.live", "run", "two_link_S1", "--out", str(out)]
    launcher = subprocess.Popen(
        [*command, "--duration", "30", "--quiet"], stderr=subprocess.PIPE, text=True
    )
    deadline = time.monotonic() + 120
    while not (out / "scenario.toml").exists() and time.monotonic() < deadline:
        time.sleep(0.02)  # written just before the nodes start; they load for seconds
    launcher.send_signal(signal.SIGINT)
    _, stderr = launcher.communicate(timeout=120)
    assert launcher.returncode == 130, stderr
    # the last line, after a node's notice of a first compile, if any; no error, no traceback
    assert stderr.splitlines()[-1:] == ["interrupted before the session started"], stderr
    assert "Traceback" not in stderr and "error:" not in stderr, stderr
    assert not (out / "summary.json").exists() and not (out / "robot.mcap").exists()


def test_collect_keeps_the_launchers_facts_of_the_same_session_only(tmp_path):
    from delaytrack.live.session import _launcher_facts

    nodes = {"robot": {"steps": 3000, "lateness_ms_p99": None}, "delay": None}
    facts = {"exit_codes": {"robot": 0}, "wall_s": 14.0, "load_average": [1.0, 0.5, 0.2]}
    path = tmp_path / "summary.json"
    path.write_text(json.dumps({"nodes": nodes, **facts, "commands": 5}))
    assert _launcher_facts(path, nodes) == facts
    assert _launcher_facts(path, {**nodes, "robot": {"steps": 1000}}) == {}  # another session
    path.write_text("[1, 2]")
    assert _launcher_facts(path, nodes) == {}


def test_nodes_that_ran_for_different_lengths_are_said_to():
    """Nodes started with different --duration join one session: the summary says so."""
    from delaytrack.live.report import lengths_text, node_lengths

    nodes = {"robot": {"steps": 2000}, "controller": {"ticks": 2000}, "delay": {"session_s": 3.0}}
    lengths = node_lengths(nodes, 0.001, 0.002)
    assert lengths == {"robot": 2.0, "controller": 4.0, "delay": 3.0}
    text = lengths_text(lengths)
    assert text is not None and "robot 2 s, controller 4 s, delay 3 s" in text
    alike = {**nodes, "controller": {"ticks": 1000}, "delay": {"session_s": 2.003}}
    assert lengths_text(node_lengths(alike, 0.001, 0.002)) is None
    assert node_lengths({"robot": None}, 0.001, 0.002)["robot"] is None
    summary = {
        "scenario": "two_link_S1", "T_c_s": 0.002, "dt_s": 0.001, "never_applied": 0,
        "realised_minus_h_ms_p50": 0.0, "realised_minus_h_abs_ms_p99": 0.0,
        "nodes": nodes, "node_lengths_s": lengths,
    }  # fmt: skip
    assert "  warning: the nodes ran for different lengths" in format_summary(summary, Path("o"))


def _held_port() -> socket.socket:
    """A socket bound to a port of 127.0.0.1, as another program's connection holds its local
    port (not listening: a node connecting to it is refused at once, where a listener that
    never answers Zenoh's handshake would hold the node's close for Zenoh's 10 s timeout)."""
    held = socket.socket()
    held.bind(("127.0.0.1", 0))
    return held


@pytest.mark.parametrize(("picked", "code"), [(True, EXIT_PORT_TAKEN), (False, 2)])
def test_a_node_whose_port_is_taken_says_so_unless_the_launcher_picked_it(tmp_path, picked, code):
    """On ports the user gave, one line naming the endpoint; on ports ``live run`` picked,
    the exit code by which it picks again, and no message."""
    pytest.importorskip("zenoh")
    with _held_port() as held:
        endpoint = f"tcp/127.0.0.1:{held.getsockname()[1]}"
        command = ["robot", "two_link_S1", "--out", str(tmp_path / "robot"), "--quiet"]
        command += ["--listen", endpoint] + (["--picked-ports"] if picked else [])
        node = subprocess.run(
            [sys.executable, "-m", "delaytrack.live", *command], capture_output=True, timeout=120
        )
    assert node.returncode == code, node.stderr.decode()
    lines = node.stderr.decode().splitlines()
    if picked:
        assert lines == []
    else:
        assert len(lines) == 1 and lines[0].startswith("error: cannot open the Zenoh session")
        assert endpoint in lines[0] and "in use" in lines[0]


def _taking_ports(monkeypatch, held: socket.socket, times: int) -> list[list[int]]:
    """Make ``live run``'s first ``times`` picks of the nodes' ports give the robot the port
    ``held`` holds (as if another program took it in between); the picks, as made."""
    picks: list[list[int]] = []
    pick = session_module._free_ports

    def taking(count: int) -> list[int]:
        ports = pick(count)
        if count == 3 and len(picks) < times:
            ports[0] = held.getsockname()[1]
        picks.append(ports)
        return ports

    monkeypatch.setattr(session_module, "_free_ports", taking)
    return picks


def test_a_session_whose_picked_port_was_taken_starts_again_on_new_ports(
    tmp_path, monkeypatch, capfd
):
    pytest.importorskip("zenoh")
    pytest.importorskip("mcap_ros2")
    with _held_port() as held:
        picks = _taking_ports(monkeypatch, held, times=1)
        out = tmp_path / "run"
        code = live_main(["run", "two_link_S1", "--duration", "0.5", "--out", str(out), "--quiet"])
        taken = held.getsockname()[1]
    stderr = capfd.readouterr().err
    assert code == 0, stderr
    assert "error" not in stderr
    assert len(picks) == 2 and picks[0][0] == taken != picks[1][0]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["exit_codes"] == {"robot": 0, "delay": 0, "controller": 0}


def test_a_session_whose_picked_ports_are_taken_every_time_gives_up_in_one_line(
    tmp_path, monkeypatch, capsys
):
    """Each start's robot node exits as on a port taken (the nodes themselves: the test above
    and the one before it): picked again, :data:`PORT_ATTEMPTS` times, then one line."""
    pytest.importorskip("zenoh")
    starts = []

    def port_taken(commands, *_):
        starts.append(commands)
        assert all("--picked-ports" in command for command in commands.values())
        codes = {"robot": EXIT_PORT_TAKEN, "delay": 0, "controller": 0}
        return codes, [], time.monotonic(), ({}, "")

    monkeypatch.setattr(session_module, "_run_nodes", port_taken)
    out = tmp_path / "run"
    code = live_main(["run", "two_link_S1", "--duration", "0.5", "--out", str(out), "--quiet"])
    errors = [line for line in capsys.readouterr().err.splitlines() if line]
    assert code == 1 and len(starts) == session_module.PORT_ATTEMPTS == 5
    listened = {c[c.index("--listen") + 1] for start in starts for c in start.values()}
    assert len(listened) == 3 * len(starts)  # new ports each time
    assert errors == [
        "error: the session did not start: 5 times in a row, another program took a port "
        "picked for it before its node could listen on it; give free ports with --port"
    ]
    assert not (out / "summary.json").exists()
