"""Atomic writes: all or nothing, with the permissions a plain write would give; JSON that
every reader takes."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np
import pytest

from delaytrack._io import (
    MAX_LINE_BYTES,
    MAX_TOML_BYTES,
    atomic_path,
    csv_rows,
    json_text,
    read_file_bytes,
    write_text,
)
from delaytrack.live._tables import json_table
from delaytrack.scenario import Scenario, ScenarioError, load_builtin


def test_a_failed_write_leaves_the_old_file_and_no_temporary(tmp_path) -> None:
    target = write_text(tmp_path / "table.csv", "old\n")
    with pytest.raises(RuntimeError), atomic_path(target) as temporary:
        temporary.write_text("half")
        raise RuntimeError("interrupted")
    assert target.read_text() == "old\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["table.csv"]


def test_a_folder_given_as_the_file_is_refused_naming_it_and_leaves_nothing(tmp_path) -> None:
    """``Scenario.to_toml("/tmp")`` said "Is a directory" of a temporary file beside it."""
    folder = tmp_path / "results"
    folder.mkdir()
    refusal = r"is a folder; give the path of a file: '.*results'"
    with pytest.raises(IsADirectoryError, match=refusal):
        load_builtin("two_link_S1").to_toml(folder)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results"]
    assert list(folder.iterdir()) == []


def test_written_files_get_the_mode_of_a_plain_write(tmp_path) -> None:
    plain = tmp_path / "plain.txt"
    plain.write_text("x")
    atomic = write_text(tmp_path / "atomic.txt", "x")
    assert os.stat(atomic).st_mode & 0o777 == os.stat(plain).st_mode & 0o777


def test_json_text_writes_numbers_that_are_not_finite_as_null() -> None:
    """A node's summary of a session with no ticks holds percentiles of nothing (NaN) and a
    rate over no time: strict JSON readers refuse ``NaN``, so they are ``null``."""
    data = {
        "lateness_ms_p50": math.nan,
        "nested": {"rates": [1.5, np.float64(np.inf), -math.inf], "ticks": 0, "ok": True},
        "where": Path("/tmp/x"),
    }
    text = json_text(data, default=str, indent=1)

    def refuse(constant: str) -> None:
        raise AssertionError(f"{constant} in {text}")

    assert json.loads(text, parse_constant=refuse) == {
        "lateness_ms_p50": None,
        "nested": {"rates": [1.5, None, None], "ticks": 0, "ok": True},
        "where": "/tmp/x",
    }
    with pytest.raises(TypeError):  # what json.dumps refuses without a default
        json_text({"where": Path("/tmp/x")})


# ---- reading: what a file gives, not what it says it holds -----------------------------------

PAGEMAP = Path("/proc/self/pagemap")


def test_a_csv_line_without_end_is_refused_before_it_fills_the_memory(tmp_path) -> None:
    path = tmp_path / "one_line.csv"
    path.write_bytes(b"t,h\n" + b"0" * (MAX_LINE_BYTES + 10))
    with pytest.raises(ValueError, match=r"one_line\.csv': a line longer than 1 MiB"):
        list(csv_rows(path))
    # Lines that end in a carriage return alone are lines too.
    path.write_bytes(b"t,h\r" + b"0,0.01\r" * 200_000)
    assert sum(1 for _ in csv_rows(path)) == 200_001


@pytest.mark.skipif(not PAGEMAP.exists(), reason="no /proc/self/pagemap here")
def test_a_file_that_says_it_is_empty_but_gives_without_end_is_refused(tmp_path) -> None:
    # A file of /proc: regular, of size 0, and it gives gigabytes (it took 5 GB as a trace).
    link = tmp_path / "trace.csv"
    link.symlink_to(PAGEMAP)
    with pytest.raises(ValueError, match=r"a line longer than 1 MiB|cannot be read"):
        list(csv_rows(link))
    with pytest.raises(ValueError, match=r"gives more than 1 MiB when read"):
        read_file_bytes(link, "scenario file", largest=2**20)


def test_a_toml_file_beyond_its_limit_is_refused_before_it_is_parsed(tmp_path) -> None:
    path = tmp_path / "big.toml"
    path.write_text("# " + "x" * (MAX_TOML_BYTES + 10) + "\n")
    with pytest.raises(ScenarioError, match=r"big\.toml' holds 8 MiB; .* at most 8 MiB"):
        Scenario.from_toml(path)


def test_a_json_table_nested_without_end_is_a_clear_error(tmp_path) -> None:
    path = tmp_path / "summary.json"
    path.write_text('{"nodes": ' + "[" * 200_000 + "]" * 200_000 + "}")
    with pytest.raises(ValueError, match=r"summary\.json is not a session's summary: its values"):
        json_table(path, "session's summary")
