"""numba's cache folder follows the compiled source (a stale engine is a bug), and only it."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

import numba
import pytest

from delaytrack._compile import disk_cache


@pytest.fixture
def package_copy(tmp_path, monkeypatch) -> Path:
    """A copy of the package's source that :mod:`delaytrack._compile.disk_cache` hashes instead."""
    copy = tmp_path / "delaytrack"
    shutil.copytree(
        Path(disk_cache.__file__).parents[1], copy, ignore=shutil.ignore_patterns("__pycache__")
    )
    monkeypatch.setattr(disk_cache, "_PACKAGE", copy)
    return copy


def test_cache_folder_is_keyed_by_the_current_source() -> None:
    assert numba.config.CACHE_DIR == str(disk_cache.cache_directory())
    assert Path(numba.config.CACHE_DIR).name == disk_cache.source_hash()


def test_editing_any_kernel_file_changes_the_key(package_copy) -> None:
    copy = package_copy
    before = disk_cache.source_hash()
    assert before == disk_cache.source_hash()
    # The controller kernel is inlined into the compiled engine but lives in another file.
    arolc = copy / "controllers" / "arolc.py"
    arolc.write_text(arolc.read_text() + "\n# an edit\n")
    assert disk_cache.source_hash() != before


def test_editing_a_file_without_compiled_code_keeps_the_key(package_copy) -> None:
    copy = package_copy
    before = disk_cache.source_hash()
    for edited in ("cli/_main.py", "report/html.py", "experiments/paper.py", "sweeps/runner.py"):
        path = copy / edited
        path.write_text(path.read_text() + "\n# a sentence of prose\n")
    assert disk_cache.source_hash() == before
    names = {path.relative_to(copy).as_posix() for path in disk_cache.kernel_files()}
    assert {"sim/engine.py", "components.py", "controllers/arolc.py"} <= names
    # not compiled, but deciding how a kernel of the user's compiles and is named
    assert {"_compile/own_options.py", "_compile/fingerprint.py"} <= names
    assert not names & {"cli/_main.py", "report/html.py", "experiments/paper.py"}


def test_user_cache_root_is_respected(monkeypatch, tmp_path) -> None:
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    assert disk_cache.cache_directory().parent == tmp_path / "delaytrack"


def test_processes_saving_entries_at_once_keep_every_entry(tmp_path, monkeypatch) -> None:
    """numba saves an entry by reading the kernel's index, adding it and writing it back: two
    processes compiling two overloads at once must not write back each other's loss."""
    files = disk_cache._LockedIndexDataCacheFile
    load = files._load_index

    def slow_load(self):  # widen the window between reading and writing the index
        overloads = load(self)
        time.sleep(0.3)
        return overloads

    monkeypatch.setattr(files, "_load_index", slow_load)
    # Two objects open the lock file each, as two processes would (flock is per open file).
    writers = [
        threading.Thread(target=files(str(tmp_path), "engine", "stamp").save, args=(key, key))
        for key in ("plant A", "plant B")
    ]
    for writer in writers:
        writer.start()
        time.sleep(0.05)
    for writer in writers:
        writer.join()
    reader = files(str(tmp_path), "engine", "stamp")
    overloads = load(reader)
    assert set(overloads) == {"plant A", "plant B"}
    assert [reader._load_data(overloads[key]) for key in ("plant A", "plant B")] == [
        "plant A",
        "plant B",
    ]


def test_every_compiled_kernel_saves_under_the_lock() -> None:
    from delaytrack.controllers.arolc import arolc_step
    from delaytrack.plants.robot.payload import robot_payload_terms
    from delaytrack.sim.engine import run_batch_compiled

    for dispatcher in (run_batch_compiled, arolc_step, robot_payload_terms):
        assert type(dispatcher._cache._cache_file) is disk_cache._LockedIndexDataCacheFile


def test_importing_with_numbas_compiler_disabled_is_a_clear_error() -> None:
    completed = subprocess.run(
        [sys.executable, "-c", "import delaytrack"],
        env={**os.environ, "NUMBA_DISABLE_JIT": "1"},
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert completed.returncode != 0
    last = completed.stderr.strip().splitlines()[-1]
    assert last.startswith("ImportError: delaytrack cannot be imported with NUMBA_DISABLE_JIT=1")
    assert "engine='python'" in last
