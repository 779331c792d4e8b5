"""The fixed-step closed loop: sampled controller, delayed zero-order hold, RK4 plant.

One run (:func:`run_closed_loop`) proceeds tick by tick. At tick ``k`` (time ``t_k``) the
controller reads ``x(t_k)`` and issues command ``k`` into the history; the plant is then integrated
with RK4 over the ``steps_per_tick`` steps of length ``dt`` up to ``t_{k+1}``.

The applied input ``u(t)`` is the command of the latest tick ``<= t - h(t)``; each plant step is
split where it switches (:mod:`delaytrack.sim.integrator`).

The engine takes its arguments by name: :class:`Kernels`, :class:`Run` (with a leading batch
axis for :func:`run_batch`, which hands :func:`run_closed_loop` one row of it), :class:`Settings`
and :class:`Records`. numba compiles named tuples as it compiles tuples (each field keeps its own
type), so ``run.x0`` costs what ``run[6]`` did. They are defined here, in a file of compiled code,
so that an edit to them changes the disk cache's key (:mod:`delaytrack._compile.disk_cache`).

All functions are written once and run either compiled (every kernel numba-compiled) or as plain
Python (a user plant given as Python callables): see :mod:`delaytrack.sim.simulate`.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from delaytrack._compile.jit import borrowing_kernel, compiled, inline_kernel, inline_part
from delaytrack.components import call_reference, call_step
from delaytrack.controllers.base import step_workspace
from delaytrack.sim.history import tick_time
from delaytrack.sim.integrator import (
    DELAY_BEYOND_HISTORY,
    DIVERGED,
    LEFT_PATH,
    MASS_NOT_POSITIVE_DEFINITE,
    OK,
    TickArguments,
    beyond,
    delay_at_tick,
    integrate,
    rk4_workspace,
)
from delaytrack.sim.measurement import measure
from delaytrack.sim.packet_loss import packet_lost
from delaytrack.sim.running_metrics import accumulate_applied, accumulate_tick

__all__ = [
    "DELAY_BEYOND_HISTORY",
    "DIVERGED",
    "LEFT_PATH",
    "MASS_NOT_POSITIVE_DEFINITE",
    "OK",
    "STATUS_NAMES",
    "Kernels",
    "Records",
    "Run",
    "Settings",
    "run_batch",
    "run_batch_compiled",
    "run_closed_loop",
]

#: Human-readable names of the status codes of a run (``OK``, ``DIVERGED``,
#: ``DELAY_BEYOND_HISTORY``, ``LEFT_PATH``, ``MASS_NOT_POSITIVE_DEFINITE``).
STATUS_NAMES = (
    "ok",
    "diverged",
    "delay beyond history",
    "left the path",
    "mass matrix not positive definite",
)


class Kernels(NamedTuple):
    """The components' kernels (:class:`~delaytrack.components.Kernel`), as the engine calls them.

    In the compiled engine ``plant_step``, ``reference``, ``controller_step`` and ``delay`` are
    :class:`~delaytrack._compile.native_call.NativeFunction` objects, each compiled for its
    component and called through its address (:mod:`delaytrack._compile.native_parts`), and
    ``model_terms`` is not read.
    """

    #: The plant's kernel (compiled: its integrator, bound to it).
    plant_step: Any
    #: The controller's nominal model's kernel.
    model_terms: Any
    #: The reference's kernel.
    reference: Any
    #: The controller's step kernel.
    controller_step: Any
    #: The batch's delay kernel, for the runs whose profile is a kernel of the user's.
    delay: Any


class Run(NamedTuple):
    """One run's arrays (or, with a leading batch axis on each, a batch's).

    Python builds a batch's only, so each field is typed as an array; in one run's, built by
    the engine, ``delay_kind``, ``capacity`` and ``records_reference`` are numbers.

    The actuators apply each command saturated to ``[-input_limits, input_limits]``: the
    history holds the saturated commands, the record ``commands`` what the controller issued.
    """

    #: The true plant's parameters (padded with zeros to the batch's widest).
    plant_params: np.ndarray
    #: The nominal model's parameters.
    model_params: np.ndarray
    #: The controller's parameters.
    controller_params: np.ndarray
    #: The controller's state, advanced in place.
    controller_state: np.ndarray
    #: The delay profile's kind (:mod:`delaytrack.delays._kernel`), int64.
    delay_kind: np.ndarray
    #: The delay profile's parameters.
    delay_params: np.ndarray
    #: The initial state ``[q(t0), q̇(t0)]`` (2n,).
    x0: np.ndarray
    #: Commands the history keeps (:func:`~delaytrack.sim.history.history_capacity`), int64.
    capacity: np.ndarray
    #: Actuator limits (m,), ``inf`` for none.
    input_limits: np.ndarray
    #: What the controller reads (:func:`~delaytrack.sim.measurement.measure`), (3n + 1,).
    measurement: np.ndarray
    #: Packets lost on the channel, ``[p, seed]``
    #: (:func:`~delaytrack.sim.packet_loss.packet_lost`): the actuators keep the latest
    #: command they received.
    loss: np.ndarray
    #: Whether this run records the reference it computes (one run per batch), bool.
    records_reference: np.ndarray


class Settings(NamedTuple):
    """What every run of a batch shares."""

    #: The reference's parameters.
    reference_params: np.ndarray
    #: The input applied before the first command arrives (m,).
    u_init: np.ndarray
    #: The run's start, seconds.
    t0: float
    #: The plant's step, seconds.
    dt: float
    #: Plant steps per controller tick.
    steps_per_tick: int
    #: Controller ticks of the run.
    n_ticks: int
    #: Record every ``record_every``-th tick; 0 records nothing.
    record_every: int
    #: A state beyond it in magnitude (or non-finite) ends the run with ``DIVERGED``.
    divergence_bound: float
    #: The run stops with ``LEFT_PATH`` at the first tick where ``|e1_j| > error_bound[j]`` (n,).
    error_bound: np.ndarray
    #: The running metrics count the ticks ``k >= metrics_from``.
    metrics_from: int
    #: ``(R, 3, n)``: ``q_d, q̇_d, q̈_d`` at the recorded ticks, written by the run that
    #: records the reference (the reference is the same for all).
    reference_record: np.ndarray


class Records(NamedTuple):
    """What a run writes (with a leading batch axis, a batch's); rows after a stop are left as
    they were (the caller fills them with NaN).

    ``sums`` accumulates the running metrics at every tick; the others are written every
    ``record_every`` ticks.
    """

    #: ``(R, 2n)``: the state at the recorded ticks.
    states: np.ndarray
    #: ``(R, m)``: the command the controller issued.
    commands: np.ndarray
    #: ``(R, m)``: the input of the first sub-step after the tick (the delayed command as the
    #: actuators applied it).
    applied: np.ndarray
    #: ``(R,)``: the delay at the tick.
    delays: np.ndarray
    #: ``(R, n_recorded)``: the leading entries of the controller's state used at the tick.
    controller_states: np.ndarray
    #: ``(3n + 3,)``: the running metrics' sums (:mod:`delaytrack.sim.running_metrics`).
    sums: np.ndarray


@inline_kernel
def left_path(qd, q, error_bound):
    """Whether some tracking error ``|q_d_j - q_j|`` exceeds ``error_bound[j]``."""
    for j in range(q.shape[0]):
        if abs(qd[j] - q[j]) > error_bound[j]:
            return True
    return False


@inline_part
def run_closed_loop(handles, run, settings, records):
    """Simulate one closed loop from ``t0`` to tick ``n_ticks``; return ``(status, t_stop)``.

    Parameters (named tuples: numba compiles them as tuples, each field of its own type)
    -------------------------------------------------------------------------------------
    handles : Kernels
        The components' kernels.
    run : Run
        This run's arrays; ``controller_state`` is advanced in place.
    settings : Settings
        What every run of the batch shares.
    records : Records
        Where the run writes what it records.
    """
    n = run.x0.shape[0] // 2
    m = settings.u_init.shape[0]
    x = run.x0.copy()
    # Zeroed, as all working memory: an entry a kernel leaves unwritten is the same in every run.
    memory = (
        x,
        np.zeros((run.capacity, m)),  # the command history
        rk4_workspace(x, m),
        np.zeros((3, n)),  # q_d, q̇_d, q̈_d
        np.zeros((2, m)),  # the command and the previous one
        step_workspace(n, m),
        np.zeros((2, n)),  # q and q̇ as the controller reads them
        np.zeros((2, m)),  # the input applied after the tick and after the one before
    )
    return _run_ticks(handles, run, settings, records, memory)


@borrowing_kernel
def _run_ticks(handles, run, settings, records, memory):
    """The tick loop of :func:`run_closed_loop`, in the working ``memory`` it allocated.

    Compiled without reference counts (:data:`delaytrack._compile.jit.borrowing_kernel`): with
    them, the arrays handed to the controller's step, the reference and the metrics at every
    tick cost about 44 atomic operations a tick, 8 % of a robot run's time.
    """
    states, commands, applied, delays, controller_states, sums = records
    x, history, work, desired, commands_now, controller_work, measured, inputs_now = memory
    t0, dt, steps_per_tick = settings.t0, settings.dt, settings.steps_per_tick
    record_every, u_init = settings.record_every, settings.u_init
    n = x.shape[0] // 2
    m = u_init.shape[0]
    T_c = steps_per_tick * dt
    qd = desired[0]
    qd_dot = desired[1]
    qd_ddot = desired[2]
    command = commands_now[0]
    previous_command = commands_now[1]
    received = inputs_now[0]
    previous_received = inputs_now[1]
    q = x[:n]  # views of x, which is advanced in place
    qdot = x[n:]
    q_measured = measured[0]  # what the controller reads
    qdot_measured = measured[1]
    for k in range(settings.n_ticks + 1):
        t_k = tick_time(k, t0, dt, steps_per_tick)
        record = record_every > 0 and k % record_every == 0
        row = k // record_every if record else 0
        h_k = delay_at_tick(handles.delay, run.delay_kind, run.delay_params, t_k, work)
        if record:  # copies written as loops: a slice copy needs numba's runtime
            for i in range(2 * n):
                states[row, i] = x[i]
            for i in range(controller_states.shape[1]):
                controller_states[row, i] = run.controller_state[i]
            delays[row] = h_k
        call_reference(handles.reference, t_k, settings.reference_params, qd, qd_dot, qd_ddot)
        if record and run.records_reference:
            for i in range(n):
                settings.reference_record[row, 0, i] = qd[i]
                settings.reference_record[row, 1, i] = qd_dot[i]
                settings.reference_record[row, 2, i] = qd_ddot[i]
        if left_path(qd, q, settings.error_bound):
            return LEFT_PATH, t_k
        measure(q, qdot, k, run.measurement, q_measured, qdot_measured)
        call_step(
            handles.controller_step,
            t_k,
            q_measured,
            qdot_measured,
            qd,
            qd_dot,
            qd_ddot,
            T_c,
            h_k,
            run.controller_params,
            run.controller_state,
            handles.model_terms,
            run.model_params,
            command,
            controller_work,
        )
        slot = k % run.capacity
        if packet_lost(k, run.loss):  # the actuators keep the latest command they received
            for j in range(m):
                history[slot, j] = u_init[j] if k == 0 else history[(k - 1) % run.capacity, j]
        else:
            limits = run.input_limits
            for j in range(m):  # the actuator saturates what it applies (inf: no limit)
                history[slot, j] = min(max(command[j], -limits[j]), limits[j])
        if record:
            for j in range(m):
                commands[row, j] = command[j]
        if beyond(command, np.inf):
            return DIVERGED, t_k
        if k >= settings.metrics_from:
            accumulate_tick(sums, qd, q, command, previous_command, k == settings.metrics_from)
            for j in range(m):
                previous_command[j] = command[j]
        # At the last tick, only the input a step from t_k would start with (for the record and
        # the running TV of the applied input).
        last = k == settings.n_ticks
        outcome, t_stop, slot = integrate(
            handles.plant_step,
            handles.delay,
            TickArguments(
                plant_params=run.plant_params,
                delay_kind=run.delay_kind,
                delay_params=run.delay_params,
                x=x,
                k=k,
                history=history,
                u_init=u_init,
                t0=t0,
                dt=dt,
                steps_per_tick=steps_per_tick,
                divergence_bound=settings.divergence_bound,
                work=work,
                probe_only=last,
            ),
        )
        if slot != -3:
            for j in range(m):
                received[j] = u_init[j] if slot == -1 else history[slot, j]
            if record:
                for j in range(m):
                    applied[row, j] = received[j]
            if k >= settings.metrics_from:
                accumulate_applied(sums, received, previous_received, k == settings.metrics_from)
                for j in range(m):
                    previous_received[j] = received[j]
        if outcome != OK:
            return outcome, t_stop
    return OK, tick_time(settings.n_ticks, t0, dt, steps_per_tick)


@inline_kernel
def run_batch(handles, runs, settings, records, status, t_stop):
    """:func:`run_closed_loop` for each batch element ``b``.

    ``runs`` (:class:`Run`) and ``records``
    (:class:`Records`) hold the arrays of
    :func:`run_closed_loop` with a leading batch axis; ``status (B,)`` and ``t_stop (B,)``
    receive each run's outcome.
    """
    for b in range(runs.x0.shape[0]):
        run = Run(
            plant_params=runs.plant_params[b],
            model_params=runs.model_params[b],
            controller_params=runs.controller_params[b],
            controller_state=runs.controller_state[b],
            delay_kind=runs.delay_kind[b],
            delay_params=runs.delay_params[b],
            x0=runs.x0[b],
            capacity=runs.capacity[b],
            input_limits=runs.input_limits[b],
            measurement=runs.measurement[b],
            loss=runs.loss[b],
            records_reference=runs.records_reference[b],
        )
        run_records = Records(
            states=records.states[b],
            commands=records.commands[b],
            applied=records.applied[b],
            delays=records.delays[b],
            controller_states=records.controller_states[b],
            sums=records.sums[b],
        )
        status[b], t_stop[b] = run_closed_loop(handles, run, settings, run_records)


#: :func:`run_batch` compiled and cached on disk. The plant's step, the reference, the
#: controller's step and the delay profile are passed by the address of their own compiled code
#: (:mod:`delaytrack._compile.native_parts`), so one engine serves every combination of
#: components.
#: It releases the GIL, so threads run sub-batches in parallel.
run_batch_compiled = compiled(run_batch, nogil=True)
