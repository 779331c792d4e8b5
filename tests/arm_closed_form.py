"""The two-link arm's closed form, re-typed from the module docstring of
``delaytrack.plants.two_link_arm`` (Dixon et al. 2003): an independent oracle for the tests."""

from __future__ import annotations

import math

import numpy as np

# Default parameters of the arm (module docstring): p1, p2, p3 in kg m^2, fd1, fd2 in N m s.
P1, P2, P3, FD1, FD2 = 3.473, 0.196, 0.242, 5.3, 1.1


def arm_mass(q: np.ndarray, p1=P1, p2=P2, p3=P3) -> np.ndarray:
    """M(q) of the module docstring."""
    c2 = math.cos(q[1])
    return np.array([[p1 + 2 * p3 * c2, p2 + p3 * c2], [p2 + p3 * c2, p2]])


def arm_nonlinear(q, qdot, p3=P3, fd1=FD1, fd2=FD2) -> np.ndarray:
    """N(q, q̇) = V(q, q̇) q̇ + F_d q̇ of the module docstring."""
    s2 = math.sin(q[1])
    coriolis = np.array([-p3 * s2 * (2 * qdot[0] * qdot[1] + qdot[1] ** 2), p3 * s2 * qdot[0] ** 2])
    return coriolis + np.array([fd1 * qdot[0], fd2 * qdot[1]])


def arm_mass_dot(q, qdot, p3=P3) -> np.ndarray:
    """dM/dt along q̇, by hand from the closed form: -p3 sin q2 q̇2 [[2, 1], [1, 0]]."""
    return -p3 * math.sin(q[1]) * qdot[1] * np.array([[2.0, 1.0], [1.0, 0.0]])
