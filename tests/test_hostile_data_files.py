"""Data files are read with the command line's number rule, only from regular files of bounded
size, with units, header names and errors that cannot mislead; files a MuJoCo model names are
checked as its own path is.

The cases of the campaigns (``0_05`` in a trace read as 5 s, ``0_5`` in waypoints read as 5, a
FIFO that hangs a read, ``/etc/passwd``'s or a token's first line in an error, ``delay_ms_mean``
read as seconds, a repeated waypoint column read twice, a header-less waypoint file losing its
first sample, a FIFO included by a MuJoCo model) as regression tests, through the Python API and
the command line, and two properties: a CSV cell and a command-line argument are read by the
same rule; whatever a header row holds, no error quotes it and no column named in another unit
is read as seconds.
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

from delaytrack._io import MAX_READ_BYTES, named_time_units, regular_file
from delaytrack.cli import main
from delaytrack.cli._numbers import scalar as _scalar
from delaytrack.cli._usage import UsageError
from delaytrack.delays import TraceDelay
from delaytrack.references import SplineReference
from delaytrack.scenario import Scenario, ScenarioError
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
        os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
        pytest.fail(f"reading {fifo} waited for a writer instead of being refused")
    return outcome[0]


def scenario_file(folder: Path, **tables: object) -> Path:
    path = folder / "case.toml"
    Scenario.from_dict({**base_dict(), **tables}).to_toml(path)
    return path


def make_fifo(path: Path) -> Path:
    """A FIFO at ``path``; the test is skipped where the system has none."""
    if not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs on this system")
    os.mkfifo(path)
    return path


def mujoco_plant() -> type:
    """The MuJoCo plant class; the test is skipped without MuJoCo."""
    pytest.importorskip("mujoco")
    from delaytrack.plants import MujocoPlant

    return MujocoPlant


@pytest.fixture
def fifo(tmp_path) -> Path:
    return make_fifo(tmp_path / "pipe.csv")


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
    with pytest.raises(ValueError, match=r"poses\.csv: line 3, column 2 must be a"):
        SplineReference.from_csv(path)
    scenario = scenario_file(tmp_path, reference={**_SPLINE, "path": "poses.csv"})
    assert main(["simulate", str(scenario), "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, "poses.csv: line 3, column 2 ", "'_'")


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
    with pytest.raises(ValueError, match=r"line 1, column 't' must be a number"):
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
        with pytest.raises(ValueError, match=r"line 2, column 2 (must|is too)"):
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
        with pytest.raises(ValueError, match=r"line 2, column 2 (must|is too)"):
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
    value = {**({"type": "trace"} if table == "delay" else _SPLINE), "path": fifo.name}
    scenario = scenario_file(tmp_path, **{table: value})
    assert promptly(fifo, main, ["simulate", str(scenario), "--out", str(tmp_path / "o")]) == 2
    one_line_error(capsys, f"'{table}.path' = ", "is not a file but a FIFO (named pipe)")


@pytest.mark.parametrize("command", ["simulate", "sweep"])
def test_a_scenario_or_sweep_file_that_is_a_fifo_is_refused(tmp_path, capsys, command):
    fifo = make_fifo(tmp_path / "case.toml")
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
    fifo = make_fifo(tmp_path / "make.py")
    scenario = scenario_file(tmp_path)
    text = scenario.read_text().replace('type = "arolc"', 'type = "python:make.py:controller"')
    scenario.write_text(text)
    error = promptly(fifo, lambda: Scenario.from_toml(scenario).build())
    assert isinstance(error, ScenarioError), error
    assert "factory file '" in str(error) and "is not a file but a FIFO" in str(error)


def test_a_mujoco_model_that_is_a_fifo_is_refused(tmp_path):
    MujocoPlant = mujoco_plant()
    fifo = make_fifo(tmp_path / "arm.xml")
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
    # The message starts with the scenario file's name (whose folder, pytest-of-<user>, may hold
    # a field of the first line, such as "root"); the rest must not quote the system file.
    line = one_line_error(capsys, "/etc/passwd")
    assert line.startswith(f"error: {scenario}: "), line
    messages.append(line.removeprefix(f"error: {scenario}: "))
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


@pytest.mark.parametrize(
    ("text", "count"),
    [
        ("sk_live_4eC39HqLyjWDarjtT1zdp7dc\n", 1),  # a line that looks like a name was quoted
        ("machine api.example.com password Hunter2\n", 1),
        ("vm-host-7\n", 1),
        ("sk_live_4eC39HqLyjWDarjtT1zdp7dc,Hunter2,api.example.com\n0,0,0\n", 3),
    ],
)
def test_a_first_line_that_looks_like_names_is_not_quoted(tmp_path, capsys, text, count):
    path = tmp_path / "token"
    path.write_text(text)
    secrets = [word for word in text.replace(",", " ").split() if len(word) > 3]
    messages = []
    for read in (
        lambda: TraceDelay.from_csv(path),
        lambda: TraceDelay.from_csv(path, time_column="t", delay_column="h"),
        lambda: SplineReference.from_csv(path),
        lambda: SplineReference.from_csv(path, time_column="t", columns=["q"]),
    ):
        with pytest.raises(ValueError) as error:
            read()
        messages.append(str(error.value))
    scenario = scenario_file(tmp_path, delay={"type": "trace", "path": "token"})
    assert main(["simulate", str(scenario), "--out", str(tmp_path / "out")]) == 2
    messages.append(one_line_error(capsys, "token: the header row has"))
    for message in messages:
        assert not any(secret in message for secret in secrets), message
    columns = "1 column" if count == 1 else f"{count} columns"
    wider = "; name the time and delay columns (time_column, delay_column) to read a wider log"
    assert messages[0] == (
        f"{path}: the header row has {columns}; a trace has 2 (t, h)" + (wider if count > 2 else "")
    )
    assert messages[1] == f"{path}: time_column = 't' is not in the header row (of {columns})"
    assert (
        messages[3]
        == f"{path}: time_column names 't', which is not in the header row (of {columns})"
    )


# ---- 4. units named inside a column's name --------------------------------------------------


@pytest.mark.parametrize(
    ("header", "options", "outcome"),
    [
        # read as seconds with exit 0 before: the unit was not at the end of the name
        ("t_s,delay_ms_mean", {}, "column 2 (the delay) names a unit (ms: milliseconds), but it"),
        ("t_s,delay_ms_mean", {"delay_unit": "ms"}, 0.05),
        ("t,h_min", {}, "column 2 (the delay) may name a unit (min: minutes); say which unit"),
        ("t,h_min", {"delay_unit": "s"}, 50.0),  # the user says min is a minimum
        ("t,h_min", {"delay_unit": "ms"}, 0.05),
        ("t,h (ms) avg", {}, "give delay_unit = 'ms'"),
        ("t,rtt/MS", {}, "give delay_unit = 'ms'"),
        ("t,delay-µs", {"delay_unit": "us"}, 50e-6),  # the micro sign, NFKC-normalised
        ("t,h_minutes", {}, "names a unit (min: minutes), which is not read"),
        ("t,h_minutes", {"delay_unit": "s"}, "but delay_unit = 's'; make them agree"),
        ("t,delay_ms", {"delay_unit": "s"}, "but delay_unit = 's'; make them agree"),
        ("t,h", {}, 50.0),  # h is the delay, not hours
        ("t [s],h (s)", {}, 50.0),
        ("t,h_s_mean", {}, 50.0),
        ("t,h_max", {}, 50.0),
        # the time column gets the same treatment
        ("t_ms,h", {}, "column 1 (the time) names a unit (ms: milliseconds), but it would be"),
        ("t_min,h", {}, "column 1 (the time) may name a unit (min: minutes); say which unit"),
        ("t_min,h", {"time_unit": "s"}, 50.0),
        ("stamp hrs,h", {}, "column 1 (the time) names a unit (hr: hours), which is not read"),
        ("stamp_us,delay_s", {"time_unit": "us"}, 50.0),
    ],
)
def test_a_unit_anywhere_in_a_column_name_is_not_read_as_seconds(
    tmp_path, header, options, outcome
):
    path = tmp_path / "trace.csv"
    path.write_text(f"{header}\n0,50\n1,50\n")
    if isinstance(outcome, str):
        with pytest.raises(ValueError) as error:
            TraceDelay.from_csv(path, **options)
        assert str(error.value).startswith(f"{path}: the name of "), str(error.value)
        assert outcome in str(error.value)
    else:
        np.testing.assert_allclose(TraceDelay.from_csv(path, **options).values, [outcome] * 2)


def test_units_in_column_names_the_user_gave_and_on_the_command_line(tmp_path, capsys):
    path = tmp_path / "trace.csv"
    path.write_text("seq,t_s,delay_ms_mean\n1,0,50\n2,1,50\n")
    with pytest.raises(ValueError) as error:
        TraceDelay.from_csv(path, time_column="t_s", delay_column="delay_ms_mean")
    assert str(error.value) == (
        f"{path}: delay_column = 'delay_ms_mean' names a unit (ms: milliseconds), but it would "
        "be read in seconds; give delay_unit = 'ms' (or correct the column's name)"
    )
    path.write_text("t_s,delay_ms_mean\n0,50\n1,50\n")
    scenario = scenario_file(
        tmp_path, delay={"type": "trace", "path": "trace.csv", "beyond": "hold"}
    )
    assert main(["simulate", str(scenario), "--out", str(tmp_path / "out")]) == 2  # was h = 50 s
    one_line_error(capsys, "column 2 (the delay) names a unit (ms: milliseconds)")


def test_waypoint_times_named_in_another_unit_are_refused(tmp_path):
    path = tmp_path / "poses.csv"
    path.write_text("t_ms,q1,q2\n0,0,0\n100,1,1\n")
    with pytest.raises(ValueError) as error:
        SplineReference.from_csv(path)
    assert str(error.value) == (
        f"{path}: the name of column 1 (the time) names a unit (ms: milliseconds), but it is "
        "read in seconds; give the values in seconds, under a name that names no other unit"
    )
    path.write_text("time (s),q1_ms,q2\n0,0,0\n0.1,1,1\n")  # a coordinate's name is its own
    np.testing.assert_array_equal(SplineReference.from_csv(path).times, [0.0, 0.1])


# ---- 5. repeated column names; files without a header row ----------------------------------


def test_repeated_column_names_are_refused_by_position(tmp_path, capsys):
    path = tmp_path / "w.csv"
    path.write_text("t,x,x\n0,0,5\n0.1,0.1,5\n0.2,0.2,5\n")  # q2_d followed column 2, exit 0
    message = (
        f"{path}: columns 2 and 3 of the header row (line 1) have the same name; each column "
        "needs a name of its own"
    )
    with pytest.raises(ValueError) as error:
        SplineReference.from_csv(path)
    assert str(error.value) == message
    scenario = scenario_file(tmp_path, reference={**_SPLINE, "path": "w.csv"})
    assert main(["simulate", str(scenario), "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, "columns 2 and 3 of the header row (line 1) have the same name")
    path.write_text("\n t ,x , \uff58,y\n0,0,5,1\n1,1,5,1\n")  # a full-width x is an x (NFKC)
    with pytest.raises(ValueError, match=r"columns 2 and 3 of the header row \(line 2\) have"):
        SplineReference.from_csv(path, columns=["y"])
    path.write_text("stamp,delay,seq,delay\n0,0.01,1,5\n1,0.01,2,5\n")
    with pytest.raises(ValueError, match=r"columns 2 and 4 of the header row \(line 1\) have"):
        TraceDelay.from_csv(path, time_column="stamp", delay_column="delay")
    path.write_text("t,h,,\n0,0.01,,\n1,0.01,,\n")
    with pytest.raises(ValueError, match=r"columns 3 and 4 of the header row \(line 1\) have no"):
        TraceDelay.from_csv(path)


def test_waypoints_without_a_header_are_read_as_a_trace_is(tmp_path):
    path = tmp_path / "w.csv"
    path.write_text("0,0.1,0.2\n0.1,0.5,0.6\n0.2,1,1.1\n")  # the first sample was a header
    spline = SplineReference.from_csv(path)
    np.testing.assert_array_equal(spline.times, [0.0, 0.1, 0.2])
    np.testing.assert_array_equal(spline.values[0], [0.1, 0.2])
    for options in ({"time_column": "t"}, {"columns": ["q1"]}):
        with pytest.raises(ValueError, match=r"names header columns, but the file has no header"):
            SplineReference.from_csv(path, **options)
    path.write_text("0,0.1,0.2\n0.1,0.5\n")
    with pytest.raises(ValueError, match=r"line 2 must have 3 columns as its first row; it has 2"):
        SplineReference.from_csv(path)
    path.write_text("0\n1\n")
    with pytest.raises(ValueError, match=r"line 1 has 1 column; waypoints need a column of"):
        SplineReference.from_csv(path)


@st.composite
def headers(draw) -> tuple[list[str], list[str]]:
    """Header rows whose names mix unit words, other words and a secret, and the secrets."""
    words = st.sampled_from(
        ["t", "h", "delay", "stamp", "mean", "x", "s", "sec", "ms", "MS", "us", "\u00b5s", "ns"]
        + ["min", "Min", "minutes", "hr", "hours", "millis", "h_max"]
    )
    cells, secrets = [], []
    for _ in range(draw(st.integers(1, 4))):
        secret = draw(st.from_regex(r"[a-z]{2}[0-9]{4}[a-z]{2}", fullmatch=True))
        parts = [*draw(st.lists(words, max_size=2)), secret, *draw(st.lists(words, max_size=2))]
        cells.append(draw(st.sampled_from(["_", " ", "-", "/", " (", "["])).join(parts))
        secrets.append(secret)
    return cells, secrets


@given(header=headers())
@settings(max_examples=200, deadline=None)
def test_errors_never_quote_a_header_and_units_are_never_read_as_seconds(tmp_path_factory, header):
    """Whatever a header row holds, no error quotes it, and a trace or waypoints read with
    default options have no time or delay column whose name names another unit."""
    cells, secrets = header
    path = tmp_path_factory.mktemp("headers") / "data.csv"
    width = len(cells)
    with path.open("w", newline="") as handle:
        csv.writer(handle).writerows([cells, ["0"] + ["0.01"] * (width - 1), ["1"] * width])
    for read, checked in ((TraceDelay.from_csv, cells[:2]), (SplineReference.from_csv, cells[:1])):
        try:
            read(path)
        except ValueError as error:
            message = str(error).replace(str(path), "")
            assert not any(secret in message for secret in secrets), message
        else:
            for cell in checked:
                assert all(unit == "s" for unit, _ in named_time_units(cell)), cell


# ---- 6. files a MuJoCo model names ----------------------------------------------------------


_ARM = Path(__file__).resolve().parents[1] / "examples" / "mujoco_arm" / "arm3.xml"


def _model(folder: Path, extra: str, suffix: str = ".xml") -> Path:
    """The example arm with ``extra`` right after its opening tag."""
    text = _ARM.read_text().replace('<mujoco model="arm3">', f'<mujoco model="arm3">\n{extra}')
    path = folder / f"arm{suffix}"
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    ("fifo_name", "extra", "element"),
    [
        ("f1", '<include file="{fifo}"/>', "<include file>"),
        ("f2.stl", '<asset><mesh name="x" file="{fifo}"/></asset>', "<mesh file>"),
        ("p.stl", '<compiler meshdir="meshes"/><asset><mesh name="x" file="p.stl"/></asset>', ""),
        ("t.png", '<asset><texture type="cube" name="x" fileright="{fifo}"/></asset>', "fileright"),
        ("deep.xml", '<include file="sub/one.xml"/>', "of '"),
    ],
)
def test_a_fifo_a_mujoco_model_includes_or_names_is_refused(tmp_path, fifo_name, extra, element):
    MujocoPlant = mujoco_plant()
    (tmp_path / "meshes").mkdir()
    (tmp_path / "sub").mkdir()
    fifo = make_fifo(tmp_path / ("meshes" if fifo_name == "p.stl" else "") / fifo_name)
    (tmp_path / "sub" / "one.xml").write_text(f'<mujoco>\n<include file="{fifo}"/>\n</mujoco>\n')
    model = _model(tmp_path, extra.format(fifo=fifo))
    error = promptly(fifo, MujocoPlant, model)  # hung in MuJoCo's read before
    assert isinstance(error, ValueError), error
    assert str(error).startswith(f"path {str(model)!r}: line ")
    assert element in str(error) and "is not a file but a FIFO (named pipe)" in str(error)


def test_a_fifo_a_urdf_names_as_a_mesh_is_refused(tmp_path):
    MujocoPlant = mujoco_plant()
    fifo = make_fifo(tmp_path / "link.stl")
    urdf = Path(__file__).resolve().parents[1] / "examples" / "mujoco_urdf" / "two_link.urdf"
    text = urdf.read_text().replace(
        '<link name="fore">',
        '<link name="fore"><collision><geometry><mesh filename="package://arm/meshes/link.stl"/>'
        "</geometry></collision>",
    )
    model = tmp_path / "arm.urdf"
    model.write_text(text)
    error = promptly(fifo, MujocoPlant, model)
    assert isinstance(error, ValueError), error
    assert f"<mesh filename> {str(fifo)!r} is not a file but a FIFO" in str(error)


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (
            '<asset><texture name="t" type="2d" builtin="checker" width="60000" height="60000"'
            ' rgb1="1 1 1" rgb2="0 0 0"/></asset>',
            r"<texture width height> asks for 3,600,000,000 points; at most 16,777,216",
        ),
        # written as MuJoCo reads them too: a sign, leading zeros
        (
            '<asset><texture name="t" type="2d" builtin="checker" width="+60000" '
            'height="0000000000000000000060000" rgb1="1 1 1" rgb2="0 0 0"/></asset>',
            r"<texture width height> asks for 3,600,000,000 points",
        ),
        # a cube or skybox is six squares of its width, whatever its height
        (
            '<asset><texture name="t" type="skybox" builtin="gradient" width="20000" height="1"'
            ' rgb1="1 1 1" rgb2="0 0 0"/></asset>',
            r"<texture width height> asks for 2,400,000,000 points",
        ),
        (
            '<worldbody><flexcomp name="f" type="grid" count="3000 3000 1" spacing=".1 .1 .1"'
            ' radius=".01" dim="2"/></worldbody>',
            r"<flexcomp count> asks for 9,000,000 points; at most 100,000",
        ),
        (
            '<asset><hfield name="h" nrow="20000" ncol="20000" size="1 1 1 1"/></asset>',
            r"<hfield nrow ncol> asks for 400,000,000 points",
        ),
        (
            '<worldbody><replicate count="1000" offset="0 0 1"><replicate count="1000" '
            'offset="0 1 0"><geom type="sphere" size=".01"/></replicate></replicate></worldbody>',
            r"replicates 1000 x 1000 = 1,000,000 copies; at most 100,000 are made",
        ),
        # a built-in mesh of resolution 4000: 16 million vertices (1000 took 3.0 GB)
        (
            '<asset><mesh name="m" builtin="supersphere" params="4000 1 1"/></asset>',
            r"<mesh builtin params> asks for about 16,000,000 vertices; at most 100,000",
        ),
        (
            '<asset><mesh name="m" builtin="wedge" params="1000 1000 1 1 1"/></asset>',
            r"<mesh builtin params> asks for about 1,000,000 vertices",
        ),
    ],
    ids=[
        "texture",
        "signed-padded",
        "skybox",
        "flexcomp",
        "hfield",
        "replicate",
        "supersphere",
        "wedge",
    ],
)
def test_a_model_that_would_take_gigabytes_is_refused_before_mujoco_reads_it(
    tmp_path, extra, message
):
    # A few bytes of XML that make MuJoCo hold gigabytes (a checker texture of 60 000 x 60 000
    # pixels took 10.7 GB): refused from the XML, before MuJoCo allocates anything.
    from delaytrack.plants.mujoco.model_files import check_model_files

    with pytest.raises(ValueError, match=message):
        check_model_files(_model(tmp_path, extra))


def test_a_built_in_mesh_of_a_usual_size_is_read(tmp_path):
    from delaytrack.plants.mujoco.model_files import check_model_files

    check_model_files(
        _model(tmp_path, '<asset><mesh name="m" builtin="supersphere" params="300 1 1"/></asset>')
    )
    # a cone makes 2 nedge vertices: 400 edges are 800 vertices, not 160 000
    check_model_files(
        _model(tmp_path, '<asset><mesh name="m" builtin="cone" params="400 1"/></asset>')
    )


def test_a_texture_image_of_too_many_pixels_is_refused_from_its_header(tmp_path):
    # A few kilobytes of PNG decode to gigabytes: its header says how many pixels it holds.
    from delaytrack.plants.mujoco.model_files import check_model_files

    header = b"\x89PNG\r\n\x1a\n" + (13).to_bytes(4, "big") + b"IHDR"
    (tmp_path / "big.png").write_bytes(
        header + (60000).to_bytes(4, "big") + (60000).to_bytes(4, "big") + b"\x08\x02\0\0\0"
    )
    model = _model(tmp_path, '<asset><texture name="t" type="2d" file="big.png"/></asset>')
    with pytest.raises(ValueError, match=r"'.*big\.png' is an image of 3,600,000,000 pixels"):
        check_model_files(model)


def test_devices_and_bounds_of_files_a_model_names(tmp_path):
    MujocoPlant = mujoco_plant()
    from delaytrack.plants.mujoco.model_files import MAX_INCLUDE_DEPTH, check_model_files

    if Path("/dev/zero").exists():
        model = _model(tmp_path, '<asset><hfield name="x" file="/dev/zero"/></asset>')
        with pytest.raises(ValueError, match=r"<hfield file> '/dev/zero' is not a file but a char"):
            MujocoPlant(model)
    chain = tmp_path / "chain"
    chain.mkdir()
    for level in range(MAX_INCLUDE_DEPTH + 2):
        (chain / f"{level}.xml").write_text(f'<mujoco><include file="{level + 1}.xml"/></mujoco>')
    with pytest.raises(ValueError, match=rf"is included {MAX_INCLUDE_DEPTH + 1} levels deep"):
        check_model_files(chain / "0.xml")
    # comments with "--" (MuJoCo reads them), commented-out names and a name that resolves to
    # nothing are left to MuJoCo, as before
    check_model_files(Path(__file__).resolve().parents[1] / "src/delaytrack/data/p3dx.xml")
    model = _model(tmp_path, '<!-- <include file="/dev/zero"/> -- -->')
    check_model_files(model)
    model = _model(tmp_path, '<include file="absent.xml"/>')
    with pytest.raises(ValueError, match=r"MuJoCo could not read it"):
        MujocoPlant(model)
