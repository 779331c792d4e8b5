"""The paper's robot with real wheels: the PIONEER-3 DX as a MuJoCo model, contacts included.

:class:`MujocoWheeledRobot` steps ``data/p3dx.xml`` (or a model file of yours with the same
joint and body names) with MuJoCo: the wheels roll on the floor through friction contacts, so
they can slip, the platform rests on a ball caster, and the paper's payload is put on and taken
off at run time. Its coordinates are those of the analytic robot,
``q = (x_c, y_c, φ, θ_r, θ_l)``, and its inputs the wheel torques, so the paper's controllers and
nominal model (:class:`~delaytrack.plants.robot.NominalRobot`) run on it unchanged. The floating
base's height, pitch and roll move in MuJoCo's data; the plant's coordinates leave them out.

The payload follows :class:`~delaytrack.plants.robot.PayloadRobot`'s schedule (the same keys,
the same random placements for a seed): before each MuJoCo step, the body ``payload`` of the
model gets the mass ``m_p`` and the placement ``p = (p_x, p_y)`` in force at the step's start as
its centre of mass (``body_mass``, ``body_ipos``; a point mass on the top plate, ``p`` from the
axle midpoint A), or no mass. As in the analytic robot, the velocities stay continuous when it
is placed or removed.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from delaytrack._compile.jit import tick_kernel
from delaytrack.plants.mujoco.capi import write_at
from delaytrack.plants.mujoco.plant import MujocoPlant, extras_start, import_mujoco, mujoco_step
from delaytrack.plants.robot.body import COORDINATES
from delaytrack.plants.robot.payload import SCHEDULE_POINTS, PayloadSchedule, active_placement

__all__ = ["P3DX_MJCF", "MujocoWheeledRobot", "wheeled_robot_step"]

#: The PIONEER-3 DX model file that ships with delaytrack (its comments give every value's source).
P3DX_MJCF = Path(str(resources.files("delaytrack") / "data" / "p3dx.xml"))
#: After MuJoCo's parameters: the addresses of the payload body's mass and centre of mass.
_BODY_MASS, _BODY_CENTER, _SCHEDULE = range(3)
#: A schedule without placements: [m_p, first_on, time_on, time_off, count].
_NO_PAYLOAD = np.array([0.0, 0.0, 1.0, 1.0, 0.0])


@tick_kernel
def wheeled_robot_step(t, x, u, dt, params, first):
    """One MuJoCo step (:func:`~delaytrack.plants.mujoco.plant.mujoco_step`) with the payload in
    force at ``t`` written into the model first: mass ``m_p`` at the placement ``(p_x, p_y)``
    from A, or no mass."""
    at = extras_start(x.shape[0] // 2)
    schedule = at + _SCHEDULE
    k = active_placement(t, params, schedule)
    if k >= 0:
        write_at(params[at + _BODY_MASS], 0, params[schedule])
        write_at(params[at + _BODY_CENTER], 0, params[schedule + SCHEDULE_POINTS + 2 * k])
        write_at(params[at + _BODY_CENTER], 1, params[schedule + SCHEDULE_POINTS + 1 + 2 * k])
    else:
        write_at(params[at + _BODY_MASS], 0, 0.0)
    mujoco_step(t, x, u, dt, params, first)


@dataclass(frozen=True, eq=False)
class MujocoWheeledRobot(PayloadSchedule, MujocoPlant):
    """The PIONEER-3 DX stepped by MuJoCo: wheels on the floor through contacts (module
    docstring), optionally carrying the paper's payload.

    Give ``seed`` and ``duration`` (random placements) or ``placements`` for the payload, or
    neither for a robot without payload. Its ``dt`` is the file's timestep (1 ms).

    Parameters
    ----------
    path : str or Path
        The model file: :data:`P3DX_MJCF` by default. One of yours needs the joints ``x, y,
        phi, theta_r, theta_l`` (the coordinates), two actuators (right wheel, left wheel) and
        a body ``payload`` whose frame is at the axle midpoint A.
    mass_scale : float
        Factor (> 0) on every body's mass and inertia (the payload's is set at run time).
    contact_time_constant : float, optional
        How soft the wheels' contacts are (s; MuJoCo's default 0.02 s by default), as for
        :class:`~delaytrack.plants.mujoco.MujocoPlant`.
    placements, seed, duration, payload_mass, time_on, time_off, first_on, plate_length,
    plate_width, plate_center, beyond
        The payload and its schedule, as for :class:`~delaytrack.plants.robot.PayloadRobot`
        (:class:`~delaytrack.plants.robot.payload.PayloadSchedule`).
    name : str, optional
        Shown in results and reports.

    Notes
    -----
    ``stepping`` is ``"mujoco"`` and ``coordinates`` the analytic robot's; other values are
    refused. MuJoCo's model of this plant is written at run time (the payload), so each thread
    of a batch runs a copy of its own, as for every MuJoCo plant.
    """

    path: str | Path = P3DX_MJCF
    stepping: str = "mujoco"
    coordinates: tuple[str, ...] | None = COORDINATES
    _schedule: np.ndarray | None = field(init=False, repr=False)
    type_name: ClassVar[str] = "wheeled-robot-mujoco"

    def __post_init__(self) -> None:
        if self.stepping != "mujoco":
            raise ValueError(
                f"stepping must be 'mujoco' for the robot with contacts; got {self.stepping!r}"
            )
        if self.coordinates is None or tuple(self.coordinates) != COORDINATES:
            raise ValueError(
                f"coordinates must be the analytic robot's {list(COORDINATES)} (the controllers' "
                f"model has them); got {self.coordinates!r}"
            )
        super().__post_init__()
        if self.m != 2:
            raise ValueError(
                f"path {str(self.path)!r}: the robot needs two actuators (right wheel, left "
                f"wheel); the model has {self.m}"
            )
        mujoco = import_mujoco()
        body = mujoco.mj_name2id(self._model, mujoco.mjtObj.mjOBJ_BODY, "payload")
        if body < 0:
            raise ValueError(
                f"path {str(self.path)!r}: the model has no body 'payload' (its frame at the "
                "axle midpoint, on the top plate), which carries the payload"
            )
        # MuJoCo skips body_ipos of a body whose centre of mass was at its frame's origin when
        # compiled (body_sameframe): the payload's moves at run time.
        self._model.body_sameframe[body] = 0
        carried = not (self.placements is None and self.seed is None and self.duration is None)
        schedule = self._checked_schedule() if carried else None
        object.__setattr__(self, "_schedule", schedule)
        schedule = _NO_PAYLOAD if schedule is None else schedule
        addresses = [
            self._model.body_mass.ctypes.data + 8 * body,
            self._model.body_ipos.ctypes.data + 24 * body,
        ]
        object.__setattr__(self, "_params", np.concatenate([self._params, addresses, schedule]))
        digest = hashlib.sha256(self._identity.tobytes() + schedule.tobytes()).digest()
        object.__setattr__(self, "_identity", np.frombuffer(digest, dtype=np.uint8).astype(float))

    @property
    def stepper_kernel(self):
        return wheeled_robot_step

    @property
    def horizon(self) -> float:
        """End of the payload's schedule (``inf`` without payload or with ``beyond="hold"``)."""
        if self._schedule is None:
            return math.inf
        return self._schedule_horizon(len(self._schedule[SCHEDULE_POINTS:]) // 2)

    def placement_at(self, t: float) -> np.ndarray | None:
        """Body-frame point (2,) of the payload in force at ``t`` (from A), or None."""
        if self._schedule is None:
            return None
        k = active_placement(float(t), self._schedule, 0)
        return None if k < 0 else self._schedule[SCHEDULE_POINTS:].reshape(-1, 2)[k].copy()

    def to_spec(self) -> dict[str, Any]:
        spec: dict[str, Any] = {"type": self.type_name}
        if Path(self.path) != P3DX_MJCF:
            spec["path"] = str(self.path)
        if self.mass_scale != 1.0:
            spec["mass_scale"] = self.mass_scale
        if self.contact_time_constant is not None:
            spec["contact_time_constant"] = self.contact_time_constant
        if self._schedule is not None:
            placements = self._schedule[SCHEDULE_POINTS:].reshape(-1, 2)
            spec.update(self._schedule_spec(placements))
        return spec
