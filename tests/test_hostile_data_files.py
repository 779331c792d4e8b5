"""Data files are read with the command line's number rule, only from regular files of bounded
size, and errors about them do not quote their text.

The cases of the campaign (``0_05`` in a trace read as 5 s, ``0_5`` in waypoints read as 5, a
FIFO that hangs a read, ``/etc/passwd``'s first line in an error) as regression tests, through
the Python API and the command line, and one property: a CSV cell and a command-line argument
are read by the same rule.
"""

from __future__ import annotations

import csv
import math
import os
import threading
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from delaytrack._io import MAX_READ_BYTES, regular_file
from delaytrack.cli import UsageError, _scalar, main
from delaytrack.delays import TraceDelay
from delaytrack.experiments import Scenario, ScenarioError
from delaytrack.references import SplineReference
from delaytrack.sweeps import SweepSpec
from test_hostile_inputs import one_line_error
from test_scenario import base_dict

#: Long enough for a first import of MuJoCo or numba on a busy machine; a read that waits on a
#: FIFO never ends, so this only turns a hang into a failure (no timing is asserted).
_HANG_GUARD_SECONDS = 120

_SPLINE = {"type": "spline", "path": "", "beyond": "hold"}


def promptly(fifo: Path, call: Callable[..., object], *arguments: object) -> object:
    """What ``call(*arguments)`` returns or raises, run in a thread so that a read waiting on
    ``fifo`` fails the test instead of hanging the suite (the FIFO is then opened for writing
    and closed, which ends the waiting read)."""
    outcome: list[object] = []

    def target() -> None:
        try:
            outcome.append(call(*arguments))
        except BaseException as error:  # noqa: BLE001 - the test inspects it
            outcome.append(error)

    thread = threading.Thread(target=target, daemon=True)
    thread.start()
    thread.join(_HANG_GUARD_SECONDS)
    if thread.is_alive():
        if fifo is not None:
            os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
        pytest.fail(f"reading {fifo} waited for a writer instead of being refused")
    return outcome[0]


def scenario_file(folder: Path, **tables: object) -> Path:
    path = folder / "case.toml"
    Scenario.from_dict({**base_dict(), **tables}).to_toml(path)
    return path


@pytest.fixture
def fifo(tmp_path) -> Path:
    if not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs on this system")
    path = tmp_path / "pipe.csv"
    os.mkfifo(path)
    return path


# ---- 1. one number rule ---------------------------------------------------------------------


def test_a_digit_separator_in_a_trace_is_refused_naming_line_and_column(tmp_path, capsys):
    path = tmp_path / "trace.csv"
    path.write_text("t,h\n0,0_05\n10,0.05\n")  # was read as h = 5.0 s
    with pytest.raises(ValueError, match=r"trace\.csv: line 2, column 'h' must be a number"):
        TraceDelay.from_csv(path)
    scenario = scenario_file(tmp_path, delay={"type": "trace", "path": "trace.csv"})
    assert main(["simulate", str(scenario), "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, "trace.csv: line 2, column 'h'", "'_' is not read as a digit separator")


def test_a_digit_separator_in_waypoints_is_refused_naming_line_and_column(tmp_path, capsys):
    path = tmp_path / "poses.csv"
    path.write_text("t,q1,q2\n0,0,0\n1,0_5,0\n2,1,1\n")  # 0_5 was read as 5.0
    with pytest.raises(ValueError, match=r"poses\.csv: line 3, column 'q1' must be a"):
        SplineReference.from_csv(path)
    scenario = scenario_file(tmp_path, reference={**_SPLINE, "path": "poses.csv"})
    assert main(["simulate", str(scenario), "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, "poses.csv: line 3, column 'q1'", "'_'")


def test_a_decimal_comma_splitting_a_row_is_refused_not_read_as_two_columns(tmp_path):
    path = tmp_path / "poses.csv"
    path.write_text("t,q\n0,0\n1,0,5\n2,1\n")  # the 5 was dropped, q(1) read as 0
    with pytest.raises(ValueError, match=r"line 3 must have 2 columns as its header; it has 3"):
        SplineReference.from_csv(path)
    quoted = tmp_path / "quoted.csv"
    quoted.write_text('t,h\n0,"0,5"\n1,0.5\n')
    with pytest.raises(ValueError, match=r"line 2, column 'h' .*not a decimal point"):
        TraceDelay.from_csv(quoted)


def test_a_first_row_that_is_a_malformed_number_is_not_taken_for_a_header(tmp_path):
    path = tmp_path / "trace.csv"
    path.write_text("0_0,0.05\n10,0.05\n")  # a header would have dropped the first knot
    with pytest.raises(ValueError, match=r"line 1, column 1 must be a number"):
        TraceDelay.from_csv(path)


@pytest.mark.parametrize(
    ("text", "value"),
    [
        ("1e3", 1e3),
        ("+1", 1.0),
        (" 0.25 ", 0.25),
        ("\t.5", 0.5),
        ("5.", 5.0),
        ("nan", None),
        ("-inf", None),
        ("1e400", None),
        ("1e-400", None),
        ("0x10", None),
        ("1_000", None),
        ("1,5", None),
        ("", None),
        ("   ", None),
        ("\u0663", None),  # Arabic-Indic three
        ("\uff11", None),  # full-width one
        ("1\u00a0", None),  # a no-break space is not a blank
    ],
)
def test_the_command_line_and_a_data_file_agree_on_a_number(tmp_path, text, value):
    path = tmp_path / "poses.csv"
    with path.open("w", newline="") as handle:
        csv.writer(handle).writerows([["t", "q"], ["0", text], ["1", text]])
    if value is None:
        with pytest.raises(UsageError):
            _scalar("--x", text)
        with pytest.raises(ValueError, match=r"line 2, column 'q' (must|is too)"):
            SplineReference.from_csv(path)
    else:
        assert _scalar("--x", text) == value
        np.testing.assert_array_equal(SplineReference.from_csv(path).values, [[value], [value]])


@st.composite
def number_texts(draw) -> str:
    """Text that is, or nearly is, a number: floats in Python's and C's spellings, integers,
    and short strings over the characters of numbers in any notation."""
    return draw(
        st.one_of(
            st.floats().map(repr),
            st.floats().map(lambda x: f"{x:e}"),
            st.integers(-(10**400), 10**400).map(str),
            st.from_regex(r"[+-]?\d{0,3}(_\d{1,3})?(\.\d*)?([eE][+-]?\d{1,4})?", fullmatch=True),
            st.text(alphabet="0123456789+-.eE_, \t\n\xa0xXabfinINF\u0663\uff11", max_size=10),
        )
    )


@given(text=number_texts())
@settings(max_examples=300, deadline=None)
def test_data_files_and_the_command_line_read_the_same_numbers(tmp_path_factory, text):
    path = tmp_path_factory.mktemp("numbers") / "poses.csv"
    with path.open("w", newline="") as handle:  # quoted as needed: the cell reads back as text
        csv.writer(handle).writerows([["t", "q"], ["0", text], ["1", text]])
    try:
        value = _scalar("--x", text)
    except UsageError:
        with pytest.raises(ValueError, match=r"line 2, column 'q' (must|is too)"):
            SplineReference.from_csv(path)
    else:
        read = SplineReference.from_csv(path).values[0, 0]
        assert read == value and math.copysign(1.0, read) == math.copysign(1.0, value)


# ---- 2. only regular files of bounded size --------------------------------------------------


@pytest.mark.parametrize("read", [TraceDelay.from_csv, SplineReference.from_csv])
def test_a_fifo_is_refused_promptly_as_a_trace_or_waypoints(fifo, read):
    error = promptly(fifo, read, fifo)
    assert isinstance(error, ValueError)
    assert str(error) == (
        f"path = {str(fifo)!r} is not a file but a FIFO (named pipe); it must be a regular file"
    )


@pytest.mark.parametrize("table", ["delay", "reference"])
def test_a_fifo_named_by_a_scenario_is_refused_on_the_command_line(fifo, tmp_path, capsys, table):
    value = {"type": "trace", "path": fifo.name} if table == "delay" else {**_SPLINE}
    value["path"] = fifo.name
    scenario = scenario_file(tmp_path, **{table: value})
    assert promptly(fifo, main, ["simulate", str(scenario), "--out", str(tmp_path / "o")]) == 2
    one_line_error(capsys, f"'{table}.path' = ", "is not a file but a FIFO (named pipe)")


@pytest.mark.parametrize("command", ["simulate", "sweep"])
def test_a_scenario_or_sweep_file_that_is_a_fifo_is_refused(tmp_path, capsys, command):
    if not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs on this system")
    fifo = tmp_path / "case.toml"
    os.mkfifo(fifo)
    read = Scenario.from_toml if command == "simulate" else SweepSpec.from_toml
    error = promptly(fifo, read, fifo)
    assert isinstance(error, ScenarioError) and "must be a regular file" in str(error)
    assert promptly(fifo, main, [command, str(fifo), "--out", str(tmp_path / "o")]) == 2
    what = "scenario" if command == "simulate" else "sweep"
    one_line_error(capsys, f"{what} file {str(fifo)!r} is not a file but a FIFO (named pipe)")


@pytest.mark.parametrize("command", ["simulate", "sweep"])
def test_a_scenario_or_sweep_file_that_is_a_device_is_refused(tmp_path, capsys, command):
    if not Path("/dev/zero").exists():
        pytest.skip("no /dev/zero here")
    assert main([command, "/dev/zero", "--out", str(tmp_path / "o")]) == 2
    one_line_error(capsys, "file '/dev/zero' is not a file but a character device")


def test_a_factory_file_that_is_a_fifo_is_refused(tmp_path):
    if not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs on this system")
    fifo = tmp_path / "make.py"
    os.mkfifo(fifo)
    scenario = scenario_file(tmp_path)
    text = scenario.read_text().replace('type = "arolc"', 'type = "python:make.py:controller"')
    scenario.write_text(text)
    error = promptly(fifo, lambda: Scenario.from_toml(scenario).build())
    assert isinstance(error, ScenarioError), error
    assert "factory file '" in str(error) and "is not a file but a FIFO" in str(error)


def test_a_mujoco_model_that_is_a_fifo_is_refused(tmp_path):
    pytest.importorskip("mujoco")
    from delaytrack.plants import MujocoPlant

    if not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs on this system")
    fifo = tmp_path / "arm.xml"
    os.mkfifo(fifo)
    error = promptly(fifo, MujocoPlant, fifo)
    assert isinstance(error, ValueError) and "is not a file but a FIFO" in str(error)


@pytest.mark.parametrize("device", ["/dev/zero", "/dev/urandom"])
def test_a_device_is_refused_directly_and_through_a_link(device, tmp_path, capsys):
    if not Path(device).exists():
        pytest.skip(f"no {device} here")
    link = tmp_path / "trace.csv"
    link.symlink_to(device)
    with pytest.raises(ValueError, match=r"is not a file but a character device"):
        TraceDelay.from_csv(device)
    with pytest.raises(ValueError, match=rf"'{link}' is not a file but a character device \("):
        SplineReference.from_csv(link)  # names where the link leads
    scenario = scenario_file(tmp_path, delay={"type": "trace", "path": device})
    assert main(["simulate", str(scenario), "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, f"'delay.path' = '{device}' is not a file but a character device")


def test_a_file_larger_than_the_bound_is_refused_before_it_is_read(tmp_path):
    path = tmp_path / "huge.csv"
    with path.open("wb") as handle:  # sparse: no disk space used
        handle.truncate(MAX_READ_BYTES + 1)
    with pytest.raises(ValueError, match=r"huge\.csv' holds 256 MiB; .* at most 256 MiB"):
        TraceDelay.from_csv(path)
    with pytest.raises(FileNotFoundError, match=r"path = '.*absent\.csv' does not exist"):
        regular_file(tmp_path / "absent.csv", "path =")


# ---- 3. no file content in errors -----------------------------------------------------------


def _passwd_lines() -> list[str]:
    path = Path("/etc/passwd")
    if not path.is_file():
        pytest.skip("no /etc/passwd here")
    return [line for line in path.read_text(errors="replace").splitlines() if line.strip()]


def test_a_system_file_read_as_a_trace_is_not_quoted(tmp_path, capsys):
    lines = _passwd_lines()
    messages = []
    for read in (
        lambda: TraceDelay.from_csv("/etc/passwd"),
        lambda: TraceDelay.from_csv("/etc/passwd", time_column="t", delay_column="h"),
        lambda: SplineReference.from_csv("/etc/passwd", columns=["q"]),
    ):
        with pytest.raises(ValueError) as error:
            read()
        messages.append(str(error.value))
    scenario = scenario_file(tmp_path, delay={"type": "trace", "path": "/etc/passwd"})
    assert main(["simulate", str(scenario), "--out", str(tmp_path / "out")]) == 2
    messages.append(one_line_error(capsys, "/etc/passwd"))
    for message in messages:
        assert lines[0] not in message, message
        assert not any(field in message for field in lines[0].split(":") if len(field) > 3)


def test_a_bad_cell_is_named_by_its_place_not_quoted(tmp_path):
    path = tmp_path / "trace.csv"
    path.write_text("t,h\n0,0.05\n1,secret-token-123\n")
    with pytest.raises(ValueError) as error:
        TraceDelay.from_csv(path)
    assert "line 3, column 'h'" in str(error.value)
    assert "secret" not in str(error.value)
    path.write_text("0,0.05\n1,0.06,secret-token-123\n")
    with pytest.raises(ValueError, match="line 2 must have 2 columns") as error:
        TraceDelay.from_csv(path)
    assert "secret" not in str(error.value)
