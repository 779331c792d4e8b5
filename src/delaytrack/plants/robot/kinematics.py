"""Kinematics of the differential-drive robot in ``q = (x_c, y_c, φ, θ_r, θ_l)``.

``(x_c, y_c) = A + d e`` is the body point at distance ``d`` ahead of the axle midpoint A,
``e = (cos φ, sin φ)`` the heading, ``n = (-sin φ, cos φ)`` the robot's left; the right wheel is at
``A - L n``, the left at ``A + L n``. With ``η = (θ̇_r, θ̇_l)``:

    v = R (θ̇_r + θ̇_l) / 2,   ω = R (θ̇_r - θ̇_l) / (2 L)        (forward speed of A, yaw rate)

    q̇ = S(q) η,   S(q) = [[R/2 cos φ - d R/(2L) sin φ,   R/2 cos φ + d R/(2L) sin φ],
                           [R/2 sin φ + d R/(2L) cos φ,   R/2 sin φ - d R/(2L) cos φ],
                           [R/(2L),                       -R/(2L)                   ],
                           [1,                            0                         ],
                           [0,                            1                         ]]

and the three nonholonomic constraints ``Λ(q) q̇ = 0`` (no lateral slip at A; each wheel rolls):

    Λ(q) = [[-sin φ,  cos φ,  -d,   0,   0],
            [ cos φ,  sin φ,   L,  -R,   0],
            [ cos φ,  sin φ,  -L,   0,  -R]]

(``Λ S = 0``; the textbook Λ with A replaced by the look-ahead point.) ``S(q)ᵀ G = I`` for
``G = [0; 0; 0; I]``: the robot's command map ``τ_w = S(q)ᵀ τ`` sends a generalised force
``τ`` (5,) to the two wheel torques (docs/robot.md). Checked symbolically by
``scripts/derive_robot.py``.
"""

from __future__ import annotations

import math

import numpy as np

from delaytrack._compile.functions import at_few_points
from delaytrack._compile.jit import hot_kernel, kernel

__all__ = [
    "constraint_matrix",
    "constraint_residual",
    "consistent_state",
    "kinematic_map",
    "kinematic_map_entries",
    "kinematic_map_kernel",
    "kinematic_map_rate",
    "robot_command_map",
    "robot_velocity_map",
]


@hot_kernel
def kinematic_map_entries(c, s, R, L, d):
    """The entries of rows x, y, φ of ``S(q)`` that vary: ``(S_00, S_01, S_10, S_11, S_20)``.

    ``c, s`` are ``cos φ, sin φ``; ``S_21 = -S_20`` and rows θ_r, θ_l are the identity.
    """
    a = 0.5 * R
    b = R / (2.0 * L)
    return a * c - d * b * s, a * c + d * b * s, a * s + d * b * c, a * s - d * b * c, b


@hot_kernel
def robot_velocity_map(q, eta, params, qdot):
    """``q̇ = S(q) η`` (module docstring), ``η = (θ̇_r, θ̇_l)``: the velocity map of the robot's
    reduced form (``eta`` may be ``qdot[3:5]`` itself; it is read first)."""
    R, L, d = params[0], params[1], params[2]
    wr = eta[0]
    wl = eta[1]
    v = 0.5 * R * (wr + wl)
    w = R * (wr - wl) / (2.0 * L)
    c = math.cos(q[2])
    s = math.sin(q[2])
    qdot[0] = v * c - d * w * s
    qdot[1] = v * s + d * w * c
    qdot[2] = w
    qdot[3] = wr
    qdot[4] = wl


@kernel
def kinematic_map_kernel(phi, R, L, d, S):
    """Fill ``S(q)`` (5, 2); it depends on φ only."""
    S[0, 0], S[0, 1], S[1, 0], S[1, 1], S[2, 0] = kinematic_map_entries(
        math.cos(phi), math.sin(phi), R, L, d
    )
    S[2, 1] = -S[2, 0]
    S[3, 0] = 1.0
    S[3, 1] = 0.0
    S[4, 0] = 0.0
    S[4, 1] = 1.0


@hot_kernel
def robot_command_map(q, params, tau, command):
    """Wheel torques ``command = S(q)ᵀ τ``; ``params`` starts with ``[R, L, d]``.

    The command map of the robot's nominal models (see
    :func:`delaytrack.components.call_command_map`).
    """
    phi = q[2]
    S00, S01, S10, S11, S20 = kinematic_map_entries(
        math.cos(phi), math.sin(phi), params[0], params[1], params[2]
    )
    command[0] = S00 * tau[0] + S10 * tau[1] + S20 * tau[2] + tau[3]
    command[1] = S01 * tau[0] + S11 * tau[1] - S20 * tau[2] + tau[4]


def _angles(q: np.ndarray) -> np.ndarray:
    q = np.asarray(q, dtype=float)
    if q.shape[-1] != 5:
        raise ValueError(f"q must have 5 entries (x_c, y_c, phi, theta_r, theta_l); got {q.shape}")
    return q[..., 2]


def kinematic_map(q: np.ndarray, wheel_radius: float, half_track: float, d: float) -> np.ndarray:
    """``S(q)`` with ``q̇ = S(q) η``; shape ``(*batch, 5, 2)`` for ``q (*batch, 5)``."""
    phi = _angles(q)

    def each_angle(kernel):
        out = np.empty((*phi.shape, 5, 2))
        for index in np.ndindex(phi.shape):
            kernel(float(phi[index]), wheel_radius, half_track, d, out[index])
        return out

    return at_few_points(kinematic_map_kernel, phi.size, each_angle)


def kinematic_map_rate(
    q: np.ndarray, qdot: np.ndarray, wheel_radius: float, half_track: float, d: float
) -> np.ndarray:
    """``Ṡ = (∂S/∂φ) φ̇``, shape ``(*batch, 5, 2)``; on the manifold ``q̈ = S η̇ + Ṡ η``."""
    phi = _angles(q)
    phidot = _angles(qdot)
    c, s = np.cos(phi), np.sin(phi)
    a = 0.5 * wheel_radius
    b = wheel_radius / (2.0 * half_track)
    out = np.zeros((*phi.shape, 5, 2))
    out[..., 0, 0] = -a * s - d * b * c
    out[..., 0, 1] = -a * s + d * b * c
    out[..., 1, 0] = a * c - d * b * s
    out[..., 1, 1] = a * c + d * b * s
    return out * phidot[..., None, None]


def constraint_matrix(
    q: np.ndarray, wheel_radius: float, half_track: float, d: float
) -> np.ndarray:
    """``Λ(q)`` (module docstring); shape ``(*batch, 3, 5)`` for ``q (*batch, 5)``."""
    phi = _angles(q)
    c, s = np.cos(phi), np.sin(phi)
    zero = np.zeros_like(phi)
    R, L = wheel_radius, half_track
    rows = [
        [-s, c, zero - d, zero, zero],
        [c, s, zero + L, zero - R, zero],
        [c, s, zero - L, zero, zero - R],
    ]
    return np.moveaxis(np.array(rows, dtype=float), (0, 1), (-2, -1))


def constraint_residual(
    x: np.ndarray, wheel_radius: float, half_track: float, d: float
) -> np.ndarray:
    """``Λ(q) q̇`` (m/s, m/s, m/s) at states ``x = [q, q̇]`` of shape ``(*batch, 10)``."""
    x = np.asarray(x, dtype=float)
    if x.shape[-1] != 10:
        raise ValueError(f"x must have 10 entries [q, qdot]; got shape {x.shape}")
    lam = constraint_matrix(x[..., :5], wheel_radius, half_track, d)
    return np.einsum("...ij,...j->...i", lam, x[..., 5:])


def consistent_state(
    q: np.ndarray, eta: np.ndarray, wheel_radius: float, half_track: float, d: float
) -> np.ndarray:
    """The state ``[q, S(q) η]`` (10,) that satisfies the constraints, for wheel rates ``η``."""
    q = np.asarray(q, dtype=float)
    eta = np.asarray(eta, dtype=float)
    if q.shape != (5,) or eta.shape != (2,):
        raise ValueError(f"q must have shape (5,) and eta (2,); got {q.shape} and {eta.shape}")
    return np.concatenate([q, kinematic_map(q, wheel_radius, half_track, d) @ eta])
