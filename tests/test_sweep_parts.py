"""Sweep parts: a tiny unit run with the batched engine, written atomically, resumed."""

from __future__ import annotations

import os
from pathlib import Path

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


def _zigzag_varint(value: int, length: int | None = None) -> bytes:
    """``value`` as Thrift's compact protocol writes an i64 (zigzag, then 7 bits a byte),
    padded with continuation bytes to ``length`` bytes when given (readers take those)."""
    n, out = 2 * value, bytearray()
    while n or not out or (length is not None and len(out) < length):
        more = n >= 0x80 or (length is not None and len(out) < length - 1)
        out.append((n & 0x7F) | (0x80 if more else 0))
        n >>= 7
    return bytes(out)


def _forge_footer_sizes(path) -> None:
    """Rewrite the footer of the Parquet file ``path`` so that its row group's and column
    chunks' sizes of values say 10 bytes, the pages unchanged (the same file length)."""
    import struct

    data = bytearray(path.read_bytes())
    length = struct.unpack("<i", data[-8:-4])[0]
    start = len(data) - 8 - length
    footer = bytes(data[start : start + length])
    group = pq.read_metadata(path).row_group(0)
    sizes = {group.total_byte_size} | {
        group.column(i).total_uncompressed_size for i in range(group.num_columns)
    }
    for size in sorted(sizes, reverse=True):
        written = _zigzag_varint(size)
        assert footer.count(written) == 1, size
        footer = footer.replace(written, _zigzag_varint(10, len(written)))
    data[start : start + length] = footer
    path.write_bytes(bytes(data))


def test_a_part_whose_footer_understates_its_pages_is_refused_before_they_are_read(
    unit_frame, tmp_path
):
    """The footer's sizes are the file's own word: a part whose footer says 10 bytes of values
    where its pages decompress to 192 MiB passes every check of the footer; its read is capped
    at a few times a unit's bound and refused there, before the pages are decompressed."""
    import pyarrow as pa

    from delaytrack._memory_budget import allocation_budget

    with allocation_budget(2**20) as capped:
        pass
    if not capped:
        pytest.skip("the process's data segment cannot be capped here (no /proc)")
    unit, frame = unit_frame
    path = write_part(frame, unit, tmp_path)
    metadata = pq.read_table(path).schema.metadata
    bloated = pa.table({"run": [0, 1, 2], "x": [letter * 64 * 2**20 for letter in "abc"]})
    pq.write_table(
        bloated.replace_schema_metadata(metadata), path, compression="zstd", use_dictionary=False
    )
    _forge_footer_sizes(path)
    assert pq.read_metadata(path).row_group(0).total_byte_size == 10
    assert path.stat().st_size < 2**16
    reason = finished_units(tmp_path, small_spec()).rejected[unit.part_name]
    # four times the unit's bound (4 MiB: 1 MiB a run, 3 runs and one more) and 64 MiB
    assert "reading its values asked for more than 83886080 bytes" in reason, reason
    assert "its pages are larger than its footer says" in reason


def test_a_part_whose_pages_are_corrupt_is_said_to_be_so(unit_frame, tmp_path):
    """The footer whole, the pages not: read under the cap, still "unreadable", not a size."""
    unit, frame = unit_frame
    path = write_part(frame, unit, tmp_path)
    data = bytearray(path.read_bytes())
    data[4:68] = b"\xff" * 64  # the first data page's header and values, after "PAR1"
    path.write_bytes(bytes(data))
    assert pq.read_metadata(path).num_rows == 3  # the footer is whole
    reason = finished_units(tmp_path, small_spec()).rejected[unit.part_name]
    assert reason.startswith("unreadable (truncated or corrupt)"), reason


def test_a_good_part_is_read_under_the_cap_on_a_machine_of_many_cores(unit_frame, tmp_path):
    """Arrow starts a thread per core, and its reading threads, on its first read, whose 8 MiB
    or larger stacks count against the cap: under 16 cores the first part failed to start a
    thread and was taken for corrupt, and under a 64 MiB stack the read hung."""
    import resource
    import subprocess
    import sys
    import textwrap

    unit, frame = unit_frame
    write_part(frame, unit, tmp_path)
    script = textwrap.dedent(
        f"""
        from test_sweep_parts import small_spec
        from delaytrack.sweeps import finished_units
        scan = finished_units({str(tmp_path)!r}, small_spec())
        print(sorted(scan.finished), dict(scan.rejected))
        """
    )

    def large_stacks() -> None:
        resource.setrlimit(resource.RLIMIT_STACK, (64 * 2**20, resource.RLIM_INFINITY))

    done = subprocess.run(
        [sys.executable, "-c", script],
        cwd=Path(__file__).parent,
        env={**os.environ, "OMP_NUM_THREADS": "32"},
        preexec_fn=large_stacks,
        capture_output=True,
        text=True,
        timeout=60,  # it hung
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[0] {}", done.stdout


def test_an_allocation_beyond_the_budget_fails_and_the_budget_ends_with_its_block():
    from delaytrack._memory_budget import allocation_budget

    with allocation_budget(64 * 2**20) as capped:
        if capped:
            with pytest.raises(MemoryError):
                np.ones(2**28)  # 2 GiB
        small = np.ones(2**20)  # 8 MiB: within it
    assert small.sum() == 2**20
    assert np.ones(2**24).size == 2**24  # 128 MiB, twice the budget, after the block
    with pytest.raises(ValueError, match="budget must be a positive number of bytes; got 0"):
        with allocation_budget(0):
            pass


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
