"""Sweeps on a real Dask cluster (scheduler and worker processes on loopback).

Checked: the same results as the local executor, bit for bit; a worker killed mid-sweep and the
sweep still complete with every run exactly once; ``--scheduler local-cluster`` from the CLI; a
scheduler that does not answer is a clear error.
"""

import logging
import os
import signal
import threading
import time
import tomllib
from pathlib import Path

import pandas as pd
import pytest

distributed = pytest.importorskip("distributed")

from delaytrack.cli import main  # noqa: E402
from delaytrack.sweeps import (  # noqa: E402
    DaskExecutor,
    LocalExecutor,
    SweepError,
    SweepInterrupted,
    SweepSpec,
    run_sweep,
)

pytestmark = pytest.mark.slow

EXAMPLE = Path(__file__).parents[1] / "examples" / "sweep_small.toml"


def spec_of(duration: float, unit_size: int) -> SweepSpec:
    """The example sweep (24 two-link runs) with longer runs."""
    data = tomllib.loads(EXAMPLE.read_text()) | {"unit_size": unit_size}
    data["grid"] = data["grid"] | {"duration": [duration]}
    return SweepSpec.from_dict(data, root=EXAMPLE.parent)


@pytest.fixture(scope="module")
def spec():
    return spec_of(40.0, 2)  # 12 units of about 0.05 s each


@pytest.fixture(scope="module")
def local_runs(spec, tmp_path_factory):
    """The sweep with the local executor; it also warms this machine's compiled-kernel cache,
    which the worker processes then load instead of compiling."""
    out = tmp_path_factory.mktemp("local")
    return run_sweep(spec, out, executor=LocalExecutor(), progress=False).runs


@pytest.fixture(scope="module")
def cluster(local_runs):
    with distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        dashboard_address=":0",
        silence_logs=logging.ERROR,
    ) as cluster:
        yield cluster


def test_dask_cluster_gives_the_local_results(spec, local_runs, cluster, tmp_path):
    executor = DaskExecutor(cluster.scheduler_address)
    outcome = run_sweep(spec, tmp_path / "dask", executor=executor, progress=False)
    assert outcome.executor == f"dask: {cluster.scheduler_address}"
    assert outcome.computed == len(spec.units())
    pd.testing.assert_frame_equal(outcome.runs, local_runs, check_exact=True)
    # Resumed on the cluster: nothing to compute.
    again = run_sweep(
        spec, tmp_path / "dask", executor=DaskExecutor(cluster.scheduler_address), progress=False
    )
    assert again.computed == 0
    pd.testing.assert_frame_equal(again.runs, local_runs, check_exact=True)


def test_a_killed_worker_loses_nothing(cluster, tmp_path):
    # 6 units of about 0.7 s each (three per worker): the kill hits a running task, with units
    # left to run after it
    spec = spec_of(300.0, 4)
    expected = run_sweep(spec, tmp_path / "local", executor=LocalExecutor(), progress=False)
    client = distributed.Client(cluster.scheduler_address)  # the test's own, outlives the sweep
    client.wait_for_workers(2, timeout=60)
    pids = client.run(os.getpid)
    out = tmp_path / "dask"
    finished = {}

    def sweep():
        # The executor is made in the thread that waits on it, as `delaytrack sweep` does: a
        # client made in one thread and waited on in another failed once with distributed's
        # "Event ... is bound to a different event loop" when the kill hit a finished unit.
        executor = DaskExecutor(cluster.scheduler_address)
        finished["outcome"] = run_sweep(spec, out, executor=executor, progress=False)

    thread = threading.Thread(target=sweep)
    thread.start()
    deadline = time.monotonic() + 120
    victim = None
    while victim is None and time.monotonic() < deadline:
        busy = [address for address, keys in client.processing().items() if keys]
        if list((out / "parts").glob("part-*.parquet")) and busy:
            victim = busy[0]
        else:
            time.sleep(0.005)
    assert victim is not None, "no part appeared within 120 s"
    parts_at_kill = len(list((out / "parts").glob("part-*.parquet")))
    in_flight = list(client.processing()[victim])
    os.kill(pids[victim], signal.SIGKILL)
    thread.join(timeout=300)
    assert not thread.is_alive()
    assert parts_at_kill < len(spec.units())
    with pytest.raises(ProcessLookupError):
        os.kill(pids[victim], 0)
    runs = finished["outcome"].runs
    assert list(runs["run"]) == list(range(len(spec.runs)))
    pd.testing.assert_frame_equal(runs, expected.runs, check_exact=True)
    # A task the dead worker held was scheduled again (on the surviving or restarted worker).
    story = client.run_on_scheduler(lambda dask_scheduler: dask_scheduler.story(*in_flight))
    processing = [transition[0] for transition in story if transition[2] == "processing"]
    assert any(processing.count(key) >= 2 for key in in_flight), story
    client.close()


class StoppingExecutor(DaskExecutor):
    """A Dask executor whose caller presses Ctrl-C after ``stop_after`` results."""

    def __init__(self, address, stop_after):
        super().__init__(address)
        self.stop_after = stop_after

    def results(self, units):
        for count, item in enumerate(super().results(units)):
            if count == self.stop_after:
                raise KeyboardInterrupt
            yield item


def test_interrupted_and_corrupt_on_dask_resume_without_recomputing(
    spec, local_runs, cluster, tmp_path
):
    out = tmp_path / "dask"
    with pytest.raises(SweepInterrupted) as stopped:
        run_sweep(
            spec, out, executor=StoppingExecutor(cluster.scheduler_address, 3), progress=False
        )
    assert stopped.value.done == 3
    kept = sorted((out / "parts").glob("part-*.parquet"))
    assert len(kept) == 3
    kept[0].write_bytes(kept[0].read_bytes()[:-50])  # truncated
    resumed = run_sweep(spec, out, executor=DaskExecutor(cluster.scheduler_address), progress=False)
    assert resumed.resumed == 2 and resumed.computed == len(spec.units()) - 2
    assert list(resumed.rejected) == [kept[0].name]
    pd.testing.assert_frame_equal(resumed.runs, local_runs, check_exact=True)


def test_cli_local_cluster(spec, local_runs, tmp_path, capsys, monkeypatch):
    # Run from a folder holding a file named like a module Dask's worker processes import at
    # their start: it must not run (it would leave a mark, and stop the worker).
    working = tmp_path / "working"
    working.mkdir()
    mark = working / "imported"
    (working / "multiprocessing.py").write_text(
        f"open({str(mark)!r}, 'w').write('ran')\nraise SystemExit('shadowed')\n"
    )
    monkeypatch.chdir(working)
    spec_file = tmp_path / "sweep.toml"
    spec_file.write_text(
        EXAMPLE.read_text()
        .replace("duration = [1.0]", "duration = [40.0]")
        .replace("unit_size = 8", "unit_size = 2")
    )
    out = tmp_path / "out"
    code = main(
        [
            "sweep",
            str(spec_file),
            "--out",
            str(out),
            "--scheduler",
            "local-cluster",
            "--workers",
            "2",
            "--quiet",
        ]
    )
    assert code == 0 and not mark.exists()
    assert "on dask: local cluster of 2 worker processes" in capsys.readouterr().out
    assert "PYTHONSAFEPATH" not in os.environ  # as it was before the cluster
    pd.testing.assert_frame_equal(
        pd.read_parquet(out / "runs.parquet"), local_runs.reset_index(drop=True), check_exact=True
    )


def test_a_local_cluster_that_does_not_start_is_one_line(monkeypatch):
    def fails(**_options):
        try:
            raise ImportError("no module named 'x'")
        except ImportError as error:
            raise RuntimeError("Nanny failed to start.") from error

    monkeypatch.setattr(distributed, "LocalCluster", fails)
    message = r"'local-cluster': the local Dask cluster did not start: Nanny .* \(no module"
    with pytest.raises(SweepError, match=message):
        DaskExecutor("local-cluster", workers=1)
    assert "PYTHONSAFEPATH" not in os.environ


def test_a_scheduler_that_does_not_answer_is_a_clear_error():
    with pytest.raises(SweepError, match=r"--scheduler 'tcp://127.0.0.1:9': no Dask scheduler"):
        DaskExecutor("tcp://127.0.0.1:9", timeout=1.0)


@pytest.mark.parametrize(
    "answer, message",
    [
        # the timeout given below, 1 s, and the second Dask's own connect may take beyond it
        (None, r"a server accepted the connection but sent no Dask handshake within 2 s"),
        (b"HTTP/1.0 200 OK\r\n\r\n", r"what answered there is not a Dask scheduler"),
    ],
    ids=["silent", "http"],
)
def test_a_server_that_is_not_a_dask_scheduler_is_a_clear_error_in_time(answer, message):
    """An HTTP server waiting for a request (a ``Client`` waited for its handshake without
    end), or one that answers at once (its bytes read as a frame length: a ``MemoryError``)."""
    import socket
    import threading

    server = socket.create_server(("127.0.0.1", 0))
    accepted = []

    def serve():
        connection, _ = server.accept()
        accepted.append(connection)
        if answer is not None:
            connection.sendall(answer)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    address = f"tcp://127.0.0.1:{server.getsockname()[1]}"
    try:
        with pytest.raises(SweepError, match=rf"--scheduler '{address}': {message}"):
            DaskExecutor(address, timeout=1.0)
    finally:
        thread.join(5)
        for connection in accepted:
            connection.close()
        server.close()


def test_the_robustness_study_runs_on_the_cluster(cluster, tmp_path):
    # The study's sweeps on the cluster give the local executor's tables, bit for bit.
    from delaytrack.experiments import robustness
    from delaytrack.jobs.robustness import run_robustness

    size = robustness.StudySize(map=1, knowledge=1, claims=1)
    local = run_robustness(tmp_path / "local", size=size, progress=False)
    on_cluster = run_robustness(
        tmp_path / "dask",
        size=size,
        executor=lambda: DaskExecutor(cluster.scheduler_address),
        progress=False,
    )
    assert on_cluster.computed == local.computed > 0
    for name, frame in local.runs.items():
        pd.testing.assert_frame_equal(on_cluster.runs[name], frame, check_exact=True)
    pd.testing.assert_frame_equal(on_cluster.verdicts, local.verdicts, check_exact=True)


def test_the_scheduler_waited_for_is_named_before_the_wait(capsys):
    """A scheduler that refuses the connection is retried until the timeout: with progress,
    the user is told which scheduler is waited for and for how long, before the wait."""
    with pytest.raises(SweepError):
        DaskExecutor("tcp://127.0.0.1:9", timeout=1.0, progress=True)
    assert capsys.readouterr().err == (
        "delaytrack: connecting to the Dask scheduler at tcp://127.0.0.1:9 (waiting up to 1 s)\n"
    )
    with pytest.raises(SweepError):
        DaskExecutor("tcp://127.0.0.1:9", timeout=0.5)
    assert capsys.readouterr().err == ""
