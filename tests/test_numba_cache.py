"""numba's cache folder follows the compiled source (a stale engine is a bug), and only it."""

from __future__ import annotations

import shutil
from pathlib import Path

import numba
import pytest

from delaytrack import _numba_cache


@pytest.fixture
def package_copy(tmp_path, monkeypatch) -> Path:
    """A copy of the package's source that :mod:`delaytrack._numba_cache` hashes instead."""
    copy = tmp_path / "delaytrack"
    shutil.copytree(
        Path(_numba_cache.__file__).parent, copy, ignore=shutil.ignore_patterns("__pycache__")
    )
    monkeypatch.setattr(_numba_cache, "_PACKAGE", copy)
    return copy


def test_cache_folder_is_keyed_by_the_current_source() -> None:
    assert numba.config.CACHE_DIR == str(_numba_cache.cache_directory())
    assert Path(numba.config.CACHE_DIR).name == _numba_cache.source_hash()


def test_editing_any_kernel_file_changes_the_key(package_copy) -> None:
    copy = package_copy
    before = _numba_cache.source_hash()
    assert before == _numba_cache.source_hash()
    # The controller kernel is inlined into the compiled engine but lives in another file.
    arolc = copy / "controllers" / "arolc.py"
    arolc.write_text(arolc.read_text() + "\n# an edit\n")
    assert _numba_cache.source_hash() != before


def test_editing_a_file_without_compiled_code_keeps_the_key(package_copy) -> None:
    copy = package_copy
    before = _numba_cache.source_hash()
    for edited in ("cli.py", "report/html.py", "experiments/paper.py", "sweeps/runner.py"):
        path = copy / edited
        path.write_text(path.read_text() + "\n# a sentence of prose\n")
    assert _numba_cache.source_hash() == before
    names = {path.relative_to(copy).as_posix() for path in _numba_cache.kernel_files()}
    assert {"sim/engine.py", "components.py", "controllers/arolc.py"} <= names
    assert not names & {"cli.py", "report/html.py", "experiments/paper.py"}


def test_user_cache_root_is_respected(monkeypatch, tmp_path) -> None:
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    assert _numba_cache.cache_directory().parent == tmp_path / "delaytrack"
