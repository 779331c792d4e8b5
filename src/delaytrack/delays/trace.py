"""A measured delay trace ``(t_i, h_i)``, linearly interpolated; loadable from CSV."""

from __future__ import annotations

import itertools
import math
import re
from array import array
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

import delaytrack.delays._kernel as _kernel
from delaytrack._io import column_label, csv_number, csv_rows, shown_header
from delaytrack._validation import beyond_choice
from delaytrack.delays.knots import KnotDelay

__all__ = ["TIME_UNITS", "TraceDelay"]

#: Units a trace file's columns may be in, with their size in seconds.
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}

#: A unit written in a column header: ``delay_ms``, ``h [ms]``, ``t (s)``, ``stamp_us``,
#: ``delay_milliseconds``.
_UNIT_ALIASES = {
    "sec": "s",
    "secs": "s",
    "second": "s",
    "seconds": "s",
    "msec": "ms",
    "millisecond": "ms",
    "milliseconds": "ms",
    "usec": "us",
    "µs": "us",
    "microsecond": "us",
    "microseconds": "us",
    "nsec": "ns",
    "nanosecond": "ns",
    "nanoseconds": "ns",
}
_HEADER_UNIT = re.compile(
    r"(?:^|[_\s(\[])(" + "|".join([*TIME_UNITS, *_UNIT_ALIASES]) + r")[)\]]?\s*$",
    re.IGNORECASE,
)


#: The start of a cell that is meant as a number (read by the number rule, refused when it is not
#: one), unlike a header name: a digit of any script, a sign, a point, inf or nan.
_NUMBER_START = re.compile(r"\s*(?:[+-]|\.?\d|inf|nan)", re.IGNORECASE)


def _header_unit(name: str) -> str | None:
    """The unit a column header names (``"delay_ms"`` -> ``"ms"``), or None."""
    match = _HEADER_UNIT.search(name.strip())
    if match is None:
        return None
    unit = match.group(1).lower()
    return _UNIT_ALIASES.get(unit, unit)


def _unit(argument: str, value: object) -> float:
    if value not in TIME_UNITS:
        raise ValueError(f"{argument} must be one of {list(TIME_UNITS)}; got {value!r}")
    return TIME_UNITS[str(value)]


@dataclass(frozen=True, eq=False)
class TraceDelay(KnotDelay):
    """``h(t)`` linear between knots ``(times[i], values[i])``.

    The trace covers ``[times[0], times[-1]]``, and before its first knot it holds its first
    value. A simulation that runs beyond its last knot is refused (the trace says nothing about
    that time), unless ``beyond = "hold"``, which holds the last value.

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

        Without column names the file has two columns ``t, h`` (a header row, one whose first
        cell does not start like a number, is skipped). A log with more columns (``stamp, delay,
        seq``) is read by naming the two columns of its header row. Numbers are read as on the
        command line: ``0_05``, ``0x10``, ``nan`` or a decimal comma are refused, naming the
        line and column.

        Units are seconds unless ``time_unit`` / ``delay_unit`` say otherwise (``"s"``,
        ``"ms"``, ``"us"``). A header that names another unit than the one applied
        (``delay_ms`` read as seconds) is refused: a delay in milliseconds read as seconds is a
        thousand times too long.

        Parameters
        ----------
        path : str or Path
            The CSV file.
        time_column, delay_column : str, optional
            Header names of the time and delay columns; give both or neither.
        time_unit, delay_unit : {"s", "ms", "us"}, optional
            Units of the columns (seconds by default).
        beyond : {"refuse", "hold"}
            See the class.
        """
        path = Path(path)
        if (time_column is None) != (delay_column is None):
            raise ValueError(
                "time_column and delay_column name the two columns of a CSV header; give both "
                f"or neither; got time_column = {time_column!r}, delay_column = {delay_column!r}"
            )
        scales = [
            _unit("time_unit", "s" if time_unit is None else time_unit),
            _unit("delay_unit", "s" if delay_unit is None else delay_unit),
        ]
        rows = csv_rows(path)
        first = next(rows, None)
        if first is None:
            raise ValueError(f"{path}: the file holds no rows; a trace needs two columns t, h")
        header = None if _NUMBER_START.match(first[1][0]) else first[1]
        columns = _columns(path, header, time_column, delay_column)
        given = (time_unit, delay_unit)
        for k, (argument, name) in enumerate(
            zip(("time_unit", "delay_unit"), columns[1], strict=True)
        ):
            named = None if name is None else _header_unit(name)
            applied = "s" if given[k] is None else given[k]
            if named is not None and named != applied:
                label = column_label(columns[0][k] + 1, name)
                raise ValueError(
                    f"{path}: {label} looks like {named}, but it would be read in {applied}; "
                    f"give {argument} = {named!r} (or {argument} = {applied!r} if the header is "
                    "wrong)"
                    if given[k] is None
                    else f"{path}: {label} names {named}, but {argument} = {applied!r}; make "
                    "them agree"
                )
        times, values = array("d"), array("d")
        width = len(header) if header is not None else 2
        data = rows if header is not None else itertools.chain([first], rows)
        for line, row in data:
            if len(row) != width:
                what = "2 columns (t, h)" if header is None else f"{width} columns as its header"
                hint = (
                    "; name the columns (time_column, delay_column) to read a wider log"
                    if header is None and len(row) > 2
                    else ""
                )
                raise ValueError(f"{path}: line {line} must have {what}; it has {len(row)}{hint}")
            for column, target, scale, name in zip(
                columns[0], (times, values), scales, columns[1], strict=True
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
) -> tuple[tuple[int, int], tuple[str | None, str | None]]:
    """Indices and header names of the time and delay columns."""
    if time_column is None:
        if header is not None and len(header) != 2:
            raise ValueError(
                f"{path}: the header row{shown_header(header)} must have 2 columns (t, h); it "
                f"has {len(header)}"
                + (
                    "; name the time and delay columns (time_column, delay_column) to read a "
                    "wider log"
                    if len(header) > 2
                    else ""
                )
            )
        names = (None, None) if header is None else (header[0].strip(), header[1].strip())
        return (0, 1), names
    if header is None:
        raise ValueError(
            f"{path}: time_column = {time_column!r} names a header column, but the file has no "
            "header row"
        )
    stripped = [name.strip() for name in header]
    if time_column == delay_column:
        raise ValueError(
            f"{path}: time_column and delay_column must name two different columns; both are "
            f"{time_column!r}"
        )
    indices = []
    for argument, name in (("time_column", time_column), ("delay_column", delay_column)):
        if name not in stripped:
            raise ValueError(
                f"{path}: {argument} = {name!r} is not in the header{shown_header(header)}"
            )
        indices.append(stripped.index(name))
    return (indices[0], indices[1]), (time_column, delay_column)
