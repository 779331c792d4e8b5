"""The base class of the toolkit's own warnings, and how its commands print them: one line."""

from __future__ import annotations

import contextlib
import sys
import warnings
from collections.abc import Iterator

__all__ = ["DelaytrackWarning", "warnings_in_one_line"]


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
            print(f"warning: {message}".replace("\n", "\\n"), file=sys.stderr)
        else:
            shown(message, category, filename, lineno, file, line)

    with warnings.catch_warnings():
        warnings.showwarning = show
        yield
