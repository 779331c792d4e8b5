"""The robots the studies draw: the payload P3-DX's uncertain parameters as a sweep's
``[random]`` table, and the seed that makes draw ``i`` the same robot in every study.

Where the payload sits (``plant.seed``, the payload's placement each time it is put on) and the
wheel friction, uniform in the ranges derived from public parts data (viscous
0.001–0.02 N·m·s/rad, Coulomb 0.07–0.35 N·m; sources in ``docs/robot.md`` and
:data:`delaytrack.plants.robot.P3DX_SOURCES`).
"""

from __future__ import annotations

from typing import Any

__all__ = [
    "DRAWN_COLUMNS",
    "FRICTION",
    "PAYLOAD",
    "PAYLOAD_ROBOT",
    "PAYLOAD_ROBOT_TYPE",
    "SEED",
    "drawn_columns",
]

#: Seed of the studies' draws (a key's draws depend on it and the key only).
SEED = 2027
#: The payload's placement.
PAYLOAD: dict[str, dict[str, Any]] = {
    "plant.seed": {"dist": "integers", "low": 0, "high": 2**31 - 1}
}
#: The wheel friction.
FRICTION: dict[str, dict[str, Any]] = {
    "plant.viscous_friction": {"dist": "uniform", "low": 0.001, "high": 0.02},
    "plant.coulomb_friction": {"dist": "uniform", "low": 0.07, "high": 0.35},
}
#: The scenario ``type`` of the payload robot's plant.
PAYLOAD_ROBOT_TYPE = "wheeled-robot-payload"
#: Every uncertain parameter of the payload robot.
PAYLOAD_ROBOT: dict[str, dict[str, Any]] = {**PAYLOAD, **FRICTION}
#: The columns of the studies' run tables that hold these draws of the payload robot, with
#: their units (:func:`drawn_columns`).
DRAWN_COLUMNS: dict[str, str] = {
    "plant.seed": "payload_seed",
    "plant.viscous_friction": "viscous_friction_Nms_per_rad",
    "plant.coulomb_friction": "coulomb_friction_Nm",
}


def drawn_columns(scenario: Any) -> dict[str, str]:
    """:data:`DRAWN_COLUMNS` for a scenario of the payload robot (its plant's ``type``
    ``wheeled-robot-payload``), whose draws they name; ``{}`` for any other plant, whose keys
    (``plant.seed`` of a plant of yours) mean something else."""
    return dict(DRAWN_COLUMNS) if scenario.plant.get("type") == PAYLOAD_ROBOT_TYPE else {}
