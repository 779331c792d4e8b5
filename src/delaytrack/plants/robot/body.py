"""The rigid body shared by the robot plants: geometry, mass, inertia, and their aggregates.

The dynamics need four aggregates of the rigid part (platform + wheel masses + wheel yaw inertia,
plus a payload when there is one), all about the axle midpoint A in the body frame
``(e, n)`` = (forward, left):

    M_b = m                            total mass
    s   = (s_x, s_y) = m_c (c_x, c_y)  first moment about A (the wheels' moments cancel)
    I_A = I                            yaw inertia about A

where ``(c_x, c_y)`` is the platform's centre of mass (``(d, 0)`` by default). Kernels receive
``[R, L, d, M_b, s_x, s_y, I_A, I_w]`` (:meth:`RobotBody.body_params`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from delaytrack._validation import finite_scalar, positive_scalar
from delaytrack.plants.robot.parameters import P3DX

__all__ = ["BODY_KEYS", "COORDINATES", "RobotBody"]

#: The robot's coordinates q: look-ahead point x, y (m), heading phi and wheel angles (rad).
COORDINATES = ("x", "y", "phi", "theta_r", "theta_l")
#: Units of :data:`COORDINATES` and of the two wheel torques.
COORDINATE_UNITS = ("m", "m", "rad", "rad", "rad")
INPUT_UNITS = ("N·m", "N·m")
#: The two wheel torques, right and left, as the wheel angles are named.
INPUT_NAMES = ("tau_r", "tau_l")

#: Names of the body fields, in the order of their scenario keys.
BODY_KEYS = (
    "wheel_radius",
    "half_track",
    "d",
    "mass",
    "yaw_inertia",
    "wheel_mass",
    "wheel_spin_inertia",
    "com_forward",
    "com_lateral",
)


@dataclass(frozen=True, eq=False)
class RobotBody:
    """Geometry and inertia of a differential-drive robot (defaults: :data:`~.parameters.P3DX`).

    Parameters
    ----------
    wheel_radius : float
        ``R`` (the paper's ``r̄``), m, ``> 0``.
    half_track : float
        ``L`` (the paper's ``b``), m, ``> 0``.
    d : float
        Distance of the tracked point ``(x_c, y_c)`` ahead of the axle midpoint A, m.
    mass : float
        Total mass ``m`` including the wheels, kg.
    yaw_inertia : float
        Yaw inertia ``I`` of the whole robot about the vertical through A, kg·m².
    wheel_mass : float
        ``m_w`` of each wheel, kg, ``0 <= 2 m_w < m``.
    wheel_spin_inertia : float
        ``I_w`` of each wheel about its axle, kg·m², ``> 0``.
    com_forward, com_lateral : float, optional
        The platform's centre of mass ``(c_x, c_y)`` from A (forward, left), m; ``(d, 0)`` by
        default. ``yaw_inertia`` stays the inertia about A.
    """

    wheel_radius: float = P3DX.wheel_radius
    half_track: float = P3DX.half_track
    d: float = P3DX.d
    mass: float = P3DX.mass
    yaw_inertia: float = P3DX.yaw_inertia
    wheel_mass: float = P3DX.wheel_mass
    wheel_spin_inertia: float = P3DX.wheel_spin_inertia
    com_forward: float | None = None
    com_lateral: float = 0.0
    # The sizes, names and units of the robot plants built on this body, typed as ELPlant
    # declares them (a plant's names may be None).
    n: ClassVar[int] = 5
    m: ClassVar[int] = 2
    coordinate_names: ClassVar[tuple[str, ...] | None] = COORDINATES
    coordinate_units: ClassVar[tuple[str, ...] | None] = COORDINATE_UNITS
    input_units: ClassVar[tuple[str, ...] | None] = INPUT_UNITS
    input_names: ClassVar[tuple[str, ...] | None] = INPUT_NAMES

    def _check_body(self) -> None:
        for name in ("wheel_radius", "half_track", "mass", "yaw_inertia", "wheel_spin_inertia"):
            object.__setattr__(self, name, positive_scalar(name, getattr(self, name)))
        object.__setattr__(
            self, "wheel_mass", positive_scalar("wheel_mass", self.wheel_mass, strictly=False)
        )
        object.__setattr__(self, "d", finite_scalar("d", self.d))
        forward = finite_scalar(
            "com_forward", self.d if self.com_forward is None else self.com_forward
        )
        object.__setattr__(self, "com_forward", forward)
        object.__setattr__(self, "com_lateral", finite_scalar("com_lateral", self.com_lateral))
        if not 2.0 * self.wheel_mass < self.mass:
            raise ValueError(
                f"wheel_mass must be less than half the total mass (the platform needs mass); "
                f"got wheel_mass = {self.wheel_mass:g} kg, mass = {self.mass:g} kg"
            )
        platform = self.mass - 2.0 * self.wheel_mass
        try:
            parallel = (
                platform * (forward**2 + self.com_lateral**2)
                + 2.0 * self.wheel_mass * self.half_track**2
            )
        except OverflowError:  # a length of 1e155 m squared
            parallel = math.inf
        if not math.isfinite(parallel):
            raise ValueError(
                "the robot's lengths (m) and masses (kg) give a parallel-axis inertia "
                "m_c |c|² + 2 m_w L² beyond the largest float: half_track = "
                f"{self.half_track:g}, com_forward = {forward:g}, com_lateral = "
                f"{self.com_lateral:g}, mass = {self.mass:g}, wheel_mass = {self.wheel_mass:g}; "
                "give the robot's lengths in metres and masses in kilograms"
            )
        own = self.yaw_inertia - parallel
        if own < 0.0:
            raise ValueError(
                "yaw_inertia must be at least the parallel-axis share of the platform and wheel "
                f"masses, m_c |c|² + 2 m_w L² = {self.yaw_inertia - own:.6g} kg·m²; "
                f"got {self.yaw_inertia:g}"
            )

    @property
    def platform_mass(self) -> float:
        """``m_c = m - 2 m_w``, kg."""
        return self.mass - 2.0 * self.wheel_mass

    def body_params(self) -> np.ndarray:
        """``[R, L, d, M_b, s_x, s_y, I_A, I_w]`` (module docstring)."""
        assert self.com_forward is not None  # construction sets it (d when not given)
        return np.array(
            [
                self.wheel_radius,
                self.half_track,
                self.d,
                self.mass,
                self.platform_mass * self.com_forward,
                self.platform_mass * self.com_lateral,
                self.yaw_inertia,
                self.wheel_spin_inertia,
            ]
        )

    def body_spec(self) -> dict[str, Any]:
        """The body fields as plain data (scenario keys)."""
        return {key: float(getattr(self, key)) for key in BODY_KEYS}
