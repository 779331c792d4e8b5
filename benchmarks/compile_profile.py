"""Where a cold compile goes: a first simulation from an empty numba cache, split per compiled
function, per compile stage and per engine part.

Each case runs in a fresh process with ``NUMBA_CACHE_DIR`` pointed at an empty temporary folder,
once with the compile helper off and once on (``DELAYTRACK_COMPILE_HELPER`` = ``0`` / ``1``,
:mod:`delaytrack._compile.helper_process`; ``--modes auto`` leaves it unset); the modes are
alternated over ``--repeats`` rounds so that the machine's drift falls on all alike (the load
average before each process is recorded: a helper forced on beside a busy core is slower than
none). Cases:

``user``
    A pendulum of the user's own, ``M q̈ + N = G u`` written as one ``numba.njit`` terms kernel in
    a module of its own and wrapped in :class:`~delaytrack.plants.CompiledPlant`, under AROLC on a
    nominal model of the same kernel, a constant 10 ms delay, 1 s simulated.
``robot``
    The paper's robot: :class:`~delaytrack.plants.robot.PayloadRobot` truth under AROLC with the
    paper's gains on :class:`~delaytrack.plants.robot.NominalRobot`, S1, 1 s simulated.
``paper-job`` (only when named)
    ``delaytrack reproduce --no-contact --no-robustness`` in full.

Each process inherits ``DELAYTRACK_INTERPRET_FIRST``: unset, a short first run is interpreted
instead of compiled (docs/decisions.md D65) and the case measures that first result; set it to
``0`` to measure the compile itself.

The parent measures each process's wall time and CPU time (its own and that of every process it
waited for, the helper included: ``RUSAGE_CHILDREN``). Inside, numba's compile events
(``numba:compile`` for each function compiled, ``numba:run_pass`` for each compiler pass) and
timers around numba's LLVM steps split the time *exclusively* (a function compiled while
another one is typed is charged to itself, not to its caller) into:

* ``bytecode+untyped``: bytecode analysis and the untyped passes (IR inlining of
  ``inline="always"`` functions among them);
* ``type inference``: numba's ``nopython_type_inference`` pass;
* ``typed passes``: the other typed passes (typed inlining of overloads, rewrites, ...);
* ``lowering``: numba IR to LLVM IR (``native_lowering``, less the LLVM steps below);
* ``LLVM function opt``: per-function optimisation of each module as it is added;
* ``LLVM module opt``: the whole library's optimisation after linking (cheap and full passes);
* ``machine code``: MCJIT code generation of the optimised module (``finalize_object``);
* ``cache write`` / ``cache load``: numba's disk cache (pickling the object code, the index);
* ``other``: the compile's remaining Python (pipeline set-up, ``add_overload``, ...).

Per engine part (the top-level compile of the engine, the plant's integrator, the reference,
the controller's step and the delay, :mod:`delaytrack._compile.native_parts`, and of anything
else), the time is inclusive: the functions compiled inside it, its cache write included.

Run it with the project's interpreter (not part of ``make bench``; a case takes 15-40 s)::

    .venv/bin/python benchmarks/compile_profile.py                 # user and robot, 1 round
    .venv/bin/python benchmarks/compile_profile.py --repeats 2 --cases user robot paper-job
    .venv/bin/python benchmarks/compile_profile.py --modes off --top 40 --ir-size

It prints the tables and writes ``benchmarks/compile_profile.json`` (``--out`` to change).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from collections import defaultdict
from pathlib import Path

HERE = Path(__file__).resolve().parent

#: The user's module of the ``user`` case: the pendulum of ``docs/performance.md``.
USER_MODULE = textwrap.dedent(
    """
    import math
    import numba


    @numba.njit
    def pendulum_terms(t, q, qdot, params, M, N, G):
        mass, length, friction = params[0], params[1], params[2]
        M[0, 0] = mass * length**2
        N[0] = mass * 9.81 * length * math.sin(q[0]) + friction * qdot[0]
        G[0, 0] = 1.0
    """
)

#: Engine parts by the compiled function at the top of a compile
#: (:mod:`delaytrack._compile.native_parts`).
PARTS = {
    "delaytrack.sim.engine.run_batch": "engine (tick loop)",
    "delaytrack.sim.integrator.integrate_tick": "plant integrator",
    "delaytrack.sim.integrator.integrate_reduced_tick": "plant integrator",
    "delaytrack._compile.native_entries.evaluate_reference": "reference",
    "delaytrack._compile.native_entries.evaluate_step": "controller step (user's)",
    "delaytrack.delays._kernel.evaluate_profile": "delay profile",
}

#: Compile stages, in the order of the tables.
STAGES = (
    "bytecode+untyped",
    "type inference",
    "typed passes",
    "lowering",
    "LLVM function opt",
    "LLVM module opt",
    "machine code",
    "cache write",
    "cache load",
    "other",
)
#: numba's typed passes (after ``nopython_type_inference``); every other pass is untyped.
_TYPED_PASSES = {
    "annotate_types",
    "dump_parfor_diagnostics",
    "inline_overloads",
    "ir_legalization",
    "native_parfor_lowering",
    "nopython_backend",
    "nopython_rewrites",
    "nopython_supported_feature_validation",
    "parfor_pass",
    "parfor_prelowering_pass",
    "parfor_preparfor_pass",
    "parfor_fixup_pass",
    "pre_lowering_validation",
    "strip_phis",
    "dead_code_elimination",
    "preparfor_pass",
}


# --- inside the profiled process ------------------------------------------------------------


#: Why a function was compiled (the third key of :class:`CompileClock`'s times).
TOP, CALLEE, INLINED_IMPL, INLINING = (
    "top-level",
    "callee (linked)",
    "always-inlined overload impl",
    "re-typed to inline",
)


def _always_inlined_overload() -> bool:
    """Whether the compile starting now is numba typing an ``@overload(..., inline="always")``
    implementation (its template compiles it in full through ``get_call_template`` only to find
    its signature, then types its IR again to inline it: that machine code is never called)."""
    frame = sys._getframe(2)
    for _ in range(12):
        if frame is None:
            return False
        inline = getattr(frame.f_locals.get("self"), "_inline", None)
        if frame.f_code.co_name == "generic" and inline is not None:
            return inline.is_always_inline
        frame = frame.f_back
    return False


class CompileClock:
    """Exclusive wall and CPU time per ``(function, stage, kind)`` from a stack of frames.

    A frame ``[function, stage, kind, compile?, pass]`` is pushed when a function's compile, a
    compiler pass or an LLVM step starts and popped when it ends; the time between two pushes or
    pops is charged to the frame on top. ``kind`` says why the function was compiled
    (:data:`TOP` .. :data:`INLINING`).
    """

    def __init__(self, ir_size: bool) -> None:
        self.ir_size = ir_size
        self.stack: list[list] = []
        self.last_wall = time.perf_counter()
        self.last_cpu = time.process_time()
        self.wall: dict = defaultdict(float)
        self.cpu: dict = defaultdict(float)
        self.signatures: dict = defaultdict(set)
        self.compiles: dict = defaultdict(int)
        self.parts: dict = defaultdict(lambda: [0.0, 0.0, 0])  # wall, cpu, compiles
        self.top_started: list = []
        self.module_sizes: dict = defaultdict(list)
        self.passes: dict = defaultdict(float)

    def _charge(self) -> None:
        wall, cpu = time.perf_counter(), time.process_time()
        if self.stack:
            key = tuple(self.stack[-1][:3])
            self.wall[key] += wall - self.last_wall
            self.cpu[key] += cpu - self.last_cpu
        self.last_wall, self.last_cpu = wall, cpu

    def _compile_frame(self) -> list | None:
        return next((frame for frame in reversed(self.stack) if frame[3]), None)

    def push(self, function: str, stage: str, kind: str, compiling: bool = False) -> None:
        self._charge()
        self.stack.append([function, stage, kind, compiling, None])

    def push_step(self, stage: str) -> None:
        """An LLVM or cache step of the function compiled now."""
        top = self.stack[-1] if self.stack else ["?", "", TOP]
        self.push(top[0], stage, top[2])

    def pop(self) -> None:
        self._charge()
        self.stack.pop()

    # numba's events
    def compile_started(self, data: dict) -> None:
        dispatcher = data["dispatcher"]
        python = getattr(dispatcher, "py_func", dispatcher)
        name = f"{getattr(python, '__module__', '?')}.{getattr(python, '__qualname__', '?')}"
        self.signatures[name].add(str(data["args"]))
        self.compiles[name] += 1
        top = self._compile_frame() is None
        if top:
            self.top_started.append((name, time.perf_counter(), time.process_time()))
        kind = TOP if top else INLINED_IMPL if _always_inlined_overload() else CALLEE
        self.push(name, "other", kind, compiling=True)

    def compile_ended(self, data: dict) -> None:
        self.pop()
        if self._compile_frame() is None:
            self._end_top(extra=False)

    def _end_top(self, extra: bool) -> None:
        """Charge the time since the top-level compile started to its part (``extra``: a cache
        write that follows it)."""
        name, wall, cpu = self.top_started[-1]
        part = self.parts[PARTS.get(name, name)]
        part[0] += time.perf_counter() - wall
        part[1] += time.process_time() - cpu
        part[2] += 0 if extra else 1
        self.top_started[-1] = (name, time.perf_counter(), time.process_time())

    def pass_started(self, data: dict) -> None:
        name = data["name"].partition(" [")[0]
        stage = (
            "type inference"
            if name == "nopython_type_inference"
            else "lowering"
            if name == "native_lowering"
            else "typed passes"
            if name in _TYPED_PASSES
            else "bytecode+untyped"
        )
        # The function the pass works on; outside its own compile (numba's inliners running
        # the untyped passes and type inference of an inlined function), it is typed to inline.
        function = f"{data['module']}.{data['qualname']}"
        owner = self._compile_frame()
        own = owner is not None and owner[0] == function
        self.push(function, stage, owner[2] if own else INLINING)
        self.stack[-1][4] = (name, time.perf_counter())

    def pass_ended(self, data: dict) -> None:
        name, started = self.stack[-1][4]
        self.passes[name] += time.perf_counter() - started
        self.pop()


def instrument(clock: CompileClock) -> None:
    """Listen to numba's compile events and time its LLVM and cache steps into ``clock``."""
    from numba.core import caching, codegen, event

    class Listener(event.Listener):
        def __init__(self, started, ended):
            self.started, self.ended = started, ended

        def on_start(self, event):
            self.started(event.data)

        def on_end(self, event):
            self.ended(event.data)

    event.register("numba:compile", Listener(clock.compile_started, clock.compile_ended))
    event.register("numba:run_pass", Listener(clock.pass_started, clock.pass_ended))

    def timed(owner, method_name, stage, measure=None):
        method = getattr(owner, method_name)

        def wrapper(self, *args, **kwargs):
            if measure is not None and clock.ir_size and clock.stack:
                clock.module_sizes[clock.stack[-1][0]].append(measure(self))
            clock.push_step(stage)
            try:
                return method(self, *args, **kwargs)
            finally:
                clock.pop()

        setattr(owner, method_name, wrapper)

    def final_module_size(library) -> int:
        return len(str(library._final_module))  # characters of LLVM IR after linking

    timed(codegen.CPUCodeLibrary, "_optimize_functions", "LLVM function opt")
    timed(codegen.CPUCodeLibrary, "_optimize_final_module", "LLVM module opt", final_module_size)
    timed(codegen.JITCodeLibrary, "_finalize_specific", "machine code")

    def cached(method_name, stage):
        method = getattr(caching.Cache, method_name)

        def wrapper(self, *args, **kwargs):
            top = clock._compile_frame() is None
            name = f"{self._py_func.__module__}.{self._py_func.__qualname__}"
            clock.push(name, stage, TOP if top else CALLEE)
            try:
                return method(self, *args, **kwargs)
            finally:
                clock.pop()
                # a top-level function's cache write follows its compile event
                if top and stage == "cache write" and clock.top_started:
                    clock._end_top(extra=True)

        setattr(caching.Cache, method_name, wrapper)

    cached("save_overload", "cache write")
    cached("load_overload", "cache load")


def _user_case(folder: Path):
    (folder / "user_plant.py").write_text(USER_MODULE)
    sys.path.insert(0, str(folder))
    import numpy as np
    from user_plant import pendulum_terms  # type: ignore[import-not-found]

    import delaytrack as dt

    truth = dt.CompiledPlant(1, 1, pendulum_terms, [1.2, 0.5, 0.4])
    model = dt.CompiledPlant(1, 1, pendulum_terms, [0.9, 0.5, 0.0])
    controller = dt.AROLC(model, K1=1.0, K2=1.0, Q=1.0, alpha=2.0, epsilon=0.1, gamma=0.001)
    reference = dt.SinusoidalReference(offset=[0.3], amplitude=[0.5], frequency=[1.0])

    def first() -> None:
        dt.simulate(
            truth,
            controller,
            dt.ConstantDelay(0.01),
            np.zeros(2),
            reference=reference,
            t1=1.0,
            dt=1e-3,
            T_c=2e-3,
            trajectories=False,
        )

    return first


def _robot_case(folder: Path):
    sys.path.insert(0, str(HERE))
    from baselines import robot_case

    from delaytrack.experiments.paper import DT, T_C
    from delaytrack.sim import simulate

    plant, controller, delay, reference, x0 = robot_case(1.0)

    def first() -> None:
        simulate(plant, controller, delay, x0, reference=reference, t1=1.0, dt=DT, T_c=T_C)

    return first


def _paper_job(folder: Path):
    from delaytrack.cli import main as command

    def first() -> None:
        argv = ["reproduce", "--no-contact", "--no-robustness", "--out", str(folder / "results")]
        if command(argv) not in (0, None):
            raise RuntimeError("delaytrack reproduce failed")

    return first


CASES = {"user": _user_case, "robot": _robot_case, "paper-job": _paper_job}


def worker(case: str, ir_size: bool) -> dict:
    """Run ``case`` in this (fresh) process under the compile clock; what it measured."""
    started = time.perf_counter()
    import numba  # noqa: F401 - its import is not delaytrack's

    numba_imported = time.perf_counter()
    clock = CompileClock(ir_size)
    instrument(clock)
    import delaytrack  # noqa: F401
    from delaytrack._compile import helper_process

    waited = [0.0]
    wait = helper_process.Helper.wait

    def timed_wait(self):
        start = time.perf_counter()
        try:
            return wait(self)
        finally:
            waited[0] += time.perf_counter() - start

    helper_process.Helper.wait = timed_wait
    imported = time.perf_counter()
    with tempfile.TemporaryDirectory() as folder:
        first = CASES[case](Path(folder))
        built = time.perf_counter()
        first()
        done = time.perf_counter()
    clock._charge()
    functions: dict = defaultdict(lambda: defaultdict(float))
    kinds: dict = defaultdict(lambda: defaultdict(float))
    by_kind: dict = defaultdict(lambda: defaultdict(float))
    for (function, stage, kind), seconds in clock.wall.items():
        functions[function][stage] += seconds
        kinds[kind][stage] += seconds
        by_kind[function][kind] += seconds
    cpu: dict = defaultdict(float)
    for (function, _, _), seconds in clock.cpu.items():
        cpu[function] += seconds
    return {
        "import_numba_s": numba_imported - started,
        "import_delaytrack_s": imported - numba_imported,
        "build_case_s": built - imported,
        "first_simulation_s": done - built,
        "helper_wait_s": waited[0],
        "in_process_total_s": done - started,
        "functions": {
            name: {
                "stages": dict(stages),
                "kinds": dict(by_kind[name]),
                "total_s": sum(stages.values()),
                "cpu_s": cpu[name],
                "compiles": clock.compiles.get(name, 0),
                "signatures": sorted(clock.signatures.get(name, ())),
                "module_ir_chars": clock.module_sizes.get(name, []),
            }
            for name, stages in functions.items()
        },
        "kinds": {kind: dict(stages) for kind, stages in kinds.items()},
        "parts": {
            name: {"wall_s": wall, "cpu_s": cpu, "compiles": count}
            for name, (wall, cpu, count) in clock.parts.items()
        },
        "passes": dict(clock.passes),
    }


# --- the parent -----------------------------------------------------------------------------


def run_case(case: str, helper: str, ir_size: bool) -> dict:
    """``case`` in a fresh process from an empty cache, with the helper ``on``, ``off`` or
    ``auto`` (started only beside a free core: the variable unset)."""
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        env.pop("DELAYTRACK_COMPILE_HELPER", None)
        if helper != "auto":
            env["DELAYTRACK_COMPILE_HELPER"] = "1" if helper == "on" else "0"
        load = os.getloadavg()[0]
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        command = [sys.executable, str(Path(__file__).resolve()), "--worker", case]
        done = subprocess.run(
            command + (["--ir-size"] if ir_size else []),
            env=env,
            capture_output=True,
            text=True,
            check=False,
        )
        wall = time.perf_counter() - start
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise RuntimeError(f"case {case} (helper {helper}) failed:\n{done.stderr[-3000:]}")
    measured = json.loads(done.stdout.strip().splitlines()[-1])
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {
        "case": case,
        "helper": helper,
        "load_average_before": load,
        "wall_s": wall,
        "cpu_s": cpu,
        **measured,
    }


def _stage_totals(result: dict) -> dict:
    totals = dict.fromkeys(STAGES, 0.0)
    for function in result["functions"].values():
        for stage, seconds in function["stages"].items():
            totals[stage] += seconds
    return totals


#: Column heads of :data:`STAGES` (but ``other``).
_SHORT = ("untyp", "infer", "typed", "lower", "fnopt", "modopt", "mcode", "write", "load")


def report(results: list[dict], top: int) -> None:
    """Print the tables of ``results``."""
    print("\n== whole process, from an empty cache (fresh process each) ==")
    print(
        f"{'case':<10} {'helper':<6} {'load':>5} {'wall s':>7} {'CPU s':>7} {'imports':>8} "
        f"{'1st sim':>8} {'compile':>8} {'waited':>7}"
    )
    for r in results:
        compiling = sum(_stage_totals(r).values())
        imports = r["import_numba_s"] + r["import_delaytrack_s"]
        print(
            f"{r['case']:<10} {r['helper']:<6} {r['load_average_before']:>5.1f} "
            f"{r['wall_s']:>7.2f} {r['cpu_s']:>7.2f} "
            f"{imports:>8.2f} {r['first_simulation_s']:>8.2f} {compiling:>8.2f} "
            f"{r['helper_wait_s']:>7.2f}"
        )
    for case in dict.fromkeys(r["case"] for r in results):
        runs = [r for r in results if r["case"] == case and r["helper"] == "off"]
        runs = runs or [r for r in results if r["case"] == case]
        r = min(runs, key=lambda r: r["wall_s"])
        print(f"\n== {case}, helper {r['helper']}: per compile stage (s, this process) ==")
        totals = _stage_totals(r)
        print("  ".join(f"{stage} {seconds:.2f}" for stage, seconds in totals.items()))
        print(f"\n== {case}, helper {r['helper']}: per reason compiled, per stage (s) ==")
        print(f"  {'reason':<30} {'total':>6} " + " ".join(f"{s:>6}" for s in _SHORT))
        for kind, stages in sorted(r["kinds"].items(), key=lambda item: -sum(item[1].values())):
            cells = " ".join(f"{stages.get(stage, 0.0):6.2f}" for stage in STAGES[:-1])
            print(f"  {kind:<30} {sum(stages.values()):6.2f} {cells}")
        print(f"\n== {case}, helper {r['helper']}: per engine part (inclusive s) ==")
        for name, part in sorted(r["parts"].items(), key=lambda item: -item[1]["wall_s"]):
            if part["wall_s"] >= 0.05:
                print(f"  {part['wall_s']:7.2f}  {part['compiles']:3d}x  {name}")
        print(f"\n== {case}, helper {r['helper']}: per compiled function (exclusive s) ==")
        print(f"  {'total':>6} " + " ".join(f"{s:>6}" for s in _SHORT) + "  n  sig  function")
        ranked = sorted(r["functions"].items(), key=lambda item: -item[1]["total_s"])
        for name, f in ranked[:top]:
            stages = " ".join(f"{f['stages'].get(stage, 0.0):6.2f}" for stage in STAGES[:-1])
            print(
                f"  {f['total_s']:6.2f} {stages} {f['compiles']:2d} {len(f['signatures']):3d}  "
                f"{name}"
            )
        twice = {n: f for n, f in r["functions"].items() if len(f["signatures"]) > 1}
        if twice:
            print(f"\n  compiled for more than one signature in {case}:")
            for name, f in sorted(twice.items(), key=lambda item: -item[1]["total_s"]):
                print(f"    {len(f['signatures'])} signatures, {f['total_s']:.2f} s: {name}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", default=["user", "robot"], choices=list(CASES))
    parser.add_argument("--modes", nargs="+", default=["off", "on"], choices=["off", "on", "auto"])
    parser.add_argument("--repeats", type=int, default=1, help="rounds of alternation")
    parser.add_argument("--top", type=int, default=25, help="functions listed per case")
    parser.add_argument(
        "--ir-size", action="store_true", help="record each library's LLVM IR size (slower)"
    )
    parser.add_argument("--out", type=Path, default=HERE / "compile_profile.json")
    parser.add_argument("--worker", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        print(json.dumps(worker(args.worker, args.ir_size)))
        return
    results = []
    for round_ in range(args.repeats):
        for case in args.cases:
            for mode in args.modes if round_ % 2 == 0 else args.modes[::-1]:
                result = run_case(case, mode, args.ir_size)
                print(
                    f"{case} helper {mode}: {result['wall_s']:.2f} s wall, "
                    f"{result['cpu_s']:.2f} s CPU",
                    flush=True,
                )
                results.append(result)
    report(results, args.top)
    summary = {
        f"{case} helper {mode}": statistics.median(
            r["wall_s"] for r in results if r["case"] == case and r["helper"] == mode
        )
        for case in args.cases
        for mode in args.modes
    }
    output = {
        "machine": {
            "python": platform.python_version(),
            "processor": platform.processor() or platform.machine(),
            "cores": len(os.sched_getaffinity(0)),
            "load_average": os.getloadavg(),
        },
        "median_wall_s": summary,
        "runs": results,
    }
    args.out.write_text(json.dumps(output, indent=2) + "\n")
    print(f"\nwrote {args.out}")


if __name__ == "__main__":
    main()
