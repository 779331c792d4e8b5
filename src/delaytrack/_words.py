"""Counts in words for messages and reports: ``1 unit``, ``2 units``."""

from __future__ import annotations

__all__ = ["counted"]


def counted(count: int, noun: str, plural: str | None = None) -> str:
    """``count`` and ``noun``, in the plural (``plural``, by default ``noun + "s"``) unless
    ``count`` is 1: ``counted(1, "draw")`` is ``"1 draw"``, ``counted(3, "draw")``
    ``"3 draws"``."""
    return f"{count} {noun if count == 1 else (plural or noun + 's')}"
