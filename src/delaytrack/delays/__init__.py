"""Input-delay profiles ``h(t)``: constant, rectified sine, piecewise constant, trace, random.

Each profile knows its bound ``h_max``; :func:`delay_from_spec` builds one from plain data (a
scenario file's ``[delay]`` table).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from delaytrack._spec import TypeSpec, build_from_table, integer, number, string, vector
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
    "DELAY_SPECS",
    "delay_from_spec",
]


def _trace(times: Any = None, values: Any = None, path: Any = None) -> TraceDelay:
    """A trace from ``path`` (a CSV file) or from ``times`` and ``values`` (checked by the spec)."""
    return TraceDelay.from_csv(path) if path is not None else TraceDelay(times, values)


#: Delay profiles that can be built from plain data, by scenario-file name; also "S1" .. "S4".
DELAY_SPECS: dict[str, TypeSpec] = {
    "constant": TypeSpec(ConstantDelay, {"h": ("value", number)}, required=("h",)),
    "abs-sine": TypeSpec(
        AbsSineDelay,
        {name: (name, number) for name in ("offset", "amplitude", "frequency", "phase")},
        required=("offset", "amplitude", "frequency"),
    ),
    "piecewise-constant": TypeSpec(
        PiecewiseConstantDelay,
        {"times": ("times", vector), "values": ("values", vector)},
        required=("times", "values"),
    ),
    "trace": TypeSpec(
        _trace,
        {"times": ("times", vector), "values": ("values", vector), "path": ("path", string)},
        alternatives=(("path",), ("times", "values")),
    ),
    "random": TypeSpec(
        RandomDelay,
        {
            **{name: (name, number) for name in ("h_low", "h_high", "max_rate", "duration")},
            "seed": ("seed", integer),
            "knot_spacing": ("knot_spacing", number),
        },
        required=("h_low", "h_high", "max_rate", "duration", "seed"),
    ),
    "S1": TypeSpec(AbsSineDelay.S1),
    "S2": TypeSpec(AbsSineDelay.S2),
    "S3": TypeSpec(ConstantDelay.S3),
    "S4": TypeSpec(ConstantDelay.S4),
}


def delay_from_spec(spec: Mapping[str, Any]) -> DelayProfile:
    """Build a profile from ``{"type": name, ...}``; ``type`` may be ``"S1"`` .. ``"S4"``.

    Unknown types and keys, missing keys and ill-typed values raise an error naming the key.
    """
    return build_from_table("delay", spec, DELAY_SPECS)
