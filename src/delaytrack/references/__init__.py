"""Desired trajectories ``q_d(t)`` with their first two derivatives: sinusoids, waypoint splines
and references of your own, and a registry by name for scenario files."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from delaytrack._spec import TypeSpec, array, build_from_table, string, vector
from delaytrack.references.base import Reference
from delaytrack.references.sinusoidal import SinusoidalReference
from delaytrack.references.spline import SplineReference

__all__ = [
    "REFERENCE_SPECS",
    "Reference",
    "SinusoidalReference",
    "SplineReference",
    "reference_from_spec",
]


def _column_names(value: object) -> str | None:
    if isinstance(value, list) and value and all(isinstance(item, str) for item in value):
        return None
    return "must be a non-empty list of column names"


def _spline(path: str | None = None, **keys: Any) -> SplineReference:
    """A :class:`SplineReference` from arrays, or from the CSV file ``path``."""
    if path is None:
        return SplineReference(**keys)
    return SplineReference.from_csv(path, **keys)


#: References that can be built from plain data, by scenario-file name.
REFERENCE_SPECS: dict[str, TypeSpec] = {
    "sinusoidal": TypeSpec(
        SinusoidalReference,
        {
            "offset": ("offset", vector),
            "slope": ("slope", vector),
            "amplitude": ("amplitude", array),
            "frequency": ("frequency", array),
            "phase": ("phase", array),
        },
        required=("offset",),
    ),
    "spline": TypeSpec(
        _spline,
        {
            "times": ("times", vector),
            "values": ("values", array),
            "path": ("path", string),
            "time_column": ("time_column", string),
            "columns": ("columns", _column_names),
            "boundary": ("boundary", string),
            "beyond": ("beyond", string),
        },
        alternatives=(("times", "values"), ("path",)),
    ),
}


def reference_from_spec(spec: Mapping[str, Any]) -> Reference:
    """Build a reference from ``{"type": name, ...}``; ``type`` defaults to ``"sinusoidal"``.

    ``name`` is one of :data:`REFERENCE_SPECS` or a factory of yours,
    ``"python:<module>:<function>"``, returning a :class:`Reference`. Refusals name the key.
    """
    table = dict(spec)
    table.setdefault("type", "sinusoidal")
    return build_from_table("reference", table, REFERENCE_SPECS, returns=Reference)
