"""One session clock across machines (delaytrack.live.clock_sync) and scenario hashes that do
not depend on where the files are.

A machine of its own is stood in for by a clock shifted by 1000 s and another boot identifier:
the nodes must start at the robot's ``t0`` mapped to their own clock, within the bound the
round trips give. Nothing here asserts a timing: the bound holds by construction.
"""

from __future__ import annotations

import contextlib
import shutil
import socket
import threading
import time
from pathlib import Path

import pytest

pytest.importorskip("zenoh")

from delaytrack.live.clock_sync import estimate_clock_offset, serve_clock  # noqa: E402
from delaytrack.live.transport import (  # noqa: E402
    Handshake,
    HandshakeError,
    open_session,
    scenario_hashes,
)
from delaytrack.scenario import Scenario  # noqa: E402

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "user_arm"
SHIFT = 1000.0
HASHES = {"plant": "p", "coordinates": "c", "T_c": "t", "dt": "d", "scenario": "s"}


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def sessions():
    port = _free_port()
    opened = [open_session([f"tcp/127.0.0.1:{port}"], [])]
    opened += [open_session([], [f"tcp/127.0.0.1:{port}"]) for _ in range(2)]
    yield opened
    for session in opened:
        session.close()


def _shifted():
    return time.monotonic() + SHIFT


def test_an_offset_estimate_lies_within_its_bound(sessions):
    robot, other, _ = sessions
    server = serve_clock(robot, "test/clock", _shifted)
    try:
        offset = estimate_clock_offset(other, "test/clock", rounds=8)
    finally:
        server.undeclare()
    assert offset.round_trips == 8
    assert offset.bound_s > 0
    assert abs(offset.offset_s - SHIFT) <= offset.bound_s


def test_no_answer_is_a_timeout_naming_the_key(sessions):
    with pytest.raises(TimeoutError, match="test/nobody"):
        estimate_clock_offset(sessions[1], "test/nobody", rounds=2, timeout=0.3)


def _handshakes(
    sessions, robot_boot, other_boot, robot_clock=_shifted, timeout=20.0, start_delay=0.3
):
    roles = ("robot", "controller", "delay")
    shakes = {
        role: Handshake(
            session,
            "test/hand",
            role,
            HASHES,
            start_delay=start_delay,
            clock=robot_clock if role == "robot" else time.monotonic,
            boot=robot_boot if role == "robot" else other_boot,
        )
        for role, session in zip(roles, sessions, strict=True)
    }
    starts = {}

    def wait(role):
        with contextlib.suppress(HandshakeError):  # not started: left out of starts
            starts[role] = shakes[role].wait(timeout)

    threads = [threading.Thread(target=wait, args=(role,)) for role in roles]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(30)
    for shake in shakes.values():
        shake.close()
    return shakes, starts


def test_nodes_on_another_machine_start_at_the_robots_t0_on_their_own_clock(sessions):
    shakes, starts = _handshakes(sessions, "robot-machine", "other-machine")
    assert set(starts) == {"robot", "controller", "delay"}
    for role in ("controller", "delay"):
        offset = shakes[role].clock_offset
        assert offset.round_trips > 0
        assert abs(starts[role] - (starts["robot"] - SHIFT)) <= offset.bound_s


def test_nodes_on_the_same_machine_take_t0_as_it_is(sessions):
    # One machine, one clock: t0 is taken as announced, with no round trip to estimate an
    # offset.
    shakes, starts = _handshakes(sessions, "one-boot", "one-boot", time.monotonic)
    for role in ("controller", "delay"):
        assert shakes[role].clock_offset.offset_s == 0.0
        assert shakes[role].clock_offset.round_trips == 0
        assert starts[role] == starts["robot"]


def test_a_start_announced_far_from_now_is_not_taken(sessions):
    # A robot node's start is seconds ahead: one days away (a peer's hello, or a clock that is
    # not this machine's under the same boot) held the other nodes waiting for it.
    shakes, starts = _handshakes(sessions, "one-boot", "one-boot", _far_ahead, timeout=3.0)
    assert "robot" in starts and "controller" not in starts and "delay" not in starts


def _far_ahead():
    return time.monotonic() + 1e6


def _copy_example(folder: Path) -> Path:
    shutil.copytree(EXAMPLE, folder)
    return folder / "arm_S1.toml"


def test_the_same_scenario_in_two_folders_has_the_same_hashes_and_an_edit_changes_them(
    tmp_path,
):
    first = Scenario.from_toml(_copy_example(tmp_path / "one"))
    second_path = _copy_example(tmp_path / "two")
    second = Scenario.from_toml(second_path)
    assert scenario_hashes(first, first.build().plant) == scenario_hashes(
        second, second.build().plant
    )
    factory = second_path.parent / "arm.py"
    factory.write_text(factory.read_text() + "\n# edited\n")
    edited = Scenario.from_toml(second_path)
    assert (
        scenario_hashes(edited, edited.build().plant)["scenario"]
        != scenario_hashes(first, first.build().plant)["scenario"]
    )


def test_a_robot_that_announced_the_start_starts_though_its_timeout_passes_before_it(sessions):
    """The robot announces ``t0`` 4 s ahead, and its 3 s handshake timeout passes before
    ``t0``: the others start at ``t0``, and so does the robot (it gave up, and the others ran
    without it). On a machine too loaded to agree within 3 s, nobody starts."""
    shakes, starts = _handshakes(
        sessions, "one-boot", "one-boot", time.monotonic, timeout=3.0, start_delay=4.0
    )
    announced = shakes["robot"].t0
    if announced is None:
        assert starts == {}
    else:
        assert starts == {"robot": announced, "controller": announced, "delay": announced}
