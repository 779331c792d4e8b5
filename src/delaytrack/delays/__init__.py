"""Input-delay profiles ``h(t)``: constant, rectified sine, piecewise constant, trace, random,
and a compiled kernel of your own.

Each profile knows its bound ``h_max``; :func:`delay_from_spec` builds one from plain data (a
scenario file's ``[delay]`` table).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from delaytrack._spec import TypeSpec, build_from_table, integer, number, string, vector
from delaytrack._validation import ArgumentError
from delaytrack.delays.abs_sine import AbsSineDelay
from delaytrack.delays.base import DelayProfile
from delaytrack.delays.compiled_delay import CompiledDelay
from delaytrack.delays.constant import ConstantDelay
from delaytrack.delays.piecewise_constant import PiecewiseConstantDelay
from delaytrack.delays.random_delay import RandomDelay
from delaytrack.delays.trace import TraceDelay

__all__ = [
    "AbsSineDelay",
    "CompiledDelay",
    "ConstantDelay",
    "DelayProfile",
    "PiecewiseConstantDelay",
    "RandomDelay",
    "TraceDelay",
    "DELAY_SPECS",
    "delay_from_spec",
]


def _trace(
    times: Any = None, values: Any = None, path: Any = None, beyond: Any = "refuse", **csv: Any
) -> TraceDelay:
    """A trace from ``path`` (a CSV file, read with the ``csv`` options) or from ``times`` and
    ``values`` (checked by the spec)."""
    if path is None:
        if csv:
            raise ArgumentError(
                sorted(csv)[0], "reads a CSV file; it needs 'path' (not 'times' and 'values')"
            )
        return TraceDelay(times, values, beyond=beyond)
    return TraceDelay.from_csv(path, beyond=beyond, **csv)


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
        {
            "times": ("times", vector),
            "values": ("values", vector),
            "path": ("path", string),
            "time_column": ("time_column", string),
            "delay_column": ("delay_column", string),
            "time_unit": ("time_unit", string),
            "delay_unit": ("delay_unit", string),
            "beyond": ("beyond", string),
        },
        alternatives=(("path",), ("times", "values")),
    ),
    "random": TypeSpec(
        RandomDelay,
        {
            **{name: (name, number) for name in ("h_low", "h_high", "max_rate", "duration")},
            "seed": ("seed", integer),
            "knot_spacing": ("knot_spacing", number),
            "beyond": ("beyond", string),
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
    A factory of yours, ``"python:<module>:<function>"``, is called with the other keys and
    returns a :class:`DelayProfile` (for example a trace read from a log of your own format).
    """
    return build_from_table("delay", spec, DELAY_SPECS, returns=DelayProfile)
