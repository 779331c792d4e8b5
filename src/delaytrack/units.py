"""How results name quantities and their units in table columns and figure axes.

Every table a run or a sweep writes names a column ``<quantity>[_<coordinate>][_<unit>]``:

- coordinates by the plant's names (``x, y, phi, theta_r, theta_l`` for the robot), otherwise
  ``q1 .. qn`` counted from 1; inputs ``u1 .. um``;
- units in ASCII (:func:`ascii_unit`): ``m``, ``rad``, ``Nm``, ``m_per_s``, ``rad_per_s``,
  ``s``, ``mm``; a quantity whose unit the plant does not declare has no unit suffix (its unit
  is the plant's own);
- metric columns ``ae_<c>``, ``rms_<c>``, ``max_<c>`` (in the coordinate's unit) and ``tv`` (in
  the inputs' unit) keep these short names where sweep files refer to them (``metrics = [...]``,
  a sweep's ``runs.csv``); the tables written for reading (``simulate``'s and a live session's
  ``metrics.csv``, a sweep's ``summary.csv``, the paper job's ``summary.csv``) carry the unit in
  the column name.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

__all__ = [
    "ascii_unit",
    "coordinate_units",
    "default_names",
    "labelled",
    "value_with_unit",
    "with_unit",
]


def ascii_unit(unit: str) -> str:
    """A unit as it appears in column names: ``N·m`` -> ``Nm``, ``m/s`` -> ``m_per_s``."""
    return unit.replace("·", "").replace("/", "_per_").replace(" ", "")


def labelled(name: str, unit: str | None) -> str:
    """``name (unit)`` for figure axes and table headers, or ``name`` when the unit is not
    known."""
    return f"{name} ({unit})" if unit else name


def with_unit(name: str, unit: str | None) -> str:
    """``name_<unit>``, or ``name`` when the unit is not known."""
    return f"{name}_{ascii_unit(unit)}" if unit else name


def value_with_unit(value: str, unit: str | None) -> str:
    """A value as text followed by its unit for a sentence (``"0.2 rad"``), or the value alone
    when the unit is not known."""
    return f"{value} {unit}" if unit else value


def default_names(names: Sequence[str] | None, n: int, prefix: str = "q") -> tuple[str, ...]:
    """``names`` as a tuple, or ``q1 .. qn`` (``prefix`` and a count from 1) when there are
    none."""
    return tuple(names) if names is not None else tuple(f"{prefix}{i + 1}" for i in range(n))


def coordinate_units(plant: Any) -> dict[str, str | None]:
    """Each coordinate of ``plant`` (its ``coordinate_names``, else ``q1 .. qn``) with its unit
    (its ``coordinate_units``; None where it declares none), in order."""
    units = getattr(plant, "coordinate_units", None) or (None,) * plant.n
    return dict(zip(default_names(plant.coordinate_names, plant.n), units, strict=True))
