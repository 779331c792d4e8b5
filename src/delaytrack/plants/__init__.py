"""Euler–Lagrange plants ``M(q) q̈ + N(q, q̇) = G(q) u``: built-in and user-defined."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from delaytrack.plants.base import ELPlant, el_rhs
from delaytrack.plants.callable_plant import CallablePlant
from delaytrack.plants.linear import LinearPlant
from delaytrack.plants.two_link_arm import TwoLinkArm

__all__ = [
    "CallablePlant",
    "ELPlant",
    "LinearPlant",
    "TwoLinkArm",
    "PLANT_TYPES",
    "el_rhs",
    "plant_from_spec",
]

#: Scenario-file names of the plants that can be built from plain data.
PLANT_TYPES: dict[str, type[ELPlant]] = {"two-link-arm": TwoLinkArm, "linear": LinearPlant}

_SPEC_KEYS = {
    "two-link-arm": {"p1": "p1", "p2": "p2", "p3": "p3", "fd1": "fd1", "fd2": "fd2"},
    "linear": {
        "mass": "mass",
        "damping": "damping",
        "stiffness": "stiffness",
        "input_map": "input_map_matrix",
    },
}


def plant_from_spec(spec: Mapping[str, Any]) -> ELPlant:
    """Build a plant from ``{"type": name, ...parameters}``; unknown names and keys are errors."""
    name = spec.get("type")
    if name not in PLANT_TYPES:
        raise ValueError(f"unknown plant type {name!r}; valid types are {sorted(PLANT_TYPES)}")
    accepted = _SPEC_KEYS[name]
    fields = {key: value for key, value in spec.items() if key != "type"}
    unknown = sorted(set(fields) - set(accepted))
    if unknown:
        raise ValueError(
            f"unknown key(s) {unknown} for plant type {name!r}; valid keys are {sorted(accepted)}"
        )
    return PLANT_TYPES[name](**{accepted[key]: value for key, value in fields.items()})
