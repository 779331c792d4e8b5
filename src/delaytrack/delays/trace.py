"""A measured delay trace ``(t_i, h_i)``, linearly interpolated; loadable from CSV."""

from __future__ import annotations

import math
from array import array
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

import delaytrack.delays._kernel as _kernel
from delaytrack._io import (
    TIME_UNITS,
    check_column_unit,
    column_count,
    column_name,
    csv_number,
    csv_table,
)
from delaytrack._validation import ArgumentError, beyond_choice
from delaytrack.delays.knots import KnotDelay

__all__ = ["TIME_UNITS", "TraceDelay"]

#: The documented names of a trace's two columns, used for them in messages.
_ROLES = ("t", "h")


def _unit(argument: str, value: object) -> float:
    if value not in TIME_UNITS:
        raise ArgumentError(argument, f"must be one of {list(TIME_UNITS)}; got {value!r}")
    return TIME_UNITS[str(value)]


@dataclass(frozen=True, eq=False)
class TraceDelay(KnotDelay):
    """``h(t)`` linear between knots ``(times[i], values[i])``.

    The trace covers ``[times[0], times[-1]]``. A simulation that starts before its first knot
    is refused, and so is one that runs beyond its last knot (the trace says nothing about
    those times), unless ``beyond = "hold"``, which holds the last value after it.

    Parameters
    ----------
    times : array_like, shape (m,)
        Seconds, strictly increasing.
    values : array_like, shape (m,)
        Delays in seconds, ``>= 0``.
    source : str, optional
        Where the trace came from (a CSV path), kept for the record.
    beyond : {"refuse", "hold"}
        What a simulation longer than the trace gets: refused (default), or the last value.
    csv_options : dict, optional
        The :meth:`from_csv` options the file was read with (kept so that the scenario as run
        reads it back the same way).
    """

    source: str | None = None
    beyond: str = "refuse"
    csv_options: dict[str, str] | None = None
    type_name: ClassVar[str] = "trace"

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "beyond", beyond_choice(self.beyond))

    @classmethod
    def from_csv(
        cls,
        path: str | Path,
        *,
        time_column: str | None = None,
        delay_column: str | None = None,
        time_unit: str | None = None,
        delay_unit: str | None = None,
        beyond: str = "refuse",
    ) -> TraceDelay:
        """Read a trace from a CSV file.

        Without column names the file has two columns ``t, h``; its first row is a header
        unless its first cell starts like a number (then every row is data). A log with more
        columns (``stamp, delay, seq``) is read by naming the two columns of its header row,
        whose names must differ from each other. Numbers are read as on the command line:
        ``0_05``, ``0x10``, ``nan`` or a decimal comma are refused, naming the line and column.
        Errors never quote the file's text, its header included.

        Units are seconds unless ``time_unit`` / ``delay_unit`` say otherwise (``"s"``,
        ``"ms"``, ``"us"``, ``"ns"``). A column whose name has a word naming another unit
        (``delay_ms_mean``, ``h [ms]``, ``t_minutes``) is refused unless its unit is given: a
        delay in milliseconds read as seconds is a thousand times too long. A word that may
        mean something else (``min`` in ``h_min``: a minimum, or minutes?) asks for the unit
        too, and a unit given stands unless the name names another one for certain.

        Parameters
        ----------
        path : str or Path
            The CSV file.
        time_column, delay_column : str, optional
            Header names of the time and delay columns; give both or neither.
        time_unit, delay_unit : {"s", "ms", "us", "ns"}, optional
            Units of the columns (seconds by default).
        beyond : {"refuse", "hold"}
            See the class.
        """
        path = Path(path)
        if (time_column is None) != (delay_column is None):
            raise ArgumentError(
                "time_column",
                "and delay_column name the two columns of a CSV header; give both or neither; "
                f"got time_column = {time_column!r}, delay_column = {delay_column!r}",
            )
        given = (time_unit, delay_unit)
        scales = [
            _unit(f"{role}_unit", "s" if unit is None else unit)
            for role, unit in zip(("time", "delay"), given, strict=True)
        ]
        header, rows = csv_table(path, "a trace needs two columns t, h")
        columns = _columns(path, header, time_column, delay_column)
        names = _ROLES if time_column is None else (time_column, delay_column)
        if header is not None:
            for k, role in enumerate(("time", "delay")):
                label = (
                    f"the name of column {columns[k] + 1} (the {role})"
                    if time_column is None
                    else f"{role}_column = {names[k]!r}"
                )
                check_column_unit(path, label, header[columns[k]], f"{role}_unit", given[k])
        times, values = array("d"), array("d")
        width = 2 if header is None else len(header)
        for line, row in rows:
            if len(row) != width:
                what = "2 columns (t, h)" if header is None else f"{width} columns as its header"
                hint = (
                    "; name the columns (time_column, delay_column) to read a wider log"
                    if header is None and len(row) > 2
                    else ""
                )
                raise ValueError(f"{path}: line {line} must have {what}; it has {len(row)}{hint}")
            for column, target, scale, name in zip(
                columns, (times, values), scales, names, strict=True
            ):
                target.append(scale * csv_number(path, line, column + 1, row[column], name))
        options = {
            key: value
            for key, value in {
                "time_column": time_column,
                "delay_column": delay_column,
                "time_unit": time_unit,
                "delay_unit": delay_unit,
            }.items()
            if value is not None
        }
        try:
            return cls(
                np.array(times),
                np.array(values),
                source=str(path),
                beyond=beyond,
                csv_options=options,
            )
        except ValueError as error:
            raise ValueError(f"{path}: {error}") from None

    @property
    def kind(self) -> int:
        return _kernel.PIECEWISE_LINEAR

    @property
    def start(self) -> float:
        return float(self.times[0])

    @property
    def horizon(self) -> float:
        return math.inf if self.beyond == "hold" else float(self.times[-1])

    def to_spec(self) -> dict[str, Any]:
        extra = {} if self.beyond == "refuse" else {"beyond": self.beyond}
        if self.source is not None:
            options = self.csv_options or {}
            return {"type": self.type_name, "path": self.source, **options, **extra}
        return {**super().to_spec(), **extra}


def _columns(
    path: Path, header: list[str] | None, time_column: str | None, delay_column: str | None
) -> tuple[int, int]:
    """Indices of the time and delay columns."""
    if time_column is None:
        if header is not None and len(header) != 2:
            raise ValueError(
                f"{path}: the header row has {column_count(len(header))}; a trace has 2 (t, h)"
                + (
                    "; name the time and delay columns (time_column, delay_column) to read a "
                    "wider log"
                    if len(header) > 2
                    else ""
                )
            )
        return 0, 1
    if header is None:
        raise ValueError(
            f"{path}: time_column = {time_column!r} names a header column, but the file has no "
            "header row (its first row is numbers)"
        )
    names = (
        ("time_column", _column_text("time_column", time_column)),
        ("delay_column", _column_text("delay_column", delay_column)),
    )
    if column_name(names[0][1]) == column_name(names[1][1]):
        raise ValueError(
            f"{path}: time_column and delay_column must name two different columns; both are "
            f"{time_column!r}"
        )
    indices = []
    for argument, name in names:
        if column_name(name) not in header:
            raise ValueError(
                f"{path}: {argument} = {name!r} is not in the header row (of "
                f"{column_count(len(header))})"
            )
        indices.append(header.index(column_name(name)))
    return indices[0], indices[1]


def _column_text(argument: str, name: object) -> str:
    """``name``, refused unless it is text (a column's name)."""
    if not isinstance(name, str):
        raise TypeError(f"{argument} must be a column's name (text); got {name!r}")
    return name
