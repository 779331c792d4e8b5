"""Reading and writing files.

Reading: every file the toolkit reads (a delay trace or waypoint CSV, a scenario or sweep file, a
model file, a factory's ``.py`` file) is first checked to be a regular file of bounded size
(:func:`regular_file`): a FIFO would wait for a writer forever and a device such as
``/dev/zero`` never ends. CSV data files are read row by row with their line numbers
(:func:`csv_rows`); their first row is a header of distinct names unless it starts like a number
(:func:`csv_table`); their numbers are read by the command line's rule (:func:`csv_number`); a
column whose name names another time unit than the one it is read in is refused
(:func:`check_column_unit`). Errors about them name the file, line and column without quoting
the file's text, a header's names included. TOML files (scenarios, sweeps, gains) are parsed by
:func:`toml_data`, which bounds how deeply their values nest.

Writing is atomic: a reader sees the old file or the complete new one, never a half-written one.
Each writer writes to a temporary file in the destination's folder (same file system) and then
renames it over the destination with :func:`os.replace`, which is atomic on POSIX and Windows.
The temporary file keeps the destination's suffix so that libraries inferring a format from the
file name (matplotlib, pandas) still do so; it is removed if the write fails.
"""

from __future__ import annotations

import contextlib
import csv
import errno
import io
import itertools
import json
import math
import os
import re
import stat
import sys
import tempfile
import tomllib
import unicodedata
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from delaytrack._validation import NumberTextError, decimal_number

if TYPE_CHECKING:
    import pandas as pd

__all__ = [
    "MAX_LINE_BYTES",
    "MAX_READ_BYTES",
    "MAX_TOML_BYTES",
    "TIME_UNITS",
    "TIME_UNIT_NAMES",
    "UnusableValue",
    "atomic_path",
    "check_column_unit",
    "column_count",
    "column_label",
    "column_name",
    "csv_number",
    "csv_rows",
    "csv_table",
    "finite_numbers",
    "json_text",
    "named_time_units",
    "open_csv_text",
    "read_file_bytes",
    "refuse_unusable_values",
    "regular_file",
    "toml_data",
    "write_bytes",
    "write_frame",
    "write_text",
]

#: Largest file the toolkit reads (256 MiB): a trace sampled at 1 kHz for an hour is about 70 MB.
MAX_READ_BYTES = 256 * 2**20

#: Largest TOML file the toolkit reads (8 MiB): Python's parser takes about half a second a
#: MiB, and a scenario or sweep file of the largest batch of initial states is a few MiB.
MAX_TOML_BYTES = 8 * 2**20

#: Deepest nesting of arrays and tables in a TOML file the toolkit reads (a scenario's deepest
#: value, a matrix in a table of a table, is four levels down).
MAX_TOML_DEPTH = 32


#: A part of a dotted key, bare or quoted (basic or literal), matched without backtracking.
_KEY_PART = r"""(?:[A-Za-z0-9_-]++|(?>"(?:[^"\\\n]|\\.)*+")|(?>'[^'\n]*+'))"""
#: A key of more than :data:`MAX_TOML_DEPTH` dotted parts (``a.b."c"``) where a key may start:
#: a line's start, or after ``[`` (a table's name), ``{`` or ``,`` (an inline table's keys). Its
#: table would be nested deeper than the toolkit reads, and Python's parser takes time and
#: memory growing with the square of the parts (a 200 KB line of ``a.a.a...`` took 24 GB).
_LONG_DOTTED_KEY = re.compile(
    rf"(?:^|[\[{{,])[ \t]*+{_KEY_PART}(?:[ \t]*+\.[ \t]*+{_KEY_PART}){{{MAX_TOML_DEPTH},}}",
    re.MULTILINE,
)


def toml_data(text: str) -> dict:
    """``tomllib.loads(text)``, refusing values nested more than :data:`MAX_TOML_DEPTH` levels
    deep with a :class:`tomllib.TOMLDecodeError` (Python's parser, which recurses, would end
    in a ``RecursionError`` for a file of a few hundred ``[``), and a dotted key or table name
    of more parts than that before parsing (:data:`_LONG_DOTTED_KEY`)."""
    too_deep = f"values nested more than {MAX_TOML_DEPTH} levels deep (arrays or tables)"
    long_key = _LONG_DOTTED_KEY.search(text)
    if long_key is not None:
        line = text.count("\n", 0, long_key.start()) + 1
        raise tomllib.TOMLDecodeError(
            f"a dotted key of more than {MAX_TOML_DEPTH} parts (line {line}): {too_deep}"
        )
    try:
        data = tomllib.loads(text)
    except RecursionError:
        raise tomllib.TOMLDecodeError(too_deep) from None
    level: list[dict | list] = [data]
    for _ in range(MAX_TOML_DEPTH):
        level = [
            item
            for value in level
            for item in (value.values() if isinstance(value, dict) else value)
            if isinstance(item, dict | list)
        ]
        if not level:
            return data
    raise tomllib.TOMLDecodeError(too_deep)


class UnusableValue(ValueError):
    """A TOML value no scenario or sweep may hold: an integer beyond the largest float, or text
    holding a NUL character."""


def refuse_unusable_values(data: dict | list, where: str = "") -> None:
    """Raise :class:`UnusableValue`, naming where (``x0[0]``), for an integer of ``data``
    beyond the largest float (TOML's integers have no bound, and every number of a scenario or
    sweep is used as a float or is far smaller: Python's conversion would raise
    ``OverflowError``) or a text holding a NUL character (valid TOML, but no name, path or
    choice holds one, and the operating system refuses it in a path). ``data`` is read by
    :func:`toml_data`, so nested at most :data:`MAX_TOML_DEPTH` deep: the walk recurses that
    deep at most."""
    entries = data.items() if isinstance(data, dict) else enumerate(data)
    for key, item in entries:
        if isinstance(data, list):
            place = f"{where}[{key}]"
        else:
            place = f"{where}.{key}" if where else str(key)
        if isinstance(key, str) and "\0" in key:
            raise UnusableValue(f"the key {key!r} holds a NUL character (\\0)")
        if isinstance(item, dict | list):
            refuse_unusable_values(item, place)
        elif type(item) is int and abs(item) > sys.float_info.max:  # compared exactly
            raise UnusableValue(
                f"{place}: an integer of {len(str(abs(item)))} digits, beyond the largest "
                f"number a float holds ({sys.float_info.max:.4g})"
            )
        elif isinstance(item, str) and "\0" in item:
            raise UnusableValue(
                f"{place} = {item!r}: a text holding a NUL character (\\0), which no name or "
                "path may hold"
            )


#: What a path that is not a regular file is, by its ``st_mode``.
_NOT_REGULAR = (
    (stat.S_ISDIR, "a folder"),
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


def regular_file(
    path: str | os.PathLike[str],
    name: str,
    error: type[Exception] = ValueError,
    *,
    largest: int | None = MAX_READ_BYTES,
) -> Path:
    """``path``, checked to be a regular file of at most ``largest`` bytes after following
    symlinks, before anything opens it.

    Parameters
    ----------
    path : str or PathLike
        The file to read.
    name : str
        What the caller calls it, to start the message: ``"path ="``, ``"scenario file"``.
    error : type
        The error raised when the path is not a readable regular file of bounded size.
    largest : int or None
        Its largest size in bytes, :data:`MAX_READ_BYTES` by default; None for the toolkit's
        own files whose size another limit bounds (a live session's tables, by the session's
        length).

    Raises
    ------
    FileNotFoundError
        When nothing is at ``path`` (or a symlink leads nowhere).
    error
        When it is a folder, a FIFO, a device or a socket, is too large, or cannot be examined;
        one line naming ``name``, the path and what is valid.
    """
    given = Path(path)
    try:
        status = given.stat()
    except FileNotFoundError:
        raise FileNotFoundError(f"{name} {str(given)!r} does not exist") from None
    except OSError as problem:
        raise error(f"{name} {str(given)!r} cannot be read: {problem.strerror}") from None
    target = os.path.realpath(given)
    link = f" ({target!r})" if target != os.path.abspath(given) else ""
    for test, kind in _NOT_REGULAR:
        if test(status.st_mode):
            raise error(
                f"{name} {str(given)!r} is not a file but {kind}{link}; it must be a regular file"
            )
    if largest is not None and status.st_size > largest:
        raise error(
            f"{name} {str(given)!r} holds {status.st_size / 2**20:.0f} MiB; the toolkit reads "
            f"files of at most {largest // 2**20} MiB"
        )
    return given


def read_file_bytes(
    path: str | os.PathLike[str],
    name: str,
    error: type[Exception] = ValueError,
    *,
    largest: int = MAX_READ_BYTES,
) -> bytes:
    """The bytes of the file ``path``, checked with :func:`regular_file` and read up to
    ``largest`` bytes: a file that gives more (a file of ``/proc`` or ``/sys`` says it holds
    nothing, then gives without end) raises ``error`` naming ``name`` and the path."""
    checked = regular_file(path, name, error, largest=largest)
    try:
        with checked.open("rb") as handle:
            data = handle.read(largest + 1)
    except OSError as problem:
        raise error(f"{name} {str(path)!r} cannot be read: {problem.strerror}") from None
    if len(data) > largest:
        raise error(_too_large(name, path, largest))
    return data


def _too_large(name: str, path: str | os.PathLike[str], largest: int) -> str:
    return (
        f"{name} {str(path)!r} gives more than {largest // 2**20} MiB when read; the toolkit "
        f"reads files of at most {largest // 2**20} MiB"
    )


#: Longest line of a CSV file the toolkit reads (1 MiB): a row of a trace is a few dozen bytes,
#: one of a waypoint table of many joints a few kilobytes.
MAX_LINE_BYTES = 2**20


class _BoundedReader(io.RawIOBase):
    """The raw bytes of ``handle``, ending in a ValueError (``too_large``) once more than
    ``largest`` bytes in all, or a line of more than :data:`MAX_LINE_BYTES`, have been read: a
    text reader asks for more and more of a file without line breaks."""

    def __init__(self, handle: Any, path: Path, largest: int, too_large: str) -> None:
        self._handle, self._path, self._largest = handle, path, largest
        self._too_large = too_large
        self._total = self._line = 0

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: Any) -> int:
        count = self._handle.readinto(buffer)
        if not count:
            return count
        data = memoryview(buffer)[:count].tobytes()
        self._total += count
        last = max(data.rfind(b"\n"), data.rfind(b"\r"))  # a line ends in either
        self._line = self._line + count if last < 0 else count - last - 1
        if self._total > self._largest:
            raise ValueError(self._too_large)
        if self._line > MAX_LINE_BYTES:
            raise ValueError(
                f"{str(self._path)!r}: a line longer than {MAX_LINE_BYTES // 2**20} MiB; give a "
                "CSV text file"
            )
        return count


@contextlib.contextmanager
def open_csv_text(path: Path, largest: int, too_large: str) -> Iterator[io.TextIOWrapper]:
    """The file ``path`` opened as CSV text (UTF-8, a leading byte-order mark skipped, lines
    left to the CSV reader), reading which raises ValueError: ``too_large`` after more than
    ``largest`` bytes, naming the file after a line longer than :data:`MAX_LINE_BYTES`."""
    with (
        path.open("rb", buffering=0) as raw,
        io.TextIOWrapper(
            io.BufferedReader(_BoundedReader(raw, path, largest, too_large), 2**16),
            encoding="utf-8-sig",
            newline="",
        ) as handle,
    ):
        yield handle


def csv_rows(path: Path) -> Iterator[tuple[int, list[str]]]:
    """The rows of the CSV file ``path`` (UTF-8, a leading byte-order mark skipped), each with
    the line it starts on; rows of blanks only are left out.

    ``path`` is checked with :func:`regular_file` first. Text that is not readable as CSV
    raises ValueError naming the file and the line, not quoting it.
    """
    checked = regular_file(path, "path =")
    line = 1
    try:
        with open_csv_text(
            checked, MAX_READ_BYTES, _too_large("path =", path, MAX_READ_BYTES)
        ) as handle:
            reader = csv.reader(handle)
            for row in reader:
                if any(cell.strip() for cell in row):
                    yield line, row
                line = reader.line_num + 1
    except UnicodeDecodeError as problem:  # decoded ahead of the rows: no line to name
        raise ValueError(
            f"{path}: not UTF-8 text ({problem.reason}); give a CSV text file"
        ) from None
    except csv.Error as problem:
        raise ValueError(
            f"{path}: line {line} is not CSV ({problem}); give a CSV text file"
        ) from None
    except OSError as problem:  # PermissionError, EIO, ...
        raise ValueError(f"path = {str(path)!r} cannot be read: {problem.strerror}") from None


#: The start of a cell that is meant as a number (read by the number rule, refused when it is not
#: one), unlike a column's name: a digit of any script, a sign, a point, inf or nan.
_NUMBER_START = re.compile(r"\s*(?:[+-]|\.?\d|inf|nan)", re.IGNORECASE)


def column_name(text: str) -> str:
    """A column's name as compared: Unicode NFKC form (``ｔ`` is ``t``), blanks around removed."""
    return unicodedata.normalize("NFKC", text).strip()


def csv_table(path: Path, needs: str) -> tuple[list[str] | None, Iterator[tuple[int, list[str]]]]:
    """The header row of the CSV file ``path`` and its rows of data, each with its line.

    The first row is the header unless its first cell starts like a number (a sign, a digit, a
    point, ``inf`` or ``nan``): then the file has no header (None) and that row is data. The
    header's names are given by :func:`column_name`; two columns of the same name are refused,
    naming their positions (a name read from the file is not quoted). ``needs`` ends the message
    about a file without rows (``"a trace needs two columns t, h"``).
    """
    rows = csv_rows(path)
    first = next(rows, None)
    if first is None:
        raise ValueError(f"{path}: the file holds no rows; {needs}")
    if _NUMBER_START.match(first[1][0]):
        return None, itertools.chain([first], rows)
    header = [column_name(cell) for cell in first[1]]
    for name in dict.fromkeys(header):
        positions = [str(k + 1) for k, other in enumerate(header) if other == name]
        if len(positions) > 1:
            listed = f"{', '.join(positions[:-1])} and {positions[-1]}"
            same = "have no name" if not name else "have the same name"
            raise ValueError(
                f"{path}: columns {listed} of the header row (line {first[0]}) {same}; each "
                "column needs a name of its own"
            )
    return header, rows


def column_count(count: int) -> str:
    """``"1 column"``, ``"3 columns"``."""
    return "1 column" if count == 1 else f"{count} columns"


def column_label(column: int, name: str | None) -> str:
    """``"column 'h'"`` for a message: the column's name when it is not the file's text (a name
    the user gave, or the documented ``t`` and ``h`` of a trace), else its number from 1
    (``"column 2"``)."""
    return f"column {column}" if name is None else f"column {name!r}"


#: Units a data file's times and delays may be given in, with their size in seconds.
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}

#: Time units by symbol, spelled out for messages; minutes and hours are recognised in column
#: names but not read.
TIME_UNIT_NAMES = {
    "s": "seconds",
    "ms": "milliseconds",
    "us": "microseconds",
    "ns": "nanoseconds",
    "min": "minutes",
    "hr": "hours",
}

#: The words of a column's name that name a time unit, by the unit's symbol. A lone ``h`` is the
#: delay's own symbol, not hours.
_UNIT_WORDS = {
    word: symbol
    for symbol, words in {
        "s": ("s", "sec", "secs", "second", "seconds"),
        "ms": ("ms", "msec", "msecs", "millis", "millisecond", "milliseconds"),
        "us": ("us", "\u03bcs", "usec", "usecs", "micros", "microsecond", "microseconds"),
        "ns": ("ns", "nsec", "nsecs", "nanos", "nanosecond", "nanoseconds"),
        "min": ("min", "mins", "minute", "minutes"),
        "hr": ("hr", "hrs", "hour", "hours"),
    }.items()
    for word in words
}

#: Unit words that may mean something else (``h_min``: a minimum, or minutes?).
_UNCERTAIN_WORDS = frozenset({"min", "mins"})

#: What separates the words of a column's name: ``delay_ms_mean``, ``h [ms]``, ``t (s)``,
#: ``rtt/ms``, ``stamp-us``.
_WORD_BREAK = re.compile(r"[\s_()\[\]{}/.,;:-]+")


def named_time_units(name: str) -> list[tuple[str, bool]]:
    """The time units the words of the column name ``name`` name, in order, without repeats:
    each as its symbol and whether the word is certain (``ms``) or may mean something else
    (``min``, a minimum).

    Examples
    --------
    >>> named_time_units("delay_ms_mean"), named_time_units("h (s)"), named_time_units("h_min")
    ([('ms', True)], [('s', True)], [('min', False)])
    """
    words = _WORD_BREAK.split(column_name(name).casefold())
    named = [
        (_UNIT_WORDS[word], word not in _UNCERTAIN_WORDS) for word in words if word in _UNIT_WORDS
    ]
    return list(dict.fromkeys(named))


def check_column_unit(
    path: Path, label: str, name: str, option: str | None, given: str | None
) -> None:
    """Refuse a column whose name names another time unit than the one it is read in.

    ``label`` says which column, without the file's text (``"the name of column 2 (the
    delay)"``, ``"delay_column = 'lag_ms'"``); ``option`` is the key that sets the column's unit
    (``"delay_unit"``), None when the column is read in seconds only; ``given`` is its value
    when the user gave one. With no unit given, a name that names another unit than seconds, or
    may name one (``min``), is refused, asking for the unit; a unit the user gave stands unless
    the name names another unit for certain.

    Raises
    ------
    ValueError
        One line naming the file, the column, the unit its name names and what to give.
    """
    named = named_time_units(name)
    certain = {unit for unit, sure in named if sure}
    units = [repr(unit) for unit in TIME_UNITS]
    readable = f"{', '.join(units[:-1])} or {units[-1]}"
    if given is not None:
        if not certain or given in certain:
            return
        unit = next(unit for unit, sure in named if sure)
        raise ValueError(
            f"{path}: {label} names a unit ({unit}: {TIME_UNIT_NAMES[unit]}), but {option} = "
            f"{given!r}; make them agree (correct the option or the column's name)"
        )
    others = [(unit, sure) for unit, sure in named if unit != "s"]
    if not others:
        return
    unit, sure = others[0]
    said = f"{'names' if sure else 'may name'} a unit ({unit}: {TIME_UNIT_NAMES[unit]})"
    if option is None:
        raise ValueError(
            f"{path}: {label} {said}, but it is read in seconds; give the values in seconds, "
            "under a name that names no other unit"
        )
    if not sure:
        raise ValueError(
            f"{path}: {label} {said}; say which unit the values are in with {option} = "
            f"{readable} (the word may also mean a minimum)"
        )
    if unit not in TIME_UNITS:
        raise ValueError(
            f"{path}: {label} {said}, which is not read; {option} is one of {readable}: convert "
            "the column"
        )
    raise ValueError(
        f"{path}: {label} {said}, but it would be read in seconds; give {option} = {unit!r} "
        "(or correct the column's name)"
    )


def csv_number(path: Path, line: int, column: int, cell: str, name: str | None) -> float:
    """The number in ``cell`` at ``line`` and ``column`` (from 1) of the CSV file ``path``, by
    the rule of the command line (:func:`~delaytrack._validation.decimal_number`).

    ``name`` is the column's name when it is not the file's text (:func:`column_label`).

    Raises
    ------
    ValueError
        Naming the file, the line, the column and what is wrong, not quoting the cell.
    """
    try:
        return decimal_number(cell)
    except NumberTextError as error:
        raise ValueError(f"{path}: line {line}, {column_label(column, name)} {error}") from None


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


_DEFAULT_MODE = 0o666 & ~_umask()


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; on success it replaces ``path`` atomically.

    The parent folder is created if needed. If the body raises, the temporary file is deleted
    and ``path`` is left as it was.

    Examples
    --------
    >>> with atomic_path("out/table.csv") as tmp:  # doctest: +SKIP
    ...     frame.to_csv(tmp)
    """
    target = Path(path)
    if target.is_dir():  # refused here, naming it, not by os.replace naming the temporary file
        raise IsADirectoryError(errno.EISDIR, "is a folder; give the path of a file", str(path))
    target.parent.mkdir(parents=True, exist_ok=True)
    handle, name = tempfile.mkstemp(
        dir=target.parent, prefix=f".{target.name}.", suffix=target.suffix
    )
    os.close(handle)
    temporary = Path(name)
    try:
        yield temporary
        # mkstemp creates the file private (0600); give it the mode a plain open() would.
        os.chmod(temporary, _DEFAULT_MODE)
        os.replace(temporary, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            temporary.unlink()
        raise


def write_bytes(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically; return the path."""
    with atomic_path(path) as temporary:
        temporary.write_bytes(data)
    return Path(path)


def write_text(path: str | os.PathLike[str], text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically; return the path."""
    return write_bytes(path, text.encode("utf-8"))


def finite_numbers(
    data: Any, replace: Callable[[float], Any], default: Callable[[Any], Any] | None = None
) -> Any:
    """``data`` (mappings, lists and tuples of numbers, strings and None) as plain dicts and
    lists, each float that is not finite replaced by ``replace(value)``; with ``default``, any
    other value replaced by ``default(value)`` (walked in turn), as :func:`json.dumps` would."""
    if isinstance(data, float):
        return data if math.isfinite(data) else replace(data)
    if isinstance(data, Mapping):
        return {key: finite_numbers(value, replace, default) for key, value in data.items()}
    if isinstance(data, list | tuple):
        return [finite_numbers(value, replace, default) for value in data]
    if default is None or data is None or isinstance(data, str | int):
        return data
    return finite_numbers(default(data), replace, default)


def json_text(data: object, **options: Any) -> str:
    """``data`` as strict JSON (RFC 8259), which every reader takes: a number that is not
    finite (NaN, ±inf: a percentile of no samples, a rate over no time) is written as ``null``,
    where :func:`json.dumps` would write ``NaN``, which browsers' and most other languages'
    readers refuse. ``options`` go to :func:`json.dumps` (``default`` is applied first)."""
    default = options.pop("default", None)
    return json.dumps(finite_numbers(data, lambda _: None, default), allow_nan=False, **options)


def write_frame(frame: pd.DataFrame, path: str | os.PathLike[str]) -> Path:
    """Write a DataFrame atomically, as Parquet or CSV according to the suffix of ``path``.

    CSV is written without the index; Parquet (pyarrow) without the index too.
    """
    target = Path(path)
    suffix = target.suffix.lower()
    with atomic_path(target) as temporary:
        if suffix == ".parquet":
            frame.to_parquet(temporary, index=False)
        elif suffix == ".csv":
            frame.to_csv(temporary, index=False)
        else:
            raise ValueError(
                f"cannot write a table to {str(target)!r}: use a .parquet or .csv name"
            )
    return target
