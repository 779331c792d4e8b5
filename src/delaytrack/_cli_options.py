"""What every command of the ``delaytrack`` command line shares, the live loop's included: the
parser with one-line errors, the types that read numbers given to options, and the ``--trust``
and ``--quiet`` options.

Numbers on the command line follow the one rule of every number the toolkit reads
(:func:`~delaytrack._validation.decimal_number`): ``1``, ``-2.5``, ``3e-2``, finite; ``1_000``,
``0x10``, ``nan`` and ``inf`` are refused. A type refuses with a message that says what is valid
and quotes the text; argparse puts the option's name in front
(``error: argument --loss: must be a probability in [0, 1) ...; got '1.5'``).
"""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

from delaytrack._validation import NumberTextError, decimal_number

__all__ = [
    "EXIT_USAGE",
    "OptionParser",
    "count",
    "decimal",
    "integer",
    "quiet_argument",
    "trust_argument",
    "within",
]

#: Exit code of a command refused for its input (argparse's own code for a usage error).
EXIT_USAGE = 2

_Number = TypeVar("_Number", int, float)


#: The namespace attribute in which the innermost command that met arguments it does not take
#: leaves its name (``delaytrack simulate``), for the error about them.
_REFUSED_BY = "_refused_by"


class OptionParser(argparse.ArgumentParser):
    """argparse with one-line errors (``error: ...``) and exit code 2, without the usage dump;
    an argument no command took points to the help of the command it was given to. A flag is
    taken only as spelled in full: argparse's default would take a shortened or mistyped one
    (``--no-robustnes``) for the flag it begins."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)
        self._given: list[str] = []  # the arguments of the last parse, for error()

    def error(self, message: str) -> None:  # type: ignore[override]
        missing = re.fullmatch(r"argument (-[^\s/:]+)(?:/\S+)?: expected one argument", message)
        given = self._given
        if missing and missing.group(1) in given[:-1]:
            # argparse takes a value that starts with "-" (-50%) for a flag of its own
            flag = missing.group(1)
            value = given[given.index(flag) + 1]
            if value.startswith("-"):
                message += f"; a value that starts with '-' is written {flag}={value}"
        self.exit(EXIT_USAGE, f"error: {message} (see {self.prog} --help)\n")

    def parse_known_args(  # type: ignore[override]
        self, args: Sequence[str] | None = None, namespace: argparse.Namespace | None = None
    ) -> tuple[argparse.Namespace, list[str]]:
        self._given = list(sys.argv[1:] if args is None else args)
        parsed, extras = super().parse_known_args(args, namespace)
        assert parsed is not None  # argparse returns the namespace it filled
        # A command's parser returns first: the innermost one that met arguments it does not
        # take names itself (a subcommand's extras reach its parent's as the parent's own).
        if extras and not hasattr(parsed, _REFUSED_BY):
            setattr(parsed, _REFUSED_BY, self.prog)
        return parsed, extras

    def parse_args(  # type: ignore[override]
        self, args: Sequence[str] | None = None, namespace: argparse.Namespace | None = None
    ) -> argparse.Namespace:
        namespace, extras = self.parse_known_args(args, namespace)
        prog = vars(namespace).pop(_REFUSED_BY, self.prog)
        if extras:
            self.exit(
                EXIT_USAGE,
                f"error: unrecognized arguments: {' '.join(extras)} (see {prog} --help)\n",
            )
        return namespace


def integer(text: str) -> int:
    """argparse type: an integer in decimal digits (``1_000`` and ``٣`` are refused)."""
    if not re.fullmatch(r"[+-]?[0-9]+", text.strip()):
        raise argparse.ArgumentTypeError(f"must be an integer in decimal digits; got {text!r}")
    return int(text)


def decimal(text: str) -> float:
    """argparse type: a number in :data:`~delaytrack._validation.DECIMAL_NOTATION`, finite."""
    try:
        return decimal_number(text)
    except NumberTextError as error:
        raise argparse.ArgumentTypeError(f"{error}; got {text!r}") from None


def within(
    parse: Callable[[str], _Number], what: str, valid: Callable[[_Number], bool]
) -> Callable[[str], _Number]:
    """argparse type: the number ``parse`` reads (:func:`decimal` or :func:`integer`), refused
    unless ``valid`` holds for it; ``what`` says which numbers are valid, for the message
    (``"seconds > 0"``)."""

    def checked(text: str) -> _Number:
        value = parse(text)
        if not valid(value):
            raise argparse.ArgumentTypeError(f"must be {what}; got {text!r}")
        return value

    return checked


#: argparse type: a count, an integer >= 1.
count = within(integer, "an integer >= 1", lambda value: value >= 1)


def trust_argument(command: argparse.ArgumentParser) -> None:
    """``--trust NAME``, repeatable: factories a scenario or sweep file may name beyond the
    ``.py`` files beside it."""
    command.add_argument(
        "--trust",
        action="append",
        default=[],
        metavar="NAME",
        help='allow the factories (type = "python:...", Python code that runs with your '
        "rights) of a module and its submodules (mylab.robots), or of a .py file or of every "
        "file below a folder (a path: ./robots, ~/lab/arm.py); repeatable. Without it only "
        ".py files in the scenario or sweep file's folder or below it run",
    )


def quiet_argument(command: argparse.ArgumentParser, shown: str = "progress bars") -> None:
    """``--quiet`` (nothing of ``shown`` on stderr), and ``--progress`` kept as an accepted
    no-op: progress is shown by default."""
    command.add_argument("--quiet", action="store_true", help=f"no {shown}")
    command.add_argument("--progress", action="store_true", help=argparse.SUPPRESS)
