"""Tracking controllers: AROLC, the plain outer loop, the predictor baselines PCON and PCONf, and a
registry by name."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from delaytrack._spec import TypeSpec, build_from_table, gain, integer, number, string
from delaytrack.controllers.arolc import AROLC
from delaytrack.controllers.base import Controller
from delaytrack.controllers.outer_loop import OuterLoop
from delaytrack.controllers.pcon import PCON, PCONf, PredictorBaseline
from delaytrack.controllers.stepper import ControllerStepper
from delaytrack.plants.base import ELPlant

__all__ = [
    "AROLC",
    "CONTROLLER_SPECS",
    "Controller",
    "ControllerStepper",
    "OuterLoop",
    "PCON",
    "PCONf",
    "PredictorBaseline",
    "controller_from_spec",
]

_PREDICTOR_KEYS = {
    "kappa": ("kappa", number),
    "vartheta": ("vartheta", gain),
    "k_b": ("k_b", gain),
    "history": ("history", number),
    "T_c": ("T_c", number),
}
#: Optional keys of both predictors.
_PREDICTOR_OPTIONS = {"space": ("space", string)}

#: Controllers that can be built from plain data, by scenario-file name.
CONTROLLER_SPECS: dict[str, TypeSpec] = {
    "arolc": TypeSpec(
        AROLC,
        {
            "K1": ("K1", gain),
            "K2": ("K2", gain),
            "Q": ("Q", gain),
            "alpha": ("alpha", number),
            "epsilon": ("epsilon", number),
            "gamma": ("gamma", number),
            "c_hat0": ("c_hat0", number),
        },
        required=("K1", "K2", "Q", "alpha", "epsilon", "gamma"),
    ),
    "outer-loop": TypeSpec(
        OuterLoop, {"K1": ("K1", gain), "K2": ("K2", gain)}, required=("K1", "K2")
    ),
    "pcon": TypeSpec(
        PCON,
        {
            **_PREDICTOR_KEYS,
            **_PREDICTOR_OPTIONS,
            **{key: (key, number) for key in ("delay_scale", "delay_offset", "delay_noise")},
            "noise_seed": ("noise_seed", integer),
        },
        required=tuple(_PREDICTOR_KEYS),
    ),
    "pconf": TypeSpec(
        PCONf,
        {**_PREDICTOR_KEYS, **_PREDICTOR_OPTIONS, "h_bar": ("h_bar", number)},
        required=(*_PREDICTOR_KEYS, "h_bar"),
    ),
}


def controller_from_spec(spec: Mapping[str, Any], model: ELPlant) -> Controller:
    """Build a controller from ``{"type": name, gains...}`` around the nominal ``model``.

    ``name`` is one of :data:`CONTROLLER_SPECS` or a factory of yours,
    ``"python:<module>:<function>"``, called as ``factory(model=model, **gains)`` and returning
    a :class:`Controller`.
    """
    return build_from_table("controller", spec, CONTROLLER_SPECS, returns=Controller, model=model)
