"""The floor for the MuJoCo case of ``make bench``: MuJoCo stepping the model alone.

:func:`bare_steps` calls ``mj_step`` ``steps`` times on the model's data from a compiled loop
(no controller, no delay, no Python between steps), through the same C entry point the
MuJoCo-stepped plant uses (:mod:`delaytrack.plants.mujoco.capi`): what a closed loop around
MuJoCo cannot be faster than.
"""

from __future__ import annotations

import numba
import numpy as np

from delaytrack.plants.mujoco.capi import call_void2, function_address

__all__ = ["bare_steps"]


@numba.njit(cache=True)
def _loop(step, model, data, steps):
    for _ in range(steps):
        call_void2(step, model, data)


def bare_steps(path: str, steps: int, qpos: np.ndarray, qvel: np.ndarray) -> None:
    """``steps`` calls of ``mj_step`` on a fresh copy of the model in ``path`` from
    ``(qpos, qvel)``."""
    import mujoco

    model = mujoco.MjModel.from_xml_path(path)
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = qpos, qvel
    _loop(
        float(function_address(mujoco, "mj_step")),
        float(model._address),
        float(data._address),
        steps,
    )
