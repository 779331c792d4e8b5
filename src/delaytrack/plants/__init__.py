"""Euler–Lagrange plants ``M(q) q̈ + N(q, q̇) = G(q) u``: built-in and user-defined."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from delaytrack._spec import TypeSpec, array, build_from_table, gain, integer, number, string
from delaytrack.plants.base import ELPlant, el_rhs
from delaytrack.plants.callable_plant import CallablePlant
from delaytrack.plants.compiled_plant import CompiledPlant
from delaytrack.plants.linear import LinearPlant
from delaytrack.plants.mujoco import MujocoPlant
from delaytrack.plants.robot import (
    MujocoWheeledRobot,
    NominalRobot,
    PayloadRobot,
    PrintedRobotModel,
    WheeledRobot,
)
from delaytrack.plants.robot.body import BODY_KEYS
from delaytrack.plants.two_link_arm import TwoLinkArm

__all__ = [
    "PLANT_SPECS",
    "CallablePlant",
    "CompiledPlant",
    "ELPlant",
    "LinearPlant",
    "MujocoPlant",
    "MujocoWheeledRobot",
    "NominalRobot",
    "PayloadRobot",
    "PrintedRobotModel",
    "TwoLinkArm",
    "WheeledRobot",
    "el_rhs",
    "plant_from_spec",
]

_TRUTH_KEYS = (
    *BODY_KEYS,
    "viscous_friction",
    "coulomb_friction",
    "friction_speed",
    "baumgarte_gain",
)
_PAYLOAD_KEYS = (
    "payload_mass",
    "time_on",
    "time_off",
    "first_on",
    "duration",
    "plate_length",
    "plate_width",
    "plate_center",
)


def _boolean(value: object) -> str | None:
    return None if isinstance(value, bool) else "must be true or false"


def _joint_names(value: object) -> str | None:
    named = isinstance(value, list) and value and all(isinstance(item, str) for item in value)
    return None if named else "must be a list of joint names"


def _payload_robot(**arguments: Any) -> PayloadRobot:
    """Build a :class:`PayloadRobot` from flat scenario keys (robot keys go to its robot)."""
    robot = WheeledRobot(**{key: arguments.pop(key) for key in _TRUTH_KEYS if key in arguments})
    return PayloadRobot(robot=robot, **arguments)


#: Plants that can be built from plain data, by scenario-file name.
PLANT_SPECS: dict[str, TypeSpec] = {
    "two-link-arm": TypeSpec(
        TwoLinkArm, {name: (name, number) for name in ("p1", "p2", "p3", "fd1", "fd2")}
    ),
    "linear": TypeSpec(
        LinearPlant,
        {
            "mass": ("mass", gain),
            "damping": ("damping", gain),
            "stiffness": ("stiffness", gain),
            "input_map": ("input_map_matrix", array),
        },
        required=("mass",),
    ),
    WheeledRobot.type_name: TypeSpec(WheeledRobot, {key: (key, number) for key in _TRUTH_KEYS}),
    PayloadRobot.type_name: TypeSpec(
        _payload_robot,
        {
            **{key: (key, number) for key in (*_TRUTH_KEYS, *_PAYLOAD_KEYS)},
            "seed": ("seed", integer),
            "placements": ("placements", array),
            "beyond": ("beyond", string),
        },
        alternatives=(("seed", "duration"), ("placements",)),
    ),
    MujocoPlant.type_name: TypeSpec(
        MujocoPlant,
        {
            **{
                key: (key, number if key == "mass_scale" else string)
                for key in (
                    "path",
                    "mass_scale",
                    "actuator_limits",
                    "constraints",
                    "stepping",
                    "name",
                )
            },
            "add_motors": ("add_motors", _boolean),
            "coordinates": ("coordinates", _joint_names),
            "contact_time_constant": ("contact_time_constant", number),
        },
        required=("path",),
    ),
    MujocoWheeledRobot.type_name: TypeSpec(
        MujocoWheeledRobot,
        {
            "path": ("path", string),
            "name": ("name", string),
            **{
                key: (key, number)
                for key in ("mass_scale", "contact_time_constant", *_PAYLOAD_KEYS)
            },
            "seed": ("seed", integer),
            "placements": ("placements", array),
            "beyond": ("beyond", string),
        },
    ),
    NominalRobot.type_name: TypeSpec(NominalRobot, {key: (key, number) for key in BODY_KEYS}),
    PrintedRobotModel.type_name: TypeSpec(
        PrintedRobotModel,
        {
            **{
                key: (key, number)
                for key in (
                    "wheel_radius",
                    "half_track",
                    "d",
                    "mass",
                    "first_moment",
                    "inertia",
                    "wheel_spin_inertia",
                )
            },
            "corrected_row2": ("corrected_row2", _boolean),
        },
    ),
}


def plant_from_spec(spec: Mapping[str, Any], table: str = "plant") -> ELPlant:
    """Build a plant from ``{"type": name, ...parameters}``; refusals name the key.

    ``name`` is one of :data:`PLANT_SPECS` or a factory of yours,
    ``"python:<module>:<function>"`` (or ``"python:<file.py>:<function>"``), called with the
    other keys as keyword arguments and returning an :class:`ELPlant`.
    """
    return build_from_table(table, spec, PLANT_SPECS, returns=ELPlant)
