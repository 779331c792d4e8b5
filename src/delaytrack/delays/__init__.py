"""Input-delay profiles ``h(t)``: constant, rectified sine, piecewise constant, trace, random.

Each profile knows its bound ``h_max``; :func:`delay_from_spec` builds one from plain data (a
scenario file's ``[delay]`` table).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from delaytrack.delays.abs_sine import AbsSineDelay
from delaytrack.delays.base import DelayProfile
from delaytrack.delays.constant import ConstantDelay
from delaytrack.delays.piecewise_constant import PiecewiseConstantDelay
from delaytrack.delays.random_delay import RandomDelay
from delaytrack.delays.trace import TraceDelay

__all__ = [
    "AbsSineDelay",
    "ConstantDelay",
    "DelayProfile",
    "PiecewiseConstantDelay",
    "RandomDelay",
    "TraceDelay",
    "DELAY_TYPES",
    "PAPER_SCENARIO_DELAYS",
    "delay_from_spec",
]

#: Scenario-file names of the profile families and the keyword arguments each accepts.
DELAY_TYPES: dict[str, tuple[type[DelayProfile], dict[str, str]]] = {
    "constant": (ConstantDelay, {"h": "value"}),
    "abs-sine": (
        AbsSineDelay,
        {"offset": "offset", "amplitude": "amplitude", "frequency": "frequency", "phase": "phase"},
    ),
    "piecewise-constant": (PiecewiseConstantDelay, {"times": "times", "values": "values"}),
    "trace": (TraceDelay, {"times": "times", "values": "values", "path": "path"}),
    "random": (
        RandomDelay,
        {
            "h_low": "h_low",
            "h_high": "h_high",
            "max_rate": "max_rate",
            "duration": "duration",
            "seed": "seed",
            "knot_spacing": "knot_spacing",
        },
    ),
}

#: Keys each family needs (a trace needs 'times' and 'values', or 'path' alone).
_REQUIRED: dict[str, tuple[str, ...]] = {
    "constant": ("h",),
    "abs-sine": ("offset", "amplitude", "frequency"),
    "piecewise-constant": ("times", "values"),
    "trace": ("times", "values"),
    "random": ("h_low", "h_high", "max_rate", "duration", "seed"),
}

#: The paper's four delay scenarios.
PAPER_SCENARIO_DELAYS = {
    "S1": AbsSineDelay.S1,
    "S2": AbsSineDelay.S2,
    "S3": ConstantDelay.S3,
    "S4": ConstantDelay.S4,
}


def delay_from_spec(spec: Mapping[str, Any]) -> DelayProfile:
    """Build a profile from ``{"type": name, ...}``; ``type`` may also be ``"S1"`` .. ``"S4"``.

    Unknown types and unknown keys raise ``ValueError`` naming them and the valid choices.
    """
    if "type" not in spec:
        raise ValueError(
            f"delay needs a 'type', one of {sorted([*DELAY_TYPES, *PAPER_SCENARIO_DELAYS])}"
        )
    name = spec["type"]
    fields = {key: value for key, value in spec.items() if key != "type"}
    if name in PAPER_SCENARIO_DELAYS:
        if fields:
            raise ValueError(f"delay type {name!r} takes no parameters; got {sorted(fields)}")
        return PAPER_SCENARIO_DELAYS[name]()
    if name not in DELAY_TYPES:
        valid = sorted([*DELAY_TYPES, *PAPER_SCENARIO_DELAYS])
        raise ValueError(f"unknown delay type {name!r}; valid types are {valid}")
    cls, accepted = DELAY_TYPES[name]
    unknown = sorted(set(fields) - set(accepted))
    if unknown:
        raise ValueError(
            f"unknown key(s) {unknown} for delay type {name!r}; valid keys are {sorted(accepted)}"
        )
    if name == "trace" and "path" in fields:
        if len(fields) > 1:
            raise ValueError(
                "delay type 'trace' takes either 'path' or 'times' and 'values', not both"
            )
        return TraceDelay.from_csv(fields["path"])
    missing = sorted(key for key in _REQUIRED[name] if key not in fields)
    if missing:
        raise ValueError(
            f"delay type {name!r} needs key(s) {missing}; valid keys are {sorted(accepted)}"
        )
    return cls(**{accepted[key]: value for key, value in fields.items()})
