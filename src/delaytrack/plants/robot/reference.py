"""The paper's reference path for the robot, as printed (``literal``) and made feasible
(``consistent``, the default).

The paper prints (Section 3)::

    x_d = 1.25 sin(0.35 t) + 0.1,   y_d = 1.25 cos(0.35 t) + 1.35,
    φ_d = 0.25 t,   θ_r,d = 3 t,   θ_l,d = 2 t.

The x–y circle (radius ρ = 1.25 m, centre (0.1, 1.35)) is driven *clockwise* at
``V = 1.25 × 0.35 = 0.4375 m/s``, while ``φ_d`` turns counter-clockwise and the wheel rates give
``v = r̄ (3 + 2)/2 ≈ 0.24 m/s`` and ``ω = r̄ (3 - 2)/(2b) ≈ 0.30 rad/s ≠ 0.25``: no motion of the
robot satisfies all five (``literal``).

``consistent`` keeps the circle for the tracked point P = (x_c, y_c) and derives φ_d, θ_r,d, θ_l,d
from the kinematics of a point at distance d ahead of the axle midpoint A. With
``(ẋ_d, ẏ_d) = V (cos ψ, sin ψ)``, ``ψ(t) = -Ω t``, ``Ω = 0.35 rad/s``::

    ẋ = v cos φ - d ω sin φ,  ẏ = v sin φ + d ω cos φ
      ⇔  v = V cos(ψ - φ),   ω = φ̇ = (V/d) sin(ψ - φ).

The heading obeys ``φ̇ = (V/d) sin(ψ - φ)`` (the internal dynamics of the look-ahead point). Its
solution that turns with the path, ``φ = ψ - β`` with β constant, needs
``ψ̇ = -Ω = (V/d) sin β``, i.e. ``sin β = -Ω d / V = -d/ρ``; the branch with ``cos β > 0`` (driving
forwards) is the attracting one (linearising, ``δφ̇ = -(V/d) cos β δφ``). So::

    φ_d(t) = asin(d/ρ) - Ω t,                      (the heading leads ψ by asin(d/ρ) = 2.29°)
    v_d = V cos β = Ω √(ρ² - d²),   ω_d = -Ω,        (A runs on the circle of radius √(ρ² - d²))
    θ̇_r,d = (v_d + L ω_d)/R,   θ̇_l,d = (v_d - L ω_d)/R,   θ_r,d(0) = θ_l,d(0) = 0.

For the P3-DX (R = 0.0975, L = 0.165, d = 0.05): φ_d = 0.040011 - 0.35 t, v_d = 0.437150 m/s,
θ̇_r,d = 3.8913 rad/s, θ̇_l,d = 5.0759 rad/s. These satisfy ``Λ(q_d) q̇_d = 0`` for all t, and
``φ_d - R(θ_r,d - θ_l,d)/(2L) = asin(d/ρ)`` (the holonomic part of the constraints) is the value
the robot has when started at ``q_d(0)``: start it at :func:`initial_state`.
"""

from __future__ import annotations

import math

import numpy as np

from delaytrack.plants.robot.kinematics import consistent_state
from delaytrack.plants.robot.parameters import P3DX
from delaytrack.references import SinusoidalReference

__all__ = [
    "CIRCLE_CENTER",
    "CIRCLE_RADIUS",
    "CIRCLE_RATE",
    "initial_state",
    "paper_reference",
    "wheel_rates",
]

#: The paper's circle: radius ρ (m), angular rate Ω (rad/s), centre (m).
CIRCLE_RADIUS = 1.25
CIRCLE_RATE = 0.35
CIRCLE_CENTER = (0.1, 1.35)
_KINDS = ("consistent", "literal")


def wheel_rates(
    kind: str = "consistent",
    *,
    wheel_radius: float = P3DX.wheel_radius,
    half_track: float = P3DX.half_track,
    d: float = P3DX.d,
) -> np.ndarray:
    """Constant wheel rates ``(θ̇_r,d, θ̇_l,d)`` of the reference, rad/s."""
    if kind == "literal":
        return np.array([3.0, 2.0])
    _check(kind, d)
    v = CIRCLE_RATE * math.sqrt(CIRCLE_RADIUS**2 - d**2)
    w = -CIRCLE_RATE
    return np.array([(v + half_track * w) / wheel_radius, (v - half_track * w) / wheel_radius])


def _check(kind: str, d: float) -> None:
    if kind not in _KINDS:
        raise ValueError(f"kind must be one of {list(_KINDS)}; got {kind!r}")
    if not abs(d) < CIRCLE_RADIUS:
        raise ValueError(f"d must be shorter than the circle's radius {CIRCLE_RADIUS} m; got {d!r}")


def paper_reference(
    kind: str = "consistent",
    *,
    wheel_radius: float = P3DX.wheel_radius,
    half_track: float = P3DX.half_track,
    d: float = P3DX.d,
) -> SinusoidalReference:
    """The paper's robot reference ``q_d(t)`` (module docstring) as a ``SinusoidalReference``.

    Parameters
    ----------
    kind : {"consistent", "literal"}
        ``literal``: the five printed formulas. ``consistent`` (default): the same x–y circle with
        φ_d, θ_r,d, θ_l,d from the kinematics of the look-ahead point.
    wheel_radius, half_track, d : float
        Geometry used by ``consistent`` (P3-DX defaults).
    """
    _check(kind, d)
    x0, y0 = CIRCLE_CENTER
    if kind == "literal":
        offset = np.array([x0, y0, 0.0, 0.0, 0.0])
        slope = np.array([0.0, 0.0, 0.25, 3.0, 2.0])
    else:
        rates = wheel_rates(kind, wheel_radius=wheel_radius, half_track=half_track, d=d)
        offset = np.array([x0, y0, math.asin(d / CIRCLE_RADIUS), 0.0, 0.0])
        slope = np.array([0.0, 0.0, -CIRCLE_RATE, rates[0], rates[1]])
    # y_d = ρ cos(Ω t) + y0 = ρ sin(Ω t + π/2) + y0
    amplitude = np.array([CIRCLE_RADIUS, CIRCLE_RADIUS, 0.0, 0.0, 0.0])
    frequency = np.array([CIRCLE_RATE, CIRCLE_RATE, 0.0, 0.0, 0.0])
    phase = np.array([0.0, math.pi / 2, 0.0, 0.0, 0.0])
    return SinusoidalReference(
        offset=offset, slope=slope, amplitude=amplitude, frequency=frequency, phase=phase
    )


def initial_state(
    reference: SinusoidalReference,
    *,
    wheel_radius: float = P3DX.wheel_radius,
    half_track: float = P3DX.half_track,
    d: float = P3DX.d,
    t0: float = 0.0,
) -> np.ndarray:
    """``x0 = [q_d(t0), S(q_d(t0)) η_d(t0)]``: on the reference's pose, with the reference's wheel
    rates, and on the constraint manifold (for ``literal`` the x–y–φ velocity then differs from the
    printed one, which no robot can have)."""
    qd, qd_dot, _ = reference.evaluate(np.array([t0]))
    return consistent_state(qd[0], qd_dot[0, 3:5], wheel_radius, half_track, d)
