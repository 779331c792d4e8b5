"""The paper's printed robot model ``M̄(q) q̈ + V̄(q, q̇) = G u`` (Section 3), as printed.

::

    M̄ = [[m,      0,      K sφ,   k1,   k2 ],        V̄ = [m d φ̇² cφ + m r̄² sφ (θ̇_r² - θ̇_l²)/(2b),
         [0,      m,     -K cφ,   k3,   k4 ],             m d φ̇² cφ - m r̄² sφ (θ̇_r² - θ̇_l²)/(2b),
         [K sφ,  -K cφ,   Ī,     -k5,   k5 ],             K r̄² (θ̇_r² - θ̇_l²)/(2b),
         [k1,     k3,    -k5,     I_w,  0  ],            -K r̄ φ̇²/2,
         [k2,     k4,     k5,     0,    I_w]]            -K r̄ φ̇²/2]

    k1 = sφ (m d r̄ - K r̄)/b - m r̄ cφ/2,   k2 = sφ (K r̄ - m d r̄)/b - m r̄ cφ/2,
    k3 = cφ (K r̄ - m d r̄)/b - m r̄ sφ/2,   k4 = cφ (m d r̄ - K r̄)/b - m r̄ sφ/2,
    k5 = r̄ (I - K d)/b,                     G = [0; 0; 0; I]

(``sφ = sin φ``, ``cφ = cos φ``; the paper's ``I`` in ``k5`` is read as its ``Ī``.)

What we find (pinned in ``tests/test_robot_printed.py``, discussed in ``docs/robot.md``):

* With P3-DX values (m = 9, d = 0.05, r̄ = 0.0975, b = 0.165, Ī = 0.264, I_w = 0.01) ``M̄`` is
  indefinite for every φ: λ_min = -0.107 (K = m d), -0.127 (K = 2 m_w d = 0.05, our default),
  -0.129 (K = 0).
* Relation to our derivation: with ``M̂₁₁`` the top-left 3×3 block of the unconstrained
  Lagrangian's mass matrix (:mod:`~delaytrack.plants.robot.nominal`, with ``Ī`` for ``I_P``),
  ``N̂₁:₃ = [K cos φ φ̇², K sin φ φ̇², 0]`` its Coriolis terms, and ``S_b`` the kinematic map in
  which ``ω = r̄ (θ̇_r - θ̇_l)/b`` (b the *full* track; the P3-DX half track 0.165 needs ``2b``)::

      M̄ = [[M̂₁₁, -M̂₁₁ S_b], [-S_bᵀ M̂₁₁, I_w I]],   V̄₁:₃ = -M̂₁₁ Ṡ_b η,   V̄₄:₅ = -S_bᵀ N̂₁:₃

  Rows 1–3 are ``M̂₁₁`` times the differentiated velocity constraints (zero along every motion
  with ``q̇ = S_b η``), except that the printed row 2 has ``cos φ`` and ``sin φ`` swapped: the
  consistent row 2 is ``m d φ̇² sin φ - m r̄² cos φ (θ̇_r² - θ̇_l²)/(2b)``
  (``corrected_row2=True``). Rows 4–5 read ``I_w θ̈ - S_bᵀ (M̂₁₁ q̈₁:₃ + N̂₁:₃) = u``, where
  Lagrange's multipliers give ``I_w θ̈ + S_bᵀ (M̂₁₁ q̈₁:₃ + N̂₁:₃) = u``.
* ``M̄`` is positive definite iff ``I_w I - S_bᵀ M̂₁₁ S_b`` is (Schur complement), i.e. iff the
  wheel's spin inertia exceeds the largest reduced inertia of the whole robot:
  ``I_w > 0.169`` (K = m d) or ``0.197 kg·m²`` (K = 0.05), never for a bare wheel.

As a nominal model its command map is ``τ_w = S(q)ᵀ τ`` with the half-track kinematics
(``command_map_kernel``), as for :class:`~delaytrack.plants.robot.nominal.NominalRobot`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from delaytrack._compile.jit import kernel
from delaytrack._validation import positive_scalar
from delaytrack.plants.base import ELPlant
from delaytrack.plants.robot.body import (
    COORDINATE_UNITS,
    COORDINATES,
    INPUT_NAMES,
    INPUT_UNITS,
)
from delaytrack.plants.robot.kinematics import robot_command_map
from delaytrack.plants.robot.parameters import P3DX

__all__ = ["PrintedRobotModel", "robot_printed_terms"]


@kernel
def robot_printed_terms(t, q, qdot, params, mass, nonlinear, input_map):
    """Fill ``M̄``, ``V̄``, ``G``; ``params = [r̄, b, d, m, K, Ī, I_w, corrected_row2]``."""
    r = params[0]
    b = params[1]
    d = params[2]
    m = params[3]
    K = params[4]
    inertia = params[5]
    Iw = params[6]
    corrected = params[7] != 0.0
    c = math.cos(q[2])
    s = math.sin(q[2])
    k1 = s * (m * d * r - K * r) / b - m * r * c / 2.0
    k2 = s * (K * r - m * d * r) / b - m * r * c / 2.0
    k3 = c * (K * r - m * d * r) / b - m * r * s / 2.0
    k4 = c * (m * d * r - K * r) / b - m * r * s / 2.0
    k5 = r * (inertia - K * d) / b
    for i in range(5):  # loops over the model's sizes: a slice assignment is a memset call
        for j in range(5):
            mass[i, j] = 0.0
    mass[0, 0] = m
    mass[1, 1] = m
    mass[0, 2] = K * s
    mass[1, 2] = -K * c
    mass[2, 2] = inertia
    mass[0, 3] = k1
    mass[0, 4] = k2
    mass[1, 3] = k3
    mass[1, 4] = k4
    mass[2, 3] = -k5
    mass[2, 4] = k5
    mass[3, 3] = Iw
    mass[4, 4] = Iw
    for i in range(5):
        for j in range(i):
            mass[i, j] = mass[j, i]
    phidot2 = qdot[2] * qdot[2]
    wheels = r * r * (qdot[3] * qdot[3] - qdot[4] * qdot[4]) / (2.0 * b)
    nonlinear[0] = m * d * phidot2 * c + m * s * wheels
    if corrected:
        nonlinear[1] = m * d * phidot2 * s - m * c * wheels
    else:
        nonlinear[1] = m * d * phidot2 * c - m * s * wheels
    nonlinear[2] = K * wheels
    nonlinear[3] = -K * r * phidot2 / 2.0
    nonlinear[4] = -K * r * phidot2 / 2.0
    for i in range(5):
        for j in range(2):
            input_map[i, j] = 0.0
    input_map[3, 0] = 1.0
    input_map[4, 1] = 1.0


@dataclass(frozen=True, eq=False)
class PrintedRobotModel(ELPlant):
    """The paper's printed ``M̄, V̄`` (module docstring) as a nominal model.

    Parameters
    ----------
    wheel_radius : float
        ``r̄``, m (0.0975).
    half_track : float
        ``b``, m (0.165, read as the half track).
    d : float
        m (0.05).
    mass : float
        ``m``, kg (9).
    first_moment : float
        ``K``, kg·m; default ``2 m_w d`` = 0.05, the value our derivation gives for the P3-DX
        (``P3DX.first_moment``).
    inertia : float
        ``Ī`` (and the ``I`` of ``k5``), kg·m² (0.264).
    wheel_spin_inertia : float
        ``I_w``, kg·m² (0.01).
    corrected_row2 : bool
        Use the consistent second row of ``V̄`` instead of the printed one (default False).
    """

    wheel_radius: float = P3DX.wheel_radius
    half_track: float = P3DX.half_track
    d: float = P3DX.d
    mass: float = P3DX.mass
    first_moment: float = P3DX.first_moment
    inertia: float = P3DX.yaw_inertia
    wheel_spin_inertia: float = P3DX.wheel_spin_inertia
    corrected_row2: bool = False
    n = 5
    m = 2
    coordinate_names = COORDINATES
    coordinate_units = COORDINATE_UNITS
    input_units = INPUT_UNITS
    input_names = INPUT_NAMES
    type_name: ClassVar[str] = "wheeled-robot-printed"

    def __post_init__(self) -> None:
        for name in ("wheel_radius", "half_track", "mass", "inertia", "wheel_spin_inertia"):
            object.__setattr__(self, name, positive_scalar(name, getattr(self, name)))
        object.__setattr__(
            self, "first_moment", positive_scalar("first_moment", self.first_moment, strictly=False)
        )
        object.__setattr__(self, "d", positive_scalar("d", self.d, strictly=False))
        if not isinstance(self.corrected_row2, bool | np.bool_):
            raise TypeError(f"corrected_row2 must be True or False; got {self.corrected_row2!r}")

    @property
    def params(self) -> np.ndarray:
        return np.array(
            [
                self.wheel_radius,
                self.half_track,
                self.d,
                self.mass,
                self.first_moment,
                self.inertia,
                self.wheel_spin_inertia,
                1.0 if self.corrected_row2 else 0.0,
            ]
        )

    @property
    def terms_kernel(self):
        return robot_printed_terms

    @property
    def command_map_kernel(self):
        return robot_command_map

    def to_spec(self) -> dict[str, Any]:
        return {
            "type": self.type_name,
            "wheel_radius": self.wheel_radius,
            "half_track": self.half_track,
            "d": self.d,
            "mass": self.mass,
            "first_moment": self.first_moment,
            "inertia": self.inertia,
            "wheel_spin_inertia": self.wheel_spin_inertia,
            "corrected_row2": bool(self.corrected_row2),
        }
