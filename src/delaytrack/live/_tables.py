"""The session folder's tables as the summary, the report and the replay read them."""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any

__all__ = ["ms", "number", "read_rows"]


def read_rows(path: Path) -> list[dict[str, str]]:
    """The rows of a CSV table of the session folder (none when the file is missing)."""
    if not path.is_file():
        return []
    with open(path, newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def number(text: str | None) -> float:
    """A cell as a number; NaN for an empty or unreadable one."""
    try:
        return float(text) if text not in (None, "") else math.nan
    except ValueError:
        return math.nan


def ms(value: Any) -> str:
    """A duration in ms for the summary and the report, or n/a."""
    return "n/a" if value is None or not math.isfinite(value) else f"{value:.3f} ms"
