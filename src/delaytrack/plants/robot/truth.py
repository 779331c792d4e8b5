"""The truth plant: the constrained differential-drive robot with wheel friction (docs/robot.md).

Reduced wheel-space dynamics (derived in ``scripts/derive_robot.py``; ``η = (θ̇_r, θ̇_l)``,
``v = R (θ̇_r + θ̇_l)/2``, ``ω = R (θ̇_r - θ̇_l)/(2L)``, aggregates ``M_b, s = (s_x, s_y), I_A``
of :mod:`~delaytrack.plants.robot.body`)::

    M_r η̇ + n_r(η) = τ - f(η)

    M_r = I_w I + Jᵀ [[M_b, -s_y], [-s_y, I_A]] J,   J = [[R/2, R/2], [R/(2L), -R/(2L)]]
    n_r = Jᵀ [-s_x ω², s_x v ω]                      (power-free: ηᵀ n_r = 0)
    f_i = b_v θ̇_i + f_c tanh(θ̇_i / v_s)             (viscous + smoothed Coulomb, per wheel)

equivalently, in body velocities, ``(M_b + 2I_w/R²) v̇ - s_y ω̇ - s_x ω² = F_v`` and
``(I_A + 2L²I_w/R²) ω̇ - s_y v̇ + s_x v ω = F_ω``; for ``s_y = 0`` this is the textbook ``M_r, C_r``
(Dhaouadi & Abu Hatab 2013). A centre of mass off the heading axis (``s_y ≠ 0``, a payload placed
sideways) couples v̇ and ω̇ through the mass matrix.

The simulator integrates the robot in this reduced form (:data:`TRUTH_REDUCED_FORM`, a
:class:`~delaytrack.components.ReducedForm`): RK4 on ``(q, η)`` with the slopes
``(S(q) η, η̇)`` and ``q̇ = S(q) η`` after each step, so that the velocity constraints hold to
rounding. Its terms kernel (for the Python methods, and a run without the reduced form) gives
the constrained form in ``q`` as ``M = I``, ``N = -a``, ``G = b`` with ``q̈ = a + b τ``:

    η̇ = M_r⁻¹ (τ - f - n_r),     q̈ = S(q) η̇ + (∂S/∂φ) φ̇ η - k_b [ρ; 0],
    ρ = q̇_{1:3} - S_{1:3}(q) η                     (velocity-constraint residual)

so that, exactly in continuous time, ``ρ̇ = -k_b ρ`` (Baumgarte stabilisation of the velocity
constraints; the term vanishes on the constraint manifold, where ``Λ(q) q̇ = Λ_{:,1:3} ρ = 0``).
RK4 would otherwise let ``Λ q̇`` drift by its truncation error; ``k_b`` (default 20 s⁻¹, a 50 ms
time constant) damps that drift and any inconsistent initial velocity. RK4 stays stable on this
term while ``k_b dt < 2.78``.
"""

from __future__ import annotations

import math
from abc import abstractmethod
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from delaytrack._compile.functions import at_few_points
from delaytrack._compile.jit import hot_kernel, kernel
from delaytrack._validation import positive_scalar
from delaytrack.components import ReducedForm
from delaytrack.plants.base import ELPlant
from delaytrack.plants.robot.body import RobotBody
from delaytrack.plants.robot.kinematics import (
    constraint_residual,
    kinematic_map_entries,
    robot_velocity_map,
)
from delaytrack.plants.robot.parameters import P3DX

__all__ = [
    "DEFAULT_BAUMGARTE_GAIN",
    "ConstrainedRobotPhysics",
    "TRUTH_PARAMS",
    "TRUTH_REDUCED_FORM",
    "WheeledRobot",
    "constrained_terms",
    "reduced_terms_kernel",
    "reduced_terms_values",
    "robot_truth_dynamics",
    "robot_truth_terms",
    "wheel_accelerations",
    "wheel_space_inverse",
]

#: Baumgarte gain k_b of the velocity-constraint residual, 1/s.
DEFAULT_BAUMGARTE_GAIN = 20.0
#: Length of the truth plant's parameter vector:
#: ``[R, L, d, M_b, s_x, s_y, I_A, I_w, b_v, f_c, v_s, k_b]``.
TRUTH_PARAMS = 12


@hot_kernel
def reduced_terms_values(wr, wl, params, mass_b, s_x, s_y, inertia_a):
    """``M_r``, ``n_r`` and ``f`` of the module docstring at ``η = (wr, wl)``, as scalars
    ``(M_r00, M_r01, M_r11, n_r0, n_r1, f_0, f_1)`` (``M_r`` is symmetric)."""
    R, L, Iw = params[0], params[1], params[7]
    b_v, f_c, v_s = params[8], params[9], params[10]
    a = 0.5 * R
    b = R / (2.0 * L)
    v = a * (wr + wl)
    w = b * (wr - wl)
    m00 = Iw + a * a * mass_b - 2.0 * a * b * s_y + b * b * inertia_a
    m01 = a * a * mass_b - b * b * inertia_a
    m11 = Iw + a * a * mass_b + 2.0 * a * b * s_y + b * b * inertia_a
    friction_r = b_v * wr
    friction_l = b_v * wl
    if f_c != 0.0:
        friction_r += f_c * math.tanh(wr / v_s)
        friction_l += f_c * math.tanh(wl / v_s)
    bias_r = s_x * w * (b * v - a * w)
    bias_l = -s_x * w * (b * v + a * w)
    return m00, m01, m11, bias_r, bias_l, friction_r, friction_l


@kernel
def reduced_terms_kernel(qdot, params, mass_b, s_x, s_y, inertia_a, reduced_mass, bias, friction):
    """Fill ``M_r`` (2, 2), ``n_r`` (2,), ``f`` (2,) from :func:`reduced_terms_values`."""
    m00, m01, m11, bias[0], bias[1], friction[0], friction[1] = reduced_terms_values(
        qdot[3], qdot[4], params, mass_b, s_x, s_y, inertia_a
    )
    reduced_mass[0, 0] = m00
    reduced_mass[0, 1] = m01
    reduced_mass[1, 0] = m01
    reduced_mass[1, 1] = m11


@hot_kernel
def wheel_space_inverse(wr, wl, params, mass_b, s_x, s_y, inertia_a):
    """``M_r⁻¹`` as ``(i00, i01, i11)`` (symmetric) and ``g = -(n_r + f)`` as ``(g0, g1)`` at
    ``η = (wr, wl)``, so that ``η̇ = M_r⁻¹ (g + τ)`` (module docstring)."""
    m00, m01, m11, bias_r, bias_l, friction_r, friction_l = reduced_terms_values(
        wr, wl, params, mass_b, s_x, s_y, inertia_a
    )
    det = m00 * m11 - m01 * m01
    return m11 / det, -m01 / det, m00 / det, -(bias_r + friction_r), -(bias_l + friction_l)


@hot_kernel
def constrained_terms(q, qdot, params, mass_b, s_x, s_y, inertia_a, mass, nonlinear, input_map):
    """``M = I``, ``N = -a``, ``G = b`` of the constrained robot (module docstring) with the
    rigid-body aggregates given (so that a payload can change them). Allocation-free: it runs at
    every RK4 stage."""
    R, L, d = params[0], params[1], params[2]
    k_b = params[11]
    # η̇ = drift + M_r⁻¹ τ
    i00, i01, i11, g0, g1 = wheel_space_inverse(
        qdot[3], qdot[4], params, mass_b, s_x, s_y, inertia_a
    )
    drift_r = i00 * g0 + i01 * g1
    drift_l = i01 * g0 + i11 * g1
    c = math.cos(q[2])
    s = math.sin(q[2])
    # Rows x, y, φ of S(q); rows θ_r, θ_l are the identity.
    S00, S01, S10, S11, S20 = kinematic_map_entries(c, s, R, L, d)
    wr = qdot[3]
    wl = qdot[4]
    v = 0.5 * R * (wr + wl)
    w = R * (wr - wl) / (2.0 * L)
    phidot = qdot[2]
    # (∂S/∂φ) φ̇ η for rows x, y (row φ of S is constant).
    sdot_x = (-v * s - d * w * c) * phidot
    sdot_y = (v * c - d * w * s) * phidot
    # Velocity-constraint residual ρ = q̇_{1:3} - S_{1:3} η.
    rho_x = qdot[0] - (v * c - d * w * s)
    rho_y = qdot[1] - (v * s + d * w * c)
    rho_phi = qdot[2] - w
    for i in range(5):
        for j in range(5):
            mass[i, j] = 1.0 if i == j else 0.0
    nonlinear[0] = -(S00 * drift_r + S01 * drift_l + sdot_x - k_b * rho_x)
    nonlinear[1] = -(S10 * drift_r + S11 * drift_l + sdot_y - k_b * rho_y)
    nonlinear[2] = -(S20 * drift_r - S20 * drift_l - k_b * rho_phi)
    nonlinear[3] = -drift_r
    nonlinear[4] = -drift_l
    input_map[0, 0] = S00 * i00 + S01 * i01
    input_map[0, 1] = S00 * i01 + S01 * i11
    input_map[1, 0] = S10 * i00 + S11 * i01
    input_map[1, 1] = S10 * i01 + S11 * i11
    input_map[2, 0] = S20 * i00 - S20 * i01
    input_map[2, 1] = S20 * i01 - S20 * i11
    input_map[3, 0] = i00
    input_map[3, 1] = i01
    input_map[4, 0] = i01
    input_map[4, 1] = i11


@hot_kernel
def wheel_accelerations(eta, u, params, mass_b, s_x, s_y, inertia_a, eta_dot):
    """``η̇ = M_r⁻¹ (τ - f - n_r)`` (module docstring) with the rigid-body aggregates given,
    summed as the constrained form's rows θ_r, θ_l are (the same numbers to the last bit)."""
    i00, i01, i11, g0, g1 = wheel_space_inverse(eta[0], eta[1], params, mass_b, s_x, s_y, inertia_a)
    eta_dot[0] = i00 * g0 + i01 * g1 + i00 * u[0] + i01 * u[1]
    eta_dot[1] = i01 * g0 + i11 * g1 + i01 * u[0] + i11 * u[1]


@hot_kernel
def robot_truth_dynamics(t, q, eta, u, params, eta_dot):
    """Reduced dynamics of :class:`WheeledRobot`: ``η̇`` (:func:`wheel_accelerations`)."""
    wheel_accelerations(eta, u, params, params[3], params[4], params[5], params[6], eta_dot)


#: The robot's reduced form (two wheel rates): the engine integrates it instead of its terms.
TRUTH_REDUCED_FORM = ReducedForm(robot_velocity_map, robot_truth_dynamics, 2)


@hot_kernel
def robot_truth_terms(t, q, qdot, params, mass, nonlinear, input_map):
    """Terms kernel of :class:`WheeledRobot`; ``params`` as :data:`TRUTH_PARAMS` describes."""
    constrained_terms(
        q, qdot, params, params[3], params[4], params[5], params[6], mass, nonlinear, input_map
    )


class ConstrainedRobotPhysics:
    """Python helpers shared by the robot truth plants (``params`` in the truth layout)."""

    @property
    @abstractmethod
    def params(self) -> np.ndarray:
        """The plant's parameters, in the truth layout (:meth:`WheeledRobot.truth_params`
        first)."""

    def aggregates(self, t: float = 0.0) -> np.ndarray:
        """``[M_b, s_x, s_y, I_A]`` of the rigid part at time ``t``."""
        return np.array(self.params[3:7], dtype=float)

    def reduced_terms(
        self, qdot: np.ndarray, t: float = 0.0
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``M_r (batch, 2, 2)``, ``n_r (batch, 2)``, friction ``f (batch, 2)`` at ``q̇ (batch, 5)``
        and time ``t``."""
        qdot = np.atleast_2d(np.asarray(qdot, dtype=float))
        if qdot.ndim != 2 or qdot.shape[1] != 5:
            raise ValueError(f"qdot must have shape (batch, 5) or (5,); got {qdot.shape}")
        params = self.params
        mass_b, s_x, s_y, inertia_a = self.aggregates(t)
        batch = qdot.shape[0]

        def each_point(terms_kernel):
            reduced_mass = np.empty((batch, 2, 2))
            bias = np.empty((batch, 2))
            friction = np.empty((batch, 2))
            for k in range(batch):
                terms_kernel(
                    np.ascontiguousarray(qdot[k]),
                    params,
                    mass_b,
                    s_x,
                    s_y,
                    inertia_a,
                    reduced_mass[k],
                    bias[k],
                    friction[k],
                )
            return reduced_mass, bias, friction

        # a few points as Python while the kernel is not compiled
        return at_few_points(reduced_terms_kernel, batch, each_point)

    def kinetic_energy(self, x: np.ndarray, t: float = 0.0) -> np.ndarray:
        """``T = ½ ηᵀ M_r η`` (J) of the constrained robot at states ``x (batch, 10)``."""
        x = np.atleast_2d(np.asarray(x, dtype=float))
        reduced_mass = self.reduced_terms(x[:, 5:], t)[0]
        eta = x[:, 8:10]
        return 0.5 * np.einsum("bi,bij,bj->b", eta, reduced_mass, eta)

    def constraint_residual(self, x: np.ndarray) -> np.ndarray:
        """``Λ(q) q̇`` (batch, 3) in m/s at states ``x (batch, 10)``."""
        R, L, d = self.params[:3]
        return np.atleast_2d(constraint_residual(x, R, L, d))


@dataclass(frozen=True, eq=False)
class WheeledRobot(RobotBody, ConstrainedRobotPhysics, ELPlant):
    """The constrained differential-drive robot of the paper's Section III (the truth plant).

    Coordinates ``q = (x_c, y_c, φ, θ_r, θ_l)``, inputs the wheel torques ``u = (τ_r, τ_l)``.
    Start it on the constraint manifold
    (:func:`~delaytrack.plants.robot.kinematics.consistent_state`): ``simulate`` integrates its
    reduced form and refuses another start; in the constrained form (its terms) an
    inconsistent initial velocity decays as ``exp(-k_b t)``.

    Parameters
    ----------
    wheel_radius, half_track, d, mass, yaw_inertia, wheel_mass, wheel_spin_inertia,
    com_forward, com_lateral : float
        The body (:class:`~delaytrack.plants.robot.body.RobotBody`; P3-DX defaults).
    viscous_friction : float
        ``b_v`` >= 0, N·m·s/rad (default 0.01, an assumption; see ``P3DX_SOURCES``).
    coulomb_friction : float
        ``f_c`` >= 0, N·m (default 0.1, an assumption).
    friction_speed : float
        ``v_s`` > 0 of the ``tanh`` smoothing, rad/s (default 0.05).
    baumgarte_gain : float
        ``k_b`` >= 0 of the velocity-constraint stabilisation, 1/s (default 20).
    """

    viscous_friction: float = P3DX.viscous_friction
    coulomb_friction: float = P3DX.coulomb_friction
    friction_speed: float = P3DX.friction_speed
    baumgarte_gain: float = DEFAULT_BAUMGARTE_GAIN
    type_name: ClassVar[str] = "wheeled-robot"
    identity_mass: ClassVar[bool] = True

    def __post_init__(self) -> None:
        self._check_body()
        for name in ("viscous_friction", "coulomb_friction", "baumgarte_gain"):
            object.__setattr__(
                self, name, positive_scalar(name, getattr(self, name), strictly=False)
            )
        object.__setattr__(
            self, "friction_speed", positive_scalar("friction_speed", self.friction_speed)
        )

    @property
    def params(self) -> np.ndarray:
        return self.truth_params()

    def truth_params(self) -> np.ndarray:
        """``[R, L, d, M_b, s_x, s_y, I_A, I_w, b_v, f_c, v_s, k_b]``."""
        return np.concatenate(
            [
                self.body_params(),
                [
                    self.viscous_friction,
                    self.coulomb_friction,
                    self.friction_speed,
                    self.baumgarte_gain,
                ],
            ]
        )

    @property
    def terms_kernel(self):
        return robot_truth_terms

    @property
    def reduced_form(self) -> ReducedForm:
        return TRUTH_REDUCED_FORM

    def to_spec(self) -> dict[str, Any]:
        return {"type": self.type_name, **self.truth_spec()}

    def truth_spec(self) -> dict[str, Any]:
        """The fields as plain data (scenario keys), without ``type``."""
        return {
            **self.body_spec(),
            "viscous_friction": self.viscous_friction,
            "coulomb_friction": self.coulomb_friction,
            "friction_speed": self.friction_speed,
            "baumgarte_gain": self.baumgarte_gain,
        }
