"""Waypoint references: a cubic spline through samples ``(t_i, q_i)``, with its derivatives.

On ``[t_i, t_{i+1}]`` each coordinate is the cubic

    q_d(t) = c0 τ³ + c1 τ² + c2 τ + c3,   τ = t - t_i,
    q̇_d(t) = 3 c0 τ² + 2 c1 τ + c2,       q̈_d(t) = 6 c0 τ + 2 c1,

with the coefficients of :class:`scipy.interpolate.CubicSpline` (continuous ``q̇_d`` and
``q̈_d``; the end conditions are ``boundary``). The samples come from arrays or a CSV file (a
measured or planned trajectory); the controller needs ``q̈_d``, which the spline provides.
"""

from __future__ import annotations

import itertools
import math
from array import array
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from delaytrack._compile.jit import tick_kernel
from delaytrack._io import (
    check_column_unit,
    column_count,
    column_name,
    csv_number,
    csv_table,
)
from delaytrack._sorted_search import count_at_or_before
from delaytrack._validation import ArgumentError, beyond_choice, finite_array
from delaytrack.references.base import Reference

__all__ = ["BOUNDARIES", "MAX_SAMPLES", "SplineReference", "spline_reference"]

#: End conditions of the spline (:class:`scipy.interpolate.CubicSpline`'s ``bc_type``):
#: ``"clamped"`` zero velocity at both ends (a trajectory from rest to rest), ``"natural"`` zero
#: acceleration, ``"not-a-knot"`` a single cubic over the first and last two intervals.
BOUNDARIES = ("clamped", "natural", "not-a-knot")

#: Most samples of one reference: each is in every run's parameters.
MAX_SAMPLES = 10**6


@tick_kernel
def spline_reference(t, params, qd, qd_dot, qd_ddot):
    """Fill ``q_d, q̇_d, q̈_d`` at ``t`` (module docstring).

    ``params = [n, K, hold, t_0 .. t_{K-1}, c]`` with ``c`` the coefficients ``(4, K-1, n)``
    row-major. Before ``t_0`` the first sample is held with zero derivatives, and after
    ``t_{K-1}`` the last one (``hold = 1``) or the last cubic continued (``hold = 0``); the
    simulator refuses runs that would reach either without ``hold``.
    """
    n = int(params[0])
    count = int(params[1])
    times = params[3 : 3 + count]
    coefficients = 3 + count
    stride = (count - 1) * n
    held = t < times[0] or (params[2] != 0.0 and t > times[count - 1])
    if t < times[0]:
        piece, tau = 0, 0.0
    elif held:
        piece, tau = count - 2, times[count - 1] - times[count - 2]
    else:
        piece = min(max(count_at_or_before(times, t) - 1, 0), count - 2)
        tau = t - times[piece]
    for i in range(n):
        j = coefficients + piece * n + i
        c0 = params[j]
        c1 = params[j + stride]
        c2 = params[j + 2 * stride]
        c3 = params[j + 3 * stride]
        qd[i] = ((c0 * tau + c1) * tau + c2) * tau + c3
        if held:
            qd_dot[i] = 0.0
            qd_ddot[i] = 0.0
        else:
            qd_dot[i] = (3.0 * c0 * tau + 2.0 * c1) * tau + c2
            qd_ddot[i] = 6.0 * c0 * tau + 2.0 * c1


@dataclass(frozen=True, eq=False)
class SplineReference(Reference):
    """A cubic spline through samples ``values[i]`` at ``times[i]``.

    Parameters
    ----------
    times : array_like, shape (K,)
        Strictly increasing sample times in seconds, ``K >= 2``.
    values : array_like, shape (K, n) or (K,)
        ``q_d`` at each time, one column per coordinate.
    boundary : {"clamped", "natural", "not-a-knot"}
        End conditions (:data:`BOUNDARIES`); ``"clamped"``, zero velocity at both ends, by
        default.
    beyond : {"refuse", "hold"}
        After the last sample: a run beyond it is refused (``"refuse"``, the default), or the
        last sample is held with zero velocity and acceleration (``"hold"``). Before the first
        sample a run is always refused.
    """

    times: np.ndarray
    values: np.ndarray
    boundary: str = "clamped"
    beyond: str = "refuse"
    _params: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        times = finite_array("times", self.times, ndim=1)
        values = finite_array("values", self.values)
        if values.ndim == 1:
            values = values[:, None]
        if not 2 <= times.size <= MAX_SAMPLES:
            raise ArgumentError("times", f"must hold 2 to {MAX_SAMPLES} samples; got {times.size}")
        if not np.all(np.diff(times) > 0):
            raise ArgumentError("times", f"must be strictly increasing; got {times.tolist()[:10]}")
        if values.ndim != 2 or values.shape[0] != times.size or values.shape[1] == 0:
            raise ArgumentError(
                "values",
                f"must have shape (K, n) with K = {times.size} rows, one per time; got "
                f"{values.shape}",
            )
        if self.boundary not in BOUNDARIES:
            raise ArgumentError(
                "boundary", f"must be one of {list(BOUNDARIES)}; got {self.boundary!r}"
            )
        beyond_choice(self.beyond)
        # Imported here, when a spline is built: SciPy's interpolation takes a quarter of a
        # second to import, which every command and live node would otherwise pay.
        from scipy.interpolate import CubicSpline

        with np.errstate(all="ignore"):  # checked below: an overflow is refused by name
            try:
                spline = CubicSpline(times, values, axis=0, bc_type=self.boundary)
            except ValueError:  # SciPy's own check of the slopes it computed
                spline = None
        n = values.shape[1]
        hold = 1.0 if self.beyond == "hold" else 0.0
        if spline is None or not np.all(np.isfinite(spline.c)):
            raise ArgumentError(
                "values",
                f"must change slowly enough for their time steps that the cubic spline through "
                f"them stays finite; it overflows (largest |value| {np.max(np.abs(values)):.3g}, "
                f"smallest time step {np.min(np.diff(times)):.3g} s)",
            )
        packed = np.concatenate([[n, times.size, hold], times, spline.c.ravel()])
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "values", values)
        object.__setattr__(self, "_params", packed)

    @classmethod
    def from_csv(
        cls,
        path: str | Path,
        *,
        time_column: str | None = None,
        columns: list[str] | None = None,
        boundary: str = "clamped",
        beyond: str = "refuse",
    ) -> SplineReference:
        """Read samples from a CSV file: a column of times in seconds, then one per coordinate.

        The first row is a header unless its first cell starts like a number (then every row is
        data, the times first), as for a delay trace. With a header, ``time_column`` (the first
        column by default) holds the times and ``columns`` (all the others by default) the
        coordinates, in order; the header's names must differ from each other, and the time
        column's name may not name another unit than seconds (``t_ms``). Every row has as many
        cells as the first, and numbers are read as on the command line: ``0_5``, ``0x10``,
        ``nan`` or a decimal comma are refused, naming the line and column. Errors never quote
        the file's text, its header included.
        """
        source = Path(path).expanduser()
        header, rows = csv_table(
            source, "waypoints need a column of times and one column per coordinate"
        )
        if header is not None:
            indices, names = _header_columns(source, header, time_column, columns)
            width = len(header)
        else:
            for option, value in (("time_column", time_column), ("columns", columns)):
                if value is not None:
                    raise ValueError(
                        f"{source}: {option} = {value!r} names header columns, but the file has "
                        "no header row (its first row is numbers)"
                    )
            first = next(rows)
            rows = itertools.chain([first], rows)
            width = len(first[1])
            indices, names = list(range(width)), [None] * width
            if width < 2:
                raise ValueError(
                    f"{source}: line {first[0]} has 1 column; waypoints need a column of times "
                    "and one column per coordinate"
                )
        samples = array("d")
        for line, row in rows:
            if len(row) != width:
                what = "its header" if header is not None else "its first row"
                raise ValueError(
                    f"{source}: line {line} must have {width} columns as {what}; it has {len(row)}"
                )
            samples.extend(
                csv_number(source, line, index + 1, row[index], name)
                for index, name in zip(indices, names, strict=True)
            )
        table = np.array(samples).reshape(-1, len(indices))
        if len(table) < 2:
            raise ValueError(
                f"{source}: waypoints need at least two samples (rows of numbers); got {len(table)}"
            )
        try:
            return cls(table[:, 0], table[:, 1:], boundary=boundary, beyond=beyond)
        except ValueError as error:
            raise ValueError(f"{source}: {error}") from None

    @property
    def n(self) -> int:
        return self.values.shape[1]

    @property
    def params(self) -> np.ndarray:
        return self._params

    @property
    def reference_kernel(self):
        return spline_reference

    @property
    def start(self) -> float:
        return float(self.times[0])

    @property
    def horizon(self) -> float:
        return math.inf if self.beyond == "hold" else float(self.times[-1])

    def to_spec(self) -> dict[str, Any]:
        return {
            "type": "spline",
            "times": self.times.tolist(),
            "values": self.values.tolist(),
            "boundary": self.boundary,
            "beyond": self.beyond,
        }


def _header_columns(
    source: Path, header: list[str], time_column: str | None, columns: list[str] | None
) -> tuple[list[int], list[str | None]]:
    """Positions of the time column and the coordinates' columns in ``header``, and their names
    for messages (the user's, or None: a name read from the file is not quoted)."""
    positions = []
    for option, name in [
        ("time_column", time_column),
        *(("columns", name) for name in columns or []),
    ]:
        if name is None:
            positions.append(0)
        elif not isinstance(name, str):
            raise TypeError(f"{option} must hold a column's name (text); got {name!r}")
        elif column_name(name) in header:
            positions.append(header.index(column_name(name)))
        else:
            raise ValueError(
                f"{source}: {option} names {name!r}, which is not in the header row (of "
                f"{column_count(len(header))})"
            )
    if columns is None:
        positions += [k for k in range(len(header)) if k != positions[0]]
    unnamed: list[str | None] = [None] * (len(positions) - 1)
    names = [time_column, *(columns or unnamed)]
    if len(positions) < 2:
        raise ValueError(
            f"{source}: the header row has no coordinate column besides the time; waypoints "
            "need a column of times and one column per coordinate"
        )
    label = (
        f"the name of column {positions[0] + 1} (the time)"
        if time_column is None
        else f"time_column = {time_column!r}"
    )
    check_column_unit(source, label, header[positions[0]], None, None)
    return positions, names
