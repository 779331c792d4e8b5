"""How a command refuses its input: a :class:`UsageError` (``error: <message>``, exit code 2),
and the library's refusals said in the command's flags (:func:`flagged`)."""

from __future__ import annotations

from collections.abc import Mapping

from delaytrack._spec import SpecError
from delaytrack._validation import ArgumentError

__all__ = ["UsageError", "flagged"]


class UsageError(Exception):
    """Bad command-line input; the message is shown as ``error: <message>``."""


def flagged(
    error: Exception,
    flags: Mapping[str, str] | None = None,
    *,
    given: Mapping[str, str] | None = None,
    keys: Mapping[str, str] | None = None,
) -> UsageError:
    """The usage error for ``error``, a refusal by the library, in the command's flags.

    An :class:`~delaytrack._validation.ArgumentError` about an argument in ``flags`` (argument
    name -> flag) calls every argument it names by its flag (:meth:`ArgumentError.spelled`),
    followed by the text given to the flag when ``given`` (flag -> text) holds it and the
    message does not end with it already (``"(got --k1 1,2)"``). A
    :class:`~delaytrack._spec.SpecError` about a scenario key in
    ``keys`` (key -> flag) names the flag instead of the key. Any other error keeps its message.
    """
    flags, given, keys = flags or {}, given or {}, keys or {}
    if isinstance(error, ArgumentError) and error.argument in flags:
        flag = flags[error.argument]
        message = error.spelled(flags)
        text = given.get(flag)
        # The text given to the flag, unless the message ends with it already.
        shown = "" if text is None or message.endswith(f"got {text}") else f" (got {flag} {text})"
        return UsageError(message + shown)
    if isinstance(error, SpecError) and error.key is not None and error.key in keys:
        return UsageError(f"{keys[error.key]} {error.problem}")
    return UsageError(str(error))
