"""Tracking controllers: AROLC, the plain outer loop, and a registry by name."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from delaytrack.controllers.arolc import AROLC
from delaytrack.controllers.base import Controller
from delaytrack.controllers.outer_loop import OuterLoop
from delaytrack.plants.base import ELPlant

__all__ = ["AROLC", "CONTROLLERS", "Controller", "OuterLoop", "controller_from_spec"]

#: Controllers by scenario-file name.
CONTROLLERS: dict[str, type[Controller]] = {"arolc": AROLC, "outer-loop": OuterLoop}

_GAINS = {
    "arolc": {"K1", "K2", "Q", "alpha", "epsilon", "gamma", "c_hat0"},
    "outer-loop": {"K1", "K2"},
}


def controller_from_spec(spec: Mapping[str, Any], model: ELPlant) -> Controller:
    """Build a controller from ``{"type": name, gains...}`` around the nominal ``model``."""
    name = spec.get("type")
    if name not in CONTROLLERS:
        raise ValueError(f"unknown controller type {name!r}; valid types are {sorted(CONTROLLERS)}")
    gains = {key: value for key, value in spec.items() if key != "type"}
    unknown = sorted(set(gains) - _GAINS[name])
    if unknown:
        raise ValueError(
            f"unknown key(s) {unknown} for controller {name!r}; "
            f"valid keys are {sorted(_GAINS[name])}"
        )
    return CONTROLLERS[name](model=model, **gains)
