"""Numbers in words for messages and reports: counts (``1 unit``, ``2 units``) and values
shown as short as they can be without reading as another number."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["counted", "shown_number", "table_text"]


def counted(count: int, noun: str) -> str:
    """``count`` and ``noun``, with an ``s`` unless ``count`` is 1: ``counted(1, "draw")`` is
    ``"1 draw"``, ``counted(3, "draw")`` ``"3 draws"``."""
    return f"{count} {noun if count == 1 else noun + 's'}"


def shown_number(value: float) -> str:
    """``value`` to six significant digits, or in full where those would read as another
    number (an ``--r`` of 1.0000000000000002 is not shown as the refused 1)."""
    short = f"{value:g}"
    return short if float(short) == value else repr(float(value))


def table_text(frame: pd.DataFrame) -> str:
    """``frame`` as a terminal shows it, without its index: numbers to four significant digits,
    "—" where a value is missing (a run that did not finish has no metrics), never "NaN"."""
    return frame.to_string(index=False, float_format=lambda v: f"{v:.4g}", na_rep="—")
