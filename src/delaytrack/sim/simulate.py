"""``simulate``: the one verb that runs closed loops.

It runs in four stages, each a module of its own: prepare (:mod:`delaytrack.sim._plan`: check,
spread over the batch, budget the memory), build (:mod:`delaytrack.sim._build`: the engine,
compiled or plain Python; :mod:`delaytrack._compile`: compile it and its parts), execute
(:mod:`delaytrack.sim._execute`: chunks on threads) and collect (:mod:`delaytrack.sim._collect`:
the :class:`~delaytrack.sim.result.SimResult`).
"""

from __future__ import annotations

import dataclasses
import math
import time
import warnings
from collections.abc import Sequence

import numpy as np
from numba.core import event

from delaytrack._compile import Interpreting, compile_engine, interpret
from delaytrack.controllers.base import Controller
from delaytrack.delays.base import DelayProfile
from delaytrack.plants.base import ELPlant
from delaytrack.references import Reference
from delaytrack.sim import _arrays
from delaytrack.sim._build import Build, build
from delaytrack.sim._collect import collect
from delaytrack.sim._execute import Chunks, cut, execute
from delaytrack.sim._machine import available_cores, physical_memory
from delaytrack.sim._plan import MAX_STEPS, Plan, announce, prepare
from delaytrack.sim.certified_bound import beyond_certified_bound, caller_states_the_delays
from delaytrack.sim.measurement import MeasurementNoise
from delaytrack.sim.no_command import no_command_arrives
from delaytrack.sim.packet_loss import PacketLoss
from delaytrack.sim.result import SimResult

__all__ = ["MAX_STEPS", "available_cores", "physical_memory", "simulate"]


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
        controller issued, ``applied`` (and the running metric ``tv_applied``) what the
        actuators applied. ``u_init`` must lie within the limits.
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
        and as plain Python otherwise, with a :class:`PythonFallbackWarning`; a short first run
        of a combination that is not compiled yet runs as plain Python while that is quicker
        than compiling it, and says so on standard error (``DELAYTRACK_INTERPRET_FIRST=0``
        turns that off; the result's ``settings["compiled"]`` says which engine ran).
        ``"compiled"`` refuses to fall back and compiles at once. ``"python"`` is the reference
        path: the same engine, controllers and kernels (their ``py_func``; helpers a kernel
        calls stay compiled) run as plain Python, one to two orders of magnitude slower;
        results agree with the compiled path to rounding.
    progress : bool
        Show a progress bar over the batch.

    Returns
    -------
    SimResult

    Warns
    -----
    BeyondCertifiedBoundWarning
        When a run's controller is AROLC and the largest delay of the run exceeds its certified
        bound ``h_m`` (Theorem 1 with the run's ``K1``, ``K2``, ``Q`` and the paper's ``β = 1``,
        ``r = 1.1``; :mod:`delaytrack.sim.certified_bound`). Exceeding it ends the guarantee,
        which does not by itself mean instability.
    NoCommandArrivesWarning
        When a run's delay is never shorter than the run (:attr:`DelayProfile.h_min` at least
        ``t1 - t0``): no command reaches the plant, which receives ``u_init`` throughout
        (:mod:`delaytrack.sim.no_command`).

    Notes
    -----
    Ctrl-C interrupts a long compiled run at once (``KeyboardInterrupt``): it computes on a
    thread of its own, which goes on to the run's end in the background, its results thrown
    away (:mod:`delaytrack.sim.interruptible`). A kernel of the user's run as plain Python that
    raises (or a :class:`~delaytrack.plants.CallablePlant` function that returns what it must
    not) ends the run with a ValueError of one line naming it and the time.
    """
    plan = prepare(
        plant,
        controller,
        delay,
        x0,
        reference=reference,
        t1=t1,
        dt=dt,
        T_c=T_c,
        t0=t0,
        u_init=u_init,
        record_every=record_every,
        trajectories=trajectories,
        metrics_from=metrics_from,
        divergence_bound=divergence_bound,
        error_bound=error_bound,
        input_limits=input_limits,
        measurement_noise=measurement_noise,
        packet_loss=packet_loss,
        workers=workers,
    )
    if progress:  # the size of the work before it starts (the library is quiet without)
        announce(plan)
    built = build(plan, engine)
    chunks = _chunks(built, progress)
    # A short first run of a combination not compiled yet: as plain Python, while that is quicker
    interpreting = interpret(built, chunks.first) if engine == "auto" and built.compiled else None
    result = _interpreted(chunks, interpreting, progress) if interpreting else None
    if result is None:
        if interpreting:  # abandoned, or it raised: compiled, in arrays it has not written
            chunks = _chunks(built, progress)
        natives = compile_engine(built, chunks.first) if built.compiled else ()
        execute(chunks, natives, progress)
        result = collect(chunks)
    _warn_about_the_delays(plan, result)
    return result


def _warn_about_the_delays(plan: Plan, result: SimResult) -> None:
    """Warn at the line that called :func:`simulate` of runs beyond their certified bound and
    of runs no command reaches, unless the caller states the runs' delays itself
    (:func:`~delaytrack.sim.certified_bound.stated_by_the_caller`)."""
    if caller_states_the_delays():
        return
    for warning in (
        beyond_certified_bound(plan.controllers, plan.delays, result),
        no_command_arrives(plan.delays, plan.t0, plan.t1),
    ):
        if warning is not None:
            warnings.warn(warning, stacklevel=3)  # 1: here, 2: simulate, 3: its caller


def _chunks(built: Build, progress: bool) -> Chunks:
    """The batch of ``built`` in chunks, with the arrays the engine fills."""
    plan = built.plan
    records, reference_record = _arrays.records(plan)
    runs, settings = _arrays.runs(plan), _arrays.settings(plan, reference_record)
    return cut(built, runs, settings, records, progress)


def _interpreted(chunks: Chunks, interpreting: Interpreting, progress: bool) -> SimResult | None:
    """The compiled engine's ``chunks`` computed by the plain-Python engine instead, in the same
    arrays, within the time ``interpreting`` allows (:mod:`delaytrack._compile.interpret_first`).
    None when it ran out of time or raised: the compiled engine then runs it, and reports what
    it finds as it would have without interpreting."""
    plan = chunks.build.plan
    started = time.perf_counter()
    python = dataclasses.replace(
        chunks.build, compiled=False, deadline=started + interpreting.seconds
    )
    interpreted = cut(python, chunks.runs, chunks.settings, chunks.records, progress)
    compiling: list[float] = []  # numba compiling the user's kernels' own helpers, once
    try:
        with np.errstate(all="ignore"), event.install_timer("numba:compile", compiling.append):
            execute(interpreted, (), progress)  # as compiled: non-finite values, no warnings
    except BaseException as error:
        interpreting.done(time.perf_counter() - started, sum(compiling), None)
        if isinstance(error, Exception):  # out of time, or plain Python raised: compiled
            return None
        raise  # Ctrl-C
    steps_run = np.rint((interpreted.t_stop - plan.t0) / plan.dt).sum()
    interpreting.done(time.perf_counter() - started, sum(compiling), int(steps_run))
    return collect(interpreted)
