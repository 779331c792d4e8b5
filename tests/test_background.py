"""A report drawn in a second process (delaytrack.jobs._background): the same files as drawn
here, and every call it does not deliver run here."""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import pytest

from delaytrack.experiments.paper import run_study
from delaytrack.jobs import _background
from delaytrack.jobs._background import second_process
from delaytrack.report.paper import write_study


@pytest.fixture
def idle(monkeypatch):
    """A core counts as idle, whatever the machine does."""
    monkeypatch.setattr(_background, "idle_cpus", lambda: 2.0)


def _files(folder: Path) -> dict[str, bytes]:
    # SVG files carry matplotlib's random ids; the PNG files and the report are compared.
    return {
        str(path.relative_to(folder)): path.read_bytes()
        for path in sorted(folder.rglob("*"))
        if path.is_file() and path.suffix != ".svg"
    }


def test_a_report_drawn_in_the_second_process_is_the_one_drawn_here(tmp_path, idle):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # beyond the certified bound, stated by the report
        study = run_study(
            reference="literal", duration=0.5, progress=False, check_dt=False, contact=False
        )
    with second_process() as second:
        second.run(write_study, study, tmp_path / "there")
        assert second._process is not None  # handed over: this process goes on
        pid = second._process.pid
        write_study(study, tmp_path / "here")
    assert pid != os.getpid()
    there, here = _files(tmp_path / "there"), _files(tmp_path / "here")
    assert there.keys() == here.keys() and "report.html" in there
    assert there == here


def test_a_call_that_fails_there_is_run_again_here_and_its_error_raised(tmp_path, idle):
    target = tmp_path / "no such folder" / "file.txt"
    with pytest.raises(FileNotFoundError), second_process() as second:
        second.run(target.write_text, "text")
        assert second._process is not None
    assert not target.exists()


def test_without_an_idle_core_or_a_pickled_call_it_runs_here(tmp_path, monkeypatch, idle):
    first, second_file = tmp_path / "first.txt", tmp_path / "second.txt"
    with second_process() as second:
        second.run(lambda: first.write_text("here"))  # a lambda does not pickle
        assert first.read_text() == "here" and second._process is None
        monkeypatch.setattr(_background, "idle_cpus", lambda: 1.0)
        second.run(second_file.write_text, "here too")
        assert second_file.read_text() == "here too" and second._process is None


def test_only_one_call_goes_there_the_next_runs_here(tmp_path, idle):
    there, here = tmp_path / "there.txt", tmp_path / "here.txt"
    with second_process() as second:
        second.run(there.write_text, "there")
        second.run(here.write_text, "here")
        assert here.read_text() == "here"  # written before the block ends
    assert there.read_text() == "there"


def test_on_another_error_the_call_under_way_is_finished_first(tmp_path, idle):
    target = tmp_path / "file.txt"
    with pytest.raises(RuntimeError, match="later"), second_process() as second:
        second.run(target.write_text, "written")
        raise RuntimeError("a later study failed")
    assert target.read_text() == "written"


def test_on_ctrl_c_the_second_process_is_stopped(idle):
    import time

    with pytest.raises(KeyboardInterrupt), second_process() as second:
        second.run(time.sleep, 600.0)
        process = second._process
        assert process is not None
        raise KeyboardInterrupt
    assert process.returncode is not None and process.returncode < 0  # killed, not waited out
