"""Numbers in words for messages and reports: counts (``1 unit``, ``2 units``), values
shown as short as they can be without reading as another number, and quantities in the unit
that reads (``9.51 mm``, not ``0.00951 m``)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import pandas as pd

__all__ = [
    "count_text",
    "counted",
    "quantity_text",
    "scaled_unit",
    "shown_number",
    "table_text",
    "with_scaled",
]

#: The smaller units a value below one of these units is shown in: (factor, unit), largest first.
_SMALLER_UNITS: dict[str, tuple[tuple[float, str], ...]] = {
    "s": ((1e-3, "ms"), (1e-6, "µs"), (1e-9, "ns")),
    "m": ((1e-3, "mm"),),
}


def counted(count: int, noun: str) -> str:
    """``count`` and ``noun``, with an ``s`` unless ``count`` is 1: ``counted(1, "draw")`` is
    ``"1 draw"``, ``counted(3, "draw")`` ``"3 draws"``."""
    return f"{count} {noun if count == 1 else noun + 's'}"


def count_text(count: float) -> str:
    """A count, possibly a bound computed as a float, in digits grouped by thousands
    (``1,234,567``) up to a trillion, in three significant digits beyond (``2.53e+302``, not
    three hundred digits)."""
    return f"{count:,.0f}" if abs(count) < 1e12 or not math.isfinite(count) else f"{count:.3g}"


def shown_number(value: float) -> str:
    """``value`` to six significant digits, or in full where those would read as another
    number (an ``--r`` of 1.0000000000000002 is not shown as the refused 1)."""
    short = f"{value:g}"
    return short if float(short) == value else repr(float(value))


def table_text(frame: pd.DataFrame) -> str:
    """``frame`` as a terminal shows it, without its index: numbers to four significant digits,
    "—" where a value is missing (a run that did not finish has no metrics), never "NaN"."""
    return frame.to_string(index=False, float_format=lambda v: f"{v:.4g}", na_rep="—")


def scaled_unit(unit: str | None, largest: float, digits: int = 3) -> tuple[float, str | None]:
    """The factor and unit to show values of ``unit`` in when the largest of them (in
    magnitude) is ``largest``: ``unit`` itself when ``largest`` shown to ``digits``
    significant digits reads as one or more (0.9996 m is "1 m", not "1e+03 mm"), else the
    first smaller unit (seconds as ms, µs or ns, metres as mm) in which it does, else the
    smallest; ``(1, unit)`` for zero, for a value that is not finite and for a unit without
    smaller ones. The unit is chosen from the number as it would be printed, so that no
    value is shown as ``1e+03`` of a unit."""
    magnitude = abs(largest)
    smaller = _SMALLER_UNITS.get(unit or "", ())
    if not smaller or not 0.0 < magnitude < math.inf:
        return 1.0, unit
    units = ((1.0, unit), *smaller)
    for i, (factor, name) in enumerate(units):
        shown = float(f"{magnitude / factor:.{digits}g}")
        if shown >= 1.0:
            # 0.0009995 s: "0.999" ms, not "1e+03" µs (rounding carried it to a thousand)
            return units[i - 1] if shown >= 1000.0 and i > 0 else (factor, name)
    return smaller[-1]


def quantity_text(
    value: float, unit: str | None, digits: int = 3, largest: float | None = None
) -> str:
    """``value`` of ``unit`` to ``digits`` significant digits in the unit
    :func:`scaled_unit` picks for it (or for ``largest``, to show several values of one
    sentence in one unit): ``quantity_text(0.00951, "m")`` is ``"9.51 mm"``,
    ``quantity_text(9.99997e-10, "s", 4)`` ``"1 ns"``, ``quantity_text(2.5, "s")``
    ``"2.5 s"``; without a unit, the number alone."""
    factor, shown = scaled_unit(unit, value if largest is None else largest, digits)
    number = f"{value / factor:.{digits}g}"
    return number if shown is None else f"{number} {shown}"


def with_scaled(value: float, unit: str, digits: int = 6) -> str:
    """``value`` in ``unit`` to ``digits`` significant digits, then, when it is below one
    ``unit``, in the smaller unit of :func:`scaled_unit` to four: ``"0.12487 s (124.9 ms)"``,
    ``"9.99997e-10 s (1 ns)"``, ``"2.5 s"``; without the second where it would add nothing (a
    value that rounds to one ``unit``, or below a thousandth of the smallest unit)."""
    text = f"{value:.{digits}g} {unit}"
    factor, shown = scaled_unit(unit, value, 4)
    if shown == unit or abs(value / factor) < 1e-3:
        return text
    return f"{text} ({quantity_text(value, unit, 4)})"
