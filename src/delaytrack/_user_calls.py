"""The user's Python functions as the plain-Python engine calls them: what they raise, named.

A plant given as Python callables (:class:`~delaytrack.plants.CallablePlant`), and every kernel
of the user's when the closed loop runs as plain Python, is called through :func:`named_errors`
or :func:`raised_by`: whatever it raises during a run (a ``SystemExit``, a ``RecursionError``, an
error of its own) ends the run with one line that names the function and the time, a
:class:`UserFunctionError`. A ``KeyboardInterrupt`` stays an interruption.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

__all__ = ["UserFunctionError", "named_errors", "raised_by"]


class UserFunctionError(ValueError):
    """A function of the user's raised, or returned what it must not, as a run called it."""


def raised_by(what: str, error: BaseException, t: float | None) -> UserFunctionError:
    """The one-line error for ``error``, raised by the user's ``what`` (``"your kernel
    mymodule:terms"``) when the run called it at time ``t`` (None: a call without a time)."""
    when = "during the run" if t is None else f"at t = {t:.6g} s"
    if isinstance(error, SystemExit):  # its text is only the exit code
        return UserFunctionError(
            f"{what} raised SystemExit({error.code!r}) {when}; a function the simulator calls "
            "must return (or raise an error that says what went wrong), not end the program"
        )
    text = str(error).replace("\n", " ")
    return UserFunctionError(
        f"{what} raised {type(error).__name__} {when}" + (f": {text}" if text else "")
    )


def named_errors(function: Callable[..., Any], what: str, timed: bool) -> Callable[..., Any]:
    """``function`` (the user's ``what``), whose errors become :func:`raised_by`'s at the time
    of its first argument (``timed``: kernels take ``t`` first) or "during the run"."""

    def call(*arguments: Any) -> Any:
        try:
            return function(*arguments)
        except (KeyboardInterrupt, UserFunctionError):  # an interruption, or named already
            raise
        except BaseException as error:
            raise raised_by(what, error, arguments[0] if timed else None) from error

    return call
