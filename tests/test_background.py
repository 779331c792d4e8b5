"""A report drawn in a second process (delaytrack.jobs._background): the same files as drawn
here, and every call it does not deliver run here."""

from __future__ import annotations

import os
import signal
import threading
import time
import warnings
from pathlib import Path

import pytest

from delaytrack._compile import first_compile, helper_process
from delaytrack.experiments.paper import run_study
from delaytrack.jobs import _background
from delaytrack.jobs._background import second_process
from delaytrack.report.paper import write_study


@pytest.fixture
def idle(monkeypatch):
    """A core counts as idle, whatever the machine does."""
    monkeypatch.delenv("DELAYTRACK_COMPILE_HELPER", raising=False)
    monkeypatch.setattr(helper_process, "idle_cpus", lambda: 2.0)


def _slow_elsewhere(parent: int, path: Path) -> None:
    """Write this process's id to ``path``; in any process but ``parent``, ten minutes later."""
    if os.getpid() != parent:
        time.sleep(600.0)
    path.write_text(str(os.getpid()))


def _write_pid(path: Path) -> None:
    """Write the id of the process that runs it to ``path``."""
    path.write_text(str(os.getpid()))


def _written_elsewhere(path: Path) -> bool:
    return path.read_text() != str(os.getpid())


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
        assert second._call is not None  # handed over: this process goes on
        process = second._process
        write_study(study, tmp_path / "here")
    assert process.returncode == 0  # drawn there, not again here
    there, here = _files(tmp_path / "there"), _files(tmp_path / "here")
    assert there.keys() == here.keys() and "report.html" in there
    assert there == here


def test_a_call_that_fails_there_is_run_again_here_and_its_error_raised(tmp_path, idle):
    target = tmp_path / "no such folder" / "file.txt"
    with pytest.raises(FileNotFoundError), second_process() as second:
        second.run(target.write_text, "text")
        assert second._call is not None
    assert not target.exists()


def test_a_call_that_does_not_pickle_runs_here_and_the_next_goes_there(tmp_path, idle):
    first, second_file = tmp_path / "first.txt", tmp_path / "second.txt"
    with second_process() as second:
        second.run(lambda: first.write_text("here"))  # a lambda does not pickle
        assert first.read_text() == "here" and second._call is None
        second.run(_write_pid, second_file)
        assert second._call is not None
    assert _written_elsewhere(second_file)


@pytest.mark.parametrize("why", ["no idle core", "the compile helper's switch"])
def test_without_an_idle_core_or_with_the_switch_off_everything_runs_here(
    tmp_path, monkeypatch, idle, why
):
    if why == "no idle core":
        monkeypatch.setattr(helper_process, "idle_cpus", lambda: 1.0)
    else:
        monkeypatch.setenv("DELAYTRACK_COMPILE_HELPER", "0")
    target = tmp_path / "file.txt"
    with second_process() as second:
        assert second._process is None
        second.run(target.write_text, "here")
        assert target.read_text() == "here"


def test_a_second_process_given_no_call_imports_its_modules_and_ends(idle):
    with second_process(("delaytrack.report.paper",)) as second:
        process = second._process
        assert process is not None
    assert process.returncode == 0


def test_a_second_process_to_start_after_the_first_compile_starts_then(tmp_path, idle):
    target = tmp_path / "file.txt"
    with second_process(("delaytrack.report.paper",), after_first_compile=True) as second:
        assert second._process is None  # not while a first compile may take the cores
        first_compile.code_is_ready()  # a compiled run has its code
        second._started()
        process = second._process
        assert process is not None
        second.run(_write_pid, target)
    assert process.returncode == 0 and _written_elsewhere(target)


def _slow_start(monkeypatch) -> list:
    """The second processes started from now on, each 0.3 s late (the block ends, or Ctrl-C
    stops it, meanwhile)."""
    started = []
    start = _background._start

    def slow_start(modules):
        time.sleep(0.3)
        started.append(start(modules))
        return started[-1]

    monkeypatch.setattr(_background, "_start", slow_start)
    return started


def test_a_block_that_ends_while_its_second_process_starts_leaves_none(monkeypatch, idle):
    started = _slow_start(monkeypatch)
    with second_process(after_first_compile=True) as second:
        first_compile.code_is_ready()
    assert second._process is None
    assert len(started) == 1 and started[0].poll() is not None  # started, then stopped


def test_a_second_process_started_after_ctrl_c_stopped_the_block_is_stopped(monkeypatch, idle):
    started = _slow_start(monkeypatch)
    # Ctrl-C in a wait for the starting thread: Python 3.11's join then returns at once after
    monkeypatch.setattr(_background.SecondProcess, "_started", lambda self: None)
    with pytest.raises(KeyboardInterrupt), second_process(after_first_compile=True) as second:
        first_compile.code_is_ready()
        raise KeyboardInterrupt
    second._starter.join()  # the thread goes on, and finds the block stopped
    assert second._process is None
    assert len(started) == 1 and started[0].poll() is not None  # started, then stopped


def test_a_call_before_any_compile_starts_the_second_process(tmp_path, idle):
    target = tmp_path / "file.txt"
    with second_process(after_first_compile=True) as second:
        second.run(_write_pid, target)
        assert second._process is not None and second._call is not None
    assert _written_elsewhere(target)


def test_its_cpu_time_counts_as_this_processs_own_for_the_compile_helper(idle):
    with second_process(("delaytrack.report.paper",)) as second:
        assert second._process is not None
        assert second._process.pid in helper_process._OWN
        pid = second._process.pid
    assert pid not in helper_process._OWN


def test_only_one_call_goes_there_the_next_runs_here(tmp_path, idle):
    there, here = tmp_path / "there.txt", tmp_path / "here.txt"
    with second_process() as second:
        second.run(_write_pid, there)
        second.run(_write_pid, here)
        assert not _written_elsewhere(here)  # written here, before the block ends
    assert _written_elsewhere(there)


def test_on_another_error_the_call_under_way_is_finished_first(tmp_path, idle):
    target = tmp_path / "file.txt"
    with pytest.raises(RuntimeError, match="later"), second_process() as second:
        second.run(_write_pid, target)
        raise RuntimeError("a later study failed")
    assert _written_elsewhere(target)


def test_on_ctrl_c_the_second_process_is_stopped(idle):
    with pytest.raises(KeyboardInterrupt), second_process() as second:
        second.run(time.sleep, 600.0)
        process = second._process
        assert process is not None
        raise KeyboardInterrupt
    assert process.returncode is not None and process.returncode < 0  # killed, not waited out


@pytest.fixture
def ctrl_c_raises():
    """SIGINT raises KeyboardInterrupt in this process, as from a terminal: a suite started
    from a background job (``make test &``) inherits SIGINT ignored, and Python keeps it so,
    which left the test below waiting ten minutes for a Ctrl-C that never came."""
    saved = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, saved)


def test_on_ctrl_c_while_the_block_waits_for_it_the_second_process_is_stopped(
    tmp_path, idle, ctrl_c_raises
):
    target = tmp_path / "file.txt"
    # Ctrl-C for this process alone (a notebook's interrupt), in the block or in its wait; never
    # after the test (the timer is cancelled), which would stop the whole test session.
    interrupt = threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT))
    try:
        with pytest.raises(KeyboardInterrupt), second_process() as second:
            second.run(_slow_elsewhere, os.getpid(), target)
            process = second._process
            assert process is not None
            interrupt.start()
    finally:
        interrupt.cancel()
    assert process.returncode is not None and process.returncode < 0
    assert not target.exists()


def test_a_second_process_too_slow_is_stopped_and_its_call_run_here(tmp_path, monkeypatch, idle):
    monkeypatch.setattr(_background, "PATIENCE", 0.5)
    target = tmp_path / "file.txt"
    with second_process() as second:
        second.run(_slow_elsewhere, os.getpid(), target)
        process = second._process
        assert process is not None
    assert process.returncode is not None and process.returncode < 0
    assert target.read_text() == str(os.getpid())


def test_a_failed_call_is_run_here_on_another_error_and_noted_on_it(tmp_path, idle):
    target = tmp_path / "no such folder" / "file.txt"
    with pytest.raises(RuntimeError, match="later") as raised, second_process() as second:
        second.run(target.write_text, "text")
        raise RuntimeError("a later study failed")
    assert any("FileNotFoundError" in note for note in raised.value.__notes__)


def test_with_matplotlib_settings_of_this_process_the_call_runs_here(tmp_path, idle):
    import matplotlib

    target = tmp_path / "file.txt"
    with matplotlib.rc_context({"lines.linewidth": 3.0}), second_process() as second:
        second.run(target.write_text, "here")
        assert second._call is None and target.read_text() == "here"


def test_the_cpu_time_of_a_process_counted_as_own_is_counted(tmp_path):
    import subprocess
    import sys

    busy = subprocess.Popen([sys.executable, "-c", "sum(range(30_000_000))"])
    try:
        # Waited for without reaping it: its /proc entry keeps its CPU time.
        os.waitid(os.P_PID, busy.pid, os.WEXITED | os.WNOWAIT)
        fields = Path(f"/proc/{busy.pid}/stat").read_text().rpartition(")")[2].split()
        its_own = int(fields[11]) + int(fields[12])  # utime, stime
        alone = helper_process._own_ticks()
        helper_process.count_as_own(busy.pid)
        together = helper_process._own_ticks()
    finally:
        helper_process.forget_own(busy.pid)
        busy.wait()
    assert its_own > 0 and together - alone >= its_own  # this process's own only grew


def _write_pid_with(path: Path, filler: bytes) -> None:
    """:func:`_write_pid`, given ``filler`` (a call larger than a pipe's buffer)."""
    _write_pid(path)


def test_a_second_process_stuck_before_reading_its_call_is_stopped_in_time(
    tmp_path, monkeypatch, idle
):
    (tmp_path / "stuck_on_import.py").write_text("import time\ntime.sleep(600.0)\n")
    monkeypatch.syspath_prepend(str(tmp_path))  # the second process gets this search path
    monkeypatch.setattr(_background, "PATIENCE", 0.5)
    target = tmp_path / "file.txt"
    with second_process(("stuck_on_import",)) as second:
        process = second._process
        assert process is not None
        second.run(_write_pid_with, target, b"x" * 1_000_000)  # waits in the pipe
    assert process.returncode is not None and process.returncode < 0
    assert not _written_elsewhere(target)
