"""The paper's wheeled robot (PIONEER-3 DX, Section III): truth, payload, nominal models, path.

* :class:`WheeledRobot` — the constrained truth plant (reduced wheel-space dynamics, wheel
  friction, Baumgarte-stabilised velocity constraints);
* :class:`PayloadRobot` — the truth plant carrying the paper's 3.5 kg payload on a schedule;
* :class:`MujocoWheeledRobot` — the same robot with real wheels: a MuJoCo model with contacts
  (``data/p3dx.xml``, :data:`P3DX_MJCF`; needs the ``mujoco`` extra);
* :class:`NominalRobot` — the unconstrained Lagrangian ``M̂, N̂`` the controllers use, with the
  command map ``τ_w = S(q)ᵀ τ``;
* :class:`PrintedRobotModel` — the paper's printed ``M̄, V̄`` as an alternative nominal model;
* :func:`paper_reference` — the paper's path, ``consistent`` (default) or ``literal``;
* :data:`P3DX`, :data:`P3DX_SOURCES` — the parameters and where they come from;
* :data:`P3DX_WHEEL_TORQUE_LIMIT` — the wheel motors' torque limit, for ``input_limits`` (opt-in).

See ``docs/robot.md`` for the derivation, the decisions and the findings on the printed model.
"""

from delaytrack.plants.robot.body import RobotBody
from delaytrack.plants.robot.contact import P3DX_MJCF, MujocoWheeledRobot
from delaytrack.plants.robot.kinematics import (
    consistent_state,
    constraint_matrix,
    constraint_residual,
    kinematic_map,
    kinematic_map_rate,
)
from delaytrack.plants.robot.nominal import NominalRobot
from delaytrack.plants.robot.parameters import (
    P3DX,
    P3DX_PAYLOAD,
    P3DX_SOURCES,
    P3DX_WHEEL_TORQUE_LIMIT,
    PayloadDefaults,
    RobotParameters,
)
from delaytrack.plants.robot.payload import PayloadRobot
from delaytrack.plants.robot.printed import PrintedRobotModel
from delaytrack.plants.robot.reference import initial_state, paper_reference, wheel_rates
from delaytrack.plants.robot.truth import WheeledRobot

__all__ = [
    "P3DX",
    "P3DX_MJCF",
    "P3DX_PAYLOAD",
    "P3DX_SOURCES",
    "P3DX_WHEEL_TORQUE_LIMIT",
    "MujocoWheeledRobot",
    "NominalRobot",
    "PayloadDefaults",
    "PayloadRobot",
    "PrintedRobotModel",
    "RobotBody",
    "RobotParameters",
    "WheeledRobot",
    "consistent_state",
    "constraint_matrix",
    "constraint_residual",
    "initial_state",
    "kinematic_map",
    "kinematic_map_rate",
    "paper_reference",
    "wheel_rates",
]
