"""run_sweep with the local executor: complete, resumable, interruptible, corrupt parts redone."""

import errno
import signal
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from delaytrack.cli import main
from delaytrack.report.sweep import findings, write_sweep_outputs
from delaytrack.sweeps import (
    LocalExecutor,
    SweepError,
    SweepInterrupted,
    SweepSpec,
    SweepUnitsFailed,
    finished_units,
    run_sweep,
    run_unit,
    summary_table,
)
from delaytrack.sweeps import executors as executors_module
from delaytrack.sweeps import runner as runner_module
from delaytrack.sweeps.summary import controller_labels, delay_classes

EXAMPLE = Path(__file__).parents[1] / "examples" / "sweep_small.toml"


def small_spec(**changes) -> SweepSpec:
    """The example sweep, 0.2 s runs, units of 5 (24 runs, 5 units)."""
    data = tomllib.loads(EXAMPLE.read_text()) | {"unit_size": 5} | changes
    data["grid"] = data["grid"] | {"duration": [0.2]}
    return SweepSpec.from_dict(data, root=EXAMPLE.parent)


class CountingExecutor(LocalExecutor):
    """The local executor, recording which units it ran; raises Ctrl-C after ``stop_after``."""

    def __init__(self, stop_after=None):
        super().__init__(workers=1)
        self.ran = []
        self.stop_after = stop_after

    def results(self, units):
        for unit in units:
            if self.stop_after is not None and len(self.ran) == self.stop_after:
                raise KeyboardInterrupt
            self.ran.append(unit.index)
            yield unit, run_unit(unit, workers=1)


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The whole small sweep run in one go."""
    out = tmp_path_factory.mktemp("reference")
    return run_sweep(small_spec(), out, progress=False)


def test_a_sweep_gives_every_run_once_with_its_files(reference):
    spec = reference.spec
    runs = reference.runs
    assert list(runs["run"]) == list(range(len(spec.runs))) == list(range(24))
    assert (runs["status"] == "ok").all()
    assert reference.computed == 5 and reference.resumed == 0
    parts = sorted((reference.folder / "parts").glob("part-*.parquet"))
    assert [p.name for p in parts] == [unit.part_name for unit in spec.units()]
    # runs.parquet is read back by pyarrow alone, equal to the returned table.
    table = pq.read_table(reference.folder / "runs.parquet").to_pandas()
    pd.testing.assert_frame_equal(table, runs.reset_index(drop=True))
    files = write_sweep_outputs(reference)
    names = {path.relative_to(reference.folder).as_posix() for path in files}
    assert names == {
        "summary.csv",
        "figures/distributions.png",
        "figures/distributions.svg",
        "figures/ae_vs_h_max.png",
        "figures/ae_vs_h_max.svg",
        "report.html",
    }
    html = (reference.folder / "report.html").read_text()
    assert "Sweep over two_link_S1" in html and html.count("data:image/png;base64,") == 2
    summary = pd.read_csv(reference.folder / "summary.csv")
    assert summary["runs"].sum() == 24 and len(summary) == 6
    # Units in the column names (the two-link arm: rad, N·m), findings computed in the report.
    assert "ae_q1_median_rad" in summary.columns and "tv_median_Nm" in summary.columns
    assert "Findings" in html and "Smallest median ae_q1, per delay class" in html
    # Each class's sentence names its smallest median first (ties: the tie test below).
    best = summary.loc[summary.groupby("delay_class").ae_q1_median_rad.idxmin()]
    for row in best.itertuples():
        assert f"{row.delay_class}: {row.controller} " in html


def test_batched_unit_equals_runs_one_by_one(reference):
    """A unit batches its runs; each equals the run simulated alone (units of one run)."""
    alone = pd.concat([run_unit(unit, workers=1) for unit in small_spec(unit_size=1).units()])
    pd.testing.assert_frame_equal(
        alone.reset_index(drop=True), reference.runs.reset_index(drop=True), check_exact=True
    )


def test_mixed_controller_unit_equals_separate_units(tmp_path):
    """A unit holding AROLC and outer-loop runs (two batches) gives the same rows."""
    changes = {
        "grid": {
            "duration": [0.2],
            "controller": [
                {
                    "type": "arolc",
                    "K1": 1.0,
                    "K2": 1.0,
                    "Q": 1.0,
                    "alpha": 2.0,
                    "epsilon": 0.1,
                    "gamma": 0.001,
                },
                {"type": "outer-loop", "K1": 1.0, "K2": 1.0},
            ],
        },
    }
    data = tomllib.loads(EXAMPLE.read_text()) | {"unit_size": 8} | changes
    mixed = SweepSpec.from_dict(data, root=EXAMPLE.parent)
    assert {run.scenario.controller["type"] for run in mixed.units()[0].runs} == {
        "arolc",
        "outer-loop",
    }
    together = run_sweep(mixed, tmp_path / "mixed", progress=False).runs
    single = SweepSpec.from_dict(data | {"unit_size": 1}, root=EXAMPLE.parent)
    apart = run_sweep(single, tmp_path / "single", progress=False).runs
    pd.testing.assert_frame_equal(together, apart, check_exact=True)
    labels = set(controller_labels(together))
    assert labels == {"arolc", "outer-loop"}


def test_resume_skips_finished_units(reference, tmp_path):
    executor = CountingExecutor()
    again = run_sweep(small_spec(), reference.folder, executor=executor, progress=False)
    assert executor.ran == [] and again.computed == 0 and again.resumed == 5
    pd.testing.assert_frame_equal(again.runs, reference.runs, check_exact=True)


def test_interrupted_sweep_keeps_parts_and_resumes_the_rest(reference, tmp_path):
    out = tmp_path / "sweep"
    first = CountingExecutor(stop_after=2)
    with pytest.raises(SweepInterrupted) as stopped:
        run_sweep(small_spec(), out, executor=first, progress=False)
    assert (stopped.value.done, stopped.value.total) == (2, 5)
    assert "run the same command again to resume" in str(stopped.value)
    assert len(list((out / "parts").glob("part-*.parquet"))) == 2
    assert not (out / "runs.parquet").exists()
    second = CountingExecutor()
    outcome = run_sweep(small_spec(), out, executor=second, progress=False)
    assert second.ran == [2, 3, 4] and outcome.resumed == 2
    pd.testing.assert_frame_equal(outcome.runs, reference.runs, check_exact=True)


def test_corrupt_and_truncated_parts_are_recomputed(reference, tmp_path):
    out = tmp_path / "sweep"
    run_sweep(small_spec(), out, progress=False)
    units = small_spec().units()
    truncated = out / "parts" / units[1].part_name
    truncated.write_bytes(truncated.read_bytes()[:100])
    garbage = out / "parts" / units[3].part_name
    garbage.write_bytes(b"not parquet at all" * 10)
    leftover = out / "parts" / f".{units[4].part_name}.abc123.parquet"
    leftover.write_bytes(b"half a part")
    executor = CountingExecutor()
    outcome = run_sweep(small_spec(), out, executor=executor, progress=False)
    assert executor.ran == [1, 3]
    assert set(outcome.rejected) == {units[1].part_name, units[3].part_name}
    assert not leftover.exists()
    pd.testing.assert_frame_equal(outcome.runs, reference.runs, check_exact=True)


def test_a_changed_spec_recomputes_only_changed_units(reference, tmp_path):
    out = tmp_path / "sweep"
    run_sweep(small_spec(), out, progress=False)
    data = tomllib.loads(EXAMPLE.read_text()) | {"unit_size": 5}
    data["grid"] = data["grid"] | {"duration": [0.2], "controller.K1": [1.0, 3.0]}
    changed = SweepSpec.from_dict(data, root=EXAMPLE.parent)
    executor = CountingExecutor()
    outcome = run_sweep(changed, out, executor=executor, progress=False)
    # Runs 0-11 (K1 = 1) are unchanged: units 0 and 1 hold runs 0-9; unit 2 mixes both K1.
    assert executor.ran == [2, 3, 4]
    assert len(outcome.rejected) == 3
    assert list(outcome.runs["controller.K1"]) == [1.0] * 12 + [3.0] * 12


def test_a_second_sweep_on_the_same_folder_is_refused(reference, tmp_path):
    fcntl = pytest.importorskip("fcntl")
    out = tmp_path / "sweep"
    out.mkdir()
    with open(out / ".lock", "w") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        with pytest.raises(SweepError, match="another sweep is writing to"):
            run_sweep(small_spec(), out, progress=False)
    # The report is written under the same lock.
    with open(reference.folder / ".lock", "w") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        with pytest.raises(SweepError, match="another sweep is writing to"):
            write_sweep_outputs(reference)


def test_a_factory_is_named_by_its_function_unless_another_type_has_that_name():
    """A delay of the user's is shown by its factory's name; two files' ``make_link`` (or a
    factory named like a built-in type) keep their full types, so their runs are not pooled."""
    kinds = ["python:/a/link.py:make_link", "python:/b/link.py:make_link", "python:/c.py:jam"]
    runs = pd.DataFrame({"delay_type": [*kinds, "constant", "python:/d.py:constant"]})
    runs["h_max"] = 0.06
    assert list(delay_classes(runs)) == [
        "python:/a/link.py:make_link, h_max 50-100 ms",
        "python:/b/link.py:make_link, h_max 50-100 ms",
        "jam, h_max 50-100 ms",
        "constant, h_max 50-100 ms",
        "python:/d.py:constant, h_max 50-100 ms",
    ]
    controllers = pd.DataFrame({"controller_type": ["arolc", "python:/a.py:pd", "python:/b.py:pd"]})
    assert list(controller_labels(controllers)) == ["arolc", "python:/a.py:pd", "python:/b.py:pd"]


def test_delays_taken_from_lists_are_classes_of_their_own():
    """Grid delays of one family whose bounds share a band are not merged (they were: 0 and
    50 ms both fell in "h_max 0-50 ms"); whole tables alike in family and bound are numbered."""
    tables = ['{"h":0.0}', '{"h":0.05}', '{"f":1}', '{"f":2}', '{"f":2}']
    runs = pd.DataFrame(
        {
            "delay_type": ["constant", "constant", "abs-sine", "abs-sine", "abs-sine"],
            "h_max": [0.0, 0.05, 0.1, 0.1, 0.1],
            "delay": tables,
            "delay.offset": [0.0, 0.0, 0.02, 0.02, 0.03],
        }
    )
    assert list(delay_classes(runs, ["delay"])) == [
        "constant, h_max 0 ms",
        "constant, h_max 50 ms",
        "abs-sine #1, h_max 100 ms",
        "abs-sine #2, h_max 100 ms",
        "abs-sine #2, h_max 100 ms",
    ]
    assert list(delay_classes(runs, ["delay.offset"]))[2:] == [
        "abs-sine, h_max 100 ms (offset=0.02)",
        "abs-sine, h_max 100 ms (offset=0.02)",
        "abs-sine, h_max 100 ms (offset=0.03)",
    ]
    assert list(delay_classes(runs))[:2] == ["constant, h_max 0-50 ms"] * 2


def test_the_findings_call_medians_within_one_percent_a_tie():
    summary = pd.DataFrame(
        {
            "controller": ["arolc", "outer-loop", "pcon"] * 3,
            "delay_class": ["a"] * 3 + ["b"] * 3 + ["c"] * 3,
            "runs": [3] * 9,
            "diverged": [0] * 9,
            "failed": [0] * 9,
            "ae_x_median": [0.00917, 0.009172, 0.02, 0.010, 0.012, 0.02, 0.0101, 0.0100, 0.01005],
        }
    )
    text = " ".join(findings(summary, ["ae_x"], {"ae_x": "m"}))
    assert "a: arolc and outer-loop within 1% of each other (0.00917 and 0.009172 m)" in text
    assert "b: arolc, median 0.01 m" in text
    assert "c: outer-loop and pcon and arolc within 1% of each other (0.01 and 0.01005 and " in text


def test_summary_statistics_and_classes():
    runs = pd.DataFrame(
        {
            "controller_type": ["arolc"] * 4 + ["pcon"] * 2,
            "controller.K1": [1.0, 1.0, 1.0, 1.0, 2.0, 2.0],
            "delay_type": ["random"] * 3 + ["constant"] * 3,
            "h_max": [0.05, 0.12, 0.12, 0.3, 0.3, 2.0],
            "status": ["ok", "ok", "diverged", "ok", "delay beyond history", "ok"],
            "ae_q1": [1.0, 2.0, np.nan, 4.0, np.nan, 5.0],
            "tv": [0.1, 0.2, np.nan, 0.4, np.nan, 0.5],
        }
    )
    assert list(delay_classes(runs)) == [
        "random, h_max 0-50 ms",
        "random, h_max 100-150 ms",
        "random, h_max 100-150 ms",
        "constant, h_max 200-300 ms",
        "constant, h_max 200-300 ms",
        "constant, h_max > 1000 ms",
    ]
    summary = summary_table(runs)
    assert list(summary["controller"]) == ["arolc (K1=1)"] * 3 + ["pcon (K1=2)"] * 2
    row = summary.iloc[1]
    assert (row["runs"], row["diverged"], row["divergence_rate"], row["failed"]) == (2, 1, 0.5, 0)
    assert row["ae_q1_mean"] == row["ae_q1_max"] == 2.0
    row = summary.iloc[3]
    assert (row["failed"], row["diverged"]) == (1, 0) and np.isnan(row["ae_q1_mean"])
    values = np.array([1.0, 2.0, 4.0, 5.0])
    frame = runs.assign(h_max=0.01, delay_type="x", **{"controller.K1": 1.0}, controller_type="a")
    whole = summary_table(frame).iloc[0]
    assert whole["ae_q1_p95"] == pytest.approx(np.percentile(values, 95))
    assert whole["ae_q1_median"] == 3.0 and whole["divergence_rate"] == pytest.approx(1 / 6)
    with pytest.raises(ValueError, match=r"summary metrics \['ae_q9'\] are not columns"):
        summary_table(runs, ["ae_q9"])


def test_cli_sweep_runs_resumes_and_refuses_bad_arguments(tmp_path, capsys):
    spec = tmp_path / "sweep.toml"
    spec.write_text(EXAMPLE.read_text().replace("duration = [1.0]", "duration = [0.1]"))
    out = tmp_path / "out"
    assert main(["sweep", str(spec), "--out", str(out), "--quiet", "--workers", "1"]) == 0
    printed = capsys.readouterr().out
    assert "24 runs done (3 units computed, 0 found finished)" in printed
    assert (out / "report.html").is_file() and (out / "summary.csv").is_file()
    assert main(["sweep", str(spec), "--out", str(out), "--quiet"]) == 0
    assert "(0 units computed, 3 found finished)" in capsys.readouterr().out
    assert main(["sweep", str(spec), "--out", str(out), "--workers", "0"]) == 2
    assert "--workers must be a positive integer; got '0'" in capsys.readouterr().err
    assert main(["sweep", str(spec), "--out", str(out), "--scheduler", "localhost"]) == 2
    assert "--scheduler must be 'local-cluster' or a Dask scheduler address" in (
        capsys.readouterr().err
    )
    assert main(["sweep", str(tmp_path / "missing.toml")]) == 2
    assert "does not exist" in capsys.readouterr().err


#: A ``delaytrack sweep`` command whose units from the third on wait for Ctrl-C: the first two
#: parts are written, then the file ``argv[1]`` says the command is blocked in unit 2.
BLOCKING_COMMAND = """
import signal, sys, time
from pathlib import Path

# A process started from a background job inherits SIGINT ignored, and Python then keeps it so.
signal.signal(signal.SIGINT, signal.default_int_handler)
from delaytrack.cli import main
from delaytrack.sweeps import executors

real_run_unit, blocked = executors.run_unit, Path(sys.argv[1])


def run_unit(unit, **kwargs):
    if unit.index < 2:
        return real_run_unit(unit, **kwargs)
    blocked.touch()
    time.sleep(3600)  # ended by Ctrl-C


executors.run_unit = run_unit
sys.exit(main(sys.argv[2:]))
"""


@pytest.mark.slow
def test_ctrl_c_on_the_command_keeps_finished_parts(tmp_path):
    """SIGINT to a running ``delaytrack sweep``: exit 130, the two finished parts kept and
    counted, no temporary files; the same command then computes only the missing units."""
    spec_file = tmp_path / "sweep.toml"
    text = EXAMPLE.read_text().replace("duration = [1.0]", "duration = [0.1]")
    spec_file.write_text(text.replace("unit_size = 8", "unit_size = 4"))
    out, blocked, log = tmp_path / "out", tmp_path / "blocked", tmp_path / "stderr.txt"
    arguments = ["sweep", str(spec_file), "--out", str(out), "--quiet", "--workers", "1"]
    with open(log, "w") as stderr:
        process = subprocess.Popen(
            [sys.executable, "-c", BLOCKING_COMMAND, str(blocked), *arguments], stderr=stderr
        )
    try:
        # Generous: the child may compile the simulation kernels first on a loaded machine.
        deadline = time.monotonic() + 300
        while not blocked.exists():
            assert process.poll() is None, log.read_text()
            assert time.monotonic() < deadline, "the sweep never reached its third unit"
            time.sleep(0.05)
        process.send_signal(signal.SIGINT)
        assert process.wait(timeout=120) == 130, log.read_text()
    finally:
        process.kill()
        process.wait()
    spec = SweepSpec.from_toml(spec_file)
    assert finished_units(out / "parts", spec).finished == {0, 1}
    assert "sweep interrupted: 2 of 6 units done" in log.read_text()
    assert not list((out / "parts").glob(".part-*"))
    executor = CountingExecutor()
    outcome = run_sweep(spec, out, executor=executor, progress=False)
    assert executor.ran == [2, 3, 4, 5] and outcome.resumed == 2
    assert list(outcome.runs["run"]) == list(range(24))


@pytest.mark.parametrize("written", [True, False], ids=["after-rename", "before-rename"])
def test_an_interrupted_sweep_counts_the_parts_on_disk(tmp_path, monkeypatch, written):
    """Ctrl-C while unit 2's part is written, just after its rename into place or before it
    (over a corrupt part of unit 2 from an earlier run, with the write's temporary file left):
    the reported count is the number of valid parts on disk, and no temporary file stays."""
    real_write_part = runner_module.write_part
    spec = small_spec()
    out = tmp_path / "sweep"
    parts = out / "parts"
    parts.mkdir(parents=True)
    stale = parts / spec.units()[2].part_name
    stale.write_bytes(b"not parquet at all")

    def interrupted_write_part(frame, unit, folder):
        if unit.index != 2:
            return real_write_part(frame, unit, folder)
        if written:
            real_write_part(frame, unit, folder)
        else:
            (parts / f".{unit.part_name}.abc123.parquet").write_bytes(b"half a part")
        raise KeyboardInterrupt

    monkeypatch.setattr(runner_module, "write_part", interrupted_write_part)
    with pytest.raises(SweepInterrupted) as stopped:
        run_sweep(spec, out, executor=CountingExecutor(), progress=False)
    finished = finished_units(parts, spec).finished
    assert finished == ({0, 1, 2} if written else {0, 1})
    assert (stopped.value.done, stopped.value.total) == (len(finished), 5)
    assert f"{len(finished)} of 5 units done" in str(stopped.value)
    assert stale.exists() and not list(parts.glob(".part-*"))
    monkeypatch.setattr(runner_module, "write_part", real_write_part)
    executor = CountingExecutor()
    outcome = run_sweep(spec, out, executor=executor, progress=False)
    assert executor.ran == [k for k in range(5) if k not in finished]
    assert outcome.resumed == len(finished)


def test_a_key_with_numbers_in_one_unit_and_text_in_another(tmp_path):
    """A scalar and a diagonal gain in one grid: one column type in every part and the table."""
    changes = {"grid": {"duration": [0.1], "controller.K1": [2.0, [1.0, 3.0]]}, "unit_size": 1}
    data = tomllib.loads(EXAMPLE.read_text()) | changes
    data.pop("random"), data.pop("draws"), data.pop("seed")
    spec = SweepSpec.from_dict(
        data | {"grid": changes["grid"] | {"controller.K2": [1.0]}}, root=EXAMPLE.parent
    )
    outcome = run_sweep(spec, tmp_path / "out", progress=False)
    table = pq.read_table(tmp_path / "out" / "runs.parquet").to_pandas()
    assert list(table["controller.K1"]) == ["2.0", "[1.0,3.0]"]
    assert list(outcome.runs["controller.K1"]) == ["2.0", "[1.0,3.0]"]


def test_a_part_with_altered_values_is_recomputed(reference, tmp_path):
    """Values changed inside a readable part (same metadata) fail its content hash."""
    out = tmp_path / "sweep"
    run_sweep(small_spec(), out, progress=False)
    path = out / "parts" / small_spec().units()[2].part_name
    table = pq.read_table(path)
    frame = table.to_pandas()
    frame.loc[0, "ae_q1"] *= 1.0 + 1e-12
    altered = pa.Table.from_pandas(frame, preserve_index=False)
    pq.write_table(altered.replace_schema_metadata(table.schema.metadata), path)
    executor = CountingExecutor()
    outcome = run_sweep(small_spec(), out, executor=executor, progress=False)
    assert executor.ran == [2]
    assert "content hash" in outcome.rejected[path.name]
    pd.testing.assert_frame_equal(outcome.runs, reference.runs, check_exact=True)


def test_continuous_controller_draws_do_not_split_the_summary(tmp_path):
    data = tomllib.loads(EXAMPLE.read_text()) | {"unit_size": 24}
    data["grid"] = {"duration": [0.1]}
    data["random"] = {"controller.K1": {"dist": "uniform", "low": 1.0, "high": 2.0}}
    spec = SweepSpec.from_dict(data, root=EXAMPLE.parent)
    outcome = run_sweep(spec, tmp_path / "out", progress=False)
    write_sweep_outputs(outcome)
    summary = pd.read_csv(tmp_path / "out" / "summary.csv")
    assert list(summary["controller"]) == ["arolc"] and summary["runs"].sum() == 4


def test_cli_refuses_workers_with_a_running_cluster(tmp_path, capsys):
    command = ["sweep", str(EXAMPLE), "--out", str(tmp_path), "--scheduler", "tcp://127.0.0.1:9"]
    assert main([*command, "--workers", "2"]) == 2
    assert "--workers 2 applies to the local executor" in capsys.readouterr().err


def test_a_failing_unit_costs_only_itself(reference, tmp_path, monkeypatch, capsys):
    """Unit 2 raises: the other units' parts are written, the error names it, exit code 1,
    and the next call computes unit 2 alone."""
    real = executors_module.run_unit

    def failing(unit, **kwargs):
        if unit.index == 2:
            raise ValueError("boom in unit 2")
        return real(unit, **kwargs)

    monkeypatch.setattr(executors_module, "run_unit", failing)
    out = tmp_path / "sweep"
    with pytest.raises(SweepUnitsFailed, match=r"1 of 5 units failed \(unit 2: ValueError: boom"):
        run_sweep(small_spec(), out, executor=LocalExecutor(workers=1), progress=False)
    assert len(list((out / "parts").glob("part-*.parquet"))) == 4
    spec_file = tmp_path / "sweep.toml"
    spec_file.write_text(EXAMPLE.read_text().replace("duration = [1.0]", "duration = [0.2]"))
    assert main(["sweep", str(spec_file), "--out", str(tmp_path / "cli"), "--quiet"]) == 1
    assert "units failed (unit 2: ValueError: boom in unit 2)" in capsys.readouterr().err
    monkeypatch.setattr(executors_module, "run_unit", real)
    executor = CountingExecutor()
    outcome = run_sweep(small_spec(), out, executor=executor, progress=False)
    assert executor.ran == [2]
    pd.testing.assert_frame_equal(outcome.runs, reference.runs, check_exact=True)


def test_a_full_disk_keeps_the_finished_parts_and_resumes(tmp_path, monkeypatch):
    """The disk fills while unit 2's part is written: the error says so, the half-written
    temporary file is removed, units 0 and 1 stay finished, and the next call computes the
    rest."""
    real_write_part = runner_module.write_part
    real_write_table = pq.write_table
    spec = small_spec()
    out = tmp_path / "sweep"

    def no_space(table, where, *args, **kwargs):
        Path(where).write_bytes(b"half a part")
        raise OSError(errno.ENOSPC, "No space left on device", str(where))

    def full_disk_write_part(frame, unit, folder):
        if unit.index != 2:
            return real_write_part(frame, unit, folder)
        with monkeypatch.context() as patch:
            patch.setattr(pq, "write_table", no_space)
            return real_write_part(frame, unit, folder)

    monkeypatch.setattr(runner_module, "write_part", full_disk_write_part)
    with pytest.raises(OSError, match="No space left on device"):
        run_sweep(spec, out, executor=CountingExecutor(), progress=False)
    assert pq.write_table is real_write_table
    parts = out / "parts"
    assert finished_units(parts, spec).finished == {0, 1}
    assert not [p for p in parts.iterdir() if p.name.startswith(".")]
    monkeypatch.setattr(runner_module, "write_part", real_write_part)
    executor = CountingExecutor()
    outcome = run_sweep(spec, out, executor=executor, progress=False)
    assert executor.ran == [2, 3, 4]
    assert outcome.resumed == 2


def test_a_sweep_over_input_limits_batches_each_run_with_its_own(tmp_path):
    """Grid points with and without saturation share units; each run equals its run alone."""
    data = tomllib.loads(EXAMPLE.read_text()) | {"unit_size": 4, "draws": 1}
    data["grid"] = data["grid"] | {"duration": [0.2], "input_limits": [0.5, float("inf")]}
    spec = SweepSpec.from_dict(data, root=EXAMPLE.parent)
    runs = run_sweep(spec, tmp_path / "out", progress=False).runs
    assert len(runs) == 12
    single = SweepSpec.from_dict(data | {"unit_size": 1}, root=EXAMPLE.parent)
    alone = pd.concat([run_unit(unit, workers=1) for unit in single.units()])
    pd.testing.assert_frame_equal(
        alone.reset_index(drop=True), runs.reset_index(drop=True), check_exact=True
    )
    limited = runs[runs["input_limits"] == 0.5]
    free = runs[runs["input_limits"] == float("inf")]
    assert len(limited) == len(free) == 6
    assert not np.allclose(limited["ae_q1"].to_numpy(), free["ae_q1"].to_numpy())


def test_the_command_says_how_many_runs_did_not_finish_and_how():
    from delaytrack.cli.sweep import unfinished_runs_line

    status = pd.Series(["ok", "left the path", "diverged", "left the path", "ok"])
    assert unfinished_runs_line(status) == (
        "  3 of 5 runs did not finish (2 left the path, 1 diverged): their metrics are empty in "
        "runs.csv, and summary.csv counts those that diverged or left the path in its "
        "divergence rate"
    )
    assert unfinished_runs_line(pd.Series(["ok", "ok"])) == ""


def test_the_figures_count_the_runs_not_ok_and_keep_the_legend_off_the_points():
    import pandas as pd

    from delaytrack.report.sweep import ae_vs_h_max_figure, distribution_figure

    runs = pd.DataFrame(
        {
            "controller_type": ["arolc"] * 4 + ["outer-loop"] * 3,
            "status": ["ok", "diverged", "ok", "left the path", "ok", "ok", "ok"],
            "h_max": [0.05, 0.05, 0.1, 0.1, 0.05, 0.1, 0.1],
            "ae_q1": [0.1, float("nan"), 0.2, float("nan"), 0.15, 0.25, 0.3],
        }
    )
    ax = distribution_figure(runs, ["ae_q1"]).axes[0]
    ticks = [tick.get_text() for tick in ax.get_xticklabels()]
    assert ticks == ["arolc\n2 of 4 not ok", "outer-loop\nall 3 ok"]
    scatter = ae_vs_h_max_figure(runs, ["ae_q1"])
    assert scatter.axes[0].get_legend() is None  # the figure's legend, below the panels
    assert [text.get_text() for text in scatter.legends[0].get_texts()] == ["arolc", "outer-loop"]
