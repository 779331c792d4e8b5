"""Reading and writing files.

Reading: every file the toolkit reads (a delay trace or waypoint CSV, a scenario or sweep file, a
model file, a factory's ``.py`` file) is first checked to be a regular file of bounded size
(:func:`regular_file`): a FIFO would wait for a writer forever and a device such as
``/dev/zero`` never ends. CSV data files are read row by row with their line numbers
(:func:`csv_rows`), their numbers by the command line's rule (:func:`csv_number`), and errors
about them name the file, line and column without quoting the file's text.

Writing is atomic: a reader sees the old file or the complete new one, never a half-written one.
Each writer writes to a temporary file in the destination's folder (same file system) and then
renames it over the destination with :func:`os.replace`, which is atomic on POSIX and Windows.
The temporary file keeps the destination's suffix so that libraries inferring a format from the
file name (matplotlib, pandas) still do so; it is removed if the write fails.
"""

from __future__ import annotations

import contextlib
import csv
import os
import re
import stat
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from delaytrack._validation import NumberTextError, decimal_number

if TYPE_CHECKING:
    import pandas as pd

__all__ = [
    "MAX_READ_BYTES",
    "atomic_path",
    "column_label",
    "csv_number",
    "csv_rows",
    "regular_file",
    "shown_header",
    "write_bytes",
    "write_frame",
    "write_text",
]

#: Largest file the toolkit reads (256 MiB): a trace sampled at 1 kHz for an hour is about 70 MB.
MAX_READ_BYTES = 256 * 2**20

#: What a path that is not a regular file is, by its ``st_mode``.
_NOT_REGULAR = (
    (stat.S_ISDIR, "a folder"),
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


def regular_file(
    path: str | os.PathLike[str], name: str, error: type[Exception] = ValueError
) -> Path:
    """``path``, checked to be a regular file of at most :data:`MAX_READ_BYTES` after following
    symlinks, before anything opens it.

    Parameters
    ----------
    path : str or PathLike
        The file to read.
    name : str
        What the caller calls it, to start the message: ``"path ="``, ``"scenario file"``.
    error : type
        The error raised when the path is not a readable regular file of bounded size.

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
    if status.st_size > MAX_READ_BYTES:
        raise error(
            f"{name} {str(given)!r} holds {status.st_size / 2**20:.0f} MiB; the toolkit reads "
            f"files of at most {MAX_READ_BYTES // 2**20} MiB"
        )
    return given


def csv_rows(path: Path) -> Iterator[tuple[int, list[str]]]:
    """The rows of the CSV file ``path`` (UTF-8, a leading byte-order mark skipped), each with
    the line it starts on; rows of blanks only are left out.

    ``path`` is checked with :func:`regular_file` first. Text that is not readable as CSV
    raises ValueError naming the file and the line, not quoting it.
    """
    checked = regular_file(path, "path =")
    line = 1
    try:
        with checked.open(newline="", encoding="utf-8-sig") as handle:
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


#: A header cell shown in messages: a short name, not a line of some other file.
_NAME = re.compile(r"[\w .()\[\]/%-]{1,40}")


def _name_like(cell: str) -> bool:
    return _NAME.fullmatch(cell.strip()) is not None


def shown_header(header: list[str]) -> str:
    """``" ['t', 'h']"`` to follow the words "the header" in a message, or ``""`` when the
    header row's cells are not short names (a row of a file that is not a table of numbers)."""
    if len(header) > 20 or not all(_name_like(cell) for cell in header):
        return ""
    return f" {[cell.strip() for cell in header]}"


def column_label(column: int, header: str | None) -> str:
    """``"column 'h'"`` for a message: the column's name in the header row when that is a
    short name, else its number from 1 (``"column 2"``)."""
    if header is None or not _name_like(header):
        return f"column {column}"
    return f"column {header.strip()!r}"


def csv_number(path: Path, line: int, column: int, cell: str, header: str | None) -> float:
    """The number in ``cell`` at ``line`` and ``column`` (from 1) of the CSV file ``path``, by
    the rule of the command line (:func:`~delaytrack._validation.decimal_number`).

    ``header`` is the column's name in the header row (:func:`column_label`).

    Raises
    ------
    ValueError
        Naming the file, the line, the column and what is wrong, not quoting the cell.
    """
    try:
        return decimal_number(cell)
    except NumberTextError as error:
        raise ValueError(f"{path}: line {line}, {column_label(column, header)} {error}") from None


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
