"""The fixed-step closed loop: sampled controller, delayed zero-order hold, RK4 plant (SPEC §5).

One run (:func:`run_closed_loop`) proceeds tick by tick. At tick ``k`` (time ``t_k``) the
controller reads ``x(t_k)`` and issues command ``k`` into the history; the plant is then integrated
with RK4 over the ``steps_per_tick`` steps of length ``dt`` up to ``t_{k+1}``.

The applied input ``u(t)`` is the command of the latest tick ``<= t - h(t)``. With a time-varying
delay it switches at instants inside a step, where ``g(t) = t - h(t)`` crosses a tick time. Each
step is split there, so that every RK4 sub-step sees a constant input and the scheme keeps its
fourth order: the step is first cut at the profile's breakpoints (pieces on which ``g`` is
continuous and monotone), then each piece at the crossings, solved from ``g(t) = t_k``. The input
of a sub-step is looked up at its midpoint. Crossings closer than ``1e-9 dt`` to the end of a piece
are not split off (the sliver is integrated with its neighbour's input).

All functions are written once and run either compiled (every model kernel numba-compiled) or
as plain Python (a user plant given as Python callables): see :mod:`delaytrack.sim.simulate`.
"""

from __future__ import annotations

import math

import numpy as np

from delaytrack._jit import inline_kernel, kernel
from delaytrack.controllers.dispatch import call_step
from delaytrack.delays._kernel import (
    crossing_time,
    delay_value,
    next_breakpoint,
    piece_end_values,
)
from delaytrack.plants.base import el_rhs, rhs_scratch
from delaytrack.reference import call_reference
from delaytrack.sim.history import latest_tick_index, tick_time

__all__ = ["STATUS_NAMES", "run_closed_loop", "run_batch", "run_batch_compiled"]

OK = 0
DIVERGED = 1
DELAY_BEYOND_HISTORY = 2
#: Human-readable names of the status codes of a run.
STATUS_NAMES = ("ok", "diverged", "delay beyond history")

_SPLIT_TOLERANCE = 1e-9


@inline_kernel
def rk4_workspace(x, m):
    """Working memory of :func:`_rk4_substep` for the state ``x = [q, q̇]`` (2n,) and ``m`` inputs.

    ``(q, q̇, slopes (4, 2n), stage, stage_q, stage_q̇, accelerations, scratch)``: the views are
    taken once per run, so the inner loop neither allocates nor slices.
    """
    n = x.shape[0] // 2
    slopes = np.empty((4, 2 * n))
    stage = np.empty(2 * n)
    accelerations = (slopes[0, n:], slopes[1, n:], slopes[2, n:], slopes[3, n:])
    return x[:n], x[n:], slopes, stage, stage[:n], stage[n:], accelerations, rhs_scratch(n, m)


@inline_kernel
def _rk4_substep(plant_terms, plant_params, t, x, u, length, work):
    """One classical RK4 step of length ``length`` with constant input ``u``; updates ``x``.

    ``work`` is :func:`rk4_workspace` of this ``x``; written as loops so that nothing is
    allocated.
    """
    q, qdot, slopes, stage, stage_q, stage_qdot, accelerations, scratch = work
    n = q.shape[0]
    half = 0.5 * length
    el_rhs(plant_terms, t, q, qdot, u, plant_params, accelerations[0], scratch)
    for i in range(n):
        slopes[0, i] = qdot[i]
    for i in range(2 * n):
        stage[i] = x[i] + half * slopes[0, i]
    el_rhs(plant_terms, t + half, stage_q, stage_qdot, u, plant_params, accelerations[1], scratch)
    for i in range(n):
        slopes[1, i] = stage_qdot[i]
    for i in range(2 * n):
        stage[i] = x[i] + half * slopes[1, i]
    el_rhs(plant_terms, t + half, stage_q, stage_qdot, u, plant_params, accelerations[2], scratch)
    for i in range(n):
        slopes[2, i] = stage_qdot[i]
    for i in range(2 * n):
        stage[i] = x[i] + length * slopes[2, i]
    el_rhs(plant_terms, t + length, stage_q, stage_qdot, u, plant_params, accelerations[3], scratch)
    for i in range(n):
        slopes[3, i] = stage_qdot[i]
    sixth = length / 6.0
    for i in range(2 * n):
        x[i] += sixth * (slopes[0, i] + 2.0 * slopes[1, i] + 2.0 * slopes[2, i] + slopes[3, i])


@inline_kernel
def _beyond(values, bound):
    """Whether any entry is non-finite or larger than ``bound`` in magnitude."""
    for value in values:
        if not math.isfinite(value) or abs(value) > bound:
            return True
    return False


@inline_kernel
def _applied_slot(delay_kind, delay_params, t, newest, capacity, t0, dt, steps_per_tick):
    """Ring slot of the command applied at ``t`` (-1 for ``u_init``, -2 beyond the history)."""
    k = latest_tick_index(t - delay_value(delay_kind, delay_params, t), t0, dt, steps_per_tick)
    if k < 0:
        return -1
    if k <= newest - capacity:
        return -2
    return k % capacity


@inline_kernel
def _integrate_step(
    plant_terms,
    plant_params,
    delay_kind,
    delay_params,
    x,
    t_start,
    t_end,
    history,
    u_init,
    newest,
    t0,
    dt,
    steps_per_tick,
    work,
    probe_only,
):
    """Integrate ``x`` over one plant step ``[t_start, t_end]``, split where the input switches.

    Each sub-step uses the command looked up at its midpoint. Returns the ring slot of the input
    of the first sub-step (-1 for ``u_init``), or -2 when a needed command has left the history.
    With ``probe_only`` nothing is integrated: only that first slot is found.
    """
    tolerance = _SPLIT_TOLERANCE * dt
    capacity = history.shape[0]
    first_slot = -3
    a = t_start
    while a < t_end:
        b = min(next_breakpoint(delay_kind, delay_params, a), t_end)
        h_a, h_b = piece_end_values(delay_kind, delay_params, a, b)
        g_a = a - h_a
        g_b = b - h_b
        k_a = latest_tick_index(g_a, t0, dt, steps_per_tick)
        k_b = latest_tick_index(g_b, t0, dt, steps_per_tick)
        # Sub-intervals end at each tick crossed by g on this piece, in time order, then at b.
        crossings = abs(k_b - k_a)
        direction = 1 if k_b >= k_a else -1
        first_tick = k_a + 1 if direction == 1 else k_a
        start = a
        for i in range(crossings + 1):
            end = b
            if i < crossings:
                target = tick_time(first_tick + direction * i, t0, dt, steps_per_tick)
                end = crossing_time(delay_kind, delay_params, a, b, g_a, g_b, target)
                if end - start <= tolerance or b - end <= tolerance:
                    continue
            slot = _applied_slot(
                delay_kind,
                delay_params,
                0.5 * (start + end),
                newest,
                capacity,
                t0,
                dt,
                steps_per_tick,
            )
            if slot == -2:
                return slot
            if first_slot == -3:
                first_slot = slot
                if probe_only:
                    return slot
            u = u_init if slot == -1 else history[slot]
            _rk4_substep(plant_terms, plant_params, start, x, u, end - start, work)
            start = end
        a = b
    return first_slot


@inline_kernel
def run_closed_loop(handles, run, settings, records):
    """Simulate one closed loop from ``t0`` to tick ``n_ticks``; return ``(status, t_stop)``.

    Parameters (tuples, so that :func:`run_batch` can pass them on whole)
    ----------------------------------------------------------------------
    handles : tuple
        ``(plant_terms, model_terms, reference, controller_step)``: kernel ids (compiled) or
        callables (plain Python); see :mod:`delaytrack.plants.dispatch`.
    run : tuple
        This run's arrays ``(plant_params, model_params, controller_params, controller_state,
        delay_kind, delay_params, x0, capacity)``; ``controller_state`` is advanced in place.
    settings : tuple
        ``(reference_params, u_init, t0, dt, steps_per_tick, n_ticks, record_every,
        divergence_bound)``, shared by every run of a batch.
    records : (states, commands, applied, delays, controller_states)
        Written every ``record_every`` ticks: ``states (R, 2n)``, ``commands (R, m)``,
        ``applied (R, m)`` (the input of the first sub-step after the tick),
        ``delays (R,)`` and ``controller_states (R, n_recorded)`` (the leading entries of the
        state used at the tick).
        Rows after a stop are left as they were (the caller fills them with NaN).
    """
    plant_terms, model_terms, reference, controller_step = handles
    (
        plant_params,
        model_params,
        controller_params,
        controller_state,
        delay_kind,
        delay_params,
        x0,
        capacity,
    ) = run
    reference_params, u_init, t0, dt, steps_per_tick, n_ticks, record_every, divergence_bound = (
        settings
    )
    states, commands, applied, delays, controller_states = records
    n = x0.shape[0] // 2
    m = u_init.shape[0]
    T_c = steps_per_tick * dt
    x = x0.copy()
    history = np.zeros((capacity, m))
    work = rk4_workspace(x, m)
    qd = np.empty(n)
    qd_dot = np.empty(n)
    qd_ddot = np.empty(n)
    command = np.empty(m)
    for k in range(n_ticks + 1):
        t_k = tick_time(k, t0, dt, steps_per_tick)
        record = k % record_every == 0
        row = k // record_every
        h_k = delay_value(delay_kind, delay_params, t_k)
        if record:
            states[row] = x
            controller_states[row] = controller_state[: controller_states.shape[1]]
            delays[row] = h_k
        call_reference(reference, t_k, reference_params, qd, qd_dot, qd_ddot)
        call_step(
            controller_step,
            t_k,
            x[:n],
            x[n:],
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
        )
        history[k % capacity] = command
        if record:
            commands[row] = command
        if _beyond(command, np.inf):
            return DIVERGED, t_k
        if k == n_ticks:
            if record:
                # The input a step from t_k would start with, found as for every other row.
                slot = _integrate_step(
                    plant_terms,
                    plant_params,
                    delay_kind,
                    delay_params,
                    x,
                    t_k,
                    t_k + dt,
                    history,
                    u_init,
                    k,
                    t0,
                    dt,
                    steps_per_tick,
                    work,
                    True,
                )
                if slot == -2:
                    return DELAY_BEYOND_HISTORY, t_k
                applied[row] = u_init if slot == -1 else history[slot]
            break
        for j in range(steps_per_tick):
            t_start = t0 + (k * steps_per_tick + j) * dt
            t_end = t0 + (k * steps_per_tick + j + 1) * dt
            slot = _integrate_step(
                plant_terms,
                plant_params,
                delay_kind,
                delay_params,
                x,
                t_start,
                t_end,
                history,
                u_init,
                k,
                t0,
                dt,
                steps_per_tick,
                work,
                False,
            )
            if slot == -2:
                return DELAY_BEYOND_HISTORY, t_start
            if record and j == 0:
                applied[row] = u_init if slot == -1 else history[slot]
            if _beyond(x, divergence_bound):
                return DIVERGED, t_end
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
    ) = runs
    states, commands, applied, delays, controller_states = records
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
        )
        run_records = (states[b], commands[b], applied[b], delays[b], controller_states[b])
        status[b], t_stop[b] = run_closed_loop(handles, run, settings, run_records)


run_batch_compiled = kernel(run_batch)
