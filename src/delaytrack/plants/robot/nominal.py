"""The controllers' nominal robot model: the unconstrained Lagrangian in ``q`` (docs/robot.md).

The kinetic energy of the robot (platform, wheels; no payload, no friction) with the constraints
*not* substituted, in ``q = (x_c, y_c, φ, θ_r, θ_l)`` (derived in ``scripts/derive_robot.py``),
gives ``M̂(q) q̈ + N̂(q, q̇) = G τ`` with ``G = [0; 0; 0; I]`` and::

    M̂(q) = [[m,                    0,                    K sφ - s_y cφ,  0,   0  ],
            [0,                    m,                   -K cφ - s_y sφ,  0,   0  ],
            [K sφ - s_y cφ,       -K cφ - s_y sφ,        I_P,            0,   0  ],
            [0,                    0,                    0,              I_w, 0  ],
            [0,                    0,                    0,              0,   I_w]]

    N̂(q, q̇) = [(K cφ + s_y sφ) φ̇²,  (K sφ - s_y cφ) φ̇²,  0,  0,  0]

with ``K = m d - s_x`` (first moment, about the tracked point, of the parts not at it: ``2 m_w d``
for the P3-DX defaults), ``I_P = I_A - 2 d s_x + m d²`` (yaw inertia about the tracked point) and
``s_y = 0`` unless the platform's centre of mass is off the heading axis. ``M̂`` is symmetric
positive definite (it is the kinetic-energy metric of free rigid bodies).

The controller computes a generalised force ``τ = M̂ u + N̂`` (5,) and the wheel torques are its
projection ``τ_w = S(q)ᵀ τ`` (:func:`~delaytrack.plants.robot.kinematics.robot_command_map`):
``Sᵀ`` removes the components the constraint forces would absorb (``Sᵀ Λᵀ = 0``), and
``Sᵀ M̂ S`` is the reduced wheel-space mass matrix of the truth plant.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from delaytrack._compile.jit import hot_kernel
from delaytrack.plants.base import ELPlant
from delaytrack.plants.robot.body import RobotBody
from delaytrack.plants.robot.kinematics import robot_command_map

__all__ = ["NominalRobot", "robot_nominal_terms"]


@hot_kernel
def robot_nominal_terms(t, q, qdot, params, mass, nonlinear, input_map):
    """Fill ``M̂``, ``N̂``, ``G``; ``params = [R, L, d, M_b, s_x, s_y, I_A, I_w]``."""
    d = params[2]
    mass_b = params[3]
    s_x = params[4]
    s_y = params[5]
    inertia_a = params[6]
    Iw = params[7]
    K = mass_b * d - s_x
    inertia_p = inertia_a - 2.0 * d * s_x + mass_b * d * d
    c = math.cos(q[2])
    s = math.sin(q[2])
    for i in range(5):  # loops over the model's sizes: a slice assignment is a memset call
        for j in range(5):
            mass[i, j] = 0.0
    mass[0, 0] = mass_b
    mass[1, 1] = mass_b
    mass[0, 2] = K * s - s_y * c
    mass[2, 0] = mass[0, 2]
    mass[1, 2] = -K * c - s_y * s
    mass[2, 1] = mass[1, 2]
    mass[2, 2] = inertia_p
    mass[3, 3] = Iw
    mass[4, 4] = Iw
    phidot2 = qdot[2] * qdot[2]
    nonlinear[0] = (K * c + s_y * s) * phidot2
    nonlinear[1] = (K * s - s_y * c) * phidot2
    nonlinear[2] = 0.0
    nonlinear[3] = 0.0
    nonlinear[4] = 0.0
    for i in range(5):
        for j in range(2):
            input_map[i, j] = 0.0
    input_map[3, 0] = 1.0
    input_map[4, 1] = 1.0


@dataclass(frozen=True, eq=False)
class NominalRobot(RobotBody, ELPlant):
    """The unconstrained Lagrangian model of the robot (module docstring), for controllers.

    Parameters are those of :class:`~delaytrack.plants.robot.body.RobotBody` (P3-DX defaults).
    As a nominal model its command map is ``τ_w = S(q)ᵀ τ`` (``command_map_kernel``). As a plant it
    would ignore the constraints: use :class:`~delaytrack.plants.robot.truth.WheeledRobot`.
    """

    type_name: ClassVar[str] = "wheeled-robot-nominal"

    def __post_init__(self) -> None:
        self._check_body()

    @property
    def params(self) -> np.ndarray:
        return self.body_params()

    @property
    def terms_kernel(self):
        return robot_nominal_terms

    @property
    def command_map_kernel(self):
        return robot_command_map

    def to_spec(self) -> dict[str, Any]:
        return {"type": self.type_name, **self.body_spec()}

    @property
    def first_moment(self) -> float:
        """``K = m d - s_x``, kg·m."""
        params = self.params
        return float(params[3] * params[2] - params[4])

    @property
    def inertia_about_point(self) -> float:
        """``I_P = I_A - 2 d s_x + m d²``, yaw inertia about the tracked point, kg·m²."""
        params = self.params
        return float(params[6] - 2.0 * params[2] * params[4] + params[3] * params[2] ** 2)
