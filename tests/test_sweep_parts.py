"""Sweep parts: a tiny unit run with the batched engine, written atomically, resumed."""

from __future__ import annotations

import numpy as np
import pyarrow.parquet as pq
import pytest

from delaytrack.sweeps import SweepSpec, finished_units, run_unit, write_part


def small_spec(**changes) -> SweepSpec:
    data = {
        "scenario": "two_link_S1",
        "unit_size": 3,
        "draws": 2,
        "seed": 3,
        "grid": {
            # Two durations: two simulate() calls within the first unit.
            "duration": [0.2, 0.1],
            "delay": [{"type": "S1"}],
        },
        "random": {"plant.fd1": {"dist": "uniform", "low": 2.0, "high": 6.0}},
    }
    data.update(changes)
    return SweepSpec.from_dict(data)


@pytest.fixture(scope="module")
def unit_frame():
    unit = small_spec().units()[0]
    return unit, run_unit(unit)


def test_run_unit_gives_one_row_per_run(unit_frame):
    unit, frame = unit_frame
    assert list(frame["run"]) == [0, 1, 2]
    assert list(frame["duration"]) == [0.2, 0.2, 0.1]
    assert list(frame["delay"]) == ['{"type":"S1"}'] * 3  # a swept table, as JSON
    assert list(frame["delay_type"]) == ["S1"] * 3
    assert list(frame["controller_type"]) == ["arolc"] * 3
    assert list(frame["status"]) == ["ok"] * 3
    for column in ("ae_q1", "ae_q2", "rms_q1", "rms_q2", "max_q1", "max_q2", "tv"):
        assert np.all(np.isfinite(frame[column])), column
    assert frame["plant.fd1"].tolist() == [run.values["plant.fd1"] for run in unit.runs]
    # Runs 0 and 1 differ only in the truth's friction.
    assert frame["ae_q1"][0] != frame["ae_q1"][1]


def test_part_is_written_atomically_with_its_hash(unit_frame, tmp_path):
    unit, frame = unit_frame
    path = write_part(frame, unit, tmp_path)
    assert path.name == unit.part_name
    assert [p.name for p in tmp_path.iterdir()] == [unit.part_name]  # no temporary left
    table = pq.read_table(path)
    assert table.num_rows == 3
    assert table.schema.metadata[b"delaytrack.unit_hash"] == unit.hash.encode()
    assert table.to_pandas().equals(frame)


def test_write_part_refuses_a_frame_of_another_size(unit_frame, tmp_path):
    unit, frame = unit_frame
    with pytest.raises(ValueError, match="frame has 2 rows; unit 0 has 3 runs"):
        write_part(frame.iloc[:2], unit, tmp_path)


def test_resume_skips_finished_units_and_rejects_bad_parts(unit_frame, tmp_path):
    unit, frame = unit_frame
    spec = small_spec()
    assert finished_units(tmp_path / "absent", spec).finished == frozenset()
    path = write_part(frame, unit, tmp_path)
    scan = finished_units(tmp_path, spec)
    assert scan.finished == {0} and not scan.rejected

    # Another spec (another seed) finds nothing of its own and says why.
    other = finished_units(tmp_path, small_spec(seed=4))
    assert other.finished == frozenset()
    assert other.rejected == {
        unit.part_name: "not a part of this spec (another spec or package version)"
    }

    # A truncated part (a copy cut short) is unfinished, and said to be.
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    scan = finished_units(tmp_path, spec)
    assert scan.finished == frozenset()
    assert scan.rejected[unit.part_name].startswith("unreadable (truncated or corrupt)")


def test_a_part_with_a_foreign_hash_is_unfinished(unit_frame, tmp_path):
    unit, frame = unit_frame
    path = write_part(frame, unit, tmp_path)
    table = pq.read_table(path)
    metadata = {**table.schema.metadata, b"delaytrack.unit_hash": b"0" * 64}
    pq.write_table(table.replace_schema_metadata(metadata), path)
    reason = finished_units(tmp_path, small_spec()).rejected[unit.part_name]
    assert reason == f"unit hash 000000000000 != {unit.hash[:12]} of this spec"


def test_a_part_whose_values_decompress_far_beyond_a_units_size_is_not_read(unit_frame, tmp_path):
    """A part of a folder someone sent, with this unit's hash and row count, whose few kB
    decompress to megabytes a row (gigabytes at scale): refused from its footer, unread."""
    import pyarrow as pa

    unit, frame = unit_frame
    path = write_part(frame, unit, tmp_path)
    metadata = pq.read_table(path).schema.metadata
    bloated = pa.table({"run": [0, 1, 2], "x": ["a" * 3 * 2**20] * 3})
    pq.write_table(bloated.replace_schema_metadata(metadata), path, compression="zstd")
    assert path.stat().st_size < 2**16
    reason = finished_units(tmp_path, small_spec()).rejected[unit.part_name]
    # the bound: 1 MiB (1048576 bytes) a run, for the unit's 3 runs and one more
    assert "bytes of values, more than 4194304; unit 0 has 3 runs of at most 1048576" in reason
    # nested, a text is read whole before any check: a part holds no nested column
    nested = pa.table({"run": [0, 1, 2], "x": [{"f": "a" * 3 * 2**20}] * 3})
    pq.write_table(nested.replace_schema_metadata(metadata), path, compression="zstd")
    reason = finished_units(tmp_path, small_spec()).rejected[unit.part_name]
    assert reason.startswith("nested columns ['x'], which no part of the toolkit holds"), reason


def test_the_code_version_covers_every_file_of_simulate_without_compiled_code():
    """An edit of any stage of ``simulate()`` may change a sweep's numbers: each is hashed."""
    from pathlib import Path

    from delaytrack.sweeps.spec import RESULT_FILES

    package = Path(__file__).resolve().parents[1] / "src" / "delaytrack"
    stages = {f"sim/{p.name}" for p in (package / "sim").glob("_*.py")}
    # Checking kernels, wording errors and counting cores decide no number (nor does compiling,
    # delaytrack._compile, whose files that decide how code compiles are hashed as compiled code).
    stages -= {
        "sim/__init__.py",
        "sim/_kernel_checks.py",
        "sim/_kernel_errors.py",
        "sim/_machine.py",
    }
    assert stages | {"sim/simulate.py"} <= set(RESULT_FILES)
    assert all((package / name).is_file() for name in RESULT_FILES)
