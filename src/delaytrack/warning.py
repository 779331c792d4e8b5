"""The base class of the toolkit's own warnings, and how its commands print them and their
errors: one line, with no character that a terminal would act on."""

from __future__ import annotations

import contextlib
import sys
import warnings
from collections.abc import Iterator

__all__ = ["DelaytrackWarning", "one_line", "warnings_in_one_line"]

#: Control characters (C0, DEL and C1) as escapes: a file or folder name may hold any of them,
#: and a terminal acts on them (a line break, a carriage return over the start of the line, the
#: escape of a colour or a cursor move) instead of showing them.
_ESCAPES = {
    code: {"\n": "\\n", "\r": "\\r", "\t": "\\t"}.get(chr(code), f"\\x{code:02x}")
    for code in (*range(0x20), *range(0x7F, 0xA0))
}


def one_line(text: str) -> str:
    """``text`` on one line as a terminal shows it: its control characters written as escapes
    (``\\n``, ``\\r``, ``\\x1b``)."""
    return text.translate(_ESCAPES)


class DelaytrackWarning(UserWarning):
    """A warning of this toolkit (a run beyond its certified bound, a plant run as plain Python,
    a figure left out, a MuJoCo model's joint names not used): filter them all by this class."""


@contextlib.contextmanager
def warnings_in_one_line() -> Iterator[None]:
    """Within it, the toolkit's own warnings (:class:`DelaytrackWarning`: a figure left out, a
    plant run as plain Python) print as one line ``warning: ...``, like the command's errors;
    other warnings as Python prints them. Which are shown, Python's filters say (``-W``)."""
    shown = warnings.showwarning

    def show(message, category, filename, lineno, file=None, line=None):  # noqa: ANN001
        if issubclass(category, DelaytrackWarning):
            print(one_line(f"warning: {message}"), file=sys.stderr)
        else:
            shown(message, category, filename, lineno, file, line)

    with warnings.catch_warnings():
        warnings.showwarning = show
        yield
