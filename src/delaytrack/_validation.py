"""Checks on user input that raise errors a control engineer can act on.

Every function names the argument, shows the offending value and says what would be valid.
None of them clamps, rounds or repairs a value.
"""

from __future__ import annotations

import math
import re
import reprlib
from collections.abc import Callable, Mapping, Sequence
from typing import TypeGuard

import numpy as np

__all__ = [
    "ArgumentError",
    "BEYOND_CHOICES",
    "DECIMAL_NOTATION",
    "MAX_PHASE",
    "NumberTextError",
    "beyond_choice",
    "decimal_number",
    "integer_multiple",
    "is_integer_at_least",
    "is_real_number",
    "as_spd_matrix",
    "as_square_matrix",
    "check_phase",
    "format_values",
    "positive_scalar",
    "finite_array",
    "finite_scalar",
    "quoted",
    "real_array",
]

_SYMMETRY_RTOL = 1e-10

#: What a time-limited input (a measured trace, a seeded random walk, a payload schedule) does
#: after the time its data covers: ``"refuse"`` a run that lasts longer, or ``"hold"`` its last
#: state, as the user chose.
BEYOND_CHOICES = ("refuse", "hold")


_QUOTED = reprlib.Repr()
_QUOTED.maxlevel = 4
_QUOTED.maxlist = _QUOTED.maxtuple = _QUOTED.maxdict = _QUOTED.maxset = 16
_QUOTED.maxstring = _QUOTED.maxother = _QUOTED.maxlong = 240


def quoted(value: object) -> str:
    """``repr(value)`` for a message, shortened (``...``) beyond 16 items of a list, tuple,
    table or set, four levels of nesting, or 240 characters of a string or other value: a value
    given by mistake (a list of millions of numbers) must not make a message of hundreds of
    megabytes."""
    return _QUOTED.repr(value)


class ArgumentError(ValueError):
    """A value refused for one argument: ``argument`` names it, ``problem`` says what is wrong
    with the value and what would be valid; the message is ``f"{argument} {problem}"``.

    Where ``problem`` names other arguments of the same call (``mentions``), it writes each as
    ``$name``, so that a caller that knows the arguments by other names (the command line's
    flags: ``--gain-bound`` for ``gain_bound``) can say the same thing in its own names
    (:meth:`spelled`) while the wording stays here. Symbols of the paper (``K1``, ``Q``,
    ``beta``) are plain words, and so is any other text.

    Examples
    --------
    >>> error = ArgumentError(
    ...     "min_bandwidth", "= 2 rad/s needs K1 >= 4, above $gain_bound = 1", ("gain_bound",)
    ... )
    >>> str(error)
    'min_bandwidth = 2 rad/s needs K1 >= 4, above gain_bound = 1'
    >>> error.spelled({"min_bandwidth": "--min-bandwidth", "gain_bound": "--gain-bound"})
    '--min-bandwidth = 2 rad/s needs K1 >= 4, above --gain-bound = 1'
    """

    def __init__(self, argument: str, problem: str, mentions: Sequence[str] = ()) -> None:
        self.argument = argument
        self.problem = problem
        self.mentions = tuple(mentions)
        super().__init__(self.spelled({}))

    def __reduce__(self) -> tuple[type, tuple[str, str, tuple[str, ...]]]:
        # Rebuilt from its parts (an error raised in a worker process crosses back pickled).
        return type(self), (self.argument, self.problem, self.mentions)

    def spelled(self, names: Mapping[str, str]) -> str:
        """The message with each argument called by its name in ``names`` (by its own name when
        ``names`` lacks it)."""
        problem = self.problem
        if self.mentions:
            fields = re.compile(r"\$(" + "|".join(map(re.escape, self.mentions)) + r")\b")
            problem = fields.sub(lambda field: names.get(field[1], field[1]), problem)
        return f"{names.get(self.argument, self.argument)} {problem}"


def beyond_choice(value: object) -> str:
    """Check a ``beyond`` argument (one of :data:`BEYOND_CHOICES`)."""
    if value not in BEYOND_CHOICES:
        raise ValueError(
            f"beyond must be one of {list(BEYOND_CHOICES)} (what happens after the time the "
            f"data covers); got {quoted(value)}"
        )
    return str(value)


def coordinate_labels(label: str, value: object, n: int) -> tuple[str, ...]:
    """``n`` different names (letters, digits and ``_``) for ``coordinate_names``, ``n``
    different non-empty names for ``input_names`` (they label figures only), or ``n``
    non-empty unit strings for ``coordinate_units`` or ``input_units``, as a tuple; else a
    ValueError naming ``label``."""
    names = tuple(value) if isinstance(value, list | tuple) else None
    fits: Callable[[str], bool]
    if label == "coordinate_names":
        fits, distinct = str.isidentifier, True
        what = f"n = {n} different names (letters, digits and '_')"
    elif label == "input_names":
        fits, distinct = _not_blank, True
        what = f"{n} different non-empty names, one per input"
    else:
        fits, distinct = _not_blank, False
        one = "input" if label.startswith("input") else "coordinate"
        what = f"{n} unit strings, one per {one} (such as 'm', 'rad' or 'N')"
    valid = (
        names is not None
        and len(names) == n
        and (not distinct or len(set(names)) == n)
        and all(isinstance(name, str) and fits(name) for name in names)
    )
    if names is None or not valid:
        raise ValueError(f"{label} must be a list of {what}; got {quoted(value)}")
    return names


def _not_blank(text: str) -> bool:
    return bool(text.strip())


def is_real_number(value: object) -> TypeGuard[int | float]:
    """Whether ``value`` is a Python ``int`` or ``float``, not a ``bool``: a number as a TOML or
    JSON file holds one (finite or not)."""
    return isinstance(value, int | float) and not isinstance(value, bool)


def is_integer_at_least(value: object, least: int) -> TypeGuard[int | np.integer]:
    """Whether ``value`` is an integer (Python or NumPy, not a bool) ``>= least``.

    The test of every count, seed and size argument; each caller words its own message.
    """
    return (
        not isinstance(value, bool) and isinstance(value, int | np.integer) and bool(value >= least)
    )


def format_values(values: np.ndarray | Sequence[float], digits: int = 6) -> str:
    """Render a short list of numbers for an error message."""
    flat = np.asarray(values, dtype=float).ravel()
    shown = ", ".join(f"{v:.{digits}g}" for v in flat[:8])
    return f"[{shown}{', ...' if flat.size > 8 else ''}]"


def integer_multiple(value: float, unit: float, *, scale: float = 0.0) -> int | None:
    """``value / unit`` when it is a positive integer up to rounding, else None.

    The tolerance is ``1e-9`` relative to the ratio plus the rounding of numbers of size
    ``scale`` (for a duration ``t1 - t0`` computed from large times, ``scale = max |t|``).
    """
    ratio = value / unit
    if not math.isfinite(ratio):
        return None
    count = round(ratio)
    tolerance = 1e-9 * max(1.0, abs(ratio)) + 4.0 * np.finfo(float).eps * scale / unit
    if count < 1 or abs(ratio - count) > tolerance:
        return None
    return int(count)


def positive_scalar(name: str, value: object, *, strictly: bool = True) -> float:
    """Return ``value`` as a finite float that is > 0 (or >= 0 when ``strictly`` is False).

    Strings, bytes and booleans are refused (``"2"`` or ``True`` for a gain is a mistake, not a
    number).
    """
    if isinstance(value, str | bytes | bool | np.bool_):
        raise TypeError(f"{name} must be a real number; got {quoted(value)}")
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a real number; got {quoted(value)}") from None
    except OverflowError:  # an integer beyond the largest float
        raise ArgumentError(name, f"must be finite; got {quoted(value)}") from None
    if not math.isfinite(number):
        raise ArgumentError(name, f"must be finite; got {number}")
    if strictly and number <= 0.0:
        raise ArgumentError(name, f"must be > 0; got {number:g}")
    if not strictly and number < 0.0:
        raise ArgumentError(name, f"must be >= 0; got {number:g}")
    return number


#: NumPy dtype kinds that are not real numbers, though NumPy converts them to floats.
_NOT_REAL = frozenset("bcSUVMm")


def real_array(name: str, value: object, *, ndim: int | None = None) -> np.ndarray:
    """Return ``value`` as a float64 array (a new one), of ``ndim`` dimensions when given."""
    try:
        given = np.asarray(value)
        # Strings, bytes, booleans, complex numbers and dates would convert to floats, and a
        # None among numbers to NaN.
        if given.dtype.kind in _NOT_REAL or (
            given.dtype.kind == "O" and any(item is None for item in given.flat)
        ):
            raise TypeError
        array = np.array(given, dtype=float)
    except OverflowError:  # an integer beyond the largest float
        raise ArgumentError(name, f"must be finite; got {quoted(value)}") from None
    except (TypeError, ValueError, RecursionError):
        raise TypeError(f"{name} must be an array of real numbers; got {quoted(value)}") from None
    if ndim is not None and array.ndim != ndim:
        raise ArgumentError(name, f"must be {ndim}-dimensional; got shape {array.shape}")
    return array


def finite_array(name: str, value: object, *, ndim: int | None = None) -> np.ndarray:
    """Return ``value`` as a float64 array with only finite entries."""
    array = real_array(name, value, ndim=ndim)
    if not np.all(np.isfinite(array)):
        bad = tuple(int(i) for i in np.argwhere(~np.isfinite(array))[0])
        where = f"{name}[{', '.join(map(str, bad))}]" if bad else name
        raise ArgumentError(name, f"must be finite; {where} is {array[bad]}")
    return array


#: Largest phase of a sine (rad): beyond it, the phase's double-precision spacing (about 1e-10
#: rad at 1e6) starts to swallow what ``frequency t`` adds in a step; at 1e16 the sine is a
#: constant.
MAX_PHASE = 1e6


def check_phase(name: str, phase: float | np.ndarray) -> None:
    """Refuse a sine's ``phase`` (rad, a number or an array) beyond :data:`MAX_PHASE` in
    magnitude: ``sin(frequency t + phase)`` would lose ``frequency t`` to rounding."""
    largest = float(np.max(np.abs(np.asarray(phase, dtype=float)), initial=0.0))
    if largest > MAX_PHASE:
        raise ArgumentError(
            name,
            f"must be at most {MAX_PHASE:g} rad in magnitude (a larger phase swallows "
            f"frequency t in rounding, and the sine stops varying); got {largest:g}: give it "
            "modulo 2π",
        )


#: How a number is written in text the toolkit reads: command-line arguments and CSV data files.
DECIMAL_NOTATION = "decimal notation such as 2, 0.5 or 1e-3"

# ASCII digits only, no "_" between them, no hexadecimal: Python's float() reads "1_000", "٣"
# and "１" too, where another tool (or a typo) meant something else. inf and nan are read so
# that they are refused as not finite rather than as not numbers.
_DECIMAL = re.compile(
    r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?|[+-]?(?:inf|infinity|nan)", re.I
)

#: Blanks around a number that are not part of it (a CSV cell "0, 0.05", an argument " 2").
_BLANKS = " \t\n\r\f\v"


class NumberTextError(ValueError):
    """Text that :func:`decimal_number` refuses.

    The message is a predicate on the text without quoting it (``"must be finite (...)"``), to
    follow the place it came from (``"--r "``, ``"line 3, column 2 "``); ``notation`` is True
    when the text is not written in :data:`DECIMAL_NOTATION` at all.
    """

    def __init__(self, message: str, *, notation: bool) -> None:
        super().__init__(message)
        self.notation = notation


def _notation_hint(text: str) -> str:
    """What makes ``text`` not decimal notation, when it is a common form of another one."""
    if not text:
        return "; it is empty"
    if "_" in text:
        return "; '_' is not read as a digit separator (write 1000, not 1_000)"
    if "," in text:
        return "; ',' is not a decimal point (write 1.5, not 1,5)"
    if any(character.isdigit() and not character.isascii() for character in text):
        return "; only the digits 0-9 are read"
    if re.match(r"[+-]?0[xob]", text, re.I):
        return "; hexadecimal, octal and binary are not read"
    return ""


def decimal_number(text: str) -> float:
    """The finite float that ``text`` writes in :data:`DECIMAL_NOTATION`: the one rule for
    numbers on the command line and in CSV data files (delay traces, waypoints).

    Accepted: an optional sign, ASCII digits with an optional point, an optional exponent
    (``2``, ``+1``, ``-0.5``, ``.5``, ``5.``, ``1e-3``), with blanks around. Refused: digit
    separators (``1_000``, ``0_05``), a decimal comma (``1,5``), hexadecimal (``0x10``), digits
    of other scripts (``٣``, ``１``), empty text, ``nan``, ``inf``, numbers beyond double
    precision (``1e400``) and nonzero numbers that round to 0 (``1e-400``).

    Raises
    ------
    NumberTextError
        Saying what is wrong and what is valid, without quoting ``text`` (the caller names
        where it came from).
    """
    number = text.strip(_BLANKS)
    if not _DECIMAL.fullmatch(number):
        raise NumberTextError(
            f"must be a number in {DECIMAL_NOTATION}{_notation_hint(number)}", notation=True
        )
    value = float(number)
    if not math.isfinite(value):
        raise NumberTextError("must be finite (doubles reach about 1.8e308)", notation=False)
    if value == 0.0 and any(digit in number.lower().partition("e")[0] for digit in "123456789"):
        raise NumberTextError(
            "is too close to 0 for double precision: it rounds to 0 (nonzero doubles have a "
            "magnitude of at least about 4.9e-324)",
            notation=False,
        )
    return value


def finite_scalar(name: str, value: object) -> float:
    """Return ``value`` as a finite float; strings, bytes and booleans are refused.

    A Python ``float`` or a small ``int`` is taken as it is, without a NumPy array (a
    ``simulate`` call checks several such numbers, and a short run is worth microseconds).
    """
    if type(value) is float and math.isfinite(value):
        return value
    if type(value) is int and abs(value) <= 2**53:
        return float(value)
    if isinstance(value, str | bytes | bool | np.bool_):
        raise TypeError(f"{name} must be a real number; got {quoted(value)}")
    return float(finite_array(name, value, ndim=0))


def as_square_matrix(name: str, value: object, n: int | None = None) -> np.ndarray:
    """Return ``value`` as an ``(n, n)`` float64 matrix.

    A scalar means ``value * I`` and a 1-D sequence means ``diag(value)``; both need ``n`` for a
    scalar. With ``n`` given, the dimension must match.
    """
    array = finite_array(name, value)
    if array.ndim == 1 and n is not None and array.size != n:
        raise ArgumentError(name, f"given as a diagonal must have {n} entries; got {array.size}")
    if array.ndim == 0:
        if n is None:
            raise ArgumentError(
                name, f"is a scalar; its dimension n must be given to build {name}*I"
            )
        matrix = float(array) * np.eye(n)
    elif array.ndim == 1:
        matrix = np.diag(array)
    elif array.ndim == 2:
        matrix = array
    else:
        raise ArgumentError(
            name, f"must be a scalar, a diagonal or a square matrix; got shape {array.shape}"
        )
    if matrix.shape[0] != matrix.shape[1]:
        raise ArgumentError(name, f"must be square; got shape {matrix.shape}")
    if n is not None and matrix.shape[0] != n:
        raise ArgumentError(name, f"must be {n}x{n}; got shape {matrix.shape}")
    if matrix.shape[0] == 0:
        raise ArgumentError(name, f"must have at least one row; got shape {matrix.shape}")
    return matrix


def as_spd_matrix(name: str, value: object, n: int | None = None) -> np.ndarray:
    """Return ``value`` as a symmetric positive definite ``(n, n)`` matrix, or raise.

    Accepts the same forms as :func:`as_square_matrix`. Symmetry is checked to a relative
    tolerance of 1e-10; the returned matrix is exactly symmetrised.
    """
    matrix = as_square_matrix(name, value, n)
    scale = max(1.0, float(np.max(np.abs(matrix))))
    asymmetry = float(np.max(np.abs(matrix - matrix.T)))
    if asymmetry > _SYMMETRY_RTOL * scale:
        raise ArgumentError(
            name,
            f"must be symmetric positive definite; it is not symmetric "
            f"(max |{name} - {name}^T| = {asymmetry:.3g})",
        )
    matrix = 0.5 * (matrix + matrix.T)
    eigenvalues = np.linalg.eigvalsh(matrix)
    if eigenvalues[0] <= 0.0:
        raise ArgumentError(
            name,
            "must be symmetric positive definite; "
            f"its eigenvalues are {format_values(eigenvalues)}",
        )
    return matrix
