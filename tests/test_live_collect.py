"""A session whose nodes were started one by one (``live_nodes`` of tests/conftest.py): ``live
collect`` summarises it as ``live run`` does, and ``live replay`` works on the folder (no timing
asserted)."""

from __future__ import annotations

import csv
import html
import json
import shutil
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("zenoh")
pytest.importorskip("mcap_ros2")

from delaytrack.live.session import ROLES  # noqa: E402

SCENARIO = "two_link_S1"
PYTHON = [sys.executable, "-m", "delaytrack.live"]


@pytest.fixture(scope="module")
def folder(live_nodes):
    out, _name, outputs, codes, _statuses = live_nodes
    assert all(code == 0 for code in codes.values()), outputs
    return out


def test_collect_writes_the_summary_and_report_and_replay_then_works(folder):
    assert not (folder / "summary.json").exists()
    done = subprocess.run(
        [*PYTHON, "collect", str(folder), SCENARIO], capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr
    assert "live session two_link_S1" in done.stdout
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["stopped_by"] == {role: "duration" for role in ROLES}
    with open(folder / "ticks.csv", newline="") as handle:
        sent = [r for r in csv.DictReader(handle) if r["status"] != "no-state"]
    assert summary["commands"] == len(sent) > 0
    assert (folder / "report.html").is_file() and (folder / "delays.csv").is_file()
    replayed = subprocess.run(
        [*PYTHON, "replay", str(folder), "--quiet"], capture_output=True, text=True, timeout=300
    )
    assert replayed.returncode == 0, replayed.stderr
    assert json.loads((folder / "replay.json").read_text())["ticks_compared"] > 0


def test_a_session_recorded_before_its_tables_named_units_is_replayed_the_same(folder, tmp_path):
    """States, ticks and steps read by their plain names (``q1``, ``q1_dot``, ``u1``) where a
    table has no others: the same replay as of the tables with units (``q1_rad``, ``u1_Nm``)."""
    if not (folder / "replay.json").exists():  # replayed by the test above, unless run alone
        subprocess.run([*PYTHON, "collect", str(folder), SCENARIO], check=True, timeout=300)
        subprocess.run([*PYTHON, "replay", str(folder), "--quiet"], check=True, timeout=300)
    copy = tmp_path / "session"
    shutil.copytree(folder, copy)
    _forget_sizes(copy)  # nodes of that version recorded none
    plain = {"_rad_per_s": "", "_rad": "", "_Nm": ""}
    for name in ("states.csv", "ticks.csv", "steps.csv"):
        header, rest = (copy / name).read_text().split("\n", 1)
        for suffix in plain:
            header = header.replace(suffix, "")
        assert "q1" in header or "u1" in header
        (copy / name).write_text(header + "\n" + rest)
    done = subprocess.run(
        [*PYTHON, "replay", str(copy), "--quiet"], capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr
    before = json.loads((folder / "replay.json").read_text())
    after = json.loads((copy / "replay.json").read_text())
    assert after == before


def test_collect_names_the_files_a_folder_lacks(tmp_path):
    done = subprocess.run(
        [*PYTHON, "collect", str(tmp_path), SCENARIO], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and "lacks controller.json" in done.stderr, done.stderr


@pytest.mark.parametrize(
    ("scenario", "edit", "message"),
    [
        ("robot_S1", None, "the robot node ran another scenario than robot_S1 (they differ in "
         "plant, coordinates, T_c); give the scenario file the nodes ran"),
        ("two_link_S3", None, "(they differ in the rest of the scenario)"),
        (SCENARIO, lambda f: (f / "robot.json").write_text("{bad"), "robot.json is not a node's "
         "record (not JSON"),
        (SCENARIO, lambda f: (f / "delay.json").write_text("[1, 2]"), "delay.json is not a "
         "node's record: it holds no JSON table"),
        (SCENARIO, lambda f: (f / "ticks.csv").write_text("k,t_s\n1,0\n"), "ticks.csv: no "
         "column 'send_s'"),
        (SCENARIO, lambda f: _edit_cell(f / "releases.csv", "seq", "x"), "releases.csv, line 2: "
         "column 'seq' holds 'x', not an index"),
    ],
)  # fmt: skip
def test_collect_refuses_another_scenario_or_a_damaged_file_in_one_line(
    folder, tmp_path, scenario, edit, message
):
    """Before it writes anything: the folder's scenario.toml is the one the nodes ran."""
    copy = tmp_path / "session"
    shutil.copytree(folder, copy)
    for name in ("scenario.toml", "summary.json"):
        (copy / name).unlink(missing_ok=True)
    if edit is not None:
        _forget_sizes(copy)  # a table's content is checked too (nodes of earlier versions)
        edit(copy)
    done = subprocess.run(
        [*PYTHON, "collect", str(copy), scenario], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr
    assert done.stderr.count("\n") == 1 and message in done.stderr, done.stderr
    assert not (copy / "scenario.toml").exists() and not (copy / "summary.json").exists()


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda f: (f / "states.csv").unlink(), "states.csv is missing or has no rows"),
        (
            lambda f: (f / "states.csv").write_text("j,t_s\n"),
            "states.csv is missing or has no rows",
        ),
        (lambda f: (f / "summary.json").write_text("[1, 2]"), "is not a session summary"),
        (lambda f: (f / "summary.json").write_text('{"nodes": 5}'), "needs a table 'nodes'"),
        (lambda f: (f / "summary.json").write_text("nope"), "summary.json is not a session"),
        (
            lambda f: _edit_cell(f / "ticks.csv", "k", "x"),
            "ticks.csv, line 2: column 'k' holds 'x'",
        ),
        (
            lambda f: _edit_cell(f / "applied.csv", "applied_s", "nan"),
            "applied.csv, line 2: ('applied_s', 't_k_s') must be finite",
        ),
        (  # the gains changed after the session: the replay would blame the robot
            lambda f: (f / "scenario.toml").write_text(
                (f / "scenario.toml").read_text().replace("K1 = ", "K1 = 5.0 #", 1)
            ),
            "the session folder's scenario.toml was changed after the session",
        ),
    ],
)
def test_replay_of_an_edited_folder_is_refused_in_one_line_naming_the_file(
    folder, tmp_path, edit, message
):
    """A copy of the folder, collected (the test above collects the folder itself), edited."""
    copy = tmp_path / "session"
    shutil.copytree(folder, copy)
    if not (copy / "summary.json").exists():
        subprocess.run([*PYTHON, "collect", str(copy), SCENARIO], check=True, timeout=300)
    _forget_sizes(copy)  # a table's content is checked too (nodes of earlier versions)
    edit(copy)
    done = subprocess.run(
        [*PYTHON, "replay", str(copy), "--quiet"], capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr
    assert done.stderr.count("\n") == 1 and message in done.stderr, done.stderr


def _edit_cell(path, column, value):
    """Put ``value`` in ``column`` of the first row of the CSV table ``path``."""
    with open(path, newline="") as handle:
        rows = list(csv.reader(handle))
    rows[1][rows[0].index(column)] = value
    with open(path, "w", newline="") as handle:
        csv.writer(handle).writerows(rows)


@pytest.mark.parametrize(
    ("command", "table", "role"),
    [("collect", "applied.csv", "robot"), ("replay", "states.csv", "robot"),
     ("replay", "ticks.csv", "controller")],
)  # fmt: skip
def test_a_table_cut_short_is_refused_naming_both_sizes(folder, tmp_path, command, table, role):
    """A node records the size of each table it wrote: a copy made before the table was whole
    (its last row cut in two, which reads as a shorter number) is refused."""
    copy = tmp_path / "session"
    shutil.copytree(folder, copy)
    if not (copy / "summary.json").exists():
        subprocess.run([*PYTHON, "collect", str(copy), SCENARIO], check=True, timeout=300)
    size = (copy / table).stat().st_size
    (copy / table).write_bytes((copy / table).read_bytes()[:-5])
    arguments = [str(copy), SCENARIO] if command == "collect" else [str(copy), "--quiet"]
    done = subprocess.run(
        [*PYTHON, command, *arguments], capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert f"{table} holds {size - 5} bytes where the {role} node wrote {size}" in done.stderr


def test_a_table_whose_line_breaks_a_copy_turned_into_newlines_is_taken(folder, tmp_path):
    copy = tmp_path / "session"
    shutil.copytree(folder, copy)
    table = copy / "ticks.csv"
    assert b"\r\n" in table.read_bytes()  # as csv writes it
    table.write_bytes(table.read_bytes().replace(b"\r\n", b"\n"))
    done = subprocess.run(
        [*PYTHON, "collect", str(copy), SCENARIO, "--quiet"], capture_output=True, text=True,
        timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr


def _forget_sizes(folder):
    """The folder as a session of nodes that recorded no table sizes nor digests (an earlier
    version)."""
    for path in [folder / f"{role}.json" for role in ROLES]:
        record = json.loads(path.read_text())
        record.pop("table_bytes", None)
        record.pop("table_sha256", None)
        path.write_text(json.dumps(record))
    summary = folder / "summary.json"
    if summary.exists():
        data = json.loads(summary.read_text())
        for record in data["nodes"].values():
            record.pop("table_bytes", None)
            record.pop("table_sha256", None)
        summary.write_text(json.dumps(data))


def _same_length_edit(path, column):
    """Replace the first row's ``column`` cell of the table ``path`` with as many ``x``: the
    table keeps its size."""
    with open(path, newline="") as handle:
        rows = list(csv.reader(handle))
    rows[1][rows[0].index(column)] = "x" * len(rows[1][rows[0].index(column)])
    with open(path, "w", newline="") as handle:
        csv.writer(handle).writerows(rows)


@pytest.mark.parametrize(
    ("command", "table", "column"),
    [("replay", "states.csv", "t_s"), ("collect", "releases.csv", "received_s")],
)
def test_a_table_changed_to_the_same_size_is_refused(folder, tmp_path, command, table, column):
    """A number replaced by text of its length was read as NaN and the session replayed: the
    nodes record each table's digest."""
    copy = tmp_path / "session"
    shutil.copytree(folder, copy)
    if not (copy / "summary.json").exists():
        subprocess.run([*PYTHON, "collect", str(copy), SCENARIO], check=True, timeout=300)
    size = (copy / table).stat().st_size
    _same_length_edit(copy / table, column)
    assert (copy / table).stat().st_size == size
    argv = [str(copy), "--quiet"] if command == "replay" else [str(copy), SCENARIO]
    done = subprocess.run([*PYTHON, command, *argv], capture_output=True, text=True, timeout=300)
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert f"{table} holds other contents than the" in done.stderr, done.stderr


def test_records_of_two_sessions_in_one_folder_are_refused(folder, tmp_path):
    copy = tmp_path / "session"
    shutil.copytree(folder, copy)
    record = json.loads((copy / "robot.json").read_text())
    record["session"]["t0_robot_clock"] += 37.0  # the robot's of a session started later
    (copy / "robot.json").write_text(json.dumps(record))
    done = subprocess.run(
        [*PYTHON, "collect", str(copy), SCENARIO], capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 2 and "the node records are of different sessions" in done.stderr


def test_a_session_whose_controller_logged_no_tick_is_reported_with_no_command(folder, tmp_path):
    # ticks.csv of its header alone: the commands read at every tick were rows -1 of nothing.
    from delaytrack.live.report import live_result
    from delaytrack.scenario import load_builtin

    copy = tmp_path / "session"
    shutil.copytree(folder, copy)
    header = (copy / "ticks.csv").read_text().splitlines()[0]
    (copy / "ticks.csv").write_text(header + "\n")
    scenario = load_builtin(SCENARIO)
    result = live_result(copy, scenario, scenario.build())
    assert result.t.size > 1 and not result.commands.any()  # zero before a first command
    assert np.isfinite(result.applied[0, :-1]).all()  # the robot's steps (to the last) read


def test_a_session_whose_controller_did_not_finish_reports_no_command_and_na(folder, tmp_path):
    """The controller killed: no ticks.csv and no record. Its commands are unknown (NaN, no TV),
    not zeros, and its rows of the report say n/a, not "0 ticks" or "the true state"."""
    from delaytrack.live.report import _timing_settings, live_result
    from delaytrack.scenario import load_builtin

    copy = tmp_path / "session"
    shutil.copytree(folder, copy)
    (copy / "ticks.csv").unlink()
    scenario = load_builtin(SCENARIO)
    result = live_result(copy, scenario, scenario.build())
    assert np.isnan(result.commands).all() and np.isnan(result.settings["commands_between_t"]).all()
    rows = _timing_settings({}, scenario, {}, {"steps": 5}, {"received": 5})
    for name in ("controller ticks", "state the controller's law read"):
        assert rows[name].startswith("n/a: the controller node wrote no record"), rows[name]
    assert rows["robot steps"].startswith("5 (")


def test_collect_says_which_node_did_not_finish(folder, tmp_path):
    """A node killed midway leaves its log, not its record and tables: said so, not "put the
    files the three nodes wrote into one folder"."""
    copy = tmp_path / "session"
    shutil.copytree(folder, copy)
    (copy / "controller.json").unlink()
    (copy / "ticks.csv").unlink()
    done = subprocess.run(
        [*PYTHON, "collect", str(copy), SCENARIO], capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert "the controller node did not finish (its log controller.mcap is there" in done.stderr


def test_a_replay_that_stops_early_is_compared_only_where_both_ran(folder, tmp_path, monkeypatch):
    """A replay that stopped (diverged, off the path) has no numbers after it: the live ticks
    after it are not compared, the RMS of both runs are taken over the same ticks, and the
    line says where the replay stopped (it said "0.00 %" beside a live RMS that counted ticks
    the replay never reached, with a RuntimeWarning of an all-NaN row)."""
    import dataclasses

    from delaytrack.live import replay as replay_module

    if not (folder / "summary.json").exists():  # collected by the first test, unless run alone
        subprocess.run([*PYTHON, "collect", str(folder), SCENARIO], check=True, timeout=300)
    copy = tmp_path / "session"
    shutil.copytree(folder, copy)
    resimulate = replay_module._resimulate
    cut = {}

    def stopped_halfway(*args, **kwargs):
        whole = resimulate(*args, **kwargs)
        half = whole.t.size // 2
        x = whole.x.copy()
        x[:, half:] = np.nan
        cut.update(whole=whole, half=half)
        return dataclasses.replace(
            whole, x=x, status=np.array([3]), t_stop=np.array([whole.t[half]])
        )

    monkeypatch.setattr(replay_module, "_resimulate", stopped_halfway)
    report, _, _ = replay_module._replay(copy)
    half, whole = cut["half"], cut["whole"]
    assert report["status"] == "left the path"
    assert report["replay_stopped_at_s"] == whole.t[half]
    assert 0 < report["ticks_compared"] <= half
    rows = np.loadtxt(copy / "replay.csv", delimiter=",", skiprows=1, ndmin=2)
    # k, t, e1 live and replayed (two coordinates each): every compared tick has both errors
    assert len(rows) == report["ticks_compared"] and np.isfinite(rows[:, :6]).all()
    assert rows[:, 1].max() < whole.t[half]
    q1 = report["coordinates"]["q1"]
    live_rms = np.sqrt(np.mean(rows[:, 2] ** 2))  # e1_q1 live, over the ticks compared
    assert q1["tracking_error_rms_live"] == pytest.approx(live_rms, rel=1e-12)
    text = replay_module.ticks_compared_text(report)
    assert text.endswith("the live ticks after it are not compared")
    assert f"stopped as 'left the path' at t = {whole.t[half]:g} s" in text


def test_the_reports_note_on_the_error_bound_comes_after_the_summary(
    folder, tmp_path, monkeypatch, capsys
):
    """The note that the live error passed the scenario's ``error_bound`` is printed below the
    session's summary, where it is read with it (it came above, while the report was written)."""
    from delaytrack.live import report as report_module
    from delaytrack.live.cli import main as live_main

    copy = tmp_path / "session"
    shutil.copytree(folder, copy)
    said = "the tracking error passed the scenario's error_bound (q1 0.001 rad) at t = 0.1 s"
    monkeypatch.setattr(report_module, "error_bound_text", lambda *_: said)
    assert live_main(["collect", str(copy), SCENARIO]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[-1] == f"note: {said}"
    assert any(line.startswith("live session two_link_S1") for line in lines[:-1]), lines
    assert said in html.unescape((copy / "report.html").read_text())


def test_a_file_the_replay_cannot_write_is_one_line_from_python_dash_m(folder, tmp_path):
    """``python -m delaytrack.live`` says it as the ``delaytrack`` command does (it printed a
    traceback naming the replay's temporary file)."""
    if not (folder / "summary.json").exists():  # collected by the first test, unless run alone
        subprocess.run([*PYTHON, "collect", str(folder), SCENARIO], check=True, timeout=300)
    copy = tmp_path / "session"
    shutil.copytree(folder, copy)
    (copy / "replay.csv").unlink(missing_ok=True)
    (copy / "replay.csv").mkdir()
    done = subprocess.run(
        [*PYTHON, "replay", str(copy), "--quiet"], capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 1 and "Traceback" not in done.stderr, done.stderr
    errors = [line for line in done.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "replay.csv" in errors[0], done.stderr
