"""The ceiling for ``make bench``: the paper's robot run as one hand-written numba loop.

What a user who knows numba well would write for exactly the case of :func:`baselines.robot_case`
(the payload robot under AROLC with the paper's gains, S1 delay ``h(t) = 20 + 80 |sin t|`` ms,
``T_c`` = 10 ms, ``dt`` = 1 ms), with nothing general left:

* one function, every buffer allocated once before the loop, the robot's own kernels called
  directly: the robot in its reduced (wheel-space) form, as the engine integrates it
  (:func:`~delaytrack.plants.robot.kinematics.robot_velocity_map` and
  :func:`~delaytrack.plants.robot.payload.robot_payload_dynamics`; the three dependent
  velocities get no slope and are set from the wheel rates after each step, which the next
  step's first stage reads as they are),
  :func:`~delaytrack.controllers.arolc.arolc_step` on the nominal model and
  :func:`~delaytrack.references.sinusoidal.sinusoidal_reference`;
* the delayed command looked up at each RK4 stage time (``k = ⌊(t - h(t)) / T_c⌋``), **without**
  splitting a step where it switches: first order across a switch, which the engine does not
  accept, and cheaper than the engine's exact splitting;
* the running metrics (sums of ``|e1|`` and TV at every tick), as the engine keeps them;
* a batch over runs with ``numba.prange`` (one run per thread at a time).

It is a ceiling for speed, not a reference for accuracy: its states agree with the engine's to
about 1e-4 (the unsplit switches); ``make bench`` prints the difference of the metrics.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from delaytrack.controllers.arolc import arolc_step
from delaytrack.controllers.base import step_workspace
from delaytrack.plants.robot.kinematics import robot_velocity_map
from delaytrack.plants.robot.payload import robot_payload_dynamics
from delaytrack.references.sinusoidal import sinusoidal_reference

__all__ = ["hand_batch", "hand_run"]


@numba.njit(cache=True, error_model="numpy", _nrt=False)
def _plant_tick(x, history, plant_params, delay, t_k, dt, steps_per_tick, T_c, buffers):
    """The plant's steps after tick ``t_k`` (RK4, the command looked up at each stage), compiled
    without numba's runtime as the engine's plant step is: no reference counts on the arrays
    its kernels take (with them, the payload's inlined branches cost about 10 ms a run)."""
    slopes, q, eta, qdot, eta_dot, applied = buffers
    n, r, m = q.shape[0], eta.shape[0], applied.shape[0]
    first = 2 * n - r  # where the wheel rates η start in [q, q̇]
    for step in range(steps_per_tick):
        t = t_k + step * dt
        for s in range(4):
            offset = 0.0 if s == 0 else (0.5 * dt if s < 3 else dt)
            for i in range(n):
                q[i] = x[i] if s == 0 else x[i] + offset * slopes[s - 1, i]
            for j in range(r):
                e = first + j
                eta[j] = x[e] if s == 0 else x[e] + offset * slopes[s - 1, e]
            time = t + offset
            h = delay[0] + delay[1] * abs(math.sin(delay[2] * time + delay[3]))
            index = math.floor((time - h) / T_c)
            for j in range(m):
                applied[j] = history[index, j] if index >= 0 else 0.0
            # the reduced form: q̇ = S(q) η (at the first stage, x's: set after the last step),
            # η̇ of the wheel-space dynamics
            if s == 0:
                for i in range(n):
                    qdot[i] = x[n + i]
            else:
                robot_velocity_map(q, eta, plant_params, qdot)
            robot_payload_dynamics(time, q, eta, applied, plant_params, eta_dot)
            for i in range(n):
                slopes[s, i] = qdot[i]
            for j in range(r):
                slopes[s, first + j] = eta_dot[j]
        for i in range(2 * n):
            x[i] += (
                dt / 6.0 * (slopes[0, i] + 2.0 * slopes[1, i] + 2.0 * slopes[2, i] + slopes[3, i])
            )
        for i in range(n):
            q[i] = x[i]
        for j in range(r):
            eta[j] = x[first + j]
        robot_velocity_map(q, eta, plant_params, qdot)
        for i in range(n):
            x[n + i] = qdot[i]


@numba.njit(cache=True, error_model="numpy")
def _one_run(plant_params, delay, sums, shared):
    """One run; ``delay = (offset, amplitude, ω, φ)`` of ``h = offset + amplitude |sin(ω t + φ)|``;
    ``sums`` (n + 1,) receives ``[Σ|e1_j| / K, TV]``; ``shared`` is :func:`_shared`. Returns the
    final state."""
    (
        x0,
        model,
        model_params,
        controller_params,
        state0,
        reference_params,
        duration,
        dt,
        steps_per_tick,
    ) = shared
    n = x0.shape[0] // 2
    m = 2
    T_c = steps_per_tick * dt
    ticks = int(round(duration / T_c))
    capacity = ticks + 2
    x = x0.copy()
    history = np.zeros((capacity, m))
    state = state0.copy()
    qd = np.empty(n)
    qd_dot = np.empty(n)
    qd_ddot = np.empty(n)
    command = np.empty(m)
    previous = np.zeros(m)
    work = step_workspace(n, m)
    r = 2  # the wheel rates η of the reduced form
    # slopes (the dependent velocities' stay zero), q, η, q̇, η̇ of a stage, the applied input
    buffers = (
        np.zeros((4, 2 * n)),
        np.empty(n),
        np.empty(r),
        np.empty(n),
        np.empty(r),
        np.empty(m),
    )
    for j in range(n + 1):
        sums[j] = 0.0
    for k in range(ticks):
        t_k = k * T_c
        sinusoidal_reference(t_k, reference_params, qd, qd_dot, qd_ddot)
        arolc_step(
            t_k,
            x[:n],
            x[n:],
            qd,
            qd_dot,
            qd_ddot,
            T_c,
            0.0,
            controller_params,
            state,
            model,
            model_params,
            command,
            work,
        )
        for j in range(m):
            history[k, j] = command[j]
        for j in range(n):
            sums[j] += abs(qd[j] - x[j])
        if k > 0:
            for j in range(m):
                sums[n] += abs(command[j] - previous[j])
        for j in range(m):
            previous[j] = command[j]
        if k == 0:  # the start onto the constraints, as the engine maps it before its first step
            qdot = buffers[3]
            robot_velocity_map(x[:n], x[2 * n - r :], plant_params, qdot)
            for i in range(n):
                x[n + i] = qdot[i]
        _plant_tick(x, history, plant_params, delay, t_k, dt, steps_per_tick, T_c, buffers)
    for j in range(n):
        sums[j] /= ticks
    return x


@numba.njit(cache=True, error_model="numpy", parallel=True)
def _batch(plant_params, delays, sums, shared):
    for b in numba.prange(plant_params.shape[0]):
        _one_run(plant_params[b], delays[b], sums[b], shared)


def _shared(controller, reference, x0, duration, dt, T_c) -> tuple:
    """What every run of a batch shares (the last argument of :func:`_one_run`)."""
    return (
        x0,
        controller.model.engine_kernel,
        controller.model.params,
        controller.params,
        controller.initial_state(),
        reference.params,
        duration,
        dt,
        round(T_c / dt),
    )


def hand_run(plant, controller, delay, reference, x0, duration, dt, T_c) -> tuple:
    """One run of the hand loop: ``(final state, [AE_j..., TV])``."""
    sums = np.zeros(plant.n + 1)
    shared = _shared(controller, reference, x0, duration, dt, T_c)
    return _one_run(plant.params, delay.params, sums, shared), sums


def hand_batch(plants, controller, delays, reference, x0, duration, dt, T_c) -> np.ndarray:
    """A batch of hand-loop runs on all cores (``prange``); ``[AE_j..., TV]`` per run.

    ``delays`` are :class:`~delaytrack.delays.AbsSineDelay` profiles.
    """
    width = max(plant.params.size for plant in plants)
    plant_params = np.zeros((len(plants), width))  # padded: the kernel reads its own length
    for b, plant in enumerate(plants):
        plant_params[b, : plant.params.size] = plant.params
    profiles = np.array([delay.params for delay in delays])
    sums = np.zeros((len(plants), plants[0].n + 1))
    _batch(plant_params, profiles, sums, _shared(controller, reference, x0, duration, dt, T_c))
    return sums
