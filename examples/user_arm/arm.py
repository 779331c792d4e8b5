"""A robot of your own at compiled speed: a planar two-link arm in a vertical plane (gravity).

Two links of lengths ``l1, l2`` with point masses ``m1, m2`` at their ends, joint angles ``q1``
(shoulder, from the horizontal) and ``q2`` (elbow, relative), viscous friction ``b`` at each
joint, one torque per joint:

    M(q) = [[(m1 + m2) l1² + m2 l2² + 2 m2 l1 l2 cos q2,  m2 l2² + m2 l1 l2 cos q2],
            [m2 l2² + m2 l1 l2 cos q2,                    m2 l2²]]
    N(q, q̇) = C(q, q̇) q̇ + g(q) + b q̇, with
    C q̇ = [-m2 l1 l2 sin q2 (2 q̇1 q̇2 + q̇2²),  m2 l1 l2 sin q2 q̇1²]
    g(q) = [(m1 + m2) g0 l1 cos q1 + m2 g0 l2 cos(q1 + q2),  m2 g0 l2 cos(q1 + q2)]

(Spong, Hutchinson & Vidyasagar, *Robot Modeling and Control*, 2006, Section 7.3.) The kernel
fills M, N and G in place and is compiled with numba; :func:`make_arm` is the factory a scenario
file names: ``type = "python:arm.py:make_arm"``, its keys become the keyword arguments.
"""

from __future__ import annotations

import math

import numba
import numpy as np

import delaytrack as dt

GRAVITY = 9.81


@numba.njit(cache=True, error_model="numpy")
def arm_terms(t, q, qdot, params, M, N, G):
    m1, m2, l1, l2, b = params[0], params[1], params[2], params[3], params[4]
    c2 = math.cos(q[1])
    s2 = math.sin(q[1])
    coupling = m2 * l1 * l2
    M[0, 0] = (m1 + m2) * l1 * l1 + m2 * l2 * l2 + 2.0 * coupling * c2
    M[0, 1] = m2 * l2 * l2 + coupling * c2
    M[1, 0] = M[0, 1]
    M[1, 1] = m2 * l2 * l2
    elbow = m2 * GRAVITY * l2 * math.cos(q[0] + q[1])
    N[0] = (
        -coupling * s2 * (2.0 * qdot[0] * qdot[1] + qdot[1] * qdot[1])
        + (m1 + m2) * GRAVITY * l1 * math.cos(q[0])
        + elbow
        + b * qdot[0]
    )
    N[1] = coupling * s2 * qdot[0] * qdot[0] + elbow + b * qdot[1]
    G[0, 0] = 1.0
    G[0, 1] = 0.0
    G[1, 0] = 0.0
    G[1, 1] = 1.0


def make_arm(
    m1: float = 1.0,
    m2: float = 0.8,
    l1: float = 0.5,
    l2: float = 0.4,
    friction: float = 0.3,
    mass_scale: float = 1.0,
) -> dt.CompiledPlant:
    """The arm, its masses multiplied by ``mass_scale`` (a wrong nominal model, as a user would
    test one)."""
    parameters = [mass_scale * m1, mass_scale * m2, l1, l2, friction]
    return dt.CompiledPlant(
        2,
        2,
        arm_terms,
        np.array(parameters, dtype=float),
        name="vertical arm",
        coordinate_names=("shoulder", "elbow"),
        coordinate_units=("rad", "rad"),
        input_units=("N·m", "N·m"),
    )
