"""Compiling on two cores: a helper process compiles part of what a first run needs.

numba compiles one function at a time, in one thread, and a first run of a new combination needs
several: the engine and the functions it calls through their address
(:mod:`delaytrack._compile.native_parts`), each compiled on its own and kept in numba's disk
cache. When there are two or more to compile and two cores or more, :func:`start` starts a
helper process if sharing them would finish sooner (:func:`share`). The helper takes the jobs it
can import longest first, each that neither process has claimed yet (:meth:`Helper.claim`: a
file created only if it is not there yet); this process takes the others first, then the same
jobs in the same order (:func:`order_here`). Among the jobs the helper can take, the two thus
finish at about the same time however far the jobs' estimated costs are from the truth (a job it
cannot import, such as a kernel defined in ``__main__``, is this process's alone). Both write
the disk cache; this process compiles what it claimed, waits for the helper
(:meth:`Helper.wait`), and then loads the rest from the cache.

The helper imports each function and kernel by its module and name (a module loaded from a file
named in a scenario, from that file), and checks that a kernel of the user's has the same
fingerprint as here (:attr:`delaytrack.components.Kernel.key`); a function it cannot import
(defined in ``__main__`` or inside another function) stays in this process. Importing the
module of a kernel of yours runs its top-level code in the helper (with the helper turned off
there, so it starts no helper of its own). Whatever the helper does not deliver, because it
failed, was stopped or took too long (:meth:`Helper.wait`), this process compiles as it would
without it, and a compile error is reported by this process.

The helper is for a core with nothing to do: it is started when, over a tenth of a second,
other processes left 1.75 of the CPUs this process may use free on average (this process's
own, as it waits, and one more, less a margin; the job's own second processes count as free:
:func:`count_as_own`; :func:`spare_core`), so not beside processes
already using every core, such as pytest's or dask's workers, where it would only compete
with them; and only where numba's cache is saved under a file lock (not on Windows). Set the
environment variable ``DELAYTRACK_COMPILE_HELPER`` to ``0`` to compile in one process, or to
``1`` to start the helper whatever the load.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import pickle
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, NamedTuple

from delaytrack._compile.disk_cache import cache_directory, locks_cache
from delaytrack._spec import module_from_file, own_bytecode
from delaytrack.components import Kernel, ReducedForm

__all__ = [
    "ENVIRONMENT",
    "IDLE_NEEDED",
    "IDLE_WINDOW",
    "CompileJob",
    "CpuTimes",
    "Helper",
    "bootstrap",
    "count_as_own",
    "forget_own",
    "idle_cpus",
    "main",
    "order_here",
    "spawn",
    "share",
    "spare_core",
    "start",
]

#: The environment variable that turns the helper off (``0``) or on whatever the load (``1``).
ENVIRONMENT = "DELAYTRACK_COMPILE_HELPER"

#: Rough seconds a helper takes to start (importing numba and delaytrack, 0.3–0.4 s, and
#: numba's first compile's set-up), in the units of :attr:`CompileJob.cost`.
START_UP = 1.0


def bootstrap(module: str) -> list[str]:
    """The command of a second Python process that runs ``module``'s ``main`` on its input
    (``python -P``: no folder is put before the module search path). It sets its module search
    path to the first pickle of its input (this process's, so that it imports the same package
    and the user's modules), then calls ``main`` with the input itself (``main`` reads what is
    written later); its exit status is what ``main`` returns, and it ends as a whole process of
    the toolkit does (:func:`~delaytrack._process_exit.exit_process`)."""
    code = (
        "import pickle, sys\n"
        "payload = sys.stdin.buffer\n"
        "sys.path[:] = pickle.load(payload)\n"
        f"from {module} import main\n"
        "from delaytrack._process_exit import exit_process\n"
        "exit_process(main(payload))\n"
    )
    return [sys.executable, "-P", "-c", code]


#: Processes of this one (by id) whose CPU time counts as its own in :func:`idle_cpus`.
_OWN: set[int] = set()


def count_as_own(pid: int) -> None:
    """Count the CPU time of the process ``pid`` (a second process this one started: a
    report's, :mod:`delaytrack.jobs._background`, or a compile helper, :func:`spawn`) as this
    process's own in :func:`idle_cpus`: its work is this job's, and must not keep another of
    the job's processes off (a job's own processes thus count as free for one another; on a
    machine busy with other work they may share its cores)."""
    _OWN.add(pid)


def forget_own(pid: int) -> None:
    """Stop counting the process ``pid`` as this process's own (:func:`count_as_own`)."""
    _OWN.discard(pid)


def _own_ticks() -> int:
    """CPU clock ticks of this process and of those counted as its own (a process that ended
    counts no more)."""
    ticks = 0
    for name in ("self", *map(str, _OWN)):
        with contextlib.suppress(OSError, ValueError, IndexError):
            fields = Path(f"/proc/{name}/stat").read_text().rpartition(")")[2].split()
            ticks += int(fields[11]) + int(fields[12])  # utime, stime
    return ticks


#: How long to wait for a helper: this many seconds, plus :data:`PATIENCE` times the cost of
#: the jobs it may have claimed (:meth:`Helper.wait`), then this process compiles what is left.
GRACE = 60.0
PATIENCE = 10.0


@dataclass(frozen=True)
class CompileJob:
    """One function to compile for one signature.

    Parameters
    ----------
    function : numba dispatcher
        The function, with numba's disk cache.
    signature : tuple of numba types
        Its argument types.
    kernels : tuple of Kernel
        The components' kernels named in ``signature``
        (:class:`~delaytrack._compile.kernel_type.KernelType`), which the helper makes again.
    cost : float
        Rough seconds its compile takes, relative to the others (to share the work).
    """

    function: Any
    signature: tuple
    kernels: tuple
    cost: float


def _quota() -> float | None:
    """The CPUs this process's cgroup may use (its ``cpu.max`` quota), None without a quota."""
    with contextlib.suppress(OSError, ValueError, ZeroDivisionError):
        quota, period = Path("/sys/fs/cgroup/cpu.max").read_text().split()[:2]
        if quota != "max":
            return int(quota) / int(period)
    return None


def _allowed() -> set[int] | None:
    """The CPUs this process may run on, None where that is not known."""
    try:
        return set(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return None


def _cores() -> int:
    """The cores this process may use: those it may run on, at most its cgroup's CPU quota."""
    allowed = _allowed()
    cores = len(allowed) if allowed is not None else os.cpu_count() or 1
    quota = _quota()
    return cores if quota is None else min(cores, max(1, int(quota)))


#: How long the machine's use is measured before a helper is started, in seconds.
IDLE_WINDOW = 0.1
#: CPUs that other processes must leave free over that window: this process's and one for the
#: helper, less a margin for the moments other processes take.
IDLE_NEEDED = 1.75


class CpuTimes(NamedTuple):
    """CPU time so far: of the CPUs this process may run on, idle (waiting for input or output
    counted as idle) and in all, and this process's (all its threads, and the processes
    :func:`count_as_own` named), in clock ticks; the
    number of those CPUs; and the CPU seconds of this process's cgroup (None without)."""

    idle: int
    total: int
    own: int
    cpus: int
    cgroup: float | None


def _cpu_times() -> CpuTimes:
    """:class:`CpuTimes` now, from ``/proc/stat``, ``/proc/self/stat`` and the cgroup's
    ``cpu.stat``."""
    allowed = _allowed()
    idle = total = cpus = 0
    for line in Path("/proc/stat").read_text().splitlines():
        name, _, values = line.partition(" ")
        if not (name.startswith("cpu") and name[3:].isdigit()):
            continue
        if allowed is not None and int(name[3:]) not in allowed:
            continue
        fields = [int(field) for field in values.split()[:8]]  # user .. steal
        idle, total, cpus = idle + fields[3] + fields[4], total + sum(fields), cpus + 1
    cgroup = None
    with contextlib.suppress(OSError, ValueError):
        for line in Path("/sys/fs/cgroup/cpu.stat").read_text().splitlines():
            if line.startswith("usage_usec "):
                cgroup = int(line.split()[1]) / 1e6
    return CpuTimes(idle, total, _own_ticks(), cpus, cgroup)


def idle_cpus(window: float = IDLE_WINDOW) -> float | None:
    """How many CPUs other processes left free, on average, over the next ``window`` seconds
    (this process sleeping through them), from ``/proc``; None where it is not known.

    Counted on the CPUs this process may run on and, under a cgroup quota, at most the quota
    less what the cgroup's other processes used. A measure of now, not of the last minute: the
    load average lags, and kept a helper off for a minute after another job had ended. All of
    this process's threads count as free: one of the linear algebra library still spinning
    after a call would otherwise keep the helper off, and it soon stops (a thread of yours
    that keeps computing is not seen, and the helper then shares its core). So does a process
    of this one's named by :func:`count_as_own`.
    """
    try:
        before, start = _cpu_times(), time.monotonic()
        time.sleep(window)
        after, elapsed = _cpu_times(), time.monotonic() - start
        ticks = os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError, AttributeError):
        return None
    if after.total <= before.total or before.cpus < 1 or elapsed <= 0.0:
        return None
    own = after.own - before.own
    free = before.cpus * (after.idle - before.idle + own) / (after.total - before.total)
    free = min(float(before.cpus), free)
    quota = _quota()
    if quota is not None and before.cgroup is not None and after.cgroup is not None:
        others = (after.cgroup - before.cgroup - own / ticks) / elapsed
        free = min(free, quota - max(0.0, others))
    return free


def spare_core() -> bool:
    """Whether a helper may run beside this process (:data:`ENVIRONMENT`, the cores, the idle
    CPUs; never in a frozen application or where the cache is saved without a lock).

    Automatically, when :data:`IDLE_NEEDED` CPUs were idle over :data:`IDLE_WINDOW` seconds
    (:func:`idle_cpus`); where that cannot be measured, when the load average of the last
    minute is below the number of cores less one half.
    """
    setting = os.environ.get(ENVIRONMENT, "").strip()
    cores = _cores()
    if setting == "0" or cores < 2 or getattr(sys, "frozen", False) or not locks_cache():
        return False
    if setting == "1":
        return True
    idle = idle_cpus()
    if idle is not None:
        return idle >= IDLE_NEEDED
    with contextlib.suppress(AttributeError, OSError):
        return os.getloadavg()[0] < cores - 0.5
    return False


def _name(function: Any) -> tuple[str, str, str | None] | None:
    """``(module, name, file)`` under which another process imports ``function`` (a numba
    dispatcher or a plain function): its qualified name, or a name its module gives it (a
    dispatcher made from another function, such as ``run_batch_compiled``), and the module's
    file (to load it from when no folder of the search path holds it: a file named in a
    scenario); None when there is none."""
    python = getattr(function, "py_func", function)
    module_name = getattr(python, "__module__", None)
    if module_name is None or module_name == "__main__":
        return None
    module = sys.modules.get(module_name)
    if module is None:
        return None
    file = getattr(module, "__file__", None)
    found: Any = module
    for attribute in getattr(python, "__qualname__", "").split("."):
        found = getattr(found, attribute, None)
    if found is function:
        return (module_name, python.__qualname__, file)
    names = [name for name, value in vars(module).items() if value is function]
    return (module_name, names[0], file) if names else None


def _kernel_recipe(kernel: Kernel) -> tuple | None:
    """How the helper makes ``kernel`` again: its key and the names of its functions."""
    functions = kernel.roots
    names = tuple(None if function is None else _name(function) for function in functions)
    pairs = zip(names, functions, strict=True)
    if any(name is None and function is not None for name, function in pairs):
        return None
    reduced_size = None if kernel.reduced is None else kernel.reduced.size
    return (kernel.key, names, kernel.identity_mass, kernel.sizes, reduced_size)


def _recipe(job: CompileJob) -> tuple | None:
    """What the helper needs to compile ``job`` (pickled), or None when it cannot."""
    function = _name(job.function)
    kernels = tuple(_kernel_recipe(kernel) for kernel in job.kernels)
    if function is None or None in kernels:
        return None
    recipe = (function, job.signature, kernels)
    try:
        pickle.dumps(recipe)
    except Exception:  # noqa: BLE001 - a type that does not pickle: compiled here
        return None
    return recipe


def share(costs: Sequence[float], movable: Sequence[bool], start_up: float = START_UP) -> list[int]:
    """The positions of ``costs`` that a helper would compile, were the costs exact.

    Longest first, each job goes to the process that would finish it first (the helper starts
    ``start_up`` late); a job that is not ``movable`` stays here. Returns no position when
    the helper would not finish before this process alone: then :func:`start` starts none
    (with one, each job goes to whichever process claims it first).
    """
    order = sorted(range(len(costs)), key=lambda i: -costs[i])
    here, helper, given = 0.0, start_up, []
    for i in order:
        if movable[i] and helper < here:
            helper += costs[i]
            given.append(i)
        else:
            here += costs[i]
    if not given or max(here, helper) >= sum(costs):
        return []
    return sorted(given)


def _claim(folder: str, position: int) -> bool:
    """Claim the job at ``position`` in ``folder`` (:meth:`Helper.claim`): whether this process
    created its file (the other process then finds it there)."""
    flags = os.O_CREAT | os.O_EXCL | os.O_WRONLY
    try:
        os.close(os.open(os.path.join(folder, str(position)), flags))
    except FileExistsError:
        return False
    return True


class Helper:
    """A helper process compiling the jobs it claims first (made by :func:`start`).

    Parameters
    ----------
    process : subprocess.Popen
        The helper.
    patience : float
        Seconds :meth:`wait` waits for it, plus :data:`PATIENCE` times the cost of each job
        the helper may have claimed (those of ``costs`` this process did not claim).
    claims : str or None
        The folder of the jobs' claims (:meth:`claim`), which :meth:`stop` removes; None for
        a helper that claims nothing.
    costs : dict of int to float, optional
        The rough cost of each job the helper was given, by position.
    """

    def __init__(
        self,
        process: subprocess.Popen,
        patience: float,
        claims: str | None = None,
        costs: dict[int, float] | None = None,
    ) -> None:
        self.process = process
        self.patience = patience
        self.claims = claims
        self.costs = dict(costs or {})
        self._mine: set[int] = set()

    def claim(self, position: int) -> bool:
        """Whether this process compiles the job at ``position``: True unless the helper
        claimed it first. A job the helper was not given is never claimed by it; a claim that
        cannot be written is this process's (the helper then cannot claim it either)."""
        if self.claims is not None:
            try:
                if not _claim(self.claims, position):
                    return False
            except OSError:
                pass
        self._mine.add(position)
        return True

    def wait(self) -> bool:
        """Wait for the helper to finish (at most its patience, then stop it); whether it
        compiled every job it claimed."""
        left = sum(cost for position, cost in self.costs.items() if position not in self._mine)
        try:
            return self.process.wait(timeout=self.patience + PATIENCE * left) == 0
        except subprocess.TimeoutExpired:
            self.stop()
            return False

    def stop(self) -> None:
        """End the helper if it still runs (this process failed or was interrupted), and
        remove the claims' folder."""
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait()
        if self.process.stdin is not None:  # a helper started ahead and never given its jobs
            with contextlib.suppress(OSError):
                self.process.stdin.close()
        forget_own(self.process.pid)
        if self.claims is not None:
            shutil.rmtree(self.claims, ignore_errors=True)


def spawn(module: str = __name__, path: Sequence[str] | None = None) -> subprocess.Popen:
    """A second process of this job, started, running ``module``'s ``main``
    (:func:`bootstrap`) on its standard input, which stays open, after the module search path
    ``path`` (this process's as it is now by default); by default a compile helper, which
    imports numba and the package and sets up numba's compiler (:func:`main`) while it waits
    for its jobs (:func:`start`). It starts no helper of its own, and its CPU time counts as
    this process's (:func:`count_as_own`). A process started does not outlive this function's
    failure."""
    process = subprocess.Popen(
        bootstrap(module),
        stdin=subprocess.PIPE,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env={**os.environ, ENVIRONMENT: "0"},  # its imports start no helper of their own
    )
    # its work is this job's: it must not keep another of the job's processes off, which it
    # would if its CPU time counted as another process's (a helper started ahead compiles while
    # a report's second process is to start, and that process draws while a compile starts)
    count_as_own(process.pid)
    try:
        assert process.stdin is not None  # opened with stdin=PIPE
        process.stdin.write(pickle.dumps(list(sys.path if path is None else path)))
        process.stdin.flush()
    except BaseException:
        Helper(process, 0.0).stop()
        raise
    return process


def start(
    jobs: Sequence[CompileJob], ahead: Callable[[], subprocess.Popen | None] = lambda: None
) -> tuple[Helper | None, list[int]]:
    """Start a helper for ``jobs`` when sharing them would finish sooner (:func:`share`), or
    hand them to the helper ``ahead()`` gives, one started ahead (:func:`spawn`), asked for
    only then: a first compile not worth a helper leaves it to the next.

    The helper takes the jobs it can import longest first, each that neither process has
    claimed yet (:meth:`Helper.claim`); this process takes them in the order of
    :func:`order_here`. Returns the helper and the positions of the jobs it may compile;
    ``(None, [])`` when there is no helper: fewer than two jobs, no spare core
    (:func:`spare_core`), no job the helper can import, or a helper that could not be started
    (an error of the operating system). A process started does not outlive this function's
    failure (Ctrl-C included).
    """
    process = claims = None
    try:
        recipes = [_recipe(job) for job in jobs]
        movable = [recipe is not None for recipe in recipes]
        costs = [job.cost for job in jobs]
        # not worth even a helper that is up already (no start-up to count)
        if len(jobs) < 2 or not share(costs, movable, 0.0):
            return None, []
        process = ahead()
        if process is not None and process.poll() is not None:
            Helper(process, 0.0).stop()  # it ended (it failed to start)
            process = None  # a new one, if one is to run
        if process is None and not (share(costs, movable, START_UP) and spare_core()):
            return None, []
        given = _longest_first(jobs, [i for i in range(len(jobs)) if movable[i]])
        claims = tempfile.mkdtemp(prefix="delaytrack-compile-claims-")
        if process is None:
            process = spawn()
        assert process.stdin is not None  # opened with stdin=PIPE
        process.stdin.write(
            pickle.dumps((str(cache_directory()), claims, [(i, recipes[i]) for i in given]))
        )
        process.stdin.close()
    except BaseException as error:
        if process is not None:
            Helper(process, 0.0).stop()
        if claims is not None:
            shutil.rmtree(claims, ignore_errors=True)
        # A process or pipe that failed (OSError; ValueError on a closed pipe): no helper,
        # everything is compiled here. Anything else, Ctrl-C or an error of this code, goes on.
        if not isinstance(error, OSError | ValueError):
            raise
        return None, []
    return Helper(process, GRACE, claims, {i: jobs[i].cost for i in given}), sorted(given)


def _longest_first(jobs: Sequence[CompileJob], positions: Sequence[int]) -> list[int]:
    """``positions`` of ``jobs`` by decreasing cost (ties in their order)."""
    return sorted(positions, key=lambda i: -jobs[i].cost)


def order_here(jobs: Sequence[CompileJob], given: Sequence[int]) -> list[int]:
    """The order in which this process takes ``jobs`` beside a helper given the positions
    ``given`` (:func:`start`): first the others, which only this process compiles, then those,
    each group longest first (the helper takes those in the same order)."""
    helpers = set(given)
    others = [i for i in range(len(jobs)) if i not in helpers]
    return _longest_first(jobs, others) + _longest_first(jobs, sorted(helpers))


def _imported(name: tuple[str, str, str | None]) -> Any:
    """The function :func:`_name` named: imported from the search path, else from its file."""
    module_name, qualname, file = name
    try:
        with own_bytecode():  # a file named in a scenario: never a .pyc shipped beside it
            found: Any = importlib.import_module(module_name)
    except ImportError:
        if file is None:
            raise
        found = module_from_file(Path(file), module_name)  # under the name it has here
    for attribute in qualname.split("."):
        found = getattr(found, attribute)
    return found


def _make_kernel(recipe: tuple) -> None:
    """Make the kernel of ``recipe`` (:func:`_kernel_recipe`) known to numba in this process;
    refuse one whose code differs from the one the other process asked for."""
    key, names, identity_mass, sizes, reduced_size = recipe
    function, command_map, stepper, velocity_map, dynamics = (
        None if name is None else _imported(name) for name in names
    )
    assert function is not None  # a kernel always has its function (:func:`_kernel_recipe`)
    reduced = None
    if reduced_size is not None:
        assert velocity_map is not None and dynamics is not None  # named with the size
        reduced = ReducedForm(velocity_map, dynamics, reduced_size)
    kernel = Kernel.of(function, command_map, identity_mass, sizes, stepper, reduced)
    if kernel.key != key:
        raise RuntimeError(f"the kernel {key} changed on disk")
    kernel.numba_type  # noqa: B018 - registers the kernel under its key for the compiler


def _prepare() -> None:
    """What every helper does before its jobs: import the engine's modules and compile a
    function of nothing, which sets up numba's compiler (about a second, in a helper started
    ahead while the other process has not reached its first compile yet)."""
    import numba

    import delaytrack.sim.engine  # noqa: F401 - the engine and the integrator, most jobs

    numba.njit(lambda x: x + 1.0)(1.0)


def main(file: IO[bytes]) -> int:
    """The helper: prepare (:func:`_prepare`), then compile the jobs pickled in ``file`` after
    the module search path, in their order, each that it claims before the other process
    (:meth:`Helper.claim`).

    Returns 0 when every job it claimed compiled (or ``file`` ended with no job: a helper
    started ahead and not used), 1 when one failed (the other process compiles it and reports
    the error), 2 when this process's cache folder is not the other's.
    """
    _prepare()
    try:
        cache, claims, recipes = pickle.load(file)
    except EOFError:
        return 0
    if str(cache_directory()) != cache:
        return 2
    parent = os.getppid()
    failed = 0
    for position, (function, signature, kernels) in recipes:
        if os.getppid() != parent:
            return 1  # the other process ended: no one waits for what is left
        try:
            if not _claim(claims, position):
                continue  # the other process compiles it
            for kernel in kernels:
                _make_kernel(kernel)
            _imported(function).compile(signature)
        except Exception:  # noqa: BLE001 - left to the other process
            failed = 1
    return failed
