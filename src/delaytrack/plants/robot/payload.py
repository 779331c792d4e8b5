"""The paper's payload experiment as a plant: a robot carrying a point mass on a schedule.

The paper adds 3.5 kg for 5 s, removes it for 5 s, and repeats, "at different places on the
robotic platform every time". :class:`PayloadRobot` wraps a
:class:`~delaytrack.plants.robot.truth.WheeledRobot` (the payload is a wrapper around the robot,
not a flag inside it) and its parameter vector carries the whole schedule, so the compiled terms
kernel picks the payload in force from ``t``:

* placement ``k = 0, 1, …`` is on during ``[t_k, t_k + time_on)``, ``t_k = first_on + k (time_on +
  time_off)``, and off otherwise; after the last placement the robot stays unloaded;
* a placement is a point ``p = (p_x, p_y)`` in the body frame (forward, left of the axle
  midpoint A); random placements are uniform on the platform rectangle
  ``[c - ℓ/2, c + ℓ/2] × [-w/2, w/2]`` (``c`` = ``plate_center``), drawn from
  ``numpy.random.default_rng(seed)``;
* the payload changes the rigid-body aggregates (point mass, parallel axis theorem)::

      M_b' = M_b + m_p,   s' = s + m_p p,   I_A' = I_A + m_p |p|²

  hence the centre of mass ``s'/M_b'`` (also sideways) and the yaw inertia about it,
  ``I_A' - |s'|²/M_b'``.

Placing or removing the payload changes the mass matrix while the wheel rates ``η`` stay continuous
(the impulse of a real placement is not modelled); the kinetic energy jumps accordingly. The
switching times fall inside RK4 steps unless they are multiples of ``dt``; that costs accuracy
over one step, not constraint satisfaction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Any, ClassVar

import numpy as np

from delaytrack._compile.jit import hot_kernel
from delaytrack._validation import (
    beyond_choice,
    finite_array,
    finite_scalar,
    is_integer_at_least,
    positive_scalar,
)
from delaytrack.components import ReducedForm
from delaytrack.plants.base import ELPlant
from delaytrack.plants.robot.body import (
    COORDINATE_UNITS,
    COORDINATES,
    INPUT_NAMES,
    INPUT_UNITS,
)
from delaytrack.plants.robot.kinematics import robot_velocity_map
from delaytrack.plants.robot.parameters import P3DX_PAYLOAD
from delaytrack.plants.robot.truth import (
    TRUTH_PARAMS,
    ConstrainedRobotPhysics,
    WheeledRobot,
    constrained_terms,
    wheel_accelerations,
)

__all__ = [
    "PAYLOAD_REDUCED_FORM",
    "SCHEDULE_KEYS",
    "SCHEDULE_POINTS",
    "PayloadRobot",
    "PayloadSchedule",
    "active_placement",
    "loaded_aggregates",
    "random_placements",
    "robot_payload_dynamics",
    "robot_payload_terms",
]

# Layout of a schedule, from its start in a parameter vector (the truth parameters' end in
# PayloadRobot's): [m_p, first_on, time_on, time_off, count, p_0x, p_0y, ...]; SCHEDULE_POINTS is
# where the points start.
_MASS, _FIRST_ON, _TIME_ON, _TIME_OFF, _COUNT, SCHEDULE_POINTS = range(6)


@hot_kernel
def active_placement(t, params, start):
    """Index of the placement in force at ``t``, or -1 when the robot is unloaded; the schedule
    starts at ``params[start]``."""
    first_on = params[start + _FIRST_ON]
    time_on = params[start + _TIME_ON]
    period = time_on + params[start + _TIME_OFF]
    count = int(params[start + _COUNT])
    if t < first_on or count == 0:
        return -1
    k = int(math.floor((t - first_on) / period))
    if k >= count:
        return -1
    if t - first_on - k * period < time_on:
        return k
    return -1


@hot_kernel
def loaded_aggregates(t, params):
    """``(M_b', s_x', s_y', I_A')`` of the robot with the payload in force at ``t`` (module
    docstring)."""
    mass_b = params[3]
    s_x = params[4]
    s_y = params[5]
    inertia_a = params[6]
    k = active_placement(t, params, TRUTH_PARAMS)
    if k >= 0:
        m_p = params[TRUTH_PARAMS + _MASS]
        p_x = params[TRUTH_PARAMS + SCHEDULE_POINTS + 2 * k]
        p_y = params[TRUTH_PARAMS + SCHEDULE_POINTS + 2 * k + 1]
        mass_b += m_p
        s_x += m_p * p_x
        s_y += m_p * p_y
        inertia_a += m_p * (p_x * p_x + p_y * p_y)
    return mass_b, s_x, s_y, inertia_a


@hot_kernel
def robot_payload_terms(t, q, qdot, params, mass, nonlinear, input_map):
    """Terms kernel of :class:`PayloadRobot`: the truth robot with the payload in force at ``t``."""
    mass_b, s_x, s_y, inertia_a = loaded_aggregates(t, params)
    constrained_terms(q, qdot, params, mass_b, s_x, s_y, inertia_a, mass, nonlinear, input_map)


@hot_kernel
def robot_payload_dynamics(t, q, eta, u, params, eta_dot):
    """Reduced dynamics of :class:`PayloadRobot`: ``η̇`` with the payload in force at ``t``."""
    mass_b, s_x, s_y, inertia_a = loaded_aggregates(t, params)
    wheel_accelerations(eta, u, params, mass_b, s_x, s_y, inertia_a, eta_dot)


#: The payload robot's reduced form (two wheel rates).
PAYLOAD_REDUCED_FORM = ReducedForm(robot_velocity_map, robot_payload_dynamics, 2)


#: Most placements of a random payload schedule (two numbers each, in every run's parameters).
MAX_PLACEMENTS = 10**6


def placement_count(duration: float, first_on: float, time_on: float, time_off: float) -> int:
    """Number of placements that start before ``duration``."""
    if duration <= first_on:
        return 0
    periods = (duration - first_on) / (time_on + time_off)
    return int(math.ceil(periods - 1e-12)) if math.isfinite(periods) else 2**63


def random_placements(
    seed: int,
    count: int,
    plate_length: float = P3DX_PAYLOAD.plate_length,
    plate_width: float = P3DX_PAYLOAD.plate_width,
    plate_center: float = P3DX_PAYLOAD.plate_center,
) -> np.ndarray:
    """``count`` points (count, 2) uniform on the plate rectangle, body frame from A, seeded."""
    rng = np.random.default_rng(seed)
    forward = rng.uniform(plate_center - plate_length / 2, plate_center + plate_length / 2, count)
    lateral = rng.uniform(-plate_width / 2, plate_width / 2, count)
    return np.column_stack([forward, lateral])


@dataclass(frozen=True, eq=False)
class PayloadSchedule:
    """The paper's payload and its schedule: the fields of the robots that carry it
    (:class:`PayloadRobot`, :class:`~delaytrack.plants.robot.MujocoWheeledRobot`).

    Give either ``placements`` or ``seed`` and ``duration`` (random placements covering
    ``[0, duration]``).

    Parameters
    ----------
    placements : array_like, shape (k, 2), optional
        Body-frame points ``(p_x, p_y)`` from A (forward, left), m, one per placement.
    seed : int, optional
        Seed of the random placements.
    duration : float, optional
        Seconds to cover with random placements.
    payload_mass : float
        ``m_p`` in kg (3.5).
    time_on, time_off, first_on : float
        Schedule in s (5, 5, 5).
    plate_length, plate_width, plate_center : float
        Rectangle of the random placements, m (0.44 × 0.38 centred ``d`` = 0.05 ahead of A).
    beyond : {"refuse", "hold"}
        After the schedule's last placement (``first_on + k (time_on + time_off)`` for ``k``
        placements, its horizon) the payload stays off. ``"refuse"`` (default): a simulation
        that runs longer is refused; ``"hold"``: it goes on without payload.
    """

    placements: np.ndarray | None = None
    seed: int | None = None
    duration: float | None = None
    payload_mass: float = P3DX_PAYLOAD.mass
    time_on: float = P3DX_PAYLOAD.time_on
    time_off: float = P3DX_PAYLOAD.time_off
    first_on: float = P3DX_PAYLOAD.first_on
    plate_length: float = P3DX_PAYLOAD.plate_length
    plate_width: float = P3DX_PAYLOAD.plate_width
    plate_center: float = P3DX_PAYLOAD.plate_center
    beyond: str = "refuse"

    def _checked_schedule(self) -> np.ndarray:
        """Check the fields (setting them to plain floats) and return the schedule as kernels
        read it (:func:`active_placement`): ``[m_p, first_on, time_on, time_off, k, p_0x,
        p_0y, …]``."""
        object.__setattr__(self, "payload_mass", positive_scalar("payload_mass", self.payload_mass))
        for name in ("time_on", "time_off", "plate_length", "plate_width"):
            object.__setattr__(self, name, positive_scalar(name, getattr(self, name)))
        object.__setattr__(
            self, "first_on", positive_scalar("first_on", self.first_on, strictly=False)
        )
        object.__setattr__(self, "plate_center", finite_scalar("plate_center", self.plate_center))
        random = self.seed is not None or self.duration is not None
        if (self.placements is None) == (not random):
            raise ValueError(
                "give either placements (a (k, 2) array of body-frame points) or seed and "
                "duration (random placements), not both"
            )
        if random:
            if self.seed is None or self.duration is None:
                raise ValueError("random placements need both seed and duration")
            if not is_integer_at_least(self.seed, 0) or self.seed > 2**63 - 1:
                raise ValueError(f"seed must be an integer from 0 to 2**63 - 1; got {self.seed!r}")
            duration = positive_scalar("duration", self.duration)
            object.__setattr__(self, "duration", duration)
            count = placement_count(duration, self.first_on, self.time_on, self.time_off)
            if count > MAX_PLACEMENTS:
                raise ValueError(
                    f"duration must cover at most {MAX_PLACEMENTS:.0e} placements of the payload "
                    f"(one every time_on + time_off = {self.time_on + self.time_off:g} s); got "
                    f"duration = {duration:g} s, {count:.3g} placements"
                )
            placements = random_placements(
                int(self.seed), count, self.plate_length, self.plate_width, self.plate_center
            )
        else:
            placements = finite_array("placements", self.placements)
            if placements.size == 0:
                placements = placements.reshape(0, 2)
            if placements.ndim != 2 or placements.shape[1] != 2:
                raise ValueError(
                    f"placements must have shape (k, 2) (forward, left in m); "
                    f"got {placements.shape}"
                )
        object.__setattr__(self, "beyond", beyond_choice(self.beyond))
        schedule = [
            self.payload_mass,
            self.first_on,
            self.time_on,
            self.time_off,
            float(len(placements)),
        ]
        return np.concatenate([schedule, placements.ravel()])

    def _schedule_horizon(self, count: int) -> float:
        """End of a schedule of ``count`` placements (``inf`` with ``beyond="hold"``)."""
        if self.beyond == "hold":
            return math.inf
        return self.first_on + count * (self.time_on + self.time_off)

    def _schedule_spec(self, placements: np.ndarray) -> dict[str, Any]:
        """The schedule's fields as plain data (scenario keys)."""
        spec: dict[str, Any] = {
            "payload_mass": self.payload_mass,
            "time_on": self.time_on,
            "time_off": self.time_off,
            "first_on": self.first_on,
        }
        if self.seed is not None:
            spec.update(
                seed=int(self.seed),
                duration=self.duration,
                plate_length=self.plate_length,
                plate_width=self.plate_width,
                plate_center=self.plate_center,
            )
        else:
            spec["placements"] = placements.tolist()
        if self.beyond != "refuse":
            spec["beyond"] = self.beyond
        return spec


#: The fields of the payload and its schedule.
SCHEDULE_KEYS = tuple(item.name for item in fields(PayloadSchedule))


@dataclass(frozen=True, eq=False)
class PayloadRobot(PayloadSchedule, ConstrainedRobotPhysics, ELPlant):
    """A :class:`WheeledRobot` carrying a point payload on a schedule (module docstring).

    Give either ``placements`` or ``seed`` and ``duration`` (random placements covering
    ``[0, duration]``); after construction ``placements`` holds the points used.

    Parameters
    ----------
    robot : WheeledRobot, optional
        The robot without payload (P3-DX defaults).
    placements, seed, duration, payload_mass, time_on, time_off, first_on, plate_length,
    plate_width, plate_center, beyond
        The payload and its schedule (:class:`PayloadSchedule`).
    """

    robot: WheeledRobot = field(default_factory=WheeledRobot)
    _params: np.ndarray = field(init=False, repr=False)
    n = 5
    m = 2
    coordinate_names = COORDINATES
    coordinate_units = COORDINATE_UNITS
    input_units = INPUT_UNITS
    input_names = INPUT_NAMES
    type_name: ClassVar[str] = "wheeled-robot-payload"
    identity_mass: ClassVar[bool] = True

    def __post_init__(self) -> None:
        if not isinstance(self.robot, WheeledRobot):
            raise TypeError(f"robot must be a WheeledRobot; got {type(self.robot).__name__}")
        schedule = self._checked_schedule()
        object.__setattr__(self, "placements", schedule[SCHEDULE_POINTS:].reshape(-1, 2))
        object.__setattr__(self, "_params", np.concatenate([self.robot.truth_params(), schedule]))

    @property
    def params(self) -> np.ndarray:
        return self._params

    @property
    def _points(self) -> np.ndarray:
        """``placements`` (k, 2), which construction sets whether given or drawn."""
        assert self.placements is not None
        return self.placements

    @property
    def terms_kernel(self):
        return robot_payload_terms

    @property
    def reduced_form(self) -> ReducedForm:
        return PAYLOAD_REDUCED_FORM

    @property
    def horizon(self) -> float:
        """End of the schedule, ``first_on + k (time_on + time_off)`` (``inf`` with ``hold``)."""
        return self._schedule_horizon(len(self._points))

    def to_spec(self) -> dict[str, Any]:
        return {
            "type": self.type_name,
            **self.robot.truth_spec(),
            **self._schedule_spec(self._points),
        }

    # ---- physics helpers ---------------------------------------------------------------------

    def placement_at(self, t: float) -> np.ndarray | None:
        """Body-frame point (2,) of the payload in force at ``t``, or None."""
        k = active_placement(float(t), self._params, TRUTH_PARAMS)
        return None if k < 0 else self._points[k].copy()

    def aggregates(self, t: float = 0.0) -> np.ndarray:
        """``[M_b, s_x, s_y, I_A]`` at time ``t``, payload included when it is on (as the
        simulator computes them, :func:`loaded_aggregates`)."""
        return np.array(loaded_aggregates(float(t), self._params))

    def mass_properties(self, t: float = 0.0) -> dict[str, Any]:
        """Total mass (kg), centre of mass from A (forward, left; m) and yaw inertia about A and
        about the centre of mass (kg·m²) at time ``t``."""
        mass_b, s_x, s_y, inertia_a = self.aggregates(t)
        com = np.array([s_x, s_y]) / mass_b
        return {
            "mass": float(mass_b),
            "center_of_mass": com,
            "yaw_inertia_about_axle": float(inertia_a),
            "yaw_inertia_about_com": float(inertia_a - mass_b * float(com @ com)),
        }
