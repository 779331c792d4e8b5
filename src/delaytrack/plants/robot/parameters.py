"""PIONEER-3 DX parameters, each with where it comes from (docs/robot.md).

No single authoritative source gives a P3-DX's dynamic parameters. Every value below is marked:

* **[source]** read in a public source (named);
* **[chosen]** our choice within the public values (docs/robot.md lists the sources);
* **[assumed]** our choice, stated so that a reader can change it;
* **[derived]** computed here from the others.

The plants of :mod:`delaytrack.plants.robot` take these as defaults; change them per plant.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "P3DX",
    "P3DX_PAYLOAD",
    "P3DX_SOURCES",
    "P3DX_WHEEL_TORQUE_LIMIT",
    "PayloadDefaults",
    "RobotParameters",
]


@dataclass(frozen=True)
class RobotParameters:
    """Physical parameters of a differential-drive robot (SI units).

    Attributes
    ----------
    wheel_radius : float
        ``R`` (the paper's ``r̄``), m.
    half_track : float
        ``L`` (the paper's ``b``): distance from the axle midpoint A to each wheel, m.
    d : float
        Distance from A to the tracked point ``(x_c, y_c)`` (the nominal centre of mass), m.
    mass : float
        Total mass ``m = m_c + 2 m_w``, kg.
    yaw_inertia : float
        Yaw inertia of the whole robot about the vertical axis through A
        (``I = I_c + m_c d² + 2 m_w L² + 2 I_m``), kg·m².
    wheel_mass : float
        ``m_w``, kg (each wheel).
    wheel_spin_inertia : float
        ``I_w`` about the wheel axle, kg·m² (each wheel; may include reflected motor inertia).
    wheel_yaw_inertia : float
        ``I_m`` of a wheel about a diameter, kg·m² (only used to split ``I`` into its parts).
    viscous_friction : float
        Wheel viscous friction ``b_v``, N·m·s/rad (truth plant only).
    coulomb_friction : float
        Wheel Coulomb friction ``f_c``, N·m (truth plant only).
    friction_speed : float
        Smoothing speed ``v_s`` of ``f_c tanh(θ̇ / v_s)``, rad/s.
    """

    wheel_radius: float
    half_track: float
    d: float
    mass: float
    yaw_inertia: float
    wheel_mass: float
    wheel_spin_inertia: float
    wheel_yaw_inertia: float
    viscous_friction: float
    coulomb_friction: float
    friction_speed: float

    @property
    def platform_mass(self) -> float:
        """``m_c = m - 2 m_w`` [derived]."""
        return self.mass - 2.0 * self.wheel_mass

    @property
    def platform_inertia(self) -> float:
        """``I_c = I - m_c d² - 2 m_w L² - 2 I_m``: platform yaw inertia about its own CoM
        [derived]."""
        return (
            self.yaw_inertia
            - self.platform_mass * self.d**2
            - 2.0 * self.wheel_mass * self.half_track**2
            - 2.0 * self.wheel_yaw_inertia
        )

    @property
    def first_moment(self) -> float:
        """``K = m d - m_c d = 2 m_w d``: first moment about the tracked point of the parts not at
        it (the wheels), the ``K`` of the paper's ``M̄`` [derived]."""
        return self.mass * self.d - self.platform_mass * self.d


#: Best public values for a PIONEER-3 DX (see :data:`P3DX_SOURCES`).
P3DX = RobotParameters(
    wheel_radius=0.0975,
    half_track=0.165,
    d=0.05,
    mass=9.0,
    yaw_inertia=0.264,
    wheel_mass=0.5,
    wheel_spin_inertia=0.01,
    wheel_yaw_inertia=0.5 * (3.0 * 0.0975**2 + 0.05**2) / 12.0,
    viscous_friction=0.01,
    coulomb_friction=0.1,
    friction_speed=0.05,
)

#: Where each value of :data:`P3DX` comes from.
P3DX_SOURCES: dict[str, str] = {
    "wheel_radius": "[source] Webots Pioneer3dx model (0.0975 m); '19 cm wheels' in its guide",
    "half_track": (
        "[chosen] 0.165 m; public values range 0.158 m (Gazebo p2os-derived model, wheel joints at "
        "±0.155–0.158 m) to 0.166 m (a controller code value of 0.3328 m track)"
    ),
    "d": (
        "[chosen] 0.05 m; a Gazebo p2os-derived model puts the chassis origin 0.045 m from the "
        "axle (behind it in that model's frame: the sign is not confirmed; the paper's 'point "
        "ahead' puts it ahead)"
    ),
    "mass": "[source] commonly quoted 9 kg (Webots guide: 10 kg)",
    "yaw_inertia": "[source] public controller code value 0.2641 kg·m² about A (low confidence)",
    "wheel_mass": (
        "[assumed] 0.5 kg (a 19.5 cm tyre and hub; the Gazebo model's 0.1 kg is a placeholder). "
        "It only splits m into m_c and 2 m_w, i.e. sets K = 2 m_w d"
    ),
    "wheel_spin_inertia": (
        "[chosen] 0.01 kg·m² (a bare 0.5 kg disc gives ½ m_w R² = 0.0024; the rest is read as "
        "reflected motor/gear inertia)"
    ),
    "wheel_yaw_inertia": (
        "[assumed] solid disc of 0.5 kg, radius R, width 0.05 m about a diameter: "
        "m_w (3 R² + w²) / 12 = 1.29e-3 kg·m²"
    ),
    "viscous_friction": (
        "[assumed] 0.01 N·m·s/rad at the wheel, inside the range 1e-3 to 2e-2 N·m·s/rad derived "
        "from a motor of the Pittman 9000 series that P3-DX models name (the 9233S013 "
        "datasheet: viscous damping 2.3e-6 N·m·s) reflected through a gear ratio N of 20 to "
        "65 (D N², efficiency 0.7-0.9, gear drag up to 2×); the ratio itself is not published "
        "(38:1 matches the 1.6 m/s top speed of the Webots Pioneer 3-DX guide); back-EMF "
        "damping belongs to the motor drive, not here"
    ),
    "coulomb_friction": (
        "[assumed] 0.1 N·m at the wheel, inside the range 0.07 to 0.35 N·m derived from the "
        "motor's friction torque (9233S013 datasheet: 4.2e-3 N·m) reflected through N = 20 to "
        "40, plus rolling resistance c_rr W R with c_rr = 0.005 to 0.02 (Engineering Toolbox, "
        "rolling friction coefficients) and a wheel load W of 35 to 61 N"
    ),
    "friction_speed": (
        "[assumed] 0.05 rad/s (≈ 5 mm/s at the rim): tanh smoothing of the Coulomb term, "
        "well below the 3.9–5.1 rad/s of the paper's path"
    ),
    "wheel_torque_limit": (
        "[derived] 6.7 N·m per wheel, the peak (stall) torque a drive motor delivers at the "
        "wheel: η N T_PK = 0.8 × 38 × 0.22 N·m, with T_PK = K_M² ω_NL (0.22 N·m = "
        "(1.88e-2)² × 628, the Pittman 9233S013 datasheet; the same for every winding of that "
        "frame, so whatever the voltage) and the gear ratio N = 38 that gives the 1.6 m/s top "
        "speed of the Webots guide (assumed, as for the friction; gearbox efficiency η = 0.8 "
        "assumed). The continuous (thermal) rating is 0.8 × 38 × 0.033 = 1.0 N·m. Since the top "
        "speed fixes ω_NL / N, the peak grows as N²: 1.9 N·m at N = 20, 20 N·m at N = 65 "
        "(docs/robot.md, 'Wheel torque limit')"
    ),
    "platform_mass": "[derived] m - 2 m_w = 8 kg",
    "platform_inertia": (
        "[derived] I - m_c d² - 2 m_w L² - 2 I_m = 0.2142 kg·m² (a uniform 8 kg plate "
        "0.44 m × 0.38 m would have 0.225 kg·m²: consistent)"
    ),
}


#: Largest torque each drive wheel of a PIONEER-3 DX can receive, N·m [derived]: the peak (stall)
#: torque of its motor through its gearbox, ``η N T_PK = 0.8 × 38 × 0.22``
#: (``P3DX_SOURCES["wheel_torque_limit"]``, docs/robot.md). Not applied by default: pass it as
#: the actuators' limit to opt in, ``simulate(..., input_limits=P3DX_WHEEL_TORQUE_LIMIT)`` or a
#: scenario's ``input_limits`` (``Scenario.replace(input_limits=P3DX_WHEEL_TORQUE_LIMIT)``).
P3DX_WHEEL_TORQUE_LIMIT = 6.7


@dataclass(frozen=True)
class PayloadDefaults:
    """The paper's payload experiment and our choices for what it leaves open.

    Attributes
    ----------
    mass : float
        3.5 kg [source: the paper].
    time_on, time_off : float
        Seconds on and off, 5 s each [source: the paper, Section III].
    first_on : float
        Time of the first placement, 5 s [assumed: the robot starts as the nominal model].
    plate_length, plate_width : float
        Placement rectangle 0.44 m × 0.38 m [source: the top-plate collision box of a Gazebo
        p2os-derived P3-DX model, ``box size="0.44 0.38 0.005"``].
    plate_center : float
        Forward offset of the rectangle's centre from A: ``d`` = 0.05 m [assumed: the platform's
        centre is the nominal centre of mass].
    """

    mass: float = 3.5
    time_on: float = 5.0
    time_off: float = 5.0
    first_on: float = 5.0
    plate_length: float = 0.44
    plate_width: float = 0.38
    plate_center: float = P3DX.d


#: Payload schedule and placement rectangle of the paper's experiment.
P3DX_PAYLOAD = PayloadDefaults()
