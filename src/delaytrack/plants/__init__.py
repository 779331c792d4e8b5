"""Euler–Lagrange plants ``M(q) q̈ + N(q, q̇) = G(q) u``: built-in and user-defined."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from delaytrack._spec import TypeSpec, array, build_from_table, gain, number
from delaytrack.plants.base import ELPlant, el_rhs
from delaytrack.plants.callable_plant import CallablePlant
from delaytrack.plants.linear import LinearPlant
from delaytrack.plants.two_link_arm import TwoLinkArm

__all__ = [
    "PLANT_SPECS",
    "CallablePlant",
    "ELPlant",
    "LinearPlant",
    "TwoLinkArm",
    "el_rhs",
    "plant_from_spec",
]

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
}


def plant_from_spec(spec: Mapping[str, Any], table: str = "plant") -> ELPlant:
    """Build a plant from ``{"type": name, ...parameters}``; refusals name the key."""
    return build_from_table(table, spec, PLANT_SPECS)
