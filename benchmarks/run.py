"""The benchmarks: ``make bench`` prints a table and writes benchmarks/results.json.

Cases (all on the paper's robot: PayloadRobot truth, AROLC with the paper's gains on the nominal
model, ``dt`` = 1 ms, ``T_c`` = 10 ms; medians of several repetitions after one untimed call that
compiles or loads numba's disk cache):

``single``
    One 60 s S1 run (60 000 RK4 steps), compiled, against two baselines measured in the same
    run: a plain NumPy per-step loop and ``scipy.integrate.solve_ivp`` with the delayed command
    looked up in the callback (:mod:`baselines`).
``ceiling``
    The engine against ceilings, allocation-free numba loops of the same robot run with nothing
    general: two without step splitting, one from the package's own kernels (:mod:`hand_loop`),
    one written from the equations alone (:mod:`independent_loop`), and the latter exact, its
    steps split where the delayed command switches as the engine's are (its final state
    compared with the engine's); in the same process: one 60 s run on one thread, the same with
    the controller at every step (``T_c = dt``), and ``B`` = 1000 runs of 60 s (|sin| delays and
    payload placements drawn per run) on all cores, each set timed alternately; ``ratio`` is the
    hand loop's time over the engine's (1 = as fast), ``ratio_to_independent_loop`` and
    ``ratio_to_exact_loop`` the independent loops'.
``batch``
    ``B`` runs, each with its own delay profile (|sin|, random-walk and constant families with
    drawn parameters) and payload placements, metrics only (``trajectories=False``), on all
    cores; each ``B`` in a fresh process, which reports its peak memory above its resting
    size. ``B`` = 1 .. 10 000 at 10 s, the duration series at ``B`` = 100, and the goal case
    ``B`` = 1000 at 60 s.
``startup``
    ``delaytrack simulate benchmarks/short_scenario.toml`` in a new process with numba's cache
    warm: time until ``metrics.csv`` exists (the first result) and until the command exits.
``controller_step``
    One AROLC tick of the 5-coordinate robot model through :meth:`Controller.step` (the checked
    Python API) and through a stepper of the same controller (:meth:`Controller.stepper`, for a
    real-time loop): called with the arrays, and ``tick`` on its own inputs; timed alternately
    in one process, the ratio is ``Controller.step``'s time over each.
``agreement``
    Largest differences between the compiled engine, the same batch on worker threads and the
    reference path (the engine run as plain Python, ``simulate(..., engine="python")``).
``mujoco``
    A 60 s run of the three-link arm of ``examples/mujoco_arm`` stepped by MuJoCo
    (``MujocoPlant(stepping="mujoco")``, AROLC on the 20 % light model, S1, ``dt`` = 1 ms,
    ``T_c`` = 10 ms), against MuJoCo stepping the same model alone for the same number of
    steps from a compiled loop (the floor, :mod:`mujoco_floor`) and against the same closed
    loop written by hand as one numba function (the ceiling, same module: the same run bit for
    bit, its final state, AE and TV compared, its model evaluations included), and the plant
    alone: the same run under a law that evaluates no MuJoCo model (the outer loop on the arm's
    mass matrix at the start, held), and the floor with the profiling clock of MuJoCo's Python
    bindings (which :func:`simulate` stops while it runs; the floor and the ceiling are timed
    with it stopped too), the five timed alternately; and 100 such runs in one batch
    on all cores (a copy of MuJoCo's data per thread), against the floor's time for as many
    steps and against the same batch on one thread.
``sweep``
    ``examples/sweep_robot.toml`` (AROLC, PCON and the outer loop over 1000 random
    delay profiles and payload placements, 3000 runs of 60 s) through :func:`run_sweep` with the
    local executor and with a Dask local cluster of one worker process per core (its start-up
    included), against the bare engine in the same run: the same runs built beforehand and
    simulated with one :func:`simulate` call per controller type.
``paper``
    ``delaytrack reproduce --no-contact --no-robustness`` (the paper's experiment, literal and
    consistent, and their reports) in a new process, from an empty numba cache and then again
    with the cache it wrote, as a user runs it (a compile helper and a second process for the
    literal report when a core is idle) against the same job kept in one process
    (``DELAYTRACK_COMPILE_HELPER=0``), each pair alternated, two rounds.
``live``
    ``delaytrack live run`` of the P3-DX in real time, ``T_c`` = 10 ms and 1 ms, 60 s each, with
    the load average, under the normal policy and, where allowed, under SCHED_FIFO
    (``--realtime``) beside it (:mod:`live_loop`); ``--skip-live`` or
    ``DELAYTRACK_BENCH_SKIP_LIVE=1`` skips them.

``python benchmarks/run.py --quick`` runs shorter versions of every case (for a smoke test).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
import tomllib
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from baselines import numpy_loop, robot_case, solve_ivp_loop  # noqa: E402
from hand_loop import hand_batch, hand_run  # noqa: E402
from independent_loop import independent_batch, independent_run  # noqa: E402
from live_loop import format_live, live_cases  # noqa: E402

from delaytrack.controllers import AROLC  # noqa: E402
from delaytrack.delays import AbsSineDelay, ConstantDelay, RandomDelay  # noqa: E402
from delaytrack.experiments.paper import AROLC_GAINS, DT, T_C  # noqa: E402
from delaytrack.plants.robot import (  # noqa: E402
    NominalRobot,
    PayloadRobot,
    initial_state,
    paper_reference,
)
from delaytrack.sim import simulate  # noqa: E402
from delaytrack.sim.certified_bound import BeyondCertifiedBoundWarning  # noqa: E402

# The paper's delays lie beyond AROLC's certified bound at its gains, as the paper's own
# experiment does: known and intended here, so not repeated at every timed call.
warnings.filterwarnings("ignore", category=BeyondCertifiedBoundWarning)

HERE = Path(__file__).resolve().parent
SHORT_SCENARIO = HERE / "short_scenario.toml"
SWEEP_EXAMPLE = HERE.parent / "examples" / "sweep_robot.toml"


def median_seconds(run, repeats: int) -> float:
    """Median wall time of ``repeats`` calls of ``run`` after one untimed call."""
    return alternating_medians(repeats, run)[0]


def alternating_medians(repeats: int, *runs) -> tuple[float, ...]:
    """Median wall times of ``runs`` called in turn ``repeats`` times each (so that the
    machine's drift falls on all alike), after one untimed call of each."""
    for run in runs:
        run()
    times: list[list[float]] = [[] for _ in runs]
    for _ in range(repeats):
        for run, timed in zip(runs, times, strict=True):
            start = time.perf_counter()
            run()
            timed.append(time.perf_counter() - start)
    return tuple(statistics.median(timed) for timed in times)


def steps(duration: float, batch: int = 1) -> int:
    """Plant RK4 steps of ``batch`` runs of ``duration`` seconds."""
    return batch * round(duration / DT)


# --- single run ------------------------------------------------------------------------------


def single_case(duration: float, repeats: int, baseline_repeats: int) -> list[dict]:
    plant, controller, delay, reference, x0 = robot_case(duration)

    def compiled():
        return simulate(
            plant, controller, delay, x0, reference=reference, t1=duration, dt=DT, T_c=T_C
        )

    engine = median_seconds(compiled, repeats)
    numpy_time = median_seconds(lambda: numpy_loop(duration), baseline_repeats)
    scipy_time = median_seconds(lambda: solve_ivp_loop(duration), baseline_repeats)
    rows = []
    for name, seconds, baseline in (
        ("compiled engine", engine, numpy_time),
        ("baseline: NumPy per-step loop", numpy_time, numpy_time),
        ("baseline: solve_ivp RK45 per period", scipy_time, numpy_time),
    ):
        rows.append(
            {
                "case": f"single S1 robot run {duration:g} s: {name}",
                "median_s": seconds,
                "steps_per_s": steps(duration) / seconds,
                "baseline": "NumPy per-step loop",
                "baseline_s": baseline,
                "ratio_to_baseline": baseline / seconds,
            }
        )
    rows[0]["ratio_to_solve_ivp"] = scipy_time / engine
    return rows


# --- the ceiling: a hand-written loop ---------------------------------------------------------


def ceiling_case(duration: float, batch: int, repeats: int) -> list[dict]:
    """The engine, :mod:`hand_loop` and :mod:`independent_loop` (unsplit, and exact: its steps
    split where the delayed command switches) on the same runs, in this process, metrics only.

    Each set is timed alternately (engine, loop, independent loop, exact loop, engine, ...), so
    that the machine's drift between minutes falls on all alike. Two single runs: at the paper's
    ``T_c`` = 10 ms, and with the controller at every step (``T_c = dt``), where the delayed
    command switches inside every step and the engine and the exact loop split each step in two.
    """
    plant, controller, delay, reference, x0 = robot_case(duration)
    common = dict(reference=reference, t1=duration, dt=DT, trajectories=False)

    def timed(period: float) -> tuple[float, float, float, float]:
        loop_args = (reference, x0, duration, DT, period)
        return alternating_medians(
            repeats,
            lambda: simulate(plant, controller, delay, x0, **common, T_c=period, workers=1),
            lambda: hand_run(plant, controller, delay, *loop_args),
            lambda: independent_run(plant, controller, delay, *loop_args),
            lambda: independent_run(plant, controller, delay, *loop_args, split=True),
        )

    def final_state_difference(period: float) -> float:
        """Largest difference of the final ``[q, q̇]`` of the engine and of the exact loop,
        relative to the state's largest entry."""
        result = simulate(
            plant, controller, delay, x0, reference=reference, t1=duration, dt=DT, T_c=period
        )
        engine = result.x.reshape(-1, result.x.shape[-1])[-1]  # one run: its last tick
        exact = independent_run(
            plant, controller, delay, reference, x0, duration, DT, period, split=True
        )[0]
        return float(np.max(np.abs(engine - exact)) / np.max(np.abs(engine)))

    engine, hand, independent, exact = timed(T_C)
    every_step = timed(DT)
    ae_engine = simulate(plant, controller, delay, x0, **common, T_c=T_C).metrics["ae"][0]
    hand_sums = hand_run(plant, controller, delay, reference, x0, duration, DT, T_C)[1]
    independent_sums = independent_run(plant, controller, delay, reference, x0, duration, DT, T_C)[
        1
    ]
    rng = np.random.default_rng(7)
    plants = [PayloadRobot(seed=b, duration=duration) for b in range(batch)]
    delays = [
        AbsSineDelay(rng.uniform(0.0, 0.05), rng.uniform(0.02, 0.1), rng.uniform(0.5, 2.0))
        for _ in range(batch)
    ]
    batch_args = (plants, controller, delays, reference, x0, duration, DT, T_C)
    many = alternating_medians(
        max(1, repeats // 3),
        lambda: simulate(plants, controller, delays, x0, **common, T_c=T_C),
        lambda: hand_batch(*batch_args),
        lambda: independent_batch(*batch_args),
        lambda: independent_batch(*batch_args, split=True),
    )
    single = (engine, hand, independent, exact)
    cases = (
        (f"{duration:g} s run, 1 thread", "same run", 1, single),
        (
            f"controller every step (T_c = dt), {duration:g} s run, 1 thread",
            "T_c = dt",
            1,
            every_step,
        ),
        (f"B={batch} runs of {duration:g} s, all cores", f"B={batch}, prange", batch, many),
    )
    rows = []
    for label, short, count, (engine_s, hand_s, independent_s, exact_s) in cases:
        for name, seconds in (
            (f"engine, {label}", engine_s),
            (f"ceiling: hand-written numba loop, {short}", hand_s),
            (f"ceiling: independent loop from the equations, {short}", independent_s),
            (f"ceiling: independent exact loop (steps split at switches), {short}", exact_s),
        ):
            rows.append(
                {
                    "case": name,
                    "median_s": seconds,
                    "steps_per_s": steps(duration, count) / seconds,
                    "baseline": "hand-written numba loop (benchmarks/hand_loop.py)",
                    "baseline_s": hand_s,
                    "ratio_to_baseline": hand_s / seconds,
                    "independent_loop_s": independent_s,
                    "ratio_to_independent_loop": independent_s / seconds,
                    "exact_loop_s": exact_s,
                    "ratio_to_exact_loop": exact_s / seconds,
                }
            )
    rows[0]["ae_relative_difference_to_hand_loop"] = float(
        np.max(np.abs(ae_engine - hand_sums[: plant.n]) / np.abs(ae_engine))
    )
    rows[0]["metrics_relative_difference_hand_to_independent_loop"] = float(
        np.max(np.abs(hand_sums - independent_sums) / np.abs(hand_sums))
    )
    rows[0]["final_state_relative_difference_to_exact_loop"] = final_state_difference(T_C)
    rows[4]["final_state_relative_difference_to_exact_loop"] = final_state_difference(DT)
    return rows


def mujoco_case(duration: float, batch: int, repeats: int) -> list[dict]:
    """The MuJoCo-stepped arm against MuJoCo stepping it alone and against the same closed loop
    written by hand (module docstring)."""
    import mujoco
    from mujoco_floor import bare_steps, hand_run

    import delaytrack as dt
    from delaytrack.plants import MujocoPlant
    from delaytrack.plants.mujoco.timer import profiler_clock_stopped

    path = str(HERE.parent / "examples" / "mujoco_arm" / "arm3.xml")
    truth = MujocoPlant(path, stepping="mujoco")
    controller = dt.AROLC(
        MujocoPlant(path, mass_scale=0.8),
        K1=16.0,
        K2=8.0,
        Q=1.0,
        alpha=2.0,
        epsilon=0.1,
        gamma=0.001,
    )
    reference = dt.SinusoidalReference(
        [0.0, 0.3, 0.0], amplitude=[[0.5], [0.3], [0.2]], frequency=[[1.0], [1.3], [0.7]]
    )
    x0 = np.array([0.0, 0.3, 0.0, 0.5, 0.39, 0.14])
    # The plant's own cost: a law that evaluates no MuJoCo model (the outer loop on the arm's
    # mass matrix at the start, held constant; gains low enough to stay on the path under S1).
    held = dt.OuterLoop(dt.LinearPlant(mass=truth.mass_matrix(x0[:3])[0]), K1=1.0, K2=2.0)
    delay = dt.AbsSineDelay.S1()
    common = dict(reference=reference, t1=duration, dt=DT, T_c=T_C)
    count = steps(duration)
    floor_steps = bare_steps(path)

    def clock_stopped(run):  # as simulate stops MuJoCo's profiling clock while it runs
        def stopped():
            with profiler_clock_stopped(mujoco):
                return run()

        return stopped

    single, hand, floor, plant_only, clocked_floor = alternating_medians(
        repeats,
        lambda: dt.simulate(truth, controller, delay, x0, **common, trajectories=False),
        clock_stopped(lambda: hand_run(truth, controller, delay, reference, x0, duration, DT, T_C)),
        clock_stopped(lambda: floor_steps(count, x0[:3], x0[3:])),
        lambda: dt.simulate(truth, held, delay, x0, **common, trajectories=False),
        lambda: floor_steps(count, x0[:3], x0[3:]),
    )
    held_status = dt.simulate(truth, held, delay, x0, **common, trajectories=False).status_names
    engine_run = dt.simulate(truth, controller, delay, x0, **common)
    hand_state, hand_sums = clock_stopped(
        lambda: hand_run(truth, controller, delay, reference, x0, duration, DT, T_C)
    )()
    delays = [dt.AbsSineDelay(0.02, 0.08, 1.0 + 0.01 * b) for b in range(batch)]
    many = median_seconds(
        lambda: dt.simulate(truth, controller, delays, x0, **common, trajectories=False),
        max(1, repeats // 3),
    )
    alone = median_seconds(
        lambda: dt.simulate(truth, controller, delays, x0, **common, trajectories=False, workers=1),
        1,
    )
    floor_name = "MuJoCo's mj_step alone, compiled loop (benchmarks/mujoco_floor.py)"
    hand_name = "the same closed loop written by hand (benchmarks/mujoco_floor.py)"
    return [
        {
            "case": f"MuJoCo arm stepped by MuJoCo, one {duration:g} s run",
            "median_s": single,
            "steps_per_s": count / single,
            "baseline": floor_name,
            "baseline_s": floor,
            "ratio_to_baseline": floor / single,
            "ceiling": hand_name,
            "ceiling_s": hand,
            "ratio_to_ceiling": hand / single,
            "largest_state_difference_to_ceiling": float(
                np.max(np.abs(engine_run.x[0, -1] - hand_state))
            ),
            "largest_metric_difference_to_ceiling": float(
                max(
                    np.max(np.abs(engine_run.metrics["ae"][0] - hand_sums[: truth.n])),
                    abs(engine_run.metrics["tv"][0] - hand_sums[truth.n]),
                )
            ),
        },
        {
            "case": f"MuJoCo arm stepped by MuJoCo, no MuJoCo model in the law, {duration:g} s run",
            "median_s": plant_only,
            "steps_per_s": count / plant_only,
            "baseline": floor_name,
            "baseline_s": floor,
            "ratio_to_baseline": floor / plant_only,
            "status": held_status[0],
        },
        {
            "case": "ceiling: the same closed loop written by hand",
            "median_s": hand,
            "steps_per_s": count / hand,
            "baseline": floor_name,
            "baseline_s": floor,
            "ratio_to_baseline": floor / hand,
        },
        {
            "case": f"floor: mj_step alone, {count} steps",
            "median_s": floor,
            "steps_per_s": count / floor,
            "baseline": floor_name,
            "baseline_s": floor,
            "ratio_to_baseline": 1.0,
        },
        {
            "case": f"mj_step alone, {count} steps, with the profiling clock of MuJoCo's Python "
            "bindings (what a run paid before it stopped that clock)",
            "median_s": clocked_floor,
            "steps_per_s": count / clocked_floor,
            "baseline": floor_name,
            "baseline_s": floor,
            "ratio_to_baseline": floor / clocked_floor,
        },
        {
            "case": f"MuJoCo arm, B={batch} runs of {duration:g} s, all cores",
            "median_s": many,
            "steps_per_s": count * batch / many,
            "baseline": floor_name,
            "baseline_s": floor * batch,
            "ratio_to_baseline": floor * batch / many,
            "one_thread_s": alone,
            "speedup_over_one_thread": alone / many,
        },
    ]


# --- batches ---------------------------------------------------------------------------------


def batch_inputs(batch: int, duration: float) -> dict:
    """``batch`` distinct robot runs: delay profile and payload placements drawn per run."""
    rng = np.random.default_rng(4)
    delays = []
    for b in range(batch):
        family = b % 3
        if family == 0:
            offset, amplitude = rng.uniform(0.0, 0.05), rng.uniform(0.02, 0.1)
            delays.append(AbsSineDelay(offset, amplitude, frequency=rng.uniform(0.5, 2.0)))
        elif family == 1:
            delays.append(RandomDelay(0.01, 0.12, max_rate=0.5, duration=duration, seed=b))
        else:
            delays.append(ConstantDelay(rng.uniform(0.0, 0.12)))
    reference = paper_reference("consistent")
    return dict(
        plant=[PayloadRobot(seed=b, duration=duration) for b in range(batch)],
        controller=AROLC(NominalRobot(), **AROLC_GAINS),
        delay=delays,
        x0=initial_state(reference),
        reference=reference,
        t1=duration,
        dt=DT,
        T_c=T_C,
        trajectories=False,
    )


def _resident_bytes() -> int:
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def _peak_resident_bytes() -> int:
    """Peak resident size of this process's own address space (``VmHWM``).

    Not ``getrusage``'s ``ru_maxrss``: Linux carries it over from the parent's address space
    through fork and exec, so a worker started by a large benchmark process would report the
    parent's size as its own peak.
    """
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) * 1024
    raise RuntimeError("no VmHWM in /proc/self/status")


def batch_worker(batch: int, duration: float, repeats: int, workers: int | None) -> dict:
    """Run in a fresh process: median time and peak memory growth of one batch size."""
    inputs = batch_inputs(batch, duration)
    simulate(**{**batch_inputs(1, 0.1), "workers": 1})  # load the compiled engine
    resting = _resident_bytes()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        result = simulate(**inputs, workers=workers)
        times.append(time.perf_counter() - start)
    peak = _peak_resident_bytes()
    return {
        "median_s": statistics.median(times),
        "peak_memory_growth_mib": max(0, peak - resting) / 2**20,
        "ok_runs": int(np.sum(result.status == 0)),
    }


def batch_case(batch: int, duration: float, repeats: int, workers: int | None = None) -> dict:
    command = [sys.executable, __file__, "--batch-worker", str(batch), str(duration), str(repeats)]
    if workers is not None:
        command.append(str(workers))
    finished = subprocess.run(command, check=True, capture_output=True, text=True)
    measured = json.loads(finished.stdout)
    threads = workers or len(os.sched_getaffinity(0))
    return {
        "case": f"batch B={batch}, {duration:g} s, {threads} thread(s)",
        "batch": batch,
        "duration_s": duration,
        "workers": threads,
        "repeats": repeats,
        **measured,
        "steps_per_s": steps(duration, batch) / measured["median_s"],
        "ms_per_run": 1e3 * measured["median_s"] / batch,
    }


# --- start-up, controller step, agreement ----------------------------------------------------


def startup_case(repeats: int) -> dict:
    """Fresh ``delaytrack simulate`` processes: time to ``metrics.csv`` and to exit."""
    executable = Path(sys.executable).with_name("delaytrack")
    first, total = [], []
    for i in range(repeats + 1):
        with tempfile.TemporaryDirectory() as folder:
            metrics = Path(folder) / "metrics.csv"
            start = time.perf_counter()
            process = subprocess.Popen(
                [str(executable), "simulate", str(SHORT_SCENARIO), "--out", folder],
                stdout=subprocess.DEVNULL,
            )
            seen = None
            while process.poll() is None:
                if seen is None and metrics.exists():
                    seen = time.perf_counter() - start
                time.sleep(0.002)
            end = time.perf_counter() - start
            if process.returncode != 0:
                raise RuntimeError("delaytrack simulate failed in the start-up benchmark")
            if i:  # the first process may compile; the cache is warm afterwards
                first.append(seen if seen is not None else end)
                total.append(end)
    return {
        "case": "start-up: delaytrack simulate short scenario (new process, cache warm)",
        "median_s": statistics.median(first),
        "first_result_s": statistics.median(first),
        "command_total_s": statistics.median(total),
    }


def _paper_job_seconds(cache: Path, one_process: bool, duration: float | None) -> float:
    """Wall time of ``delaytrack reproduce --no-contact --no-robustness`` with numba's cache in
    ``cache``, in one process or as a user runs it."""
    environment = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    environment.pop("DELAYTRACK_COMPILE_HELPER", None)
    if one_process:
        environment["DELAYTRACK_COMPILE_HELPER"] = "0"
    with tempfile.TemporaryDirectory() as out:
        command = [str(Path(sys.executable).with_name("delaytrack")), "reproduce", "--quiet"]
        command += ["--no-contact", "--no-robustness", "--out", out]
        if duration is not None:
            command += ["--duration", f"{duration:g}"]
        start = time.perf_counter()
        subprocess.run(
            command,
            env=environment,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            check=True,
        )
        return time.perf_counter() - start


def paper_job_case(rounds: int, duration: float | None) -> list[dict]:
    """The paper job from an empty cache and warm, as a user runs it and in one process
    (module docstring); ``ratio`` is the one-process time over the user's."""
    seconds: dict[tuple[str, bool], list[float]] = {}
    with tempfile.TemporaryDirectory() as root:
        for round_ in range(rounds):
            for state in ("empty", "warm"):  # the warm runs read the cache the empty ones wrote
                for one_process in (False, True):
                    cache = Path(root) / f"cache-{round_}-{one_process}"
                    took = _paper_job_seconds(cache, one_process, duration)
                    seconds.setdefault((state, one_process), []).append(took)
    rows = []
    for state, what in (("empty", "from an empty cache"), ("warm", "with the cache warm")):
        mine = statistics.median(seconds[(state, False)])
        alone = statistics.median(seconds[(state, True)])
        rows.append(
            {
                "case": f"paper job {what} (reproduce --no-contact --no-robustness)",
                "median_s": mine,
                "seconds": seconds[(state, False)],
                "baseline": "the same job in one process (DELAYTRACK_COMPILE_HELPER=0)",
                "baseline_s": alone,
                "baseline_seconds": seconds[(state, True)],
                "ratio_to_baseline": alone / mine,
            }
        )
    return rows


def controller_step_case(repeats: int, calls: int = 2000) -> list[dict]:
    """One AROLC tick of the 5-coordinate robot model three ways, timed alternately (``calls``
    ticks a repetition): :meth:`Controller.step` (checked; state copied in and out), a stepper
    called with the arrays (``stepper(t, q, qdot, reference)``: inputs copied into its own) and
    its ``tick`` on its own inputs; ``ratio`` is ``Controller.step``'s time over the row's."""
    controller = AROLC(NominalRobot(), **AROLC_GAINS)
    reference = paper_reference("consistent")
    x0 = initial_state(reference)
    qd = tuple(values[0] for values in reference.evaluate(np.array([0.5])))
    q, qdot = x0[:5], x0[5:]
    state = controller.initial_state()
    stepper = controller.stepper(T_c=T_C)
    ticker = controller.stepper(T_c=T_C)
    for own, value in zip(ticker.inputs, (q, qdot, *qd), strict=True):
        own[:] = value

    def step():
        for _ in range(calls):
            controller.step(0.5, q, qdot, qd, state, T_c=T_C)

    def call():
        for _ in range(calls):
            stepper(0.5, q, qdot, qd)

    def tick():
        for _ in range(calls):
            ticker.tick(0.5)

    medians = [seconds / calls for seconds in alternating_medians(repeats, step, call, tick)]
    rows = []
    for name, seconds in zip(
        (
            "one AROLC tick of the 5-coordinate robot through Controller.step",
            "the same through a stepper, stepper(t, q, qdot, reference)",
            "the same through stepper.tick(t) on its own inputs",
        ),
        medians,
        strict=True,
    ):
        rows.append(
            {
                "case": name,
                "median_s": seconds,
                "median_us": 1e6 * seconds,
                "baseline": "Controller.step",
                "baseline_s": medians[0],
                "ratio_to_baseline": medians[0] / seconds,
            }
        )
    return rows


def _largest_difference(a, b) -> float:
    """Largest absolute difference of the states and commands of two results."""
    return float(max(np.max(np.abs(a.x - b.x)), np.max(np.abs(a.commands - b.commands))))


def agreement_case(duration: float) -> dict:
    inputs = {**batch_inputs(6, duration), "trajectories": True}
    single = simulate(**inputs, workers=1)
    threaded = simulate(**inputs, workers=3)
    # The reference path is slow: two of the runs (one |sin| and one random-walk profile).
    pair = {**inputs, "plant": inputs["plant"][:2], "delay": inputs["delay"][:2]}
    reference = simulate(**pair, engine="python")
    return {
        "case": f"agreement, {duration:g} s robot runs (max |difference| of states and commands)",
        "threads_vs_single": _largest_difference(threaded, single),
        "reference_python_vs_compiled": _largest_difference(reference, single[:2]),
    }


# --- main ------------------------------------------------------------------------------------


# --- sweeps -----------------------------------------------------------------------------------


def sweep_case(draws: int, duration: float) -> list[dict]:
    """The robot example sweep (``draws`` draws, runs of ``duration`` s) three ways."""
    # Imported here: the batch cases' fresh processes measure memory above their resting size.
    from delaytrack.sweeps import DaskExecutor, LocalExecutor, SweepSpec, run_sweep

    data = tomllib.loads(SWEEP_EXAMPLE.read_text()) | {"draws": draws}
    data["grid"]["duration"] = [duration]
    spec = SweepSpec.from_dict(data, root=SWEEP_EXAMPLE.parent)
    runs = len(spec.runs)
    total = steps(duration, runs)
    groups: dict[str, list] = {}
    for run in spec.runs:
        groups.setdefault(run.scenario.controller["type"], []).append(run.scenario.build())
    settings = dict(t1=duration, dt=DT, T_c=T_C, trajectories=False)
    reference = groups["arolc"][0].reference
    for built in groups.values():  # load every controller's compiled engine, untimed
        simulate(
            built[0].plant,
            built[0].controller,
            built[0].delay,
            built[0].x0,
            reference=reference,
            **{**settings, "t1": 10 * T_C},
        )
    start = time.perf_counter()
    for built in groups.values():
        simulate(
            [b.plant for b in built],
            [b.controller for b in built],
            [b.delay for b in built],
            np.stack([b.x0 for b in built]),
            reference=reference,
            **settings,
        )
    bare = time.perf_counter() - start
    cases = [
        {
            "case": f"sweep baseline: bare engine, {runs} runs x {duration:g} s",
            "median_s": bare,
            "steps_per_s": total / bare,
            "runs_per_s": runs / bare,
        }
    ]
    executors = {
        "local executor": LocalExecutor,
        "Dask local-cluster": lambda: DaskExecutor("local-cluster"),
    }
    for name, make in executors.items():
        with tempfile.TemporaryDirectory() as out:
            start = time.perf_counter()
            outcome = run_sweep(spec, out, executor=make(), progress=False)
            seconds = time.perf_counter() - start
        cases.append(
            {
                "case": f"sweep {name}, {runs} runs x {duration:g} s",
                "median_s": seconds,
                "steps_per_s": total / seconds,
                "runs_per_s": runs / seconds,
                "ratio_to_baseline": bare / seconds,
                "ok_runs": int((outcome.runs["status"] == "ok").sum()),
            }
        )
    return cases


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="short versions of every case")
    parser.add_argument(
        "--skip-live",
        action="store_true",
        default=os.environ.get("DELAYTRACK_BENCH_SKIP_LIVE", "") not in ("", "0"),
        help="skip the live-loop sessions (live_loop.py; also DELAYTRACK_BENCH_SKIP_LIVE=1)",
    )
    parser.add_argument("--batch-worker", nargs="+", help=argparse.SUPPRESS)
    args = parser.parse_args()
    # The compiled engine is what is timed: a first run is never interpreted here (a short first
    # run would otherwise run as plain Python; docs/decisions.md D65). Its processes inherit it.
    os.environ["DELAYTRACK_INTERPRET_FIRST"] = "0"
    if args.batch_worker:
        batch, duration, repeats, *workers = args.batch_worker
        workers = int(workers[0]) if workers else None
        print(json.dumps(batch_worker(int(batch), float(duration), int(repeats), workers)))
        return

    quick = args.quick
    cases: list[dict] = []
    cases += single_case(6.0 if quick else 60.0, 3 if quick else 9, 1 if quick else 3)
    cases += ceiling_case(6.0 if quick else 60.0, 100 if quick else 1000, 3 if quick else 9)
    cases += mujoco_case(6.0 if quick else 60.0, 10 if quick else 100, 3 if quick else 9)
    sizes = (1, 10, 100) if quick else (1, 10, 100, 1000, 10000)
    for batch in sizes:
        cases.append(batch_case(batch, 1.0 if quick else 10.0, 3 if batch <= 1000 else 1))
    for duration in (1.0, 3.0) if quick else (30.0, 60.0):
        cases.append(batch_case(100, duration, 3))
    goal = 100 if quick else 1000
    goal_duration = 6.0 if quick else 60.0
    cases.append(batch_case(goal, goal_duration, 1, workers=1))  # the threads' speed-up
    cases.append(batch_case(goal, goal_duration, 1 if quick else 3))
    cases.append(startup_case(3 if quick else 5))
    cases += paper_job_case(1 if quick else 2, 1.0 if quick else None)
    cases += controller_step_case(9)
    agreement = agreement_case(2.0 if quick else 10.0)
    cases += sweep_case(20 if quick else 1000, 6.0 if quick else 60.0)
    live = [] if args.skip_live else live_cases(quick)  # real time: 2-5 minutes
    cases += live
    cases.append(agreement)

    print(f"{'case':<68} {'median s':>10} {'steps/s':>10} {'ratio':>8} {'peak MiB':>9}")
    for case in cases:
        if any(case is run for run in live):  # printed below, a few lines each (format_live)
            continue
        rate = f"{case['steps_per_s']:.3g}" if "steps_per_s" in case else ""
        ratio = f"{case['ratio_to_baseline']:.1f}x" if "ratio_to_baseline" in case else ""
        memory = case.get("peak_memory_growth_mib")
        memory = f"{memory:.1f}" if memory is not None else ""
        median = f"{case['median_s']:.4g}" if "median_s" in case else ""
        print(f"{case['case']:<68} {median:>10} {rate:>10} {ratio:>8} {memory:>9}")
    extra = cases[0]
    print(f"compiled single run vs solve_ivp: {extra['ratio_to_solve_ivp']:.0f}x faster")
    ceiling = next(c for c in cases if "ae_relative_difference_to_hand_loop" in c)
    every_step = next(c for c in cases if c["case"].startswith("engine, controller every step"))
    many = next(
        c for c in cases if c["case"].startswith("engine, B=") and "independent_loop_s" in c
    )
    print(
        "engine vs hand-written loop: AE differs by "
        f"{ceiling['ae_relative_difference_to_hand_loop']:.1%} at most (the loop does not split "
        "steps where the delayed input switches)"
    )
    print(
        "engine vs the independent loop from the equations: "
        f"{ceiling['ratio_to_independent_loop']:.2f} of its speed at T_c = {T_C * 1e3:g} ms, "
        f"{every_step['ratio_to_independent_loop']:.2f} with the controller "
        f"at every step, {many['ratio_to_independent_loop']:.2f} of its "
        "throughput on the batch; the two loops' metrics agree to "
        f"{ceiling['metrics_relative_difference_hand_to_independent_loop']:.0e} (the same scheme, "
        "written twice)"
    )
    print(
        "engine vs the independent exact loop (steps split where the command switches, as the "
        f"engine's): {ceiling['ratio_to_exact_loop']:.2f} of its speed at T_c = "
        f"{T_C * 1e3:g} ms, {every_step['ratio_to_exact_loop']:.2f} with the controller at every "
        f"step, {many['ratio_to_exact_loop']:.2f} of its throughput on the batch; final states "
        f"agree to {ceiling['final_state_relative_difference_to_exact_loop']:.0e} and "
        f"{every_step['final_state_relative_difference_to_exact_loop']:.0e}"
    )
    mujoco = next(c for c in cases if "ratio_to_ceiling" in c)
    print(
        f"MuJoCo arm vs the same closed loop by hand: {mujoco['ratio_to_ceiling']:.3f} of its "
        f"speed ({mujoco['ratio_to_baseline']:.3f} of mj_step alone, which evaluates no model); "
        f"final states differ by {mujoco['largest_state_difference_to_ceiling']:.1e}, AE and TV by "
        f"{mujoco['largest_metric_difference_to_ceiling']:.1e}"
    )
    plant_only = next(c for c in cases if "no MuJoCo model in the law" in c["case"])
    print(
        f"MuJoCo arm, no MuJoCo model in the law: {plant_only['ratio_to_baseline']:.3f} of "
        f"mj_step alone's speed (run {plant_only['status']})"
    )
    clocked = next(c for c in cases if "profiling clock" in c["case"])
    print(
        f"mj_step alone with the Python bindings' profiling clock: {clocked['median_s']:.3f} s, "
        f"{1 / clocked['ratio_to_baseline']:.2f} times its time with the clock stopped"
    )
    startup = next(c for c in cases if c["case"].startswith("start-up"))
    print(
        f"start-up: first result {startup['first_result_s']:.2f} s, "
        f"command done {startup['command_total_s']:.2f} s"
    )
    if live:
        print(format_live(live))
    agreement = cases[-1]
    print(
        f"agreement: threads vs one thread {agreement['threads_vs_single']:.1e}, "
        f"reference Python engine vs compiled {agreement['reference_python_vs_compiled']:.1e}"
    )
    output = {
        "machine": {
            "python": platform.python_version(),
            "processor": platform.processor() or platform.machine(),
            "cores": len(os.sched_getaffinity(0)),
            "platform": platform.platform(),
        },
        "settings": {"dt": DT, "T_c": T_C, "quick": quick},
        "cases": cases,
    }
    path = HERE / ("results-quick.json" if quick else "results.json")
    path.write_text(json.dumps(output, indent=2) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
