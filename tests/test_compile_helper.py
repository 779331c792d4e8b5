"""First compiles shared with a helper process (delaytrack._compile.helper_process)."""

from __future__ import annotations

import io
import os
import pickle
import subprocess
import sys
import threading
import time

import numba
import pytest

from delaytrack._compile import helper_process
from delaytrack._compile.ahead import ahead, parts_ahead
from delaytrack._compile.disk_cache import cache_directory
from delaytrack._compile.helper_process import (
    PATIENCE,
    START_UP,
    CompileJob,
    Helper,
    order_here,
    share,
    start,
)
from delaytrack._compile.native_parts import controller_step_part, plant_tick_part
from delaytrack.components import Kernel
from delaytrack.controllers.arolc import arolc_step
from delaytrack.delays._kernel import NO_KERNEL
from delaytrack.plants import TwoLinkArm
from delaytrack.plants.robot import PayloadRobot
from delaytrack.sim.engine import run_batch_compiled


def test_the_work_is_shared_longest_first_so_both_finish_together():
    # the engine, the integrator, the reference, a step, the delay
    costs = [9.0, 12.0, 1.5, 5.0, 1.5]
    given = share(costs, [True] * 5)
    assert given == [0, 3]  # the engine and the step: 9 + 5 + start-up against 12 + 1.5 + 1.5
    helper = START_UP + sum(costs[i] for i in given)
    here = sum(costs) - sum(costs[i] for i in given)
    assert max(helper, here) < sum(costs)
    # what the helper cannot import stays here
    assert 1 not in share(costs, [True, False, True, True, True])
    assert share(costs, [False] * 5) == []


def test_this_process_takes_first_what_only_it_can_compile_then_the_helpers_jobs():
    jobs = [CompileJob(None, (), (), cost) for cost in (5.0, 7.0, 0.5, 1.5, 0.3, 1.5)]
    # the helper may take 0, 1, 3 and 4 (longest first: 1, 0, 3, 4); 2 and 5 are this one's
    assert order_here(jobs, [0, 1, 3, 4]) == [5, 2, 1, 0, 3, 4]
    assert order_here(jobs, []) == [1, 0, 3, 5, 2, 4]  # no helper: longest first (ties in order)


def test_the_helper_is_waited_for_as_long_as_the_jobs_it_may_have_claimed():
    seen = []

    class Process:  # a stand-in: nothing is started
        def wait(self, timeout):
            seen.append(timeout)
            return 0

    helper = Helper(Process(), 60.0, None, {0: 5.0, 3: 1.5})  # type: ignore[arg-type]
    assert helper.claim(0)  # this process took the longest: the helper can only have the other
    assert helper.wait() is True
    assert seen == [60.0 + PATIENCE * 1.5]


def test_a_helper_whose_parent_ended_claims_nothing_more(tmp_path, monkeypatch):
    parents = iter([100, 1, 1])  # the parent at the start, then init: it was orphaned
    monkeypatch.setattr(os, "getppid", lambda: next(parents))
    payload = _payload(str(cache_directory()), str(tmp_path), [_MISSING])
    assert helper_process.main(payload) == 1
    assert list(tmp_path.iterdir()) == []  # no claim written


def test_no_helper_when_it_would_not_finish_sooner():
    assert share([1.0, 1.0], [True, True]) == []  # its start-up is longer than the work
    assert share([9.0], [True]) == []
    assert start([]) == (None, [])


def test_no_helper_when_turned_off(monkeypatch):
    job = plant_tick_part(TwoLinkArm().engine_kernel, NO_KERNEL, 2, 2).compile_job()
    monkeypatch.setenv(helper_process.ENVIRONMENT, "0")
    assert start([job, job]) == (None, [])


def test_a_helper_runs_only_beside_a_spare_core(monkeypatch):
    monkeypatch.setattr(helper_process, "_cores", lambda: 2)
    monkeypatch.delenv(helper_process.ENVIRONMENT, raising=False)
    monkeypatch.setattr(helper_process, "idle_cpus", lambda: 1.9)
    assert helper_process.spare_core()  # this process's core (it waits) and another one idle
    monkeypatch.setattr(helper_process, "idle_cpus", lambda: 1.2)
    assert not helper_process.spare_core()  # another process busy on the other core
    monkeypatch.setattr(helper_process, "idle_cpus", lambda: None)  # not measured here
    monkeypatch.setattr(os, "getloadavg", lambda: (1.2, 0.0, 0.0), raising=False)
    assert helper_process.spare_core()  # then the load average of the last minute decides
    monkeypatch.setattr(os, "getloadavg", lambda: (1.9, 0.0, 0.0), raising=False)
    assert not helper_process.spare_core()
    monkeypatch.setenv(helper_process.ENVIRONMENT, "1")
    assert helper_process.spare_core()  # asked for, whatever the load
    monkeypatch.setattr(helper_process, "locks_cache", lambda: False)
    assert not helper_process.spare_core()  # no lock on the cache's index (Windows)
    monkeypatch.setattr(helper_process, "locks_cache", lambda: True)
    monkeypatch.setattr(sys, "frozen", True, raising=False)
    assert not helper_process.spare_core()  # sys.executable is the application, not Python
    monkeypatch.delattr(sys, "frozen")
    monkeypatch.setenv(helper_process.ENVIRONMENT, "0")
    monkeypatch.setattr(helper_process, "idle_cpus", lambda: 2.0)
    assert not helper_process.spare_core()
    monkeypatch.delenv(helper_process.ENVIRONMENT)
    monkeypatch.setattr(helper_process, "_cores", lambda: 1)
    assert not helper_process.spare_core()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_a_process_busy_on_a_cpu_is_not_idle_time():
    import time

    cpus = helper_process._cpu_times().cpus  # those this process may run on
    assert cpus >= 1
    other = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        time.sleep(0.5)  # started and spinning
        idle = helper_process.idle_cpus(0.3)
        assert idle is not None
        assert 0.0 <= idle < cpus - 0.5
    finally:
        other.kill()
        other.wait()


def _readings(monkeypatch, *readings):
    monkeypatch.setattr(helper_process.time, "sleep", lambda seconds: None)
    times = iter([0.0, 0.1])  # the window: 0.1 s
    monkeypatch.setattr(helper_process.time, "monotonic", lambda: next(times))
    values = iter(readings)
    monkeypatch.setattr(helper_process, "_cpu_times", lambda: next(values))


def test_the_cpus_this_process_uses_count_as_free(monkeypatch):
    # Over the window two CPUs ran 10 of 20 clock ticks. When this process ran them (a linear
    # algebra thread still spinning after a call), both are free for a helper; when another
    # process did, one is.
    before = helper_process.CpuTimes(100, 200, 50, 2, None)
    _readings(monkeypatch, before, helper_process.CpuTimes(110, 220, 60, 2, None))
    assert helper_process.idle_cpus() == 2.0
    _readings(monkeypatch, before, helper_process.CpuTimes(110, 220, 50, 2, None))
    assert helper_process.idle_cpus() == 1.0
    _readings(monkeypatch, before, before)
    assert helper_process.idle_cpus() is None  # no time passed: nothing measured


def test_under_a_cgroup_quota_what_the_cgroup_used_counts(monkeypatch):
    # A container limited to two CPUs on a larger machine whose CPUs are idle: another process
    # of the container used a whole CPU over the window (0.1 s of CPU in 0.1 s), so one is free.
    monkeypatch.setattr(helper_process, "_quota", lambda: 2.0)
    monkeypatch.setattr(helper_process.os, "sysconf", lambda name: 100, raising=False)
    before = helper_process.CpuTimes(1000, 1000, 0, 8, 5.0)
    _readings(monkeypatch, before, helper_process.CpuTimes(1080, 1080, 0, 8, 5.1))
    assert helper_process.idle_cpus() == pytest.approx(1.0)
    # The cgroup's time spent by this process (1 clock tick of 10 ms) is its own, left free.
    _readings(monkeypatch, before, helper_process.CpuTimes(1080, 1080, 1, 8, 5.01))
    assert helper_process.idle_cpus() == pytest.approx(2.0)


def test_only_the_cpus_this_process_may_run_on_are_counted(monkeypatch):
    stat = (
        "cpu  10 0 10 980 0 0 0 0 0 0\n"
        "cpu0 10 0 10 80 0 0 0 0 0 0\n"  # busy
        "cpu1 0 0 0 900 0 0 0 0 0 0\n"  # idle, but not this process's
        "intr 0\n"
    )
    files = {
        "/proc/stat": stat,
        "/proc/self/stat": "1 (python) R " + " ".join(["0"] * 10) + " 7 3 0 0",
        "/sys/fs/cgroup/cpu.stat": "",
    }

    class FakePath:
        def __init__(self, path):
            self.path = str(path)

        def read_text(self):
            if self.path not in files:
                raise OSError(self.path)
            return files[self.path]

    monkeypatch.setattr(helper_process, "Path", FakePath)
    monkeypatch.setattr(helper_process, "_allowed", lambda: {0})
    # cpu0 alone: idle 80 of 10 + 10 + 80 ticks; own time utime 7 + stime 3; no cgroup
    assert helper_process._cpu_times() == helper_process.CpuTimes(80, 100, 10, 1, None)
    monkeypatch.setattr(helper_process, "_allowed", lambda: None)
    assert helper_process._cpu_times() == helper_process.CpuTimes(980, 1000, 10, 2, None)


def test_a_real_helper_compiles_its_share_and_says_so(monkeypatch):
    # (That the run then loads the helper's code from the cache is shown by
    # test_components.py::test_a_user_compiled_plant_is_compiled_once_then_loaded_from_disk.)
    monkeypatch.setenv(helper_process.ENVIRONMENT, "1")
    helper, given = start(_movable_jobs())
    if helper is None:
        pytest.skip("one core, or no lock on numba's cache")
    try:
        assert given == [0, 1]  # it may take either
        # this process takes neither: its bootstrap ran, it claimed both, imported the
        # functions and kernels by name and compiled (or, with a warm cache, loaded) them; a
        # failure on any of these exits with 1
        assert helper.wait() is True
        assert not helper.claim(0) and not helper.claim(1)  # the helper's claims
    finally:
        helper.stop()
    assert not os.path.exists(helper.claims)  # stop removes the claims' folder


def test_functions_are_named_as_another_process_imports_them():
    engine = helper_process._name(run_batch_compiled)
    # a dispatcher made from run_batch: found by its module's name
    assert engine[:2] == ("delaytrack.sim.engine", "run_batch_compiled")
    assert helper_process._name(arolc_step)[:2] == ("delaytrack.controllers.arolc", "arolc_step")
    assert helper_process._name(lambda: None) is None

    def inner():
        pass

    assert helper_process._name(inner) is None


def test_a_kernel_from_a_file_named_in_a_scenario_is_loaded_from_that_file(tmp_path):
    from delaytrack._spec import module_from_file

    (tmp_path / "helper_scenario_kernel.py").write_text("def kernel_of_a_file(x):\n    return x\n")
    module = module_from_file(tmp_path / "helper_scenario_kernel.py")
    try:
        name = helper_process._name(module.kernel_of_a_file)
        assert name == (module.__name__, "kernel_of_a_file", module.__file__)
        del sys.modules[module.__name__]  # as in the helper: its folder is not on the path
        assert helper_process._imported(name)(3) == 3
    finally:
        sys.modules.pop(module.__name__, None)


def test_a_part_whose_kernel_cannot_be_imported_stays_here():
    def local_terms(t, q, qdot, params, mass, nonlinear, input_map):
        pass

    mine = CompileJob(run_batch_compiled, (), (Kernel(local_terms),), 1.0)
    assert helper_process._recipe(mine) is None
    step = controller_step_part(Kernel.of(arolc_step), TwoLinkArm().engine_kernel, 2, 2)
    assert helper_process._recipe(step.compile_job()) is not None


def _payload(cache: str, claims: str, recipes: list) -> io.BytesIO:
    file = io.BytesIO()
    pickle.dump((cache, claims, list(enumerate(recipes))), file)
    file.seek(0)
    return file


#: A job whose function does not exist: the helper fails on it.
_MISSING = (("delaytrack.sim.engine", "no_such_function", None), (), ())


def test_the_helper_refuses_another_cache_folder_and_reports_a_failed_job(tmp_path):
    assert helper_process.main(_payload("/elsewhere", str(tmp_path), [])) == 2
    assert helper_process.main(_payload(str(cache_directory()), str(tmp_path), [_MISSING])) == 1
    assert helper_process.main(_payload(str(cache_directory()), str(tmp_path), [])) == 0


def test_each_job_is_compiled_by_the_process_that_claims_it_first(tmp_path):
    mine = Helper(None, 0.0, str(tmp_path))  # type: ignore[arg-type] - this process's claims
    assert mine.claim(0)  # this process takes the first job before the helper reads it
    payload = _payload(str(cache_directory()), str(tmp_path), [_MISSING, _MISSING])
    # the helper skips the first and claims the second, which fails (exit status 1)
    assert helper_process.main(payload) == 1
    assert not mine.claim(1)  # the helper's claim
    assert not mine.claim(0)  # a job is claimed once
    payload = _payload(str(cache_directory()), str(tmp_path), [_MISSING, _MISSING])
    assert helper_process.main(payload) == 0  # both claimed already: nothing to do, no failure
    assert Helper(None, 0.0).claim(5)  # type: ignore[arg-type] - no helper's claims: always here


def test_the_helper_refuses_a_kernel_whose_code_changed():
    for kernel in (TwoLinkArm().engine_kernel, PayloadRobot(seed=1, duration=1.0).engine_kernel):
        key, *rest = helper_process._kernel_recipe(kernel)
        helper_process._make_kernel((key, *rest))  # the same code: made
        with pytest.raises(RuntimeError, match="changed on disk"):
            helper_process._make_kernel((key + "#0123", *rest))


def test_a_failed_or_slow_helper_is_reported_and_stopped():

    failed = Helper(subprocess.Popen([sys.executable, "-c", "raise SystemExit(1)"]), 30.0)
    assert failed.wait() is False
    slow = Helper(subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"]), 0.5)
    assert slow.wait() is False  # waited half a second, then stopped
    assert slow.process.returncode is not None
    running = Helper(subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"]), 60)
    running.stop()
    assert running.process.returncode is not None


def test_parts_named_ahead_are_kept_once_and_only_within_the_context():
    first, second = object(), object()  # stand-ins for two parts
    with ahead([("PCON's step", first), ("PCONf's step", first), ("x", second)]):
        assert parts_ahead() == (("PCONf's step", first), ("x", second))
    assert parts_ahead() == ()


def test_contexts_ahead_add_up_and_take_plants_integrators():
    from delaytrack._compile.native_parts import plant_tick_part
    from delaytrack.delays import AbsSineDelay
    from delaytrack.plants import TwoLinkArm
    from delaytrack.sim import compile_ahead

    outer = object()  # a stand-in part
    arm = TwoLinkArm()
    # the part a run of the arm under a built-in delay compiles (parts are made once each)
    needed = plant_tick_part(arm.engine_kernel, AbsSineDelay.S1().engine_kernel, arm.n, arm.m)
    with ahead([("a step", outer)]):
        with compile_ahead([], arm.n, arm.m, plants=[arm]):
            assert parts_ahead() == (("a step", outer), ("TwoLinkArm's integrator", needed))
        assert parts_ahead() == (("a step", outer),)  # the inner context's parts, left
    assert parts_ahead() == ()


def test_the_paper_job_compiles_the_contact_runs_integrator_ahead_only_with_them():
    pytest.importorskip("mujoco")
    from delaytrack._compile.native_parts import plant_tick_part
    from delaytrack.experiments.paper import SCENARIOS, contact_ahead
    from delaytrack.plants.robot import MujocoWheeledRobot

    robot = MujocoWheeledRobot(seed=1, duration=60.0, contact_time_constant=0.01)
    delay = SCENARIOS["S3"].engine_kernel
    with contact_ahead(0.5):  # contact runs by default with MuJoCo installed
        assert parts_ahead() == (
            (
                "MujocoWheeledRobot's integrator",
                plant_tick_part(robot.engine_kernel, delay, robot.n, robot.m),
            ),
        )
    with contact_ahead(60.0, contact=False):
        assert parts_ahead() == ()


def test_a_helper_given_no_job_ends_at_once():
    # started ahead and not used: its input ends before any job
    assert helper_process.main(io.BytesIO(b"")) == 0


def test_a_helper_started_ahead_is_handed_the_first_shared_compile_or_stopped(monkeypatch):
    from delaytrack._compile import helper_ahead

    monkeypatch.setenv(helper_process.ENVIRONMENT, "1")
    monkeypatch.setattr(helper_ahead, "_engine_compiled", lambda: True)
    with helper_ahead.helper_ahead():
        assert helper_ahead.take() is None  # the engine is in the cache: no compile is certain
    monkeypatch.setattr(helper_ahead, "_engine_compiled", lambda: False)
    jobs = _movable_jobs()
    with helper_ahead.helper_ahead():
        ready = helper_ahead.take()
        if ready is None:
            pytest.skip("one core, or no lock on numba's cache")
        assert helper_ahead.take() is None  # taken once
        helper, given = start(jobs, lambda: ready)
        assert helper is not None and helper.process is ready and given == [0, 1]
        try:
            assert helper.wait() is True  # it compiled (or loaded) both: this process took none
        finally:
            helper.stop()
    with helper_ahead.helper_ahead():
        unused = helper_ahead._WAITING[-1]
        unused.thread.join()
        process = unused.process
    assert process is not None and process.poll() is not None  # stopped with the block
    assert process.pid not in helper_process._OWN and process.stdin.closed


def test_a_block_that_ends_while_its_helper_starts_leaves_no_helper(monkeypatch):
    from delaytrack._compile import helper_ahead

    monkeypatch.setenv(helper_process.ENVIRONMENT, "1")
    monkeypatch.setattr(helper_ahead, "_engine_compiled", lambda: False)
    made, started = [], []

    class Recorded(helper_ahead._Ahead):
        def __init__(self) -> None:
            super().__init__()
            made.append(self)

    def slow_spare_core():  # the thread decides only once the block has ended
        deadline = time.monotonic() + 60.0
        while not made[0].taken and time.monotonic() < deadline:
            time.sleep(0.01)
        return True

    def spawn(path):
        started.append(path)
        return helper_process.spawn(path=path)

    monkeypatch.setattr(helper_ahead, "_Ahead", Recorded)
    monkeypatch.setattr(helper_ahead, "spare_core", slow_spare_core)
    monkeypatch.setattr(helper_ahead, "spawn", spawn)
    with helper_ahead.helper_ahead():
        ahead = helper_ahead._WAITING[-1]
    assert not ahead.thread.is_alive() and ahead.process is None and started == []


def test_a_helper_that_ended_before_its_jobs_is_cleaned_up_and_replaced(monkeypatch):
    monkeypatch.setenv(helper_process.ENVIRONMENT, "0")  # no new helper either
    dead = helper_process.spawn()
    dead.kill()
    dead.wait()
    jobs = _movable_jobs()
    assert start(jobs, lambda: dead) == (None, [])
    assert dead.pid not in helper_process._OWN and dead.stdin.closed


def test_a_compile_not_worth_a_helper_leaves_the_one_started_ahead_to_the_next():
    def ahead():
        raise AssertionError("asked for the helper started ahead")

    one, immovable = _movable_jobs()[:1], [CompileJob(None, (), (), 10.0)] * 2
    assert start(one, ahead) == (None, [])  # one job
    assert start(immovable, ahead) == (None, [])  # none the helper can import


def _movable_jobs() -> list[CompileJob]:
    """Two jobs a helper can take, of equal costs: worth a helper (the reference's and the
    delay profiles' parts of a one-coordinate sinusoid)."""
    from delaytrack._compile.native_parts import delay_part, reference_part
    from delaytrack.references import SinusoidalReference

    reference = reference_part(SinusoidalReference([0.0], [1.0], [1.0], [1.0]).engine_kernel, 1)
    return [
        CompileJob(part.function, part.signature, part.compile_job().kernels, 10.0)
        for part in (reference, delay_part(NO_KERNEL))
    ]


def test_the_engine_is_seen_in_numbas_cache_only_once_compiled(tmp_path):
    from delaytrack._compile.helper_ahead import _engine_compiled

    empty = subprocess.run(
        [sys.executable, "-c", _ENGINE_COMPILED],
        env={**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)},
        capture_output=True,
        text=True,
        timeout=300,
        check=True,
    )
    assert empty.stdout.strip() == "False"  # a new cache: a helper ahead would pay
    _short_robot_run("compiled")
    assert _engine_compiled()  # compiled here, or loaded from this cache


def _short_robot_run(engine: str) -> None:
    """20 ms of the paper's robot under AROLC and S1 (compiled by other tests too)."""
    from delaytrack.controllers import AROLC
    from delaytrack.delays import AbsSineDelay
    from delaytrack.experiments.paper import AROLC_GAINS
    from delaytrack.plants.robot import NominalRobot, initial_state, paper_reference
    from delaytrack.sim import simulate

    reference = paper_reference("consistent")
    plant, controller = PayloadRobot(seed=1, duration=1.0), AROLC(NominalRobot(), **AROLC_GAINS)
    simulate(plant, controller, AbsSineDelay.S1(), initial_state(reference),
             reference=reference, t1=0.02, dt=1e-3, T_c=1e-2, engine=engine)  # fmt: skip


#: What a process with an empty cache says of the engine.
_ENGINE_COMPILED = (
    "from delaytrack._compile.helper_ahead import _engine_compiled; print(_engine_compiled())"
)


def test_what_waits_for_the_first_compile_is_called_once_when_a_compiled_run_has_its_code():
    from delaytrack._compile.first_compile import after_first_compile

    calls: list[str] = []
    with after_first_compile(lambda: calls.append("outer")):
        with after_first_compile(lambda: calls.append("inner")):
            assert calls == []
            for _ in range(2):
                _short_robot_run("compiled")
        assert sorted(calls) == ["inner", "outer"]  # each once, at the first run
    with after_first_compile(lambda: calls.append("python")):
        _short_robot_run("python")
    assert "python" not in calls  # no compiled run: not called


@pytest.mark.parametrize("kind", ["sinusoidal", "spline", "delay", "delay of yours"])
def test_values_compiled_ahead_are_those_evaluate_and_h_call(kind):
    import numpy as np

    from delaytrack._compile.ahead import values_ahead
    from delaytrack.delays import AbsSineDelay, CompiledDelay
    from delaytrack.plants.robot import paper_reference
    from delaytrack.references import SplineReference
    from delaytrack.sim import compile_ahead

    times = np.linspace(0.0, 1.0, 200)  # more than a few points: evaluated compiled
    component, evaluate = {
        "sinusoidal": (paper_reference("consistent"), "evaluate"),
        "spline": (SplineReference(times, np.sin(times)[:, None]), "evaluate"),
        "delay": (AbsSineDelay.S1(), "h"),
        "delay of yours": (CompiledDelay(_constant_delay, h_max=0.1), "h"),
    }[kind]
    name, part = values_ahead(component)
    with compile_ahead([], 1, 1, values=[component, component]):  # kept once
        assert parts_ahead() == ((name, part),)
    part.native()  # as a first compile does
    compiled = set(part.function.signatures)
    read_only = times.copy()
    read_only.setflags(write=False)
    for at in (times, read_only, times[::2]):  # writable, read-only, strided
        getattr(component, evaluate)(at)
    assert set(part.function.signatures) == compiled  # nothing more to compile
    assert part.ready()


@numba.njit
def _constant_delay(t, params):
    return 0.05


@pytest.mark.parametrize("error", [OSError("no more processes"), TypeError("a bug of ours")])
def test_a_helper_that_cannot_start_means_none_and_an_error_of_the_code_goes_on(
    monkeypatch, tmp_path, error
):
    monkeypatch.setenv(helper_process.ENVIRONMENT, "1")
    monkeypatch.setattr(helper_process.tempfile, "tempdir", str(tmp_path))  # the claims' folder

    def spawn():
        raise error

    monkeypatch.setattr(helper_process, "spawn", spawn)
    if isinstance(error, OSError):
        assert start(_movable_jobs()) == (None, [])  # compiled here
    else:
        with pytest.raises(TypeError, match="a bug of ours"):
            start(_movable_jobs())
    assert list(tmp_path.iterdir()) == []  # the claims' folder removed either way


def test_a_helper_started_ahead_has_the_module_search_path_of_the_blocks_start(monkeypatch):
    # The path take() compares with the present one is the path the helper was given, even when
    # this process changed its own while the helper was being started.
    from delaytrack._compile import helper_ahead

    monkeypatch.setenv(helper_process.ENVIRONMENT, "1")
    monkeypatch.setattr(helper_ahead, "_engine_compiled", lambda: False)
    decided = threading.Event()
    monkeypatch.setattr(helper_ahead, "spare_core", lambda: decided.wait(60))
    given = []
    monkeypatch.setattr(helper_ahead, "spawn", lambda path: given.append(list(path)))
    at_start = list(sys.path)
    with helper_ahead.helper_ahead():
        monkeypatch.syspath_prepend("/a folder added while the helper starts")
        decided.set()
        assert helper_ahead.take() is None  # the stand-in starts no process
    assert given == [at_start]
