"""Atomic writes: all or nothing, with the permissions a plain write would give; JSON that
every reader takes."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np
import pytest

from delaytrack._io import atomic_path, json_text, write_text


def test_a_failed_write_leaves_the_old_file_and_no_temporary(tmp_path) -> None:
    target = write_text(tmp_path / "table.csv", "old\n")
    with pytest.raises(RuntimeError), atomic_path(target) as temporary:
        temporary.write_text("half")
        raise RuntimeError("interrupted")
    assert target.read_text() == "old\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["table.csv"]


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
