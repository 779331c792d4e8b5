"""``simulate``: the one verb that runs closed loops."""

from __future__ import annotations

import contextlib
import functools
import math
import os
import re
import sys
import threading
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from types import SimpleNamespace
from typing import Any, TypeVar

import numpy as np
from tqdm.auto import tqdm

from delaytrack._result_columns import trajectory_columns
from delaytrack._validation import (
    as_spd_matrix,
    finite_array,
    finite_scalar,
    integer_multiple,
    is_integer_at_least,
    positive_scalar,
    real_array,
)
from delaytrack.components import (
    Kernel,
    call_reference,
    compiled_functions_reached,
    refuse_changed_globals,
    refuse_random_draws,
)
from delaytrack.controllers.base import Controller
from delaytrack.delays._kernel import NO_KERNEL
from delaytrack.delays.base import DelayProfile
from delaytrack.kernel_arguments import KERNEL_ARGUMENTS, check_kernel_arguments
from delaytrack.plants.base import ELPlant
from delaytrack.references import Reference
from delaytrack.sim.compile_helper import CompileJob, parts_ahead
from delaytrack.sim.compile_helper import start as start_helper
from delaytrack.sim.engine import run_batch, run_batch_compiled
from delaytrack.sim.fallback import PythonFallbackWarning, python_kernel
from delaytrack.sim.first_compile import announce_compile, code_ready
from delaytrack.sim.history import history_capacity, tick_time
from delaytrack.sim.interruptible import run_interruptibly
from delaytrack.sim.measurement import MeasurementNoise
from delaytrack.sim.native_parts import (
    controller_step_name,
    controller_step_part,
    delay_part,
    plant_tick_part,
    reference_part,
)
from delaytrack.sim.packet_loss import PacketLoss
from delaytrack.sim.result import SimResult
from delaytrack.sim.running_metrics import accumulator_size, finish_metrics
from delaytrack.sim.stale_caches import compile_from_source

__all__ = ["MAX_STEPS", "physical_memory", "simulate"]

_T = TypeVar("_T")

#: Values of ``simulate(engine=...)``.
ENGINES = ("auto", "compiled", "python")

#: Most RK4 steps of one run, ``(t1 - t0) / dt``: at a few million steps a second, minutes of
#: computing. A longer run is refused before anything is allocated.
MAX_STEPS = 10**8

#: What a run without ``progress`` updates instead of a progress bar.
_NO_PROGRESS_BAR = SimpleNamespace(update=lambda done: None)
#: Chunks per worker thread: enough for load balance and a moving progress bar, few enough
#: that the per-call overhead stays negligible.
_CHUNKS_PER_WORKER = 8
#: Rough seconds of the engine's first compile, in the units of the parts' costs
#: (:mod:`delaytrack.sim.native_parts`), to share first compiles between two processes.
_ENGINE_COST = 9.0
#: What the controller reads and loses when no noise and no loss are given.
_TRUE_STATE = MeasurementNoise()
_NO_LOSS = PacketLoss()


def _as_batch(name: str, value: _T | Sequence[_T], kind: type) -> list[_T]:
    items = list(value) if isinstance(value, list | tuple) else [value]
    if not items:
        raise ValueError(f"{name} must not be empty")
    for i, item in enumerate(items):
        if not isinstance(item, kind):
            raise TypeError(
                f"{name}[{i}] must be an instance of {kind.__name__}; got {type(item).__name__}"
            )
    return items


def _integer_ratio(name: str, value: float, unit: float, what: str, scale: float = 0.0) -> int:
    count = integer_multiple(value, unit, scale=scale)
    if count is None:
        raise ValueError(
            f"{name} must be a positive integer multiple of {what}; "
            f"got ({name})/{what} = {value / unit:.12g}"
        )
    return count


_NUMBA_CAUSES = ("Error: ", "Untyped global name", "Unknown attribute", "Cannot unify")
#: What numba says of an array made (``np.zeros``, array arithmetic, a copy) in code compiled
#: without its runtime, as the simulator's loop is.
_ALLOCATION = (
    "Only accept returning of array passed into the function as argument",
    "NRT required but not enabled",
)


#: The colour and bold codes numba writes into its messages.
_TERMINAL_CODES = re.compile(r"\x1b\[[0-9;]*m")


def _compiled_if_it_can(part: Any) -> Any:
    """How a part compiled ahead for a later run is compiled here: an error is left to that
    run, which compiles the part again and reports it with its own kernels."""

    def compile_it() -> None:
        try:
            part.native()
        except Exception:  # noqa: BLE001, S110 - reported by the run that needs the part
            pass

    return compile_it


def _raised_during_the_run(error: Exception, yours: list, when: str = "during the run") -> str:
    """The one-line message for ``error``, raised by one of the user's kernels ``yours``
    (:class:`~delaytrack.components.Kernel`) while the closed loop ran (or ``when`` it did)."""
    names = sorted({name for kernel in yours for name in kernel.callable_names})
    which = (
        f"your kernel {names[0]}"
        if len(names) == 1
        else f"one of your kernels ({', '.join(names)})"
    )
    hint = (
        " (a kernel compiled with numba.njit(error_model='numpy') divides by zero into inf or "
        "nan instead, which ends only that run, with the status 'diverged')"
        if isinstance(error, ZeroDivisionError)
        else ""
    )
    return f"{which} raised {type(error).__name__} {when}: {error}{hint}"


def _checked_before_the_run(kernel: Kernel, what: str, check: Any) -> Any:
    """``check()``, a call of the user's ``kernel`` before the run (``what`` it checks), with
    what it raises other than a ValueError of ours in one line naming the kernel: an error of
    the kernel itself, or numba's when it cannot compile the check around it."""
    try:
        return check()
    except Exception as error:
        if isinstance(error, ValueError) and not _raised_in_code_of(kernel, error):
            raise  # a refusal of ours
        if type(error).__module__.startswith("numba"):
            raise ValueError(
                f"numba could not compile {what} for your kernel {kernel.callable_names[0]}: "
                f"{_numba_cause(error)}"
            ) from None
        raise ValueError(
            _raised_during_the_run(error, [kernel], when=f"before the run ({what})")
        ) from None


def _raised_in_code_of(kernel: Kernel, error: Exception) -> bool:
    """Whether ``error`` was raised in the code of the user's ``kernel``: a frame of its traceback
    lies in a file of the kernel's functions or of the compiled functions they call (numba gives
    the ``raise`` of compiled code a frame of its own)."""
    functions = [
        reached
        for root in (kernel.function, kernel.command_map, kernel.stepper)
        if root is not None
        for reached in (root, *compiled_functions_reached(root))
    ]
    files = {
        code.co_filename
        for function in functions
        if (code := getattr(getattr(function, "py_func", function), "__code__", None))
    }
    frame = error.__traceback__
    while frame is not None:
        if frame.tb_frame.f_code.co_filename in files:
            return True
        frame = frame.tb_next
    return False


#: How a message names a kernel of each kind (a key of ``KERNEL_ARGUMENTS``).
_KIND_NAMES = {"step": "controller step"}


def _refuse_reads_past(kernel: Kernel, kind: str, arguments: tuple, where: str) -> None:
    """Run the plain-Python version of the user's ``kernel`` (a ``kind`` of
    :data:`~delaytrack.kernel_arguments.KERNEL_ARGUMENTS`) once on copies of ``arguments``, the
    arrays the engine passes it, of their sizes: compiled, a read past an array's end runs on
    silently with whatever lies there, and a write past it overwrites other memory (or crashes
    the process); Python raises IndexError, refused here naming the kernel and the arrays'
    sizes. Other errors are left to the compiled kernel, which is what runs (Python may lack
    what numba provides). An index only on another branch, or in a compiled helper the kernel
    calls, is not seen."""
    python = getattr(kernel.function, "py_func", None)
    if kernel.built_in or python is None:
        return
    copies = [value.copy() if isinstance(value, np.ndarray) else value for value in arguments]
    try:
        python(*copies)
    except IndexError as error:
        sizes = ", ".join(
            f"{name} {value.shape[0] if value.ndim == 1 else value.shape}"
            for name, value in zip(KERNEL_ARGUMENTS[kind], arguments, strict=True)
            if isinstance(value, np.ndarray)
        )
        raise ValueError(
            f"your {_KIND_NAMES.get(kind, kind)} kernel {kernel.callable_names[0]} reads or "
            f"writes beyond an array {where} ({error}); the arrays it is given have these "
            f"sizes: {sizes}. Index only within them (compiled, it would read or write other "
            "memory silently, or crash the process)"
        ) from None
    except Exception:  # noqa: BLE001 - only reads past an array's end are checked here
        return


def _check_plant_at_x0(plant: ELPlant, x0: np.ndarray, t0: float) -> None:
    """A plant of the user's (solved for ``q̈``) at the run's start: its kernel reads no index
    past an array's end (:func:`_refuse_reads_past`) and gives an ``M`` that is symmetric
    positive definite, or it is refused naming the kernel (the run would stop at once)."""
    kernel = plant.engine_kernel
    if kernel.built_in or kernel.stepper is not None or kernel.identity_mass:
        return
    n = plant.n
    terms = (t0, x0[:n], x0[n:], plant.params, np.zeros((n, n)), np.zeros(n))
    _refuse_reads_past(kernel, "terms", (*terms, np.zeros((n, plant.m))), "at x0")
    mass = _checked_before_the_run(
        kernel, "the check of M at x0", lambda: plant.terms(x0[None, :n], x0[None, n:], t0)[0][0]
    )
    as_spd_matrix(f"the plant's M at x0 (from your kernel {kernel.callable_names[0]})", mass, n)


def _check_controller_at_x0(
    controller: Controller, x0: np.ndarray, t0: float, T_c: float, delay: DelayProfile
) -> None:
    """A controller's kernels of the user's at the run's first tick: its nominal model's and
    its step's read no index past an array's end (:func:`_refuse_reads_past`; the reference
    taken as zeros, the delay as ``h(t0)``)."""
    n, m = controller.n, controller.m
    model = controller.model
    q, qdot = x0[:n], x0[n:]
    terms = (t0, q, qdot, model.params, np.zeros((n, n)), np.zeros(n), np.zeros((n, m)))
    _refuse_reads_past(model.engine_kernel, "terms", terms, "at x0")
    step = controller.engine_kernel
    if step.built_in:
        return
    arguments = controller.step_arguments(
        t0,
        q,
        qdot,
        tuple(np.zeros((3, n))),
        controller.initial_state(),
        T_c=T_c,
        h=float(delay.h(t0)),
    )
    _refuse_reads_past(step, "step", arguments, "at its first tick")


def _numba_cause(error: Exception) -> str:
    """What to tell of a numba error in compiling a kernel of the user's: an array made by code
    inlined into the simulator's loop, named as such; else the innermost cause in numba's
    message (``NameError: name 'x' is not defined``), or its first line, and where to see the
    whole message."""
    text = _TERMINAL_CODES.sub("", str(error))  # numba colours its messages for a terminal
    if any(marker in text for marker in _ALLOCATION):
        return (
            "code of yours inlined into the simulator's loop (inline='always') makes a new "
            "array (np.zeros, array arithmetic, a copy), which the loop, compiled without "
            "numba's runtime, cannot free: do not inline it, or write into the arrays it is "
            "given"
        )
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    causes = [
        line
        for line in lines
        if any(marker in line for marker in _NUMBA_CAUSES)
        and not line.startswith(("Failed in", "During", "File", "raised from"))
    ]
    cause = causes[-1] if causes else f"{type(error).__name__}: {lines[0] if lines else ''}"
    return f"{cause} (call a kernel of yours alone, compiled, to see numba's whole message)"


def _check_same_kernel(name: str, plant: ELPlant, first: ELPlant) -> None:
    """A compiled batch runs one kernel for all its elements."""
    if plant.compiled and plant.engine_kernel != first.engine_kernel:
        raise ValueError(
            f"{name} has another compiled kernel than element 0; a batch runs one kernel "
            "(split it into one simulate call per kernel)"
        )


def _metrics_from_tick(
    metrics_from: float | None, t0: float, t1: float, dt: float, steps_per_tick: int, n_ticks: int
) -> int:
    """First tick counted by the running metrics: the first one at or after ``metrics_from``."""
    if metrics_from is None:
        return 0
    start = finite_scalar("metrics_from", metrics_from)
    if not t0 <= start <= t1:
        raise ValueError(
            f"metrics_from must lie in [t0, t1] = [{t0:g}, {t1:g}] s; got {metrics_from!r}"
        )
    # The first k with tick_time(k) >= start, with tick times computed as the engine and
    # metrics._window compute them, so that both count the same ticks.
    k = min(n_ticks, max(0, math.ceil((start - t0) / (steps_per_tick * dt))))
    while k > 0 and tick_time(k - 1, t0, dt, steps_per_tick) >= start:
        k -= 1
    while k < n_ticks and tick_time(k, t0, dt, steps_per_tick) < start:
        k += 1
    return k


def available_cores() -> int:
    """The cores this process may use (its CPU affinity where the OS has one, else all)."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return os.cpu_count() or 1


def _workers(workers: int | None) -> int:
    """Thread count: ``workers`` checked, or the cores this process may use."""
    if workers is None:
        return available_cores()
    if not is_integer_at_least(workers, 1):
        raise ValueError(f"workers must be a positive integer (threads); got {workers!r}")
    return int(workers)


def physical_memory() -> float:
    """Bytes of physical memory (infinite where the platform does not say)."""
    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, ValueError, OSError):
        return math.inf


def _broadcast(name: str, items: list[_T], batch: int) -> list[_T]:
    if len(items) == batch:
        return items
    if len(items) == 1:
        return items * batch
    raise ValueError(
        f"{name} has {len(items)} entries but the batch has {batch}; give 1 or {batch}"
    )


def _check_kernel_arguments(plant: ELPlant, controller: Controller, reference: Reference) -> None:
    """Check that the plant's, the controller's and the reference's kernels take the arguments
    the engine passes them (:mod:`delaytrack.kernel_arguments`), before anything is compiled."""
    for owner, component in (("plant", plant), ("controller's model", controller.model)):
        kernel = component.engine_kernel
        check_kernel_arguments(owner, "terms", kernel.function)
        for kind in ("command_map", "stepper"):
            if getattr(kernel, kind) is not None:
                check_kernel_arguments(owner, kind, getattr(kernel, kind))
    check_kernel_arguments("controller", "step", controller.step_kernel)
    check_kernel_arguments("reference", "reference", reference.reference_kernel)


def _check_horizons(
    plants: list[ELPlant], delays: list[DelayProfile], reference: Reference, t0: float, t1: float
) -> None:
    """Refuse a run longer than the time its plant's, delay's or reference's data cover (never
    extend them silently)."""
    if reference.start > t0:
        raise ValueError(
            f"reference ({type(reference).__name__}) starts at t = {reference.start:g} s, after "
            f"the run's start t0 = {t0:g} s; give it a sample at or before t0"
        )
    for name, items in (("delay", delays), ("plant", plants), ("reference", [reference])):
        for i, item in enumerate(items):
            if item.horizon < t1 * (1.0 - 1e-12):
                raise ValueError(
                    f"{name}[{i}] ({type(item).__name__}) is defined up to t = {item.horizon:g} s, "
                    f"but the run lasts until t1 = {t1:g} s; give it data that cover the run, "
                    f'or beyond = "hold" to hold its last state after t = {item.horizon:g} s'
                )


def _positive_limits(key: str, value: object, shape: tuple[int, ...], entries: str) -> np.ndarray:
    """``value`` broadcast to ``shape`` (a leading row of one spreads to every run), each entry
    ``> 0`` (``inf``: none); refusals name ``key`` and what ``entries`` it takes."""
    if (type(value) is float and value > 0) or (type(value) is int and 0 < value <= 2**53):
        return np.full(shape, float(value))  # one for all, the default
    try:
        array = real_array(key, value)
        if array.ndim == 2 and array.shape[0] == 1 and len(shape) == 2:
            array = array[0]
        # C order whatever was broadcast: another layout would be another engine to compile
        array = np.array(np.broadcast_to(array, shape), order="C")
    except (TypeError, ValueError):
        raise ValueError(
            f"{key} must be a number > 0 or {entries}; inf for none; got {value!r}"
        ) from None
    if np.any(np.isnan(array)) or np.any(array <= 0.0):
        raise ValueError(f"{key} must be > 0 (inf for none) in every entry; got {value!r}")
    return array


def _stack_padded(vectors: list[np.ndarray]) -> np.ndarray:
    width = max(1, max(vector.size for vector in vectors))
    out = np.zeros((len(vectors), width))
    for i, vector in enumerate(vectors):
        out[i, : vector.size] = vector
    return out


def simulate(
    plant: ELPlant | Sequence[ELPlant],
    controller: Controller | Sequence[Controller],
    delay: DelayProfile | Sequence[DelayProfile],
    x0: np.ndarray,
    *,
    reference: Reference,
    t1: float,
    dt: float,
    T_c: float,
    t0: float = 0.0,
    u_init: np.ndarray | None = None,
    record_every: int = 1,
    trajectories: bool = True,
    metrics_from: float | None = None,
    divergence_bound: float = 1e6,
    error_bound: float | Sequence[float] = math.inf,
    input_limits: float | Sequence[float] | np.ndarray = math.inf,
    measurement_noise: MeasurementNoise | Sequence[MeasurementNoise] | None = None,
    packet_loss: PacketLoss | Sequence[PacketLoss] | None = None,
    workers: int | None = None,
    engine: str = "auto",
    progress: bool = False,
) -> SimResult:
    """Simulate ``M(q) q̈ + N(q, q̇) = G(q) τ(t - h(t))`` under a sampled controller.

    The controller runs every ``T_c`` seconds with zero-order hold; the plant is integrated by RK4
    at ``dt``, with each step split where the delayed input switches (see
    :mod:`delaytrack.sim.engine`). The batch size is the largest of the lengths of ``plant``,
    ``controller``, ``delay`` and the first axis of a 2-D ``x0``; each of them has 1 entry
    (shared) or one per batch element.

    Parameters
    ----------
    plant : ELPlant or sequence of ELPlant
        The true plant(s); all of one kind (same terms kernel).
    controller : Controller or sequence of Controller
        Controller(s) of one kind, each with its nominal model.
    delay : DelayProfile or sequence of DelayProfile
        Input delay ``h(t)`` per batch element.
    x0 : array_like, shape (2n,) or (batch, 2n)
        Initial state ``[q(t0), q̇(t0)]``.
    reference : Reference
        Desired trajectory ``q_d(t)`` (:class:`~delaytrack.references.SinusoidalReference`,
        :class:`~delaytrack.references.SplineReference` or a reference of yours).
    t1, dt, T_c : float
        Final time, plant step and controller period, in seconds. ``T_c`` must be an integer
        multiple of ``dt`` and ``t1 - t0`` an integer multiple of ``T_c``. There is no default
        ``dt``: the choice is yours to justify.
    t0 : float
        Initial time.
    u_init : array_like, shape (m,), optional
        Input applied before the first command arrives (zero by default).
    record_every : int
        Record every ``record_every``-th controller tick.
    trajectories : bool
        Record trajectories (every ``record_every``-th tick). With False nothing is recorded and
        memory does not grow with ``t1 - t0``: the result carries only the running metrics
        (:attr:`SimResult.metrics`), which are always accumulated at every tick.
    metrics_from : float, optional
        Start of the running metrics' window, seconds (``t0`` by default), e.g. to skip a
        transient; in ``[t0, t1]``. The window holds the ticks at or after it.
    divergence_bound : float
        A run whose state leaves ``max |x_i| <= divergence_bound`` (or becomes non-finite) stops
        with status ``diverged``; the rest of the batch goes on.
    error_bound : float or sequence of float, shape (n,)
        The "left the path" rule: a run stops with status ``left the path`` at the first
        controller tick where a tracking error ``|e1_j| = |q_d_j - q_j|`` exceeds
        ``error_bound`` (one bound for every coordinate, or one per coordinate; ``inf``
        leaves a coordinate unbounded, the default). Its metrics are NaN, as for a diverged
        run: a loop that wanders this far off the path is unstable, whatever its state's size.
    input_limits : float or array_like, shape (m,) or (batch, m)
        Actuator saturation: each command is applied as ``clip(u_j, -limit_j, limit_j)`` (one
        limit for every input, one per input, or one row per batch element; ``inf``, the
        default, for none; each ``> 0``). The record ``commands`` (and TV) is what the
        controller issued, ``applied`` what the actuators applied. ``u_init`` must lie within
        the limits.
    measurement_noise : MeasurementNoise or sequence of MeasurementNoise, optional
        What the controller reads instead of the true ``q, q̇``: encoder quantisation and
        seeded white noise (:class:`~delaytrack.sim.measurement.MeasurementNoise`; one for the
        batch or one per element). None: the true state. The metrics and ``error_bound`` use
        the true state.
    packet_loss : PacketLoss or sequence of PacketLoss, optional
        Command packets lost on the delayed channel, seeded
        (:class:`~delaytrack.sim.packet_loss.PacketLoss`; one for the batch or one per
        element): the actuators keep the latest command they received. None: none lost.
    workers : int, optional
        Threads that run the batch in parallel (compiled plants only; all cores by default).
        Each run is computed by one thread exactly as it would be alone, so results do not
        depend on ``workers``.
    engine : {"auto", "compiled", "python"}
        ``"auto"`` runs compiled when every kernel is (built-in plants, :class:`CompiledPlant`)
        and as plain Python otherwise, with a :class:`PythonFallbackWarning`. ``"compiled"``
        refuses to fall back. ``"python"`` is the reference path: the same engine, controllers
        and kernels (their ``py_func``; helpers a kernel calls stay compiled) run as plain
        Python, one to two orders of magnitude slower; results agree with the compiled path to
        rounding.
    progress : bool
        Show a progress bar over the batch.

    Returns
    -------
    SimResult

    Notes
    -----
    Ctrl-C interrupts a long compiled run at once (``KeyboardInterrupt``): it computes on a
    thread of its own, which goes on to the run's end in the background, its results thrown
    away (:mod:`delaytrack.sim.interruptible`). A kernel of the user's run as plain Python that
    raises (or a :class:`~delaytrack.plants.CallablePlant` function that returns what it must
    not) ends the run with a ValueError of one line naming it and the time.
    """
    plants = _as_batch("plant", plant, ELPlant)
    controllers = _as_batch("controller", controller, Controller)
    delays = _as_batch("delay", delay, DelayProfile)
    dt = positive_scalar("dt", dt)
    T_c = positive_scalar("T_c", T_c)
    t0 = finite_scalar("t0", t0)
    t1 = finite_scalar("t1", t1)
    if t1 <= t0:
        raise ValueError(f"t1 must be later than t0; got t0 = {t0:g}, t1 = {t1:g}")
    if max(abs(t0), abs(t1)) * np.finfo(float).eps > 1e-3 * dt:
        raise ValueError(
            f"t0 and t1 must be small enough for dt to be resolved: times of size "
            f"{max(abs(t0), abs(t1)):g} s are spaced {max(abs(t0), abs(t1)) * 2.2e-16:.2g} s apart "
            f"in double precision, not far below dt = {dt:g} s; start the run at t0 = 0"
        )
    steps_per_tick = _integer_ratio("T_c", T_c, dt, "dt")
    n_ticks = _integer_ratio("t1 - t0", t1 - t0, T_c, "T_c", scale=max(abs(t0), abs(t1)))
    if n_ticks * steps_per_tick > MAX_STEPS:
        raise ValueError(
            f"t1 - t0 must be at most {MAX_STEPS:.0e} plant steps of dt per run (about a "
            f"minute of computing for one run); got (t1 - t0)/dt = {n_ticks * steps_per_tick:.3g} "
            f"({t1 - t0:g} s at dt = {dt:g} s): shorten the run or raise dt"
        )
    if (
        isinstance(record_every, bool)
        or not isinstance(record_every, int | np.integer)
        or record_every < 1
    ):
        raise ValueError(f"record_every must be a positive integer; got {record_every!r}")
    divergence_bound = positive_scalar("divergence_bound", divergence_bound)
    if not isinstance(reference, Reference):
        raise TypeError(
            f"reference must be a Reference (SinusoidalReference, SplineReference or one of "
            f"yours); got {type(reference).__name__}"
        )

    first_plant, first_controller = plants[0], controllers[0]
    n, m = first_plant.n, first_plant.m
    for i, item in enumerate(plants):
        if type(item) is not type(first_plant) or (item.n, item.m) != (n, m):
            raise ValueError(
                f"plant[{i}] must be a {type(first_plant).__name__} with n = {n}, m = {m}"
            )
        _check_same_kernel(f"plant[{i}]", item, first_plant)
    for i, item in enumerate(controllers):
        if item.step_kernel is not first_controller.step_kernel or type(item.model) is not type(
            first_controller.model
        ):
            raise ValueError(
                f"controller[{i}] must be of the same kind as controller[0] "
                "(with the same model type)"
            )
        if (item.n, item.m) != (n, m):
            raise ValueError(
                f"controller[{i}] has n = {item.n}, m = {item.m}; the plant has n = {n}, m = {m}"
            )
        _check_same_kernel(f"controller[{i}].model", item.model, first_controller.model)
        if item.state_size != first_controller.state_size:
            raise ValueError(
                f"controller[{i}] keeps {item.state_size} state numbers and controller[0] "
                f"{first_controller.state_size}: a batch stacks them, so they must be equal "
                "(a predictor's state is sized by its history: give every one the same history)"
            )
    if reference.n != n:
        raise ValueError(f"reference has n = {reference.n} coordinates; the plant has n = {n}")
    _check_kernel_arguments(first_plant, first_controller, reference)
    trajectory_columns(  # the result's table: names that would share a column are refused
        first_plant.coordinate_names,
        first_plant.coordinate_units,
        n,
        first_plant.input_units,
        m,
        first_controller.reported_state_names,
    )
    error_bounds = _positive_limits(
        "error_bound", error_bound, (n,), f"{n} of them (one per coordinate)"
    )

    states0 = finite_array("x0", x0)
    if states0.ndim == 1:
        states0 = states0[None, :]
    if states0.ndim != 2 or states0.shape[1] != 2 * n:
        raise ValueError(f"x0 must have shape ({2 * n},) or (batch, {2 * n}); got {np.shape(x0)}")
    batch = max(len(plants), len(controllers), len(delays), states0.shape[0])
    plants = _broadcast("plant", plants, batch)
    controllers = _broadcast("controller", controllers, batch)
    delays = _broadcast("delay", delays, batch)
    # A writable C-contiguous copy: numba compiles the engine once per argument type, and a
    # read-only broadcast view would be another type (another two-minute compile).
    states0 = np.array(
        np.broadcast_to(states0, (batch, 2 * n)) if states0.shape[0] == 1 < batch else states0,
        order="C",
    )
    if states0.shape[0] != batch:
        raise ValueError(
            f"x0 has {states0.shape[0]} rows but the batch has {batch}; give 1 or {batch}"
        )
    for plant_b in plants:
        plant_b.check_step(dt)
    for controller_b, delay_b in zip(controllers, delays, strict=True):
        controller_b.check_run(T_c, delay_b.h_max)
    _check_horizons(plants, delays, reference, t0, t1)
    own_delays = [i for i, delay_b in enumerate(delays) if delay_b.engine_kernel != NO_KERNEL]
    delay_kernel = delays[own_delays[0]].engine_kernel if own_delays else NO_KERNEL
    for i in own_delays:
        if delays[i].engine_kernel != delay_kernel:
            raise ValueError(
                f"delay[{i}] has another kernel than delay[{own_delays[0]}]; a batch runs one "
                "delay kernel of yours (split it into one simulate call per kernel)"
            )
    if own_delays:
        check_kernel_arguments(f"delay[{own_delays[0]}]", "delay", delay_kernel.function)
    for component in (first_plant, first_controller.model, first_controller, reference):
        refuse_random_draws(component.engine_kernel)
    refuse_random_draws(delay_kernel)
    if own_delays:
        _refuse_reads_past(delay_kernel, "delay", (t0, delays[own_delays[0]].params), "at t0")
    for delay_b in {id(delay_b): delay_b for delay_b in delays}.values():  # once per profile
        _checked_before_the_run(
            delay_b.engine_kernel,
            "the check of h at every plant step",
            functools.partial(delay_b.check_run, t0, dt, n_ticks * steps_per_tick + 1),
        )
    for i, delay_b in enumerate(delays):
        switches = delay_b.switch_bound(t0, t1, T_c)
        if not switches <= MAX_STEPS:
            raise ValueError(
                f"delay[{i}] ({type(delay_b).__name__}) may switch the applied command up to "
                f"{switches:.3g} times in this run (its t - h(t) sweeps over the controller ticks "
                f"that often), more than {MAX_STEPS:.0e}: every switch splits a plant step. "
                "Lower its rate of change (amplitude x frequency, or the jumps between knots)"
            )
    u_init = np.zeros(m) if u_init is None else np.array(finite_array("u_init", u_init, ndim=1))
    if u_init.shape != (m,):
        raise ValueError(f"u_init must have shape ({m},); got {u_init.shape}")
    limits = _positive_limits(
        "input_limits",
        input_limits,
        (batch, m),
        f"{m} of them (one per input) or a ({batch}, {m}) array (one row per run)",
    )
    noises = _broadcast(
        "measurement_noise",
        _as_batch(
            "measurement_noise",
            _TRUE_STATE if measurement_noise is None else measurement_noise,
            MeasurementNoise,
        ),
        batch,
    )
    losses = _broadcast(
        "packet_loss",
        _as_batch("packet_loss", _NO_LOSS if packet_loss is None else packet_loss, PacketLoss),
        batch,
    )
    if np.any(np.abs(u_init) > limits):
        raise ValueError(
            f"u_init = {u_init.tolist()} lies beyond input_limits: the actuators cannot apply it"
        )

    if np.max(np.abs(states0)) > divergence_bound:
        raise ValueError(
            f"x0 must lie within divergence_bound = {divergence_bound:g}; "
            f"max |x0| = {np.max(np.abs(states0)):g}"
        )
    _check_plant_at_x0(first_plant, states0[0], t0)
    reference_arrays = (real_array("reference.params", reference.params, ndim=1), *np.zeros((3, n)))
    _refuse_reads_past(reference.engine_kernel, "reference", (t0, *reference_arrays), "at t0")
    _check_controller_at_x0(first_controller, states0[0], t0, T_c, delays[0])

    if not isinstance(trajectories, bool | np.bool_):
        raise TypeError(f"trajectories must be True or False; got {trajectories!r}")
    metrics_from_tick = _metrics_from_tick(metrics_from, t0, t1, dt, steps_per_tick, n_ticks)
    workers = _workers(workers)
    # Kernels that write memory of their own (a MuJoCo model's data) get a copy per chunk.
    own_memory = not (first_plant.thread_safe and first_controller.model.thread_safe)

    # Every k-th tick with k beyond the run records tick 0 only, as k = n_ticks + 1 does (which
    # fits the kernel's 64-bit integers).
    every = min(int(record_every), n_ticks + 1)
    records = n_ticks // every + 1 if trajectories else 0
    state_size = first_controller.state_size
    recorded_state = len(first_controller.state_names)
    size = records * (batch * (2 * n + 2 * m + 1 + recorded_state) + 3 * n) * 8
    too_big = (
        f"recording {batch} run(s) x {records} samples needs {size / 2**30:.3g} GiB, more than "
        "{what}; raise record_every, pass trajectories=False (running metrics only), shorten "
        "t1 - t0 or split the batch"
    )
    if size > physical_memory():
        raise ValueError(too_big.format(what="this machine's memory"))
    capacities = np.array([history_capacity(d.h_max, T_c, n_ticks) for d in delays], dtype=np.int64)
    working = (batch * state_size + min(workers, batch) * int(capacities.max()) * m) * 8
    if working > physical_memory():
        raise ValueError(
            f"the runs' working memory needs {working / 2**30:.3g} GiB, more than this machine's "
            f"memory: {state_size} controller-state numbers per run (a predictor keeps its "
            f"history there) and {int(capacities.max())} commands of history per thread (the "
            "delay bound or the run's length, whichever is shorter, over T_c); shorten the "
            "predictor's history, the delay or the run, or split the batch"
        )
    if progress:  # the size of the work before it starts (the library is quiet without)
        scale, unit = (2**30, "GiB") if size >= 2**30 else (2**20, "MiB")
        recorded = f"about {size / scale:.3g} {unit} of trajectories ({records} samples per run)"
        print(
            f"delaytrack: simulating {batch} run(s) of {n_ticks * steps_per_tick} steps "
            f"(dt = {dt:g} s), n = {n} coordinates; "
            + (recorded if trajectories else "metrics only, no trajectories recorded"),
            file=sys.stderr,
            flush=True,
        )
    try:
        states = np.full((batch, records, 2 * n), np.nan)
        commands = np.full((batch, records, m), np.nan)
        applied = np.full((batch, records, m), np.nan)
        delay_records = np.full((batch, records), np.nan)
        controller_states = np.full((batch, records, recorded_state), np.nan)
        reference_rows = np.full((records, 3, n), np.nan)  # q_d, q̇_d, q̈_d, by run 0
    except MemoryError:
        raise ValueError(too_big.format(what="is free")) from None
    sums = np.zeros((batch, accumulator_size(n)))
    status = np.zeros(batch, dtype=np.int64)
    t_stop = np.zeros(batch)

    compiled = first_plant.compiled and first_controller.compiled and reference.compiled
    if engine not in ENGINES:
        raise ValueError(f"engine must be one of {list(ENGINES)}; got {engine!r}")
    if engine == "compiled" and not compiled:
        raise ValueError(
            "engine='compiled' needs compiled kernels; "
            + str(PythonFallbackWarning.describe(first_plant, first_controller, reference))
        )
    if engine == "python":
        compiled = False
    elif not compiled:
        PythonFallbackWarning.warn(first_plant, first_controller, reference)

    # The plant's step, the reference, the controller's step and the delay are called through
    # their address, each compiled for its component alone: one engine serves every combination
    # (delaytrack.sim.native_parts).
    parts: tuple = ()
    helper, waiting = None, []
    part_names = (
        f"{type(first_plant).__name__}'s integrator",
        type(reference).__name__,
        controller_step_name(first_controller),
        f"the delay kernel {delay_kernel.callable_names[0]}"
        if own_delays
        else "the delay profiles",
    )
    if compiled:
        for component in (first_plant, first_controller.model, first_controller, reference):
            refuse_changed_globals(component.engine_kernel)
        refuse_changed_globals(delay_kernel)
        parts = (
            plant_tick_part(first_plant.engine_kernel, delay_kernel, n, m),
            reference_part(reference.engine_kernel, n),
            controller_step_part(
                first_controller.engine_kernel, first_controller.model.engine_kernel, n, m
            ),
            delay_part(delay_kernel),
        )

    def kernels(b: int) -> tuple:
        """Element ``b``'s kernels (:class:`~delaytrack.components.Kernel`): plant, nominal model,
        reference, controller step, delay."""
        return (
            plants[b].engine_kernel,
            controllers[b].model.engine_kernel,
            reference.engine_kernel,
            controllers[b].engine_kernel,
            delay_kernel,
        )

    def handles(b: int, natives: tuple) -> tuple:
        """Element ``b``'s kernels as the engine takes them: as plain Python, or compiled, the
        :class:`~delaytrack._native_call.NativeFunction` objects ``natives`` of ``parts``."""
        if not compiled:
            return tuple(python_kernel(kernel) for kernel in kernels(b))
        plant_step, reference_native, step, delay = natives
        return (plant_step, NO_KERNEL, reference_native, step, delay)

    runs = (
        _stack_padded([p.params for p in plants]),
        _stack_padded([c.model.params for c in controllers]),
        _stack_padded([c.params for c in controllers]),
        # float64, as the compiled parts take them (a user's class may give integers)
        real_array(
            "the controllers' initial states", [c.initial_state() for c in controllers]
        ).reshape(batch, state_size),
        np.array([d.kind for d in delays], dtype=np.int64),
        _stack_padded([d.params for d in delays]),
        states0,
        capacities,
        limits,
        np.array([noise.params(n) for noise in noises]),
        np.array([loss.params() for loss in losses]),
        np.arange(batch) == 0,  # the run that records the reference
    )
    settings = (
        real_array("reference.params", reference.params, ndim=1),
        u_init,
        t0,
        dt,
        steps_per_tick,
        n_ticks,
        every if trajectories else 0,
        divergence_bound,
        error_bounds,
        metrics_from_tick,
        reference_rows,
    )
    outputs = (states, commands, applied, delay_records, controller_states, sums)

    runner = run_batch_compiled if compiled else run_batch

    def chunk_arguments(index: int, natives: tuple) -> tuple:
        chunk = chunks[index]
        part = slice(chunk[0], chunk[-1] + 1)
        chunk_runs = [array[part] for array in runs]
        if in_parallel and own_memory and index > 0:  # this chunk's copies of plants and models
            chunk_runs[0] = _stack_padded([plants[b].for_worker(index).params for b in chunk])
            chunk_runs[1] = _stack_padded(
                [controllers[b].model.for_worker(index).params for b in chunk]
            )
        return (
            handles(int(chunk[0]), natives),
            tuple(chunk_runs),
            settings,
            tuple(array[part] for array in outputs),
            status[part],
            t_stop[part],
        )

    # Compiled kernels are shared by the whole batch and release the GIL: chunks run on
    # `workers` threads. Python callables may differ per element and hold the GIL, so the
    # plain-Python engine runs one element at a time.
    if compiled:
        per_worker = 1 if own_memory else _CHUNKS_PER_WORKER
        pieces = min(batch, workers * per_worker if (progress or workers > 1) else 1)
    else:
        pieces = batch
    chunks = [np.arange(batch)] if pieces == 1 else np.array_split(np.arange(batch), pieces)
    in_parallel = compiled and workers > 1 and len(chunks) > 1
    if compiled:

        @functools.cache
        def engine_signature() -> tuple:
            """The engine's argument types: those of the compiled parts' stand-ins, which have
            an address of 0 and give the types without compiling."""
            probes = tuple(part.probe() for part in parts)
            return tuple(runner.typeof_pyval(item) for item in chunk_arguments(0, probes))

        engine_ready = code_ready(
            runner,
            ("the engine", parts[2].bound),  # one variant for built-in steps, one for the user's
            engine_signature,
        )
        # (name, job, how this process compiles it or loads it from the cache)
        waiting = [
            (name, part.compile_job(), part.native)
            for name, part in zip(part_names, parts, strict=True)
            if not part.ready()
        ]
        if not engine_ready:
            engine_job = CompileJob(runner, engine_signature(), (NO_KERNEL,), _ENGINE_COST)
            waiting.insert(
                0, ("the engine", engine_job, lambda: runner.compile(engine_signature()))
            )
        if waiting:  # a first compile: with the parts the caller will need next, if any
            for name, part in parts_ahead():
                if part not in parts and not part.ready():
                    waiting.append((name, part.compile_job(), _compiled_if_it_can(part)))
    natives: tuple = ()
    interrupted = threading.Event()  # Ctrl-C: the chunks not yet started are left

    def run_chunk(index: int) -> int:
        if interrupted.is_set():
            return 0
        try:
            runner(*chunk_arguments(index, natives))
        except Exception as error:
            yours = [k for k in kernels(0) if not k.built_in and k is not NO_KERNEL]
            if compiled and yours and not type(error).__module__.startswith("numba"):
                # Raised by a kernel of the user's as it ran (ours do not raise there; the
                # engine was compiled before the first chunk).
                raise ValueError(_raised_during_the_run(error, yours)) from error
            raise
        return chunks[index].size

    compiling = "the engine"  # what the message of a compile error names
    try:
        if compiled:  # compiled here, so that a chunk's error is a run's
            # Your functions' own disk caches may hold code older than the kernels' names.
            compile_from_source(kernel for _, job, _ in waiting for kernel in job.kernels)
            # Two or more to compile: a helper process compiles some of them on another core.
            helper, handed = start_helper([job for _, job, _ in waiting])
            if waiting:
                announce_compile([name for name, _, _ in waiting], helped=helper is not None)
            # This process's share first, the engine included, then the helper's (loaded from
            # the cache it wrote, or compiled here if it did not deliver).
            for position, (name, _, make) in enumerate(waiting):
                if position not in handed:
                    compiling = name
                    make()
            if helper is not None:
                helper.wait()
            for name, _, make in waiting:
                compiling = name
                make()
            for name, part in zip(part_names, parts, strict=True):
                compiling = name
                natives += (part.native(),)
            compiling = "the engine"  # loaded from the cache at the first chunk's call
        bar_context = (
            tqdm(total=batch, desc="simulate", unit="run")
            if progress
            else contextlib.nullcontext(_NO_PROGRESS_BAR)  # a disabled tqdm costs ~0.1 ms
        )
        with bar_context as bar:  # closed here, on a new line, when Ctrl-C leaves the run

            def run_chunks() -> None:
                if in_parallel:
                    with ThreadPoolExecutor(max_workers=workers) as pool:
                        for done in pool.map(run_chunk, range(len(chunks))):
                            bar.update(done)
                else:
                    for index in range(len(chunks)):
                        bar.update(run_chunk(index))

            if compiled:  # compiled code holds off Ctrl-C until it returns
                try:
                    run_interruptibly(run_chunks, size=batch * n_ticks * steps_per_tick * n)
                except KeyboardInterrupt:
                    interrupted.set()
                    raise
            else:
                run_chunks()
    except Exception as error:
        if compiled and type(error).__module__.startswith("numba"):
            # numba could not compile a kernel of the user's: their error, in one line.
            raise ValueError(
                f"numba could not compile {compiling} for the kernels "
                f"{[k.key for k in kernels(0)]}: {_numba_cause(error)}"
            ) from None
        raise
    finally:
        if helper is not None:
            helper.stop()

    times = t0 + (np.arange(records) * every * steps_per_tick) * dt
    for b in np.flatnonzero(status != 0):
        after = times > t_stop[b]
        for array in (states, commands, applied, delay_records, controller_states):
            array[b, after] = np.nan
    # Rows run 0 did not record (it stopped before them), from the kernel the engine ran.
    unrecorded = np.flatnonzero(np.isnan(reference_rows).any(axis=(1, 2)))
    if unrecorded.size and compiled:
        reference_rows[unrecorded] = np.stack(reference.evaluate(times[unrecorded]), axis=1)
    elif unrecorded.size:
        reference_kernel = handles(0, ())[2]
        for row in unrecorded:
            call_reference(reference_kernel, float(times[row]), settings[0], *reference_rows[row])
    record: dict[str, Any] = {
        "t0": t0,
        "t1": t1,
        "dt": dt,
        "T_c": T_c,
        "record_every": int(record_every),
        "trajectories": bool(trajectories),
        "metrics_from": t0 + metrics_from_tick * steps_per_tick * dt,
        "divergence_bound": divergence_bound,
        "error_bound": error_bounds.tolist(),
        "input_limits": limits[0].tolist() if np.all(limits == limits[0]) else limits.tolist(),
        "measurement_noise": None
        if measurement_noise is None
        else [noise.to_spec() for noise in noises],
        "packet_loss": None if packet_loss is None else [loss.to_spec() for loss in losses],
        "compiled": compiled,
        "plant": [p.to_spec() for p in plants]
        if len(set(map(id, plants))) > 1
        else plants[0].to_spec(),
        "controller": controllers[0].to_spec()
        if len(set(map(id, controllers))) == 1
        else [c.to_spec() for c in controllers],
        "model": controllers[0].model.to_spec(),
        "delays": [d.to_spec() for d in delays],
        "reference": reference.to_spec(),
    }
    return SimResult(
        t=times,
        x=states,
        reference=reference_rows,
        commands=commands,
        applied=applied,
        h=delay_records,
        controller_state=controller_states,
        controller_state_names=first_controller.state_names,
        reported_state_names=first_controller.reported_state_names,
        status=status,
        t_stop=t_stop,
        metrics=finish_metrics(sums, status == 0),
        settings=record,
        coordinate_names=first_plant.coordinate_names,
        coordinate_units=first_plant.coordinate_units,
        input_units=first_plant.input_units,
    )
