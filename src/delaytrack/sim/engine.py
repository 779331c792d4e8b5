"""The fixed-step closed loop: sampled controller, delayed zero-order hold, RK4 plant.

One run (:func:`run_closed_loop`) proceeds tick by tick. At tick ``k`` (time ``t_k``) the
controller reads ``x(t_k)`` and issues command ``k`` into the history; the plant is then integrated
with RK4 over the ``steps_per_tick`` steps of length ``dt`` up to ``t_{k+1}``.

The applied input ``u(t)`` is the command of the latest tick ``<= t - h(t)``; each plant step is
split where it switches (:mod:`delaytrack.sim.integrator`).

All functions are written once and run either compiled (every kernel numba-compiled) or as plain
Python (a user plant given as Python callables): see :mod:`delaytrack.sim.simulate`.
"""

from __future__ import annotations

import numpy as np

from delaytrack._jit import borrowing_kernel, compiled, inline_kernel
from delaytrack.components import call_reference, call_step
from delaytrack.controllers.base import step_workspace
from delaytrack.delays._kernel import delay_at
from delaytrack.sim.history import tick_time
from delaytrack.sim.integrator import (
    DELAY_BEYOND_HISTORY,
    DIVERGED,
    LEFT_PATH,
    MASS_NOT_POSITIVE_DEFINITE,
    OK,
    beyond,
    integrate,
    rk4_workspace,
)
from delaytrack.sim.measurement import measure
from delaytrack.sim.packet_loss import packet_lost
from delaytrack.sim.running_metrics import accumulate_tick

__all__ = [
    "DELAY_BEYOND_HISTORY",
    "DIVERGED",
    "LEFT_PATH",
    "MASS_NOT_POSITIVE_DEFINITE",
    "OK",
    "STATUS_NAMES",
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


@inline_kernel
def left_path(qd, q, error_bound):
    """Whether some tracking error ``|q_d_j - q_j|`` exceeds ``error_bound[j]``."""
    for j in range(q.shape[0]):
        if abs(qd[j] - q[j]) > error_bound[j]:
            return True
    return False


@inline_kernel
def run_closed_loop(handles, run, settings, records):
    """Simulate one closed loop from ``t0`` to tick ``n_ticks``; return ``(status, t_stop)``.

    Parameters (tuples, so that :func:`run_batch` can pass them on whole)
    ----------------------------------------------------------------------
    handles : tuple
        ``(plant_step, model_terms, reference, controller_step, delay)``: the components'
        :class:`~delaytrack.components.Kernel` objects (``plant_step``: the plant's;
        ``delay``: the batch's delay kernel, for the runs whose profile is a kernel of the
        user's). In the compiled engine the plant's step, the reference, the controller's step
        and the delay are :class:`~delaytrack._native_call.NativeFunction` objects, each
        compiled for its component and called through its address
        (:mod:`delaytrack.sim.native_parts`), and ``model_terms`` is not read.
    run : tuple
        This run's arrays ``(plant_params, model_params, controller_params, controller_state,
        delay_kind, delay_params, x0, capacity, input_limits, measurement, loss,
        records_reference)``; ``controller_state`` is advanced in place. The actuators apply
        each command saturated to ``[-input_limits, input_limits]`` (m,): the history holds
        the saturated commands, the record ``commands`` what the controller issued. The
        controller reads the state
        through :func:`~delaytrack.sim.measurement.measure` with ``measurement`` (3n + 1,);
        a packet lost on the channel (:func:`~delaytrack.sim.packet_loss.packet_lost`,
        ``loss = [p, seed]``) leaves the latest received command in its history slot. The run
        with ``records_reference`` (one per batch) writes the reference it computes at the
        recorded ticks into ``reference_record``.
    settings : tuple
        ``(reference_params, u_init, t0, dt, steps_per_tick, n_ticks, record_every,
        divergence_bound, error_bound, metrics_from, reference_record)``, shared by every run
        of a batch;
        ``record_every = 0`` records nothing, the run stops with ``LEFT_PATH`` at the first tick
        where ``|e1_j| > error_bound[j]`` (n,), the running metrics count the ticks
        ``k >= metrics_from``, and ``reference_record (R, 3, n)`` receives ``q_d, q̇_d, q̈_d``
        at the recorded ticks (from one run: the reference is the same for all).
    records : (states, commands, applied, delays, controller_states, sums)
        ``sums`` (3n + 2,) accumulates the running metrics at every tick
        (:mod:`delaytrack.sim.running_metrics`). The others are written every ``record_every``
        ticks: ``states (R, 2n)``, ``commands (R, m)``,
        ``applied (R, m)`` (the input of the first sub-step after the tick),
        ``delays (R,)`` and ``controller_states (R, n_recorded)`` (the leading entries of the
        state used at the tick).
        Rows after a stop are left as they were (the caller fills them with NaN).
    """
    x0, capacity, u_init = run[6], run[7], settings[1]
    n = x0.shape[0] // 2
    m = u_init.shape[0]
    x = x0.copy()
    # Zeroed, as all working memory: an entry a kernel leaves unwritten is the same in every run.
    memory = (
        x,
        np.zeros((capacity, m)),  # the command history
        rk4_workspace(x, m),
        np.zeros((3, n)),  # q_d, q̇_d, q̈_d
        np.zeros((2, m)),  # the command and the previous one
        step_workspace(n, m),
        np.zeros((2, n)),  # q and q̇ as the controller reads them
    )
    return _run_ticks(handles, run, settings, records, memory)


@borrowing_kernel
def _run_ticks(handles, run, settings, records, memory):
    """The tick loop of :func:`run_closed_loop`, in the working ``memory`` it allocated.

    Compiled without reference counts (:data:`delaytrack._jit.borrowing_kernel`): with them, the
    arrays handed to the controller's step, the reference and the metrics at every tick cost
    about 44 atomic operations a tick, 8 % of a robot run's time.
    """
    plant_step, model_terms, reference, controller_step, delay = handles
    (
        plant_params,
        model_params,
        controller_params,
        controller_state,
        delay_kind,
        delay_params,
        _,  # x0: x starts from it (run_closed_loop)
        capacity,
        input_limits,
        measurement,
        loss,
        records_reference,
    ) = run
    (
        reference_params,
        u_init,
        t0,
        dt,
        steps_per_tick,
        n_ticks,
        record_every,
        divergence_bound,
        error_bound,
        metrics_from,
        reference_record,
    ) = settings
    states, commands, applied, delays, controller_states, sums = records
    x, history, work, desired, commands_now, controller_work, measured = memory
    n = x.shape[0] // 2
    m = u_init.shape[0]
    T_c = steps_per_tick * dt
    qd = desired[0]
    qd_dot = desired[1]
    qd_ddot = desired[2]
    command = commands_now[0]
    previous_command = commands_now[1]
    q = x[:n]  # views of x, which is advanced in place
    qdot = x[n:]
    q_measured = measured[0]  # what the controller reads
    qdot_measured = measured[1]
    for k in range(n_ticks + 1):
        t_k = tick_time(k, t0, dt, steps_per_tick)
        record = record_every > 0 and k % record_every == 0
        row = k // record_every if record else 0
        h_k = delay_at(delay, delay_kind, delay_params, t_k)
        if record:  # copies written as loops: a slice copy needs numba's runtime
            for i in range(2 * n):
                states[row, i] = x[i]
            for i in range(controller_states.shape[1]):
                controller_states[row, i] = controller_state[i]
            delays[row] = h_k
        call_reference(reference, t_k, reference_params, qd, qd_dot, qd_ddot)
        if record and records_reference:
            for i in range(n):
                reference_record[row, 0, i] = qd[i]
                reference_record[row, 1, i] = qd_dot[i]
                reference_record[row, 2, i] = qd_ddot[i]
        if left_path(qd, q, error_bound):
            return LEFT_PATH, t_k
        measure(q, qdot, k, measurement, q_measured, qdot_measured)
        call_step(
            controller_step,
            t_k,
            q_measured,
            qdot_measured,
            qd,
            qd_dot,
            qd_ddot,
            T_c,
            h_k,
            controller_params,
            controller_state,
            model_terms,
            model_params,
            command,
            controller_work,
        )
        slot = k % capacity
        if packet_lost(k, loss):  # the actuators keep the latest command they received
            for j in range(m):
                history[slot, j] = u_init[j] if k == 0 else history[(k - 1) % capacity, j]
        else:
            for j in range(m):  # the actuator saturates what it applies (inf: no limit)
                history[slot, j] = min(max(command[j], -input_limits[j]), input_limits[j])
        if record:
            for j in range(m):
                commands[row, j] = command[j]
        if beyond(command, np.inf):
            return DIVERGED, t_k
        if k >= metrics_from:
            accumulate_tick(sums, qd, q, command, previous_command, k == metrics_from)
            for j in range(m):
                previous_command[j] = command[j]
        # At the last tick, only the input a step from t_k would start with (for the record).
        last = k == n_ticks
        if last and not record:
            break
        outcome, t_stop, slot = integrate(
            plant_step,
            delay,
            (
                plant_params,
                delay_kind,
                delay_params,
                x,
                k,
                history,
                u_init,
                t0,
                dt,
                steps_per_tick,
                divergence_bound,
                work,
                last,
            ),
        )
        if record and slot != -3:
            for j in range(m):
                applied[row, j] = u_init[j] if slot == -1 else history[slot, j]
        if outcome != OK:
            return outcome, t_stop
    return OK, tick_time(n_ticks, t0, dt, steps_per_tick)


@inline_kernel
def run_batch(handles, runs, settings, records, status, t_stop):
    """:func:`run_closed_loop` for each batch element ``b``.

    ``runs`` and ``records`` hold the arrays of :func:`run_closed_loop` with a leading batch axis;
    ``status (B,)`` and ``t_stop (B,)`` receive each run's outcome.
    """
    (
        plant_params,
        model_params,
        controller_params,
        controller_state,
        delay_kind,
        delay_params,
        x0,
        capacity,
        input_limits,
        measurement,
        loss,
        records_reference,
    ) = runs
    states, commands, applied, delays, controller_states, sums = records
    for b in range(x0.shape[0]):
        run = (
            plant_params[b],
            model_params[b],
            controller_params[b],
            controller_state[b],
            delay_kind[b],
            delay_params[b],
            x0[b],
            capacity[b],
            input_limits[b],
            measurement[b],
            loss[b],
            records_reference[b],
        )
        run_records = (
            states[b],
            commands[b],
            applied[b],
            delays[b],
            controller_states[b],
            sums[b],
        )
        status[b], t_stop[b] = run_closed_loop(handles, run, settings, run_records)


#: :func:`run_batch` compiled and cached on disk. The plant's step, the reference, the
#: controller's step and the delay profile are passed by the address of their own compiled code
#: (:mod:`delaytrack.sim.native_parts`), so one engine serves every combination of components.
#: It releases the GIL, so threads run sub-batches in parallel.
run_batch_compiled = compiled(run_batch, nogil=True)
