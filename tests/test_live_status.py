"""The live session's status: each node's JSON on ``delaytrack/<session>/status/<role>``, the
launcher's combined line, a node's own line when it runs alone, and none with ``--quiet``.

Two 2 s sessions of tests/conftest.py, run once for all the live modules (one after the
other): ``live run`` with its status line (``live_run``), and the three nodes started as the
launcher starts them but with the robot not quiet, with the fixture subscribed to their
statuses (``live_nodes``); ``live run --quiet`` is
checked on the session of test_live_mujoco.py. No timing is asserted: only that the numbers are
there, positive or finite.
"""

from __future__ import annotations

import json
import math
import re
from types import SimpleNamespace

import pytest

pytest.importorskip("zenoh")
pytest.importorskip("mcap_ros2")

from delaytrack.live.session import ROLES  # noqa: E402

#: The fields of each node's status (docs/live.md, delaytrack.live.status).
FIELDS = {
    "controller": (
        {"ticks", "tick_rate_hz", "missed", "stale", "lateness_ms_p99", "compute_ms_p99"},
        {"ticks", "missed", "stale"},
    ),
    "delay": ({"received", "lost", "gaps", "releases"}, {"received", "lost", "gaps", "releases"}),
    "robot": (
        {
            "steps",
            "missed",
            "zero_input",
            "applied",
            "realised_minus_h_abs_ms_p50",
            "realised_minus_h_abs_ms_p99",
        },
        {"steps", "missed", "zero_input", "applied"},
    ),
}

#: One node's part of the status line, with the numbers the test reads (n/a: not defined).
_MS = r"(n/a|\S+) ?(?:ms)?"
PARTS = {
    "controller": re.compile(
        rf"^controller (\S+) Hz, lateness p99 {_MS}, (\d+) missed, (\d+) stale$"
    ),
    "delay": re.compile(r"^delay (\d+) received, (\d+) lost, (\d+) gaps$"),
    "robot": re.compile(
        rf"^robot (\d+) missed, (\d+) without a command, realised-h \|\.\| p99 {_MS}$"
    ),
}


def _status_parts(stderr: str) -> dict[str, list[tuple[str, ...]]]:
    """The numbers of every part of every status line (``t=... s | ... | ...``), by role."""
    found: dict[str, list[tuple[str, ...]]] = {role: [] for role in PARTS}
    for line in stderr.splitlines():
        if not re.match(r"^t=\d+ s( \| |$)", line):
            continue
        for part in line.split(" | ")[1:]:
            role = part.split(" ", 1)[0]
            match = PARTS[role].match(part)
            assert match, line
            found[role].append(match.groups())
    return found


def _positive(text: str) -> bool:
    return math.isfinite(float(text)) and float(text) > 0


@pytest.fixture(scope="module")
def sessions(live_run, live_nodes):
    """The launcher's outcome and the nodes' (the shared sessions of tests/conftest.py)."""
    _folder, launched = live_run
    _folder, name, outputs, codes, received = live_nodes
    stdout, stderr, code = launched.outcome
    return {
        "run": ((stdout, stderr), code),
        "nodes": (outputs, codes),
        "statuses": (name, received),
    }


def test_live_run_prints_one_line_a_second_with_the_three_nodes(sessions):
    (stdout, stderr), code = sessions["run"]
    assert code == 0, stderr.decode()
    parts = _status_parts(stderr.decode())
    assert all(parts.values()), stderr.decode()
    for rate, lateness, missed, stale in parts["controller"]:
        assert _positive(rate) and math.isfinite(float(lateness)), (rate, lateness)
        assert int(missed) >= 0 and int(stale) >= 0
    assert any(int(received) > 0 for received, _lost, _gaps in parts["delay"])
    assert all(math.isfinite(float(p99)) for *_, p99 in parts["robot"] if p99 != "n/a")
    assert b"live session" in stdout  # the final summary, as before


def test_each_node_publishes_its_status_as_json(sessions):
    name, received = sessions["statuses"]
    _outputs, codes = sessions["nodes"]
    assert codes == {"robot": 0, "delay": 0, "controller": 0}
    statuses = {}
    for key, payload in received:
        status = json.loads(payload)
        assert key == f"delaytrack/{name}/status/{status['role']}"
        last, total = FIELDS[status["role"]]
        assert set(status["last"]) == last and set(status["total"]) == total, status
        assert status["t"] > 0 and status["window_s"] > 0
        statuses.setdefault(status["role"], []).append(status)
    assert set(statuses) == set(ROLES)
    controller = statuses["controller"][0]
    assert controller["last"]["tick_rate_hz"] > 0 and controller["total"]["ticks"] > 0
    assert math.isfinite(controller["last"]["lateness_ms_p99"])
    assert statuses["delay"][0]["total"]["received"] > 0
    robot = statuses["robot"][0]
    assert robot["total"]["steps"] > 0 and robot["total"]["applied"] > 0
    assert math.isfinite(robot["last"]["realised_minus_h_abs_ms_p99"])


def test_a_node_alone_prints_its_own_status_line(sessions):
    outputs, _codes = sessions["nodes"]
    robot_parts = _status_parts(outputs["robot"][1].decode())
    assert robot_parts["robot"] and not robot_parts["controller"], outputs["robot"][1]
    for role in ("controller", "delay"):  # quiet
        assert not any(part for part in _status_parts(outputs[role][1].decode()).values())


def test_a_status_that_is_not_a_nodes_is_not_read():
    # Any peer may publish on a session's status keys: a number given as text stopped the
    # launcher with a traceback while it wrote the status line.
    import json

    from delaytrack.live.messages import MAX_JSON_BYTES
    from delaytrack.live.status import decode_status, format_line

    good = {"role": "controller", "t": 1.0, "last": {"tick_rate_hz": 100.0}, "total": {}}
    assert decode_status(json.dumps(good).encode()) == good
    assert "controller 100 Hz" in format_line({"controller": good})
    for bad in (
        {**good, "last": {"tick_rate_hz": "x"}},
        {**good, "total": {"missed": [1]}},
        {**good, "last": {"tick_rate_hz": True}},
        {**good, "role": "robot2"},
    ):
        assert decode_status(json.dumps(bad).encode()) is None, bad
    assert decode_status(b"[" * 100_000 + b"]" * 100_000) is None  # no RecursionError
    assert decode_status(b" " * (MAX_JSON_BYTES + 1)) is None


def test_a_hello_that_is_not_a_nodes_is_not_read():
    # A peer's hello whose hashes were a list, or whose t0 was NaN, stopped the other nodes in
    # the handshake with a traceback.
    import json

    from delaytrack.live.transport import read_hello

    good = {"role": "robot", "pid": 1, "hashes": {"plant": "ab"}, "agree": [], "t0": 12.5}
    assert read_hello(json.dumps(good).encode()) == good
    for bad in (
        {**good, "hashes": [1]},
        {**good, "hashes": {"plant": 1}},
        {**good, "agree": "controller"},
        {**good, "t0": "soon"},
        {**good, "t0": True},
        {**good, "role": "spy"},
    ):
        assert read_hello(json.dumps(bad).encode()) is None, bad
    assert read_hello(json.dumps(good).replace("12.5", "NaN").encode()) is None
    assert read_hello(b"[" * 100_000 + b"]" * 100_000) is None


def test_a_reader_that_closed_the_status_output_ends_the_lines_not_the_launcher():
    """``delaytrack live run ... 2>&1 | head -1``: the first line is read, the next write meets
    a closed pipe. The status lines stop; the launcher goes on to the summary (a
    ``BrokenPipeError`` from the watch would end it, its nodes with it)."""
    from delaytrack.live.status import StatusWatch
    from ports import free_ports

    class ReadOnce:
        def __init__(self):
            self.lines = []

        def isatty(self):
            return False

        def write(self, text):
            if self.lines:
                raise BrokenPipeError(32, "Broken pipe")
            self.lines.append(text)

        def flush(self):
            pass

    class Sample:  # as Zenoh gives a status to the watch
        def __init__(self, second):
            status = {"role": "controller", "t": second, "last": {"tick_rate_hz": 1e2}, "total": {}}
            self.payload = SimpleNamespace(to_bytes=lambda: json.dumps(status).encode())

    stream = ReadOnce()
    watch = StatusWatch(f"tcp/127.0.0.1:{free_ports(1)[0]}", "delaytrack/test", stream=stream)
    try:
        for second in (1.0, 2.0, 3.0):
            watch._on_status(Sample(second))
            watch.show(now=True)
    finally:
        watch.close()
    assert len(stream.lines) == 1 and stream.lines[0].startswith("t=1 s"), stream.lines
