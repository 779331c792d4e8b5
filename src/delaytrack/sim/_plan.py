"""Prepare a ``simulate`` call: check every argument, spread it over the batch and budget the
memory, into a frozen :class:`Plan`; nothing is allocated or compiled yet."""

from __future__ import annotations

import functools
import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TypeVar

import numpy as np

from delaytrack._compile.guards import refuse_random_draws
from delaytrack._result_columns import trajectory_columns
from delaytrack._validation import (
    finite_array,
    finite_scalar,
    integer_multiple,
    positive_scalar,
    real_array,
)
from delaytrack._words import count_text, counted, shown_number
from delaytrack.components import Kernel
from delaytrack.controllers.base import Controller
from delaytrack.delays._kernel import NO_KERNEL
from delaytrack.delays.base import DelayProfile
from delaytrack.kernel_arguments import check_kernel_arguments
from delaytrack.plants.base import ELPlant
from delaytrack.references import Reference
from delaytrack.sim._broadcast import as_batch, broadcast, positive_limits
from delaytrack.sim._kernel_checks import (
    check_controller_at_x0,
    check_kernels_take_their_arguments,
    check_plant_at_x0,
    check_reduced_start,
    checked_before_the_run,
    refuse_reads_past,
)
from delaytrack.sim._machine import available_cores, physical_memory, workers_problem
from delaytrack.sim.history import history_capacity, tick_time
from delaytrack.sim.measurement import MeasurementNoise
from delaytrack.sim.packet_loss import PacketLoss

__all__ = ["MAX_STEPS", "Plan", "announce", "prepare"]

#: Most RK4 steps of one run, ``(t1 - t0) / dt``: at a few million steps a second, minutes of
#: computing. A longer run is refused before anything is allocated.
MAX_STEPS = 10**8

#: What the controller reads and loses when no noise and no loss are given.
_TRUE_STATE = MeasurementNoise()
_NO_LOSS = PacketLoss()
#: A per-run setting (measurement noise or packet loss).
_Given = TypeVar("_Given", MeasurementNoise, PacketLoss)


@dataclass(frozen=True)
class Plan:
    """A ``simulate`` call checked and spread over its batch (:func:`prepare`).

    Every sequence has one entry per batch element; the arguments of
    :func:`~delaytrack.sim.simulate` keep their names and meaning.
    """

    plants: tuple[ELPlant, ...]
    controllers: tuple[Controller, ...]
    delays: tuple[DelayProfile, ...]
    reference: Reference
    #: ``(batch, 2n)``, C order.
    x0: np.ndarray
    t0: float
    t1: float
    dt: float
    T_c: float
    #: Plant steps per controller tick, and controller ticks of the run.
    steps_per_tick: int
    n_ticks: int
    record_every: int
    #: Every how many ticks a row is recorded (``record_every``, at most ``n_ticks + 1``).
    every: int
    #: Rows recorded per run (0 without trajectories).
    records: int
    trajectories: bool
    #: The first tick the running metrics count.
    metrics_from_tick: int
    divergence_bound: float
    #: ``(n,)``.
    error_bound: np.ndarray
    #: ``(batch, m)``.
    input_limits: np.ndarray
    #: ``(m,)``.
    u_init: np.ndarray
    measurement_noise: tuple[MeasurementNoise, ...]
    packet_loss: tuple[PacketLoss, ...]
    #: Whether noise or loss were given (the record says None otherwise).
    noise_given: bool
    loss_given: bool
    #: The batch's delay kernel of the user's (``NO_KERNEL`` when none), and the elements
    #: whose profile is one.
    delay_kernel: Kernel
    own_delays: tuple[int, ...]
    #: Commands of history per run.
    capacities: np.ndarray
    workers: int
    #: Whether the plant or the model write memory of their own (a MuJoCo model's data): a
    #: chunk of runs on another thread needs copies of them.
    own_memory: bool
    #: Bytes of the recorded trajectories.
    recorded_bytes: int

    @property
    def batch(self) -> int:
        """Runs in the batch."""
        return len(self.plants)

    @property
    def n(self) -> int:
        """Coordinates of the plant."""
        return self.plants[0].n

    @property
    def m(self) -> int:
        """Inputs of the plant."""
        return self.plants[0].m

    def too_big(self, what: str) -> ValueError:
        """The refusal of trajectories that need more memory than ``what``."""
        return ValueError(
            f"recording {self.batch} run(s) x {self.records} samples needs "
            f"{self.recorded_bytes / 2**30:.3g} GiB, more than {what}; raise record_every, "
            "pass trajectories=False (running metrics only), shorten t1 - t0 or split the batch"
        )


def prepare(
    plant: ELPlant | Sequence[ELPlant],
    controller: Controller | Sequence[Controller],
    delay: DelayProfile | Sequence[DelayProfile],
    x0: np.ndarray,
    *,
    reference: Reference,
    t1: float,
    dt: float,
    T_c: float,
    t0: float,
    u_init: np.ndarray | None,
    record_every: int,
    trajectories: bool,
    metrics_from: float | None,
    divergence_bound: float,
    error_bound: float | Sequence[float],
    input_limits: float | Sequence[float] | np.ndarray,
    measurement_noise: MeasurementNoise | Sequence[MeasurementNoise] | None,
    packet_loss: PacketLoss | Sequence[PacketLoss] | None,
    workers: int | None,
) -> Plan:
    """The arguments of :func:`~delaytrack.sim.simulate` checked, in the order it documents
    its refusals, and spread over the batch; the memory the run needs checked against the
    machine's."""
    plants, controllers, delays = _batches(plant, controller, delay)
    t0, t1, dt, T_c, steps_per_tick, n_ticks = _times(t0, t1, dt, T_c)
    _check_record_every(record_every)
    divergence_bound = positive_scalar("divergence_bound", divergence_bound)
    _check_reference(reference)
    _check_one_kind(plants, controllers, reference)
    error_bounds = _error_bounds(error_bound, plants[0].n)
    plants, controllers, delays, states0 = _spread(plants, controllers, delays, x0)
    _check_fit_to_run(plants, controllers, delays, reference, t0, t1, dt, T_c)
    delay_kernel, own_delays = _delay_kernel(delays)
    _refuse_random_draws(plants[0], controllers[0], reference, delay_kernel)
    _check_delays(delays, own_delays, t0, t1, dt, T_c, n_ticks * steps_per_tick + 1)
    u_init, limits, noises, losses = _per_run_arrays(
        u_init, input_limits, measurement_noise, packet_loss, len(plants), plants[0].m
    )
    _check_start(plants, controllers[0], delays[0], reference, states0, divergence_bound, t0, T_c)
    every, records = _recording(record_every, trajectories, n_ticks)
    plan = Plan(
        plants=tuple(plants),
        controllers=tuple(controllers),
        delays=tuple(delays),
        reference=reference,
        x0=states0,
        t0=t0,
        t1=t1,
        dt=dt,
        T_c=T_c,
        steps_per_tick=steps_per_tick,
        n_ticks=n_ticks,
        record_every=int(record_every),
        every=every,
        records=records,
        trajectories=bool(trajectories),
        metrics_from_tick=_metrics_from_tick(metrics_from, t0, t1, dt, steps_per_tick, n_ticks),
        divergence_bound=divergence_bound,
        error_bound=error_bounds,
        input_limits=limits,
        u_init=u_init,
        measurement_noise=tuple(noises),
        packet_loss=tuple(losses),
        noise_given=measurement_noise is not None,
        loss_given=packet_loss is not None,
        delay_kernel=delay_kernel,
        own_delays=tuple(own_delays),
        capacities=_capacities(delays, T_c, n_ticks),
        workers=_workers(workers),
        own_memory=not (plants[0].thread_safe and controllers[0].model.thread_safe),
        recorded_bytes=_recorded_bytes(records, plants, controllers[0]),
    )
    _check_memory(plan)
    return plan


def announce(plan: Plan) -> None:
    """One line on standard error with the size of the work before it starts."""
    size = plan.recorded_bytes
    scale, unit = (2**30, "GiB") if size >= 2**30 else (2**20, "MiB")
    recorded = (
        f"about {size / scale:.3g} {unit} of trajectories ({counted(plan.records, 'sample')} "
        "per run"
        + ("; record_every is beyond the run: its start only" if plan.records == 1 else "")
        + ")"
    )
    print(
        f"delaytrack: simulating {counted(plan.batch, 'run')} of "
        f"{plan.n_ticks * plan.steps_per_tick} steps (dt = {plan.dt:g} s), n = "
        f"{counted(plan.n, 'coordinate')}; "
        + (recorded if plan.trajectories else "metrics only, no trajectories recorded"),
        file=sys.stderr,
        flush=True,
    )


def _batches(
    plant: ELPlant | Sequence[ELPlant],
    controller: Controller | Sequence[Controller],
    delay: DelayProfile | Sequence[DelayProfile],
) -> tuple[list[ELPlant], list[Controller], list[DelayProfile]]:
    """The plants, controllers and delays as lists, each of its kind."""
    return (
        as_batch("plant", plant, ELPlant),
        as_batch("controller", controller, Controller),
        as_batch("delay", delay, DelayProfile),
    )


def _times(
    t0: float, t1: float, dt: float, T_c: float
) -> tuple[float, float, float, float, int, int]:
    """``(t0, t1, dt, T_c, steps_per_tick, n_ticks)``: the times checked, ``T_c`` a multiple of
    ``dt`` and ``t1 - t0`` of ``T_c``, within :data:`MAX_STEPS`."""
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
    steps_per_tick = _integer_ratio(
        "T_c", T_c, dt, "dt", f"T_c = {shown_number(T_c)}, dt = {shown_number(dt)}"
    )
    n_ticks = _integer_ratio(
        "t1 - t0",
        t1 - t0,
        T_c,
        "T_c",
        f"t1 = {shown_number(t1)}, t0 = {shown_number(t0)}, T_c = {shown_number(T_c)}",
        scale=max(abs(t0), abs(t1)),
    )
    if n_ticks * steps_per_tick > MAX_STEPS:
        raise ValueError(
            f"t1 - t0 must be at most {MAX_STEPS:.0e} plant steps of dt per run (about a "
            f"minute of computing for one run); got (t1 - t0)/dt = {n_ticks * steps_per_tick:.3g} "
            f"({t1 - t0:g} s at dt = {dt:g} s): shorten the run or raise dt"
        )
    return t0, t1, dt, T_c, steps_per_tick, n_ticks


def _check_record_every(record_every: int) -> None:
    """``record_every`` is a positive integer."""
    if (
        isinstance(record_every, bool)
        or not isinstance(record_every, int | np.integer)
        or record_every < 1
    ):
        raise ValueError(f"record_every must be a positive integer; got {record_every!r}")


def _check_reference(reference: Reference) -> None:
    """``reference`` is a :class:`~delaytrack.references.Reference`."""
    if not isinstance(reference, Reference):
        raise TypeError(
            f"reference must be a Reference (SinusoidalReference, SplineReference or one of "
            f"yours); got {type(reference).__name__}"
        )


def _check_one_kind(
    plants: list[ELPlant], controllers: list[Controller], reference: Reference
) -> None:
    """A batch's plants, controllers and reference are of one kind and size, with kernels that
    take the arguments the engine passes, and names that make one table."""
    first_plant, first_controller = plants[0], controllers[0]
    n, m = first_plant.n, first_plant.m
    for i, plant in enumerate(plants):
        if type(plant) is not type(first_plant) or (plant.n, plant.m) != (n, m):
            raise ValueError(
                f"plant[{i}] must be a {type(first_plant).__name__} with n = {n}, m = {m}"
            )
        _check_same_kernel(f"plant[{i}]", plant, first_plant)
    for i, controller in enumerate(controllers):
        if controller.step_kernel is not first_controller.step_kernel or type(
            controller.model
        ) is not type(first_controller.model):
            raise ValueError(
                f"controller[{i}] must be of the same kind as controller[0] "
                "(with the same model type)"
            )
        if (controller.n, controller.m) != (n, m):
            raise ValueError(
                f"controller[{i}] has n = {controller.n}, m = {controller.m}; the plant has "
                f"n = {n}, m = {m}"
            )
        _check_same_kernel(f"controller[{i}].model", controller.model, first_controller.model)
        if controller.state_size != first_controller.state_size:
            raise ValueError(
                f"controller[{i}] keeps {controller.state_size} state numbers and controller[0] "
                f"{first_controller.state_size}: a batch stacks them, so they must be equal "
                "(a predictor's state is sized by its history: give every one the same history)"
            )
    if reference.n != n:
        raise ValueError(f"reference has n = {reference.n} coordinates; the plant has n = {n}")
    check_kernels_take_their_arguments(first_plant, first_controller, reference)
    trajectory_columns(  # the result's table: names that would share a column are refused
        first_plant.coordinate_names,
        first_plant.coordinate_units,
        n,
        first_plant.input_units,
        m,
        first_controller.reported_state_names,
    )


def _error_bounds(error_bound: float | Sequence[float], n: int) -> np.ndarray:
    """``error_bound`` checked, one per coordinate ``(n,)``."""
    return positive_limits("error_bound", error_bound, (n,), f"{n} of them (one per coordinate)")


def _spread(
    plants: list[ELPlant],
    controllers: list[Controller],
    delays: list[DelayProfile],
    x0: np.ndarray,
) -> tuple[list[ELPlant], list[Controller], list[DelayProfile], np.ndarray]:
    """The plants, controllers, delays and rows of ``x0`` (checked) spread to the batch: the
    longest of them."""
    states0 = _initial_states(x0, plants[0].n)
    batch = max(len(plants), len(controllers), len(delays), states0.shape[0])
    return (
        broadcast("plant", plants, batch),
        broadcast("controller", controllers, batch),
        broadcast("delay", delays, batch),
        _initial_states_of_batch(states0, batch),
    )


def _initial_states(x0: np.ndarray, n: int) -> np.ndarray:
    """``x0`` checked, as rows ``(rows, 2n)``."""
    states0 = finite_array("x0", x0)
    if states0.ndim == 1:
        states0 = states0[None, :]
    if states0.ndim != 2 or states0.shape[1] != 2 * n:
        raise ValueError(f"x0 must have shape ({2 * n},) or (batch, {2 * n}); got {np.shape(x0)}")
    return states0


def _initial_states_of_batch(states0: np.ndarray, batch: int) -> np.ndarray:
    """The rows of ``x0`` spread to ``batch`` rows."""
    # A writable C-contiguous copy: numba compiles the engine once per argument type, and a
    # read-only broadcast view would be another type (another two-minute compile).
    states0 = np.array(
        np.broadcast_to(states0, (batch, states0.shape[1]))
        if states0.shape[0] == 1 < batch
        else states0,
        order="C",
    )
    if states0.shape[0] != batch:
        raise ValueError(
            f"x0 has {states0.shape[0]} rows but the batch has {batch}; give "
            + ("one row" if batch == 1 else f"1 row (for every run) or {batch}")
        )
    return states0


def _check_fit_to_run(
    plants: list[ELPlant],
    controllers: list[Controller],
    delays: list[DelayProfile],
    reference: Reference,
    t0: float,
    t1: float,
    dt: float,
    T_c: float,
) -> None:
    """Every plant takes steps of ``dt``, every controller ticks of ``T_c`` under its delay's
    bound, and every component's data cover ``[t0, t1]``."""
    for plant in plants:
        plant.check_step(dt)
    for controller, delay in zip(controllers, delays, strict=True):
        controller.check_run(T_c, delay.h_max)
    _check_horizons(plants, delays, reference, t0, t1)


def _delay_kernel(delays: list[DelayProfile]) -> tuple[Kernel, list[int]]:
    """The batch's one delay kernel of the user's (``NO_KERNEL`` when none) and the elements
    whose profile is one."""
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
    return delay_kernel, own_delays


def _refuse_random_draws(
    plant: ELPlant, controller: Controller, reference: Reference, delay_kernel: Kernel
) -> None:
    """No kernel of the batch draws random numbers."""
    for component in (plant, controller.model, controller, reference):
        refuse_random_draws(component.engine_kernel)
    refuse_random_draws(delay_kernel)


def _check_delays(
    delays: list[DelayProfile],
    own_delays: list[int],
    t0: float,
    t1: float,
    dt: float,
    T_c: float,
    steps: int,
) -> None:
    """The delay profiles over the run's ``steps`` plant steps: a kernel of the user's reads
    nothing past its arrays, ``h`` is valid at every step, and the applied command switches at
    most :data:`MAX_STEPS` times."""
    if own_delays:
        first = delays[own_delays[0]]
        refuse_reads_past(first.engine_kernel, "delay", (t0, first.params), "at t0")
    for delay_b in {id(delay_b): delay_b for delay_b in delays}.values():  # once per profile
        checked_before_the_run(
            delay_b.engine_kernel,
            "the check of h at every plant step",
            functools.partial(delay_b.check_run, t0, dt, steps),
        )
    for i, delay_b in enumerate(delays):
        switches = delay_b.switch_bound(t0, t1, T_c)
        if not switches <= MAX_STEPS:
            ticks = (t1 - t0) / T_c  # each tick's command comes into force once
            advice = (
                f"The run's {count_text(ticks)} controller ticks alone are most of them: shorten "
                "the run or lengthen T_c"
                if ticks >= switches / 2
                else "Lower its rate of change (amplitude x frequency, or the jumps between knots)"
            )
            raise ValueError(
                f"delay[{i}] ({type(delay_b).__name__}) may switch the applied command up to "
                f"{count_text(switches)} times in this run (its t - h(t) sweeps over the "
                f"controller ticks that often), more than {MAX_STEPS:,.0f}: every switch splits a "
                "plant step. "
                f"{advice}"
            )


def _per_run_arrays(
    u_init: np.ndarray | None,
    input_limits: float | Sequence[float] | np.ndarray,
    measurement_noise: MeasurementNoise | Sequence[MeasurementNoise] | None,
    packet_loss: PacketLoss | Sequence[PacketLoss] | None,
    batch: int,
    m: int,
) -> tuple[np.ndarray, np.ndarray, list[MeasurementNoise], list[PacketLoss]]:
    """``(u_init, input_limits, measurement_noise, packet_loss)`` checked, the last three
    spread over the batch, with ``u_init`` within every run's limits."""
    u_init = np.zeros(m) if u_init is None else np.array(finite_array("u_init", u_init, ndim=1))
    if u_init.shape != (m,):
        raise ValueError(f"u_init must have shape ({m},); got {u_init.shape}")
    limits = positive_limits(
        "input_limits",
        input_limits,
        (batch, m),
        f"{m} of them (one per input) or a ({batch}, {m}) array (one row per run)",
    )
    noises = _per_run("measurement_noise", measurement_noise, _TRUE_STATE, batch)
    losses = _per_run("packet_loss", packet_loss, _NO_LOSS, batch)
    if np.any(np.abs(u_init) > limits):
        raise ValueError(
            f"u_init = {u_init.tolist()} lies beyond input_limits: the actuators cannot apply it"
        )
    return u_init, limits, noises, losses


def _per_run(
    name: str, value: _Given | Sequence[_Given] | None, default: _Given, batch: int
) -> list[_Given]:
    """``value`` (``default`` when None), one of the kind of ``default``, spread over the batch."""
    return broadcast(
        name, as_batch(name, default if value is None else value, type(default)), batch
    )


def _check_start(
    plants: list[ELPlant],
    controller: Controller,
    delay: DelayProfile,
    reference: Reference,
    states0: np.ndarray,
    divergence_bound: float,
    t0: float,
    T_c: float,
) -> None:
    """The run's start: ``x0`` within ``divergence_bound``, the kernels of the user's tried
    there (:mod:`delaytrack.sim._kernel_checks`), and the plants' reduced coordinates at it."""
    if np.max(np.abs(states0)) > divergence_bound:
        raise ValueError(
            f"x0 must lie within divergence_bound = {divergence_bound:g}; "
            f"max |x0| = {np.max(np.abs(states0)):g}"
        )
    check_plant_at_x0(plants[0], states0[0], t0)
    reference_arrays = (
        real_array("reference.params", reference.params, ndim=1),
        *np.zeros((3, reference.n)),
    )
    refuse_reads_past(reference.engine_kernel, "reference", (t0, *reference_arrays), "at t0")
    check_controller_at_x0(controller, states0[0], t0, T_c, delay)
    check_reduced_start(plants, states0)


def _recording(record_every: int, trajectories: bool, n_ticks: int) -> tuple[int, int]:
    """``(every, records)``: every how many ticks a row is recorded, and the rows of a run
    (0 without ``trajectories``, which must be True or False)."""
    if not isinstance(trajectories, bool | np.bool_):
        raise TypeError(f"trajectories must be True or False; got {trajectories!r}")
    # Every k-th tick with k beyond the run records tick 0 only, as k = n_ticks + 1 does (which
    # fits the kernel's 64-bit integers).
    every = min(int(record_every), n_ticks + 1)
    return every, n_ticks // every + 1 if trajectories else 0


def _capacities(delays: list[DelayProfile], T_c: float, n_ticks: int) -> np.ndarray:
    """Commands of history each run keeps."""
    return np.array([history_capacity(d.h_max, T_c, n_ticks) for d in delays], dtype=np.int64)


def _recorded_bytes(records: int, plants: list[ELPlant], controller: Controller) -> int:
    """Bytes of the batch's recorded trajectories: ``records`` rows of every run's state,
    command, applied command, delay and controller state, and of the reference."""
    batch, n, m = len(plants), plants[0].n, plants[0].m
    recorded_state = len(controller.state_names)
    return records * (batch * (2 * n + 2 * m + 1 + recorded_state) + 3 * n) * 8


def _check_memory(plan: Plan) -> None:
    """Refuse a run whose records or working memory exceed this machine's memory, before
    anything is allocated."""
    if plan.recorded_bytes > physical_memory():
        raise plan.too_big("this machine's memory")
    state_size = plan.controllers[0].state_size
    history = int(plan.capacities.max())
    working = (plan.batch * state_size + min(plan.workers, plan.batch) * history * plan.m) * 8
    if working > physical_memory():
        raise ValueError(
            f"the runs' working memory needs {working / 2**30:.3g} GiB, more than this machine's "
            f"memory: {state_size} controller-state numbers per run (a predictor keeps its "
            f"history there) and {history} commands of history per thread (the "
            "delay bound or the run's length, whichever is shorter, over T_c); shorten the "
            "predictor's history, the delay or the run, or split the batch"
        )


def _integer_ratio(
    name: str, value: float, unit: float, what: str, given: str, scale: float = 0.0
) -> int:
    """``value / unit`` as a positive integer, or a ValueError naming ``name``, the values
    ``given`` (their text) and the ratio."""
    count = integer_multiple(value, unit, scale=scale)
    if count is None:
        ratio = name if name.isidentifier() else f"({name})"
        raise ValueError(
            f"{name} must be a positive integer multiple of {what}; got {given} "
            f"({ratio}/{what} = {value / unit:.12g})"
        )
    return count


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


def _workers(workers: int | None) -> int:
    """Thread count: ``workers`` checked (:func:`~delaytrack.sim._machine.workers_problem`), or
    the cores this process may use."""
    problem = workers_problem(workers)
    if problem is not None:
        raise ValueError(f"workers {problem}")
    return available_cores() if workers is None else int(workers)


def _check_horizons(
    plants: list[ELPlant], delays: list[DelayProfile], reference: Reference, t0: float, t1: float
) -> None:
    """Refuse a run that starts before, or lasts longer than, the time its plant's, delay's or
    reference's data cover (never extend them silently)."""
    starts: list[tuple[str, DelayProfile | Reference]] = [("reference", reference)]
    starts += [(f"delay[{i}]", delay) for i, delay in enumerate(delays)]
    for name, timed in starts:
        if timed.start > t0:
            raise ValueError(
                f"{name} ({type(timed).__name__}) starts at t = {timed.start:g} s, after the "
                f"run's start t0 = {t0:g} s; give it a sample at or before t0"
            )
    components: tuple[tuple[str, Sequence[DelayProfile | ELPlant | Reference]], ...] = (
        ("delay", delays),
        ("plant", plants),
        ("reference", [reference]),
    )
    for name, items in components:
        for i, item in enumerate(items):
            if item.horizon < t1 * (1.0 - 1e-12):
                raise ValueError(
                    f"{name}[{i}] ({type(item).__name__}) is defined up to t = {item.horizon:g} s, "
                    f"but the run lasts until t1 = {t1:g} s; give it data that cover the run, "
                    f'or beyond = "hold" to hold its last state after t = {item.horizon:g} s'
                )
