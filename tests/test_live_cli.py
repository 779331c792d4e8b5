"""The live loop's command line and output folders, without a live session.

Every refusal here comes before the handshake (bad numbers when the options are read, a session
too long or a folder that is not the toolkit's once the scenario is read), so nothing opens a
Zenoh session. The wire format of the messages is compared with byte strings built by hand.
"""

from __future__ import annotations

import json
import os
import signal
import struct
import subprocess
import sys
import threading

import numpy as np
import pytest

from delaytrack._output import MANIFEST, OutputFolderError
from delaytrack.cli import main
from delaytrack.live._node import _folder_turn, claim_node_folder, record_node_files
from delaytrack.live.log import write_csv
from delaytrack.live.messages import CommandMessage, ReleaseMessage, StateMessage

SCENARIO = "two_link_S1"


@pytest.fixture
def signals_kept():
    """A node installs SIGINT/SIGTERM handlers; give the test process its own back."""
    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    yield
    for signum, handler in saved.items():
        signal.signal(signum, handler)


def refusal(capsys, *argv: str) -> str:
    """Run ``delaytrack live ...`` in-process; assert exit 2 and one line on stderr; return it."""
    try:
        code = main(["live", *argv])
    except SystemExit as stopped:  # refused while the options are read
        code = stopped.code
    err = capsys.readouterr().err
    assert code == 2, err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("error: ")
    return lines[0]


# ---- numbers ----------------------------------------------------------------------------------

RUN = ("run", SCENARIO, "--out", "unused")

BAD_NUMBERS = [
    (RUN, "--loss", "1.5"),
    (RUN, "--loss", "1"),
    (RUN, "--loss", "-0.1"),
    (RUN, "--loss", "nan"),
    (RUN, "--loss-seed", "-1"),
    (RUN, "--loss-seed", "4294967296"),
    (RUN, "--loss-seed", "1.5"),
    (RUN, "--port", "70000"),
    (RUN, "--port", "65534"),
    (RUN, "--port", "0"),
    (RUN, "--port", "1_000"),
    (RUN, "--duration", "-1"),
    (RUN, "--duration", "0"),
    (RUN, "--duration", "inf"),
    (RUN, "--duration", "1_000"),
    (RUN, "--handshake-timeout", "0"),
    (RUN, "--lead", "-0.001"),
    (RUN, "--lead", "0x10"),
    (("delay", SCENARIO, "--out", "unused"), "--loss", "1.5"),
    (("delay", SCENARIO, "--out", "unused"), "--start-delay", "-1"),
    (("controller", SCENARIO, "--out", "unused"), "--state-timeout", "0"),
    (("controller", SCENARIO, "--out", "unused"), "--phase", "nan"),
    (("robot", SCENARIO, "--out", "unused"), "--state-every", "0"),
    (("robot", SCENARIO, "--out", "unused"), "--state-every", "2.5"),
    (("robot", SCENARIO, "--out", "unused"), "--command-timeout", "0"),
    (("robot", SCENARIO, "--out", "unused"), "--duration", "1e400"),
    (RUN, "--realtime", "0"),
    (RUN, "--realtime", "100"),
    (("controller", SCENARIO, "--out", "unused"), "--realtime", "50.5"),
]


@pytest.mark.parametrize(("command", "flag", "value"), BAD_NUMBERS)
def test_a_bad_number_is_refused_in_one_line_naming_the_flag(
    capsys, tmp_path, monkeypatch, command, flag, value
):
    monkeypatch.chdir(tmp_path)
    line = refusal(capsys, *command, flag, value)
    assert flag in line and repr(value) in line, line
    assert "must be" in line  # what is valid
    assert os.listdir(tmp_path) == []  # refused before anything is made


@pytest.mark.parametrize(
    ("flag", "value"),
    [
        ("--connect", "tcp/127.0.0.1:notaport"),  # Zenoh retried it until the handshake gave up
        ("--connect", "udp/10.0.0.2:70000"),
        ("--connect", "tcp/127.0.0.1"),
        ("--connect", "tcp/127.0.0.1:0"),  # any free port: to listen on, not to reach
        ("--listen", "foo"),
        ("--listen", "TCP/0.0.0.0:7447"),
    ],
)
def test_a_malformed_endpoint_is_refused_before_the_node_starts(capsys, tmp_path, flag, value):
    out = tmp_path / "out"
    line = refusal(capsys, "controller", SCENARIO, "--out", str(out), flag, value)
    assert line.startswith(f"error: argument {flag}: must be a Zenoh endpoint PROTOCOL/ADDRESS")
    assert ("from 1 to 65535" if flag == "--connect" else "from 0 to 65535") in line
    assert f"got {value!r}" in line and not out.exists()


def test_endpoints_zenoh_takes_are_taken():
    from delaytrack.live.cli import _endpoint

    listen = _endpoint(0)
    for endpoint in ("tcp/127.0.0.1:7447", "tcp/[::1]:0", "udp/host.lab:9000#iface=eth0"):
        assert listen(endpoint) == endpoint
    assert listen("unixsock-stream//tmp/zenoh.sock") == "unixsock-stream//tmp/zenoh.sock"


def test_the_module_entry_point_refuses_in_one_line_too():
    done = subprocess.run(
        [sys.executable, "-m", "delaytrack.live", "run", SCENARIO, "--out", "x", "--loss", "2"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and "--loss" in done.stderr, done.stderr


@pytest.mark.parametrize("role", ["run", "delay"])
def test_a_loss_seed_without_a_loss_is_refused(capsys, tmp_path, role):
    line = refusal(capsys, role, SCENARIO, "--out", str(tmp_path / "out"), "--loss-seed", "7")
    assert "--loss-seed" in line and "--loss P" in line
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("role", ["run", "delay"])
def test_a_session_longer_than_the_nodes_hold_is_refused_before_its_folder_is_made(
    capsys, tmp_path, signals_kept, role
):
    out = tmp_path / "out"
    line = refusal(capsys, role, SCENARIO, "--out", str(out), "--duration", "1e9", "--quiet")
    assert "--duration 1e+09 s" in line and "plant steps" in line and "shorten" in line
    assert not out.exists()


@pytest.mark.parametrize("role", ["run", "robot"])
def test_a_session_shorter_than_two_ticks_is_refused_before_its_folder_is_made(
    capsys, tmp_path, signals_kept, role
):
    """One tick is a session no replay can check (two_link_S1: T_c = 2 ms)."""
    out = tmp_path / "out"
    line = refusal(capsys, role, SCENARIO, "--out", str(out), "--duration", "1e-9", "--quiet")
    assert line == (
        "error: --duration must be at least two controller periods, 2 T_c = 0.004 s (a session "
        "of one tick cannot be replayed); got 1e-09"
    )
    assert not out.exists()


@pytest.mark.parametrize("role", ["run", "delay"])
def test_a_trace_that_starts_after_the_session_is_refused(capsys, tmp_path, signals_kept, role):
    from delaytrack.scenario import load_builtin

    text = load_builtin(SCENARIO).to_toml()
    text = text[: text.index("[delay]")] + text[text.index("[reference]") :]
    scenario = tmp_path / "late.toml"
    scenario.write_text(
        text + '\n[delay]\ntype = "trace"\ntimes = [0.5, 2.0]\nvalues = [0.02, 0.03]\n'
    )
    out = tmp_path / "out"
    line = refusal(capsys, role, str(scenario), "--out", str(out), "--duration", "1", "--quiet")
    assert "starts at t = 0.5 s" in line and "give it a sample at or before" in line
    assert not out.exists()


def test_trust_and_quiet_are_the_options_of_every_command(capsys):
    texts = {}
    for argv in (["simulate", "--help"], ["live", "run", "--help"], ["live", "robot", "--help"]):
        with pytest.raises(SystemExit):
            main(argv)
        texts[argv[-2]] = " ".join(capsys.readouterr().out.split())
    for text in texts.values():
        assert "or of every file below a folder" in text  # --trust's help, one definition
    assert "no status line" in texts["run"] and "no status line" in texts["robot"]


# ---- output folders ---------------------------------------------------------------------------


def test_a_standalone_node_refuses_a_folder_that_holds_files_of_yours(
    capsys, tmp_path, signals_kept
):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    line = refusal(capsys, "controller", SCENARIO, "--out", str(out), "--quiet")
    assert "--out" in line and "notes.txt" in line
    assert sorted(os.listdir(out)) == ["notes.txt"]  # nothing written, not even the marker
    assert (out / "notes.txt").read_text() == "mine"


def test_a_node_folder_with_a_link_is_refused(tmp_path):
    out = tmp_path / "out"
    claim_node_folder(str(out))
    (out / "figures").symlink_to(tmp_path)
    with pytest.raises(OutputFolderError, match="symbolic link"):
        claim_node_folder(str(out))


def test_a_node_folder_is_resolved_before_it_is_made(tmp_path):
    folder = claim_node_folder(str(tmp_path / "new" / ".." / "mine"))
    assert folder == (tmp_path / "mine").resolve()
    assert (folder / MANIFEST).is_file()
    assert not (tmp_path / "new").exists()


def test_the_nodes_of_one_session_share_a_folder_and_keep_each_others_files(tmp_path):
    out = tmp_path / "session"
    robot = claim_node_folder(str(out))
    controller = claim_node_folder(str(out))  # the folder now holds the robot's marker
    assert robot == controller
    (robot / "robot.json").write_text("{}")
    record_node_files(robot)
    (controller / "controller.json").write_text("{}")
    record_node_files(controller)
    listed = json.loads((out / MANIFEST).read_text())["files"]
    assert listed == ["controller.json", "robot.json"]
    assert (out / "robot.json").is_file()
    assert claim_node_folder(str(out)) == robot  # the next session's node accepts it


def test_a_node_waits_while_another_node_claims_the_shared_folder(tmp_path):
    """Another node of the session is writing the folder's marker (a hidden temporary file
    beside it); without taking turns, this node would see a folder holding a file the toolkit
    did not mark and refuse it."""
    out = tmp_path / "session"
    out.mkdir()
    outcome: dict[str, object] = {}

    def claim() -> None:
        try:
            outcome["folder"] = claim_node_folder(str(out))
        except OutputFolderError as error:
            outcome["error"] = error

    with _folder_turn(str(out)):
        half_written = out / f"{MANIFEST}.tmp123.json"
        half_written.write_text(json.dumps({"files": []}))
        thread = threading.Thread(target=claim)
        thread.start()
        thread.join(0.5)  # long enough for a claim that does not wait to finish
        half_written.replace(out / MANIFEST)
    thread.join()
    assert outcome == {"folder": out.resolve()}


def test_a_table_is_written_whole_or_not_at_all(tmp_path):
    path = tmp_path / "ticks.csv"
    write_csv(path, ["k", "t_s"], [[0, 0.5]])
    before = path.read_bytes()

    class Unwritable:
        def __str__(self) -> str:
            raise ValueError("cannot be written")

    with pytest.raises(ValueError, match="cannot be written"):
        write_csv(path, ["k", "t_s"], [[0, 1.5], [1, Unwritable()]])
    assert path.read_bytes() == before
    assert sorted(os.listdir(tmp_path)) == ["ticks.csv"]


# ---- messages ---------------------------------------------------------------------------------

X = np.array([1.0, -2.0, 3.5, 0.0])
U = np.array([0.5, -0.25])

#: (message, its bytes built by hand, its bytes as the encoder wrote them before it was shared)
WIRE = [
    (
        StateMessage(7, 0.25, 1.5, X),
        struct.pack("<qddI4d", 7, 0.25, 1.5, 2, *X),
        "0700000000000000000000000000d03f000000000000f83f02000000000000000000f03f000000000000"
        "00c00000000000000c400000000000000000",
    ),
    (
        CommandMessage(3, 0.01, 2.0, 0.005, 1, U),
        struct.pack("<qdddqI2d", 3, 0.01, 2.0, 0.005, 1, 2, *U),
        "03000000000000007b14ae47e17a843f00000000000000407b14ae47e17a743f01000000000000000200"
        "0000000000000000e03f000000000000d0bf",
    ),
    (
        ReleaseMessage(2**40, 1e-3, 3.0, 3.25, 0.012, np.array([9.0])),
        struct.pack("<qddddId", 2**40, 1e-3, 3.0, 3.25, 0.012, 1, 9.0),
        "0000000000010000fca9f1d24d62503f00000000000008400000000000000a40fa7e6abc7493883f0100"
        "00000000000000002240",
    ),
    (
        CommandMessage(0, 0.0, 0.0, 0.0, 0, np.zeros(0)),
        struct.pack("<qdddqI", 0, 0.0, 0.0, 0.0, 0, 0),
        "00" * 44,
    ),
]


@pytest.mark.parametrize(("message", "by_hand", "before"), WIRE)
def test_messages_keep_their_bytes_and_read_back(message, by_hand, before):
    data = message.encode()
    assert data == by_hand == bytes.fromhex(before)
    decoded = type(message).decode(data)
    for name, value in vars(message).items():
        got = getattr(decoded, name)
        if isinstance(value, np.ndarray):
            assert got.dtype == np.float64 and np.array_equal(got, value)
        else:
            assert got == value and type(got) is type(value)


R, C, S = ReleaseMessage, CommandMessage, StateMessage


@pytest.mark.parametrize(
    ("kind", "message", "why"),
    [
        (R, R(1, 0.1, 0.1, 0.1, 0.1, np.array([1.0, 2.0, 3.0])), "3 values per unit, not 2"),
        (R, R(1, 0.1, 0.1, 0.1, 0.1, np.array([np.nan, 0.0])), "a value that is not finite"),
        (S, S(1, 0.1, 0.1, np.array([np.nan, 0.0, 0.0, 0.0])), "a value that is not finite"),
        (S, S(1, 0.1, 0.1, np.array([0.1, 0.2])), "1 values per unit, not 2"),
        (C, C(1, np.nan, 0.1, 0.1, 0, U), "a time that is not finite"),
        (R, R(1, 1e12, 0.1, 0.1, 0.1, U), "a time that is not finite or beyond"),
        (C, C(-1, -1.0, 0.1, 0.1, 0, U), "sequence number -1"),
        (C, C(2**62, 0.1, 0.1, 0.1, 0, U), "sequence number 4611686018427387904"),
        # the 60 bytes of a command of two inputs (a header of 44, two doubles), and one more
        (C, C(1, 0.1, 0.1, 0.1, 0, U).encode() + b"\0", "61 bytes, not those of 2 values"),
    ],
    ids=["long-u", "nan-u", "nan-x", "short-x", "nan-t_k", "huge-t_k", "negative-seq"]
    + ["huge-seq", "trailing-byte"],
)
def test_a_message_a_node_cannot_use_is_refused_when_decoded(kind, message, why):
    # Any peer on the network may publish: a node takes only whole, finite messages of its
    # sizes (such messages crashed nodes, or reached a robot as NaN).
    data = message if isinstance(message, bytes) else message.encode()
    with pytest.raises(ValueError, match=why):
        kind.decode(data, 2)


def test_a_message_of_a_time_after_the_session_is_refused_when_decoded():
    # Kept until the session's end, a flood of them made the robot miss steps.
    assert R.decode(R(1, 0.1, 0.1, 0.1, 2.0, U).encode(), 2, until=2.0).apply_at == 2.0
    with pytest.raises(ValueError, match="apply_at 1000000000.0 after the session's end"):
        R.decode(R(1, 0.1, 0.1, 0.1, 1e9, U).encode(), 2, until=2.0)
    with pytest.raises(ValueError, match="t_k 3.0 after the session's end"):
        C.decode(C(1, 3.0, 0.1, 0.1, 0, U).encode(), 2, until=2.0)
    with pytest.raises(ValueError, match="sample_time 5.0 after the session's end"):
        S.decode(S(1, 5.0, 0.1, X).encode(), 2, until=2.0)


def test_a_lead_longer_than_half_the_smallest_delay_is_refused(capsys, tmp_path, signals_kept):
    # S1's smallest delay is 20 ms: a release sent 15 ms ahead would go out before most
    # commands have reached the delay node, and every delay would grow by about that much.
    line = refusal(
        capsys, "delay", SCENARIO, "--out", str(tmp_path / "out"), "--lead", "0.015", "--quiet"
    )
    assert "--lead 0.015 s" in line and "h = 20 ms" in line and "at most 0.01 s" in line
    # live run refuses it before any node starts (the robot compiled its plant first)
    out = tmp_path / "run"
    line = refusal(capsys, "run", SCENARIO, "--out", str(out), "--lead", "0.015", "--quiet")
    assert "--lead 0.015 s" in line and not out.exists()


def test_a_phase_past_the_next_tick_is_refused(capsys, tmp_path, signals_kept):
    """The controller would wake after the next tick's time, every time: it never ticked."""
    line = refusal(
        capsys, "controller", SCENARIO, "--out", str(tmp_path / "out"), "--phase", "1e308"
    )
    # T_c = 2 ms: the period of the scenario, two_link_S1
    assert "--phase must be less than the controller period T_c = 0.002 s" in line


@pytest.mark.parametrize("name", ["", "a?b", "x/", "a//b", "*", "**", "a$b"])
def test_a_session_name_that_is_not_one_key_chunk_is_refused(capsys, tmp_path, name):
    line = refusal(capsys, "controller", SCENARIO, "--out", str(tmp_path / "o"), "--session", name)
    assert "--session" in line and f"got {name!r}" in line and "letters, digits" in line
    assert os.listdir(tmp_path) == []


def test_a_node_that_exits_before_the_sessions_end_ends_it(tmp_path):
    from delaytrack.live.session import _ended_early, _exit_text

    (tmp_path / "delay.json").write_text(json.dumps({"stopped_by": "duration"}))
    (tmp_path / "controller.json").write_text(json.dumps({"stopped_by": "SIGTERM"}))
    assert not _ended_early(tmp_path, "delay", None)  # still running
    assert not _ended_early(tmp_path, "delay", 0)  # its session ran to the end
    assert _ended_early(tmp_path, "controller", 0)  # stopped by a signal of its own
    assert _ended_early(tmp_path, "robot", 0)  # no record of how it ended
    assert _ended_early(tmp_path, "delay", 1)
    assert _exit_text("robot", -signal.SIGKILL) == "robot (killed by SIGKILL)"
    assert _exit_text("robot", 1) == "robot (exit 1)"


def test_realtime_is_set_or_refused_never_left_out(monkeypatch, tmp_path, capsys):
    from argparse import Namespace

    from delaytrack.live._node import enter_realtime
    from delaytrack.live.session import node_commands

    def denied(*_args):
        raise PermissionError(1, "Operation not permitted")

    with monkeypatch.context() as patched:
        patched.setattr(os, "sched_setscheduler", denied)
        with pytest.raises(ValueError, match=r"--realtime 50: SCHED_FIFO could not be set"):
            enter_realtime(50)
        enter_realtime(None)  # not asked for: nothing to set
        # live run checks it once, before its nodes start (each would print the same error)
        out = tmp_path / "out"
        assert main(["live", "run", SCENARIO, "--out", str(out), "--realtime", "50"]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "--realtime 50: SCHED_FIFO could not be set" in err
        assert not out.exists()  # no node started
    options = Namespace(
        scenario=SCENARIO,
        handshake_timeout=1.0,
        duration=None,
        trust=[],
        loss=None,
        realtime=7,
        certificates=None,
    )
    commands = node_commands(options, "out", [1, 2, 3], "s")
    assert all(command[-2:] == ["--realtime", "7"] for command in commands.values())


def test_realtime_puts_the_loop_under_sched_fifo_where_allowed():
    code = (
        "import os; from delaytrack.live._node import enter_realtime; enter_realtime(3); "
        "print(os.sched_getscheduler(0) == os.SCHED_FIFO, os.sched_getparam(0).sched_priority)"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    if done.returncode != 0 and "SCHED_FIFO could not be set" in done.stderr:
        pytest.skip("this machine does not allow SCHED_FIFO")
    assert done.stdout.split() == ["True", "3"], done.stderr


def test_ticks_missed_count_only_ticks_of_the_session():
    """A loop that wakes after the session's end counts the ticks before the end as missed,
    not the ticks after it (a 60 s session at 1 ms once showed 60001 ticks)."""
    import time

    from delaytrack.live.clock import Ticker

    ticker = Ticker(time.monotonic() - 10.0, 1.0, until=3.0)
    assert list(ticker) == []
    assert ticker.missed == 3


def test_a_summary_of_a_session_that_measured_nothing_is_strict_json_and_reports_na():
    """A session of no ticks: its percentiles and rates are NaN in the nodes, null in the JSON
    files (strict JSON), and 'n/a' in the report's timing table, not a TypeError."""
    from types import SimpleNamespace

    from delaytrack._io import json_text
    from delaytrack.live.report import _timing_settings

    nan = float("nan")
    written = json_text(
        {
            "realised_minus_h_ms_p50": nan,
            "nodes": {
                "controller": {"ticks": 0, "lateness_ms_p50": nan, "compute_ms_p99": nan},
                "robot": {"steps": 0, "lateness_ms_p99": nan},
                "delay": {"received": 0, "wakes_per_s": nan, "lead_ms": 0.5},
            },
        }
    )
    assert "NaN" not in written
    summary = json.loads(written)
    nodes = summary["nodes"]
    settings = _timing_settings(
        summary,
        SimpleNamespace(measurement_noise=None, simulated_packet_loss=None),
        nodes["controller"],
        nodes["robot"],
        nodes["delay"],
    )
    assert settings["delay node"].endswith(
        "releases, 0 steps missed (woke too late to release for them), n/a wake-ups/s, lead 0.5 ms"
    )
    assert settings["packet loss"] == "none"  # the delay node recorded none
    assert settings["controller wake-up lateness p50 / p99"] == "n/a / n/a"
    assert settings["realised delay − h(t) p50 / |.| p99"].startswith("n/a / n/a")


def test_a_node_starts_with_the_launchers_module_path_and_not_the_working_folder(tmp_path):
    # A node imports what the launcher imports (an uninstalled copy of the package, a
    # factory's module on its path), and nothing of the working folder.
    from delaytrack.live.session import NODE_START

    for folder, said in ((tmp_path / "launchers", "launcher's"), (tmp_path / "working", "sent")):
        package = folder / "delaytrack" / "live"
        package.mkdir(parents=True)
        (folder / "delaytrack" / "__init__.py").write_text("")
        (package / "__init__.py").write_text("")
        (package / "__main__.py").write_text(f"import sys; print({said!r}, sys.argv[1:])")
    path = [str(tmp_path / "launchers"), *sys.path]
    done = subprocess.run(
        [*NODE_START, json.dumps(path), "robot", "s.toml", "--quiet"],
        cwd=tmp_path / "working",
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.stdout.strip() == "launcher's ['robot', 's.toml', '--quiet']", done.stderr


def test_the_controller_takes_the_newest_state_by_sample_time_not_by_arrival():
    # A copy of an older state arriving late (replayed by a peer, or held by the network) was
    # taken for the newest: every tick then computed on a state two ticks old.
    import threading
    from collections import deque
    from types import SimpleNamespace

    from delaytrack.live.controller import ControllerNode

    node = object.__new__(ControllerNode)
    node._lock, node._states, node.n, node.dt = threading.Lock(), deque(maxlen=64), 2, 1e-3
    node.duration = 1.0

    def arrive(sample_time):
        data = StateMessage(int(sample_time * 1e3), sample_time, 0.0, X).encode()
        node._on_state(SimpleNamespace(payload=SimpleNamespace(to_bytes=lambda: data)))

    for sample_time in (0.000, 0.002, 0.004, 0.002, 0.001, 5.0):  # copies, late; one ahead
        arrive(sample_time)
    assert node._latest_state(0.0045)[0].sample_time == 0.004
    assert node._latest_state(0.003)[0].sample_time == 0.002
    assert [m.sample_time for m, _ in node._states] == [0.0, 0.001, 0.002, 0.002, 0.004]


def test_the_robot_applies_no_release_older_than_the_command_in_force():
    # A copy of an old release replayed on the network alternated with the new ones.
    from delaytrack.live.robot import RobotNode

    node = object.__new__(RobotNode)
    node.dt, node.releases_out_of_order = 1e-3, 0

    def release(seq, apply_at):
        return ReleaseMessage(
            seq, apply_at - 0.05, apply_at - 0.049, apply_at - 0.001, apply_at, X[:2]
        )

    first, second, replayed = release(1, 0.010), release(2, 0.020), release(1, 0.010)
    pending, taken = node._release_to_apply([(second, 0.0185), (first, 0.0085)], None, 0.020)
    assert pending == [] and taken == (second, 0.0185)  # the latest due, not the first arrived
    early = release(3, 0.030)
    pending, taken = node._release_to_apply([(replayed, 0.021), (early, 0.022)], second, 0.021)
    assert taken is None and pending == [(early, 0.022)]  # the copy is dropped, counted
    assert node.releases_out_of_order == 1
    pending, taken = node._release_to_apply([(second, 0.022)], second, 0.022)  # again: kept
    assert taken is None and pending == [] and node.releases_out_of_order == 1
    pending, taken = node._release_to_apply(pending + [(early, 0.022)], second, 0.030)
    assert taken == (early, 0.022)


def test_the_delay_node_takes_a_command_once_and_counts_its_copies():
    # A copy of a command (replayed, or sent twice) overwrote the record of the first.
    from types import SimpleNamespace

    from delaytrack.live.delay import DelayNode

    node = object.__new__(DelayNode)
    node.commands, node.duplicates, node.lost_count, node._seq_range = {}, 0, 0, None
    node._held_times, node._held = [], []
    node._loss = np.array([0.0, 0.0])
    first = CommandMessage(4, 0.008, 0.0081, 0.0079, 0, X[:2])
    copy = CommandMessage(4, 0.008, 0.0090, 0.0079, 0, -X[:2])
    arrivals = [(first, 10.0082), (copy, 10.0095), (copy, 10.0101)]
    node._received = SimpleNamespace(drain=lambda: arrivals)
    assert node._take(10.0)
    assert node.duplicates == 2 and list(node.commands) == [4]
    assert node.commands[4][2:4] == [0.0081, pytest.approx(0.0082)]  # the first copy's times
    assert node._held == [first]


def test_a_command_a_newer_one_supersedes_at_its_step_is_not_counted_as_never_applied():
    # Where h falls, s - h(s) advances by dt (1 - h') a step: past two commands 1 ms apart at
    # some steps, where the rule applies the newer. At T_c = dt they were counted as never
    # applied (82 of 85 in a 5 s session of the P3-DX).
    from types import SimpleNamespace

    from delaytrack.live.session import _due_steps, _superseded

    delay = SimpleNamespace(h=lambda s: np.maximum(0.05 - 0.5 * np.asarray(s), 0.0))
    dt, end = 1e-3, 0.2
    t_k = np.arange(120) * dt
    steps, due = _due_steps(t_k, delay, dt, end)
    reach = np.maximum.accumulate(steps - delay.h(steps))
    for k in range(t_k.size):  # the first step whose reach covers t_k, as the rule says
        inside = np.flatnonzero(reach >= t_k[k] - 1e-9 * dt)
        assert due[k] == (inside[0] if inside.size else steps.size)
    taken = due < steps.size
    superseded = _superseded(t_k, taken, due)
    groups = {int(d) for d in due[taken]}
    assert superseded.sum() == taken.sum() - len(groups) > 0
    for step in groups:  # the newest of each step is the one applied
        members = np.flatnonzero(taken & (due == step))
        assert not superseded[members[-1]] and superseded[members[:-1]].all()
    lost = taken.copy()
    lost[np.flatnonzero(superseded)[0] + 1] = False  # the newer one lost: the older applies
    assert not _superseded(t_k, lost, due)[np.flatnonzero(superseded)[0]]
    ten_ms = np.arange(12) * 0.01  # T_c = 10 ms: never two commands at one step
    steps, due = _due_steps(ten_ms, delay, dt, end)
    assert not _superseded(ten_ms, due < steps.size, due).any()


@pytest.mark.parametrize("lead", [1e-4, 2.5e-4, 5e-4, 1e-3, 2e-3])
def test_a_release_a_little_late_still_reaches_its_step(lead):
    """The delay node wakes ``lead`` before a step to release for it: a wake-up late by less
    than half the lead still releases for that step (with the margin equal to a lead of 0.5
    ms or less, any lateness moved every release of a 2 ms delay one step later)."""
    from delaytrack.live.delay import default_lead, first_reachable_step, release_margin

    dt = 1e-3
    margin = release_margin(lead, dt)
    assert 0 < margin < lead and margin <= min(dt / 2, 5e-4)
    for step in (1, 7, 1000, 59_999):
        wake = step * dt - lead
        for late in (0.0, 1e-5, 0.49 * lead):  # the node releases for max(step, reachable)
            assert first_reachable_step(wake + late, margin, dt) <= step
        assert first_reachable_step(step * dt - 0.99 * margin + 1e-12, margin, dt) == step + 1
    assert release_margin(default_lead(dt, 2e-3), dt) == 2.5e-4  # h = 2 ms: lead 0.5 ms


class _SessionClock:
    """The delay node's clock and its inbox in a test: time passes only while the node waits
    (to the end of its wait, or to the next arrival), and a wait that should end at
    ``stall_at`` ends ``stall`` later, as a wake-up of a loaded machine does."""

    def __init__(self, arrivals, stall_at, stall):
        self.now, self.arrivals, self.stall_at, self.stall = 0.0, sorted(arrivals), stall_at, stall

    def __call__(self):
        return self.now

    def drain(self):
        arrived = [(message, at) for at, message in self.arrivals if at <= self.now]
        self.arrivals = self.arrivals[len(arrived) :]
        return arrived

    def wait(self, timeout):
        until = self.now + timeout
        if abs(until - self.stall_at) < 1e-9:
            until += self.stall
        if self.arrivals and self.arrivals[0][0] <= until:
            self.now = self.arrivals[0][0]
            return True
        self.now = until
        return False


def test_a_late_wake_up_releases_for_a_later_step_with_the_commands_that_arrive_by_its_deadline(
    tmp_path,
):
    """h = 2 ms, T_c = dt = 1 ms: command k (t_k = k ms) is due at step k + 2, released 0.5 ms
    (the lead) before it. The wake-up for step 12 comes 0.3 ms late, closer to the step than
    the margin (a quarter of a millisecond): the rule is then evaluated at step 13, whose own
    deadline (12.5 ms) is still ahead, and command 11, due there, arrives late too, at 12.2 ms.
    It is released for step 13, as the rule says; the node had released command 10 for step 13
    at once, then command 11 for step 14."""
    from types import SimpleNamespace

    from delaytrack.live.delay import DelayNode, release_margin
    from delaytrack.scenario import load_builtin

    scenario = load_builtin(SCENARIO).replace(delay={"type": "constant", "h": 0.002}, T_c=0.001)
    args = SimpleNamespace(duration=0.03, out=tmp_path, quiet=True, loss=None, lead=None)
    node = DelayNode(scenario, scenario.build(), args)
    ms = 1e-3
    assert node.lead == 0.5 * ms and release_margin(node.lead, node.dt) == 0.25 * ms
    arrivals = [
        (
            k * ms + (1.2 * ms if k == 11 else 0.1 * ms),
            CommandMessage(k, k * ms, k * ms, k * ms, 0, X[:2]),
        )
        for k in range(25)
    ]
    clock = _SessionClock(arrivals, stall_at=11.5 * ms, stall=0.3 * ms)
    node._clock, node._received = clock, clock
    released = []
    node._publisher = SimpleNamespace(put=lambda data: released.append(data))
    node.loop(0.0, stop=lambda: False, handshake=SimpleNamespace(publish=lambda: None))
    node.log.close()
    apply_at = {seq: round(s / ms) for seq, _t_k, _now, s, _h in node.releases}
    assert node.missed_steps == 1  # step 12: the robot held command 9 over it
    assert 10 not in apply_at and apply_at[11] == 13, apply_at
    # every other command at its own step, released before its deadline
    assert all(apply_at[k] == k + 2 for k in range(23) if k not in (10, 11)), apply_at
    for seq, _t_k, now, s, _h in node.releases:
        assert now <= s - node.lead + 1e-12 or seq == 11, (seq, now, s)
    assert len(released) == len(node.releases)


def test_the_report_gives_the_packet_loss_the_delay_node_ran_and_the_scenarios_beside():
    """``--loss``/``--loss-seed`` change the session's losses, not its scenario file: the
    report gave the scenario's alone (0.2, seed 3) for a session run with 0.5, seed 9."""
    from delaytrack.live.report import _packet_loss_text
    from delaytrack.scenario import load_builtin

    lossy = load_builtin("two_link_S1").replace(packet_loss={"probability": 0.2, "seed": 3})
    ran = {"packet_loss": {"probability": 0.5, "seed": 9}}
    assert _packet_loss_text(ran, lossy) == (
        "probability 0.5, seed 9 (--loss/--loss-seed; the scenario's: probability 0.2, seed 3)"
    )
    assert _packet_loss_text({"packet_loss": {"probability": 0.2, "seed": 3}}, lossy) == (
        "probability 0.2, seed 3"
    )
    plain = load_builtin("two_link_S1")
    assert _packet_loss_text({"packet_loss": {"probability": 0.0, "seed": 0}}, plain) == "none"
    assert _packet_loss_text(ran, plain) == (
        "probability 0.5, seed 9 (--loss/--loss-seed; the scenario's: none)"
    )
