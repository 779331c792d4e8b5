"""Numbers that a command reads from its options' text itself: one number, or a comma list of
them (``--k1 1,2``), by the rule of every number the toolkit reads
(:func:`~delaytrack._validation.decimal_number`), refused with a :class:`UsageError` that
names the flag."""

from __future__ import annotations

import numpy as np

from delaytrack._validation import DECIMAL_NOTATION, NumberTextError, decimal_number
from delaytrack.cli._usage import UsageError

__all__ = ["numbers", "scalar"]


def _number(flag: str, part: str, text: str, what: str) -> float:
    """One number of ``text`` by the rule of every number the toolkit reads
    (:func:`~delaytrack._validation.decimal_number`): ``1``, ``-2.5``, ``3e-2``, finite and
    not rounded to 0; ``1_000``, ``0x10`` and ``٣`` are refused.
    """
    try:
        return decimal_number(part)
    except NumberTextError as error:
        if error.notation:
            message = f"{flag} must be {what} in {DECIMAL_NOTATION}"
        elif part.strip() == text.strip():
            message = f"{flag} {error}"
        else:
            message = f"{flag} entry {part.strip()} {error}"
        raise UsageError(f"{message}; got {text!r}") from None


def numbers(flag: str, text: str) -> np.ndarray:
    """Parse ``"1"`` or ``"1,2.5,3"`` into a 1-D array of finite floats."""
    what = "a number or a comma-separated list of numbers"
    return np.array([_number(flag, part, text, what) for part in text.split(",")])


def scalar(flag: str, text: str) -> float:
    """Parse one finite float."""
    return _number(flag, text, text, "a single number" if "," in text else "a number")
