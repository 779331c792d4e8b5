"""A measured delay trace ``(t_i, h_i)``, linearly interpolated; loadable from CSV."""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from delaytrack.delays import _kernel
from delaytrack.delays.knots import KnotDelay

__all__ = ["TraceDelay"]


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


@dataclass(frozen=True, eq=False)
class TraceDelay(KnotDelay):
    """``h(t)`` linear between knots ``(times[i], values[i])``, held constant outside them.

    Parameters
    ----------
    times : array_like, shape (m,)
        Seconds, strictly increasing.
    values : array_like, shape (m,)
        Delays in seconds, ``>= 0``.
    source : str, optional
        Where the trace came from (a CSV path), kept for the record.
    """

    source: str | None = None
    type_name: ClassVar[str] = "trace"

    @classmethod
    def from_csv(cls, path: str | Path) -> TraceDelay:
        """Read a CSV of two columns ``t, h`` in seconds; a non-numeric header row is skipped."""
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"delay trace file {str(path)!r} does not exist")
        with path.open(newline="") as handle:
            rows = [row for row in csv.reader(handle) if row and any(cell.strip() for cell in row)]
        if rows and not _is_number(rows[0][0]):
            rows = rows[1:]
        times, values = [], []
        for number, row in enumerate(rows, start=1):
            if len(row) != 2:
                raise ValueError(f"{path}: data row {number} must have 2 columns (t, h); got {row}")
            try:
                times.append(float(row[0]))
                values.append(float(row[1]))
            except ValueError:
                raise ValueError(f"{path}: data row {number} is not numeric: {row}") from None
        try:
            return cls(np.array(times), np.array(values), source=str(path))
        except ValueError as error:
            raise ValueError(f"{path}: {error}") from None

    @property
    def kind(self) -> int:
        return _kernel.PIECEWISE_LINEAR

    def to_spec(self) -> dict[str, Any]:
        if self.source is not None:
            return {"type": self.type_name, "path": self.source}
        return super().to_spec()
