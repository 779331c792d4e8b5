"""How ``make test`` shares the suite between pytest-xdist's workers (``--dist loadscope``), and
the live sessions and the ``delaytrack reproduce`` run that several modules read.

A worker takes a whole test module at a time, so a module's fixture (the live sessions, the
Dask cluster, the golden runs) is made once and the kernels its tests share are compiled by
one worker; the live modules go together, so that one worker runs their real-time sessions
while the other keeps compiling, and so do the modules of :data:`REPRODUCED`, which read one
``delaytrack reproduce`` run (:func:`reproduced`). First go the modules of :data:`FIRST`, which
compile in a worker the kernels that the live sessions' and the documentation examples'
processes then load from numba's disk cache (compiled in each of those processes instead, they
cost more); then the live modules and the modules holding a test marked ``slow``: the short
modules left at the end keep both workers busy until the suite ends.
"""

from __future__ import annotations

import functools
import gc
import os
import subprocess
import sys
import threading
import time
from argparse import Namespace
from pathlib import Path, PurePosixPath

import pytest

from delaytrack._compile.interpret_first import INTERPRETING

# The suite runs as a user's code runs: a short first run of a combination not compiled yet is
# interpreted (the same numbers), unless a module of :data:`COMPILED` turns that off.
os.environ.pop(INTERPRETING, None)
#: Modules whose subject is the compiled engine or compiling it (its numbers against the golden
#: runs and the oracle, its order, its compile and cache, its refusals of kernels numba cannot
#: compile): their tests, fixtures and processes compile at once.
COMPILED = (
    "test_golden.py",
    "test_engine.py",
    "test_speed_paths.py",
    "test_native_call.py",
    "test_components.py",
    "test_user_components.py",
    "test_compile_helper.py",
    "test_stale_caches.py",
    "test_numba_cache.py",
    "test_hostile_kernels.py",
    "test_reduced_form.py",
    "test_mujoco_plant.py",
    "test_robot_closed_loop.py",
)


def pytest_unconfigure(config: pytest.Config) -> None:
    """The end of a pytest-xdist worker, a process that ends with pytest: its objects frozen,
    so that Python's collections at exit skip them, as the toolkit's own processes end
    (:mod:`delaytrack._process_exit`): about 0.8 s less at a worker's end. Not in a process
    that runs pytest in-process and goes on."""
    if hasattr(config, "workerinput"):
        gc.freeze()


@pytest.fixture(autouse=True, scope="module")
def _compiled_at_once(request: pytest.FixtureRequest):
    """In a module of :data:`COMPILED`, ``DELAYTRACK_INTERPRET_FIRST=0`` (before the module's
    own fixtures, and for the processes its tests start)."""
    if PurePosixPath(str(request.path)).name not in COMPILED:
        yield
        return
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv(INTERPRETING, "0")
        yield


#: The unit of work of the live modules (``tests/test_live_*.py``).
LIVE = "live sessions"
#: Modules that compile the engine and the parts of the two-link arm, the robot and the linear
#: plant with the paper's controllers: the kernels most tests and their processes share. The
#: first compiles the engine while the other worker runs :data:`WITHOUT_THE_ENGINE`, so that
#: the two do not compile it at once.
FIRST = ("test_engine.py", "test_golden.py", "test_cli_empirical.py")
#: Modules that simulate nothing compiled (the documentation site, the analysis of bad input):
#: the other worker's first work, while the engine compiles.
WITHOUT_THE_ENGINE = ("test_docs.py", "test_analysis_hostile.py")
#: The unit of work of the modules that read :func:`reproduced` (one run in one worker).
REPRODUCED = ("test_paper.py", "test_report_rendering.py")


def _unit(nodeid: str) -> str:
    """The unit of work of a test: its module, :data:`LIVE`, or the modules of
    :data:`REPRODUCED` together."""
    module = nodeid.split("::", 1)[0]
    name = PurePosixPath(module).name
    if name.startswith("test_live_"):
        return LIVE
    return " ".join(REPRODUCED) if name in REPRODUCED else module


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """On a worker: the first module of :data:`FIRST`, the modules of
    :data:`WITHOUT_THE_ENGINE`, the rest of :data:`FIRST`, then the live modules and the
    modules with a ``slow`` test, then the rest, each module's tests in their own order (every
    worker sorts alike)."""
    if not hasattr(config, "workerinput"):
        return
    slow = {_unit(item.nodeid) for item in items if item.get_closest_marker("slow")} | {LIVE}
    order = (FIRST[0], *WITHOUT_THE_ENGINE, *FIRST[1:])

    def rank(item: pytest.Item) -> tuple[int, int]:
        unit = _unit(item.nodeid)
        name = PurePosixPath(unit).name
        if name in order:
            return 0, order.index(name)
        return (1 if unit in slow else 2), 0

    items.sort(key=rank)


@pytest.hookimpl(optionalhook=True, tryfirst=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log):
    """``--dist loadscope`` with the units of :func:`_unit`, in the order of
    :func:`pytest_collection_modifyitems` (not reordered by their number of tests)."""
    if config.getvalue("dist") != "loadscope":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class ByUnit(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return _unit(nodeid)

    config.option.loadscopereorder = False
    return ByUnit(config, log)


# ---- live sessions read by several live modules ------------------------------------------------

#: The scenario of the shared sessions.
LIVE_SCENARIO = "two_link_S1"
#: Modules a live node imports, written into the working folder of :func:`live_run`.
SHADOWED = ("zenoh", "numpy", "json", "delaytrack")


class Launched:
    """A process started at once, whose outcome is read when first asked for."""

    def __init__(self, command: list[str], cwd: Path | None = None) -> None:
        self.process = subprocess.Popen(
            command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=cwd
        )

    @functools.cached_property
    def outcome(self) -> tuple[bytes, bytes, int]:
        """Its standard output, its standard error and its exit code."""
        stdout, stderr = self.process.communicate(timeout=180)
        return stdout, stderr, self.process.returncode

    def stop(self) -> None:
        """End it if no test read its outcome."""
        if self.process.poll() is None:
            self.process.kill()
            self.process.communicate()


@pytest.fixture(scope="session")
def live_run(tmp_path_factory):
    """``delaytrack live run`` of :data:`LIVE_SCENARIO` for 2 s with its status line, its links
    mutual TLS (certificates of an authority of the tests' own), started when first asked for
    (test_live_loop.py, test_live_status.py): its folder and the launcher (:class:`Launched`)."""
    pytest.importorskip("zenoh")
    pytest.importorskip("mcap_ros2")
    pytest.importorskip("cryptography")
    from certificates import certificates

    folder = tmp_path_factory.mktemp("live_run") / "run"
    ca, certificate, key = certificates(folder.parent / "tls")
    command = ["run", LIVE_SCENARIO, "--duration", "2", "--out", str(folder), "--tls-ca", ca]
    command += ["--tls-certificate", certificate, "--tls-key", key]
    # Started from a folder of files named like modules the nodes import, each of which would
    # leave a mark (test_live_loop.py): the launcher as the `delaytrack` command starts (no
    # folder first on its module search path), then the nodes it starts must not import them.
    working = folder.parent / "working"
    working.mkdir()
    for module in SHADOWED:
        (working / f"{module}.py").write_text(
            f"open({str(working / 'imported')!r}, 'a').write({module!r} + '\\n')\n"
        )
    launched = Launched([sys.executable, "-P", "-m", "delaytrack.live", *command], cwd=working)
    yield folder, launched
    launched.stop()


@pytest.fixture(scope="session")
def live_nodes(tmp_path_factory):
    """The three nodes of a 2 s session of :data:`LIVE_SCENARIO` started one by one, as the
    launcher starts them (all quiet) but with the robot not quiet, while a subscriber takes
    their statuses (test_live_status.py, test_live_collect.py).

    Returns the session's folder, name, each node's ``(stdout, stderr)`` and exit code, and the
    statuses received, ``(key, payload)``.
    """
    pytest.importorskip("zenoh")
    pytest.importorskip("mcap_ros2")
    from delaytrack.live.session import ROLES, node_commands
    from delaytrack.live.transport import open_session
    from ports import free_ports

    folder = tmp_path_factory.mktemp("live_nodes") / "nodes"
    ports, name = free_ports(3), "nodes-test"
    options = Namespace(
        scenario=LIVE_SCENARIO,
        handshake_timeout=60.0,
        duration=2.0,
        trust=[],
        quiet=False,
        loss=None,
        certificates=None,
    )
    watch = f"tcp/127.0.0.1:{free_ports(1)[0]}"
    commands = node_commands(options, folder, ports, name, watch)
    commands["robot"].remove("--quiet")
    received: list[tuple[str, bytes]] = []
    lock = threading.Lock()

    def on_status(sample):
        with lock:
            received.append((str(sample.key_expr), sample.payload.to_bytes()))

    session = open_session([watch], [])  # listening before the nodes start, as the launcher
    subscriber = session.declare_subscriber(f"delaytrack/{name}/status/*", on_status)
    try:
        nodes = {
            role: subprocess.Popen(commands[role], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
            for role in ROLES
        }
        outputs = {role: node.communicate(timeout=180) for role, node in nodes.items()}
        time.sleep(0.2)  # the last statuses on their way
    finally:
        subscriber.undeclare()
        session.close()
    codes = {role: node.returncode for role, node in nodes.items()}
    with lock:
        return folder, name, outputs, codes, list(received)


# ---- the reproduce run read by several modules ------------------------------------------------


@pytest.fixture(scope="session")
def reproduced(tmp_path_factory):
    """``delaytrack reproduce --duration 1 --quiet`` (the paper job, its literal sibling and the
    robustness study at a tiny size; contact physics and the dt check on), run once for the
    modules of :data:`REPRODUCED` (test_paper.py, test_report_rendering.py), which only read it.

    Returns its output folder, its exit code and what it printed.
    """
    import contextlib
    import io

    from delaytrack.cli import main
    from delaytrack.experiments import robustness

    out = tmp_path_factory.mktemp("reproduce")
    printed = io.StringIO()
    with pytest.MonkeyPatch.context() as patch, contextlib.redirect_stdout(printed):
        patch.setitem(robustness.SIZES, "default", robustness.StudySize(1, 1, 2))
        code = main(["reproduce", "--out", str(out), "--duration", "1", "--quiet"])
    return out, code, printed.getvalue()
