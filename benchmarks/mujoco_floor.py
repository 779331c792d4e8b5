"""The floor and the ceiling for the MuJoCo case of ``make bench``.

:func:`bare_steps` gives a function that calls ``mj_step`` ``steps`` times on the model's data
from a compiled loop (no controller, no delay, no Python between steps; the model read once,
before the timing), through the same C entry point the
MuJoCo-stepped plant uses (:mod:`delaytrack.plants.mujoco.capi`): what a closed loop around
MuJoCo cannot be faster than, whatever its controller.

:func:`hand_run` is the closed loop of the case itself written by hand as one numba function,
with nothing general left (the counterpart of :mod:`hand_loop` for the robot): at every tick
the reference and AROLC's step on the nominal MuJoCo model (the package's
:func:`~delaytrack.controllers.arolc.arolc_step`, which evaluates ``M̂``, the bias and the
input map through MuJoCo), at every step the S1 delay ``h(t) = 20 + 80 |sin t|`` ms evaluated
at the step's start, the command of the latest tick ``<= t - h(t)`` held over the step and one
``mj_step`` (:func:`~delaytrack.plants.mujoco.plant.mujoco_step`), and the running sums of
``|e1|`` and TV at every tick, the run's last included, as the engine keeps them. It does the
work a closed loop under AROLC cannot skip, and gives the engine's run bit for bit (its final
state, AE and TV: ``make bench`` prints their differences): the ceiling for the engine on this
case, as the floor is for MuJoCo alone.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numba
import numpy as np

from delaytrack.controllers.arolc import arolc_step
from delaytrack.controllers.base import step_workspace
from delaytrack.plants.mujoco.capi import call_void2, function_address
from delaytrack.plants.mujoco.plant import mujoco_step
from delaytrack.references.sinusoidal import sinusoidal_reference

__all__ = ["bare_steps", "hand_run"]


@numba.njit(cache=True)
def _loop(step, model, data, steps):
    for _ in range(steps):
        call_void2(step, model, data)


def bare_steps(path: str) -> Callable[[int, np.ndarray, np.ndarray], None]:
    """A function that calls ``mj_step`` ``steps`` times on the data of the model in ``path``
    from ``(qpos, qvel)`` (the data reset first, as a run of the engine resets it). The model
    is read once, here, outside what is timed: the engine's runs do not read it either."""
    import mujoco

    model = mujoco.MjModel.from_xml_path(path)
    data = mujoco.MjData(model)
    step = float(function_address(mujoco, "mj_step"))

    def run(steps: int, qpos: np.ndarray, qvel: np.ndarray) -> None:
        mujoco.mj_resetData(model, data)
        data.qpos[:], data.qvel[:] = qpos, qvel
        _loop(step, float(model._address), float(data._address), steps)

    return run


@numba.njit(cache=True, error_model="numpy")
def _closed_loop(x0, plant_params, delay, sums, shared):
    """One run; ``delay = (offset, amplitude, ω, φ)`` of ``h = offset + amplitude |sin(ω t + φ)|``;
    ``sums`` (n + 1,) receives ``[Σ|e1_j| / K, TV]``. Returns the final state."""
    model, model_params, controller_params, state0, reference_params, m, ticks, dt, per_tick = (
        shared
    )
    n = x0.shape[0] // 2
    T_c = per_tick * dt
    x = x0.copy()
    history = np.zeros((ticks + 1, m))
    applied = np.zeros(m)
    state = state0.copy()
    qd, qd_dot, qd_ddot = np.empty(n), np.empty(n), np.empty(n)
    command, previous = np.empty(m), np.zeros(m)
    work = step_workspace(n, m)
    sums[:] = 0.0
    for k in range(ticks + 1):  # the last tick, at the run's end, counts in the metrics
        t_k = (k * per_tick) * dt
        sinusoidal_reference(t_k, reference_params, qd, qd_dot, qd_ddot)
        arolc_step(
            t_k, x[:n], x[n:], qd, qd_dot, qd_ddot, T_c, 0.0, controller_params, state, model,
            model_params, command, work,
        )  # fmt: skip
        variation = 0.0
        for j in range(m):
            history[k, j] = command[j]
            variation += abs(command[j] - previous[j])
            previous[j] = command[j]
        if k > 0:
            sums[n] += variation
        for j in range(n):
            sums[j] += abs(qd[j] - x[j])
        if k == ticks:
            break
        for step in range(per_tick):
            t = (k * per_tick + step) * dt
            h = delay[0] + delay[1] * abs(math.sin(delay[2] * t + delay[3]))
            g = (t - h) + 1e-9 * dt
            index = math.floor(g / T_c)  # the latest tick <= g, tick i at (i per_tick) dt
            while (index + 1) * per_tick * dt <= g:
                index += 1
            while index >= 0 and (index * per_tick) * dt > g:
                index -= 1
            for j in range(m):
                applied[j] = history[index, j] if index >= 0 else 0.0
            mujoco_step(t, x, applied, dt, plant_params, k == 0 and step == 0)
    for j in range(n):
        sums[j] /= ticks + 1
    return x


def hand_run(plant, controller, delay, reference, x0, duration, dt, T_c) -> tuple:
    """One run of the hand-written closed loop: ``(final state, [AE_j..., TV])``.

    ``plant`` is a :class:`~delaytrack.plants.MujocoPlant` stepped by MuJoCo, ``controller``
    an :class:`~delaytrack.controllers.AROLC` on a MuJoCo model, ``delay`` an
    :class:`~delaytrack.delays.AbsSineDelay`.
    """
    per_tick = round(T_c / dt)
    shared = (
        controller.model.engine_kernel,
        controller.model.params,
        controller.params,
        controller.initial_state(),
        reference.params,
        plant.m,
        round(duration / T_c),
        dt,
        per_tick,
    )
    sums = np.zeros(plant.n + 1)
    return _closed_loop(np.asarray(x0, float), plant.params, delay.params, sums, shared), sums
