"""The session folder's tables as the summary, the report and the replay read them."""

from __future__ import annotations

import array
import csv
import hashlib
import json
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from delaytrack._io import open_csv_text, read_file_bytes, regular_file
from delaytrack._result_columns import input_column, state_columns
from delaytrack.live.transport import differing_parts
from delaytrack.units import coordinate_units, with_unit

__all__ = [
    "ROLE_FILES",
    "RowsByIndex",
    "SessionColumns",
    "SessionTable",
    "check_nodes_ran",
    "check_one_session",
    "check_tables_whole",
    "content_digest",
    "json_table",
    "ms",
    "node_record",
    "number",
    "read_table",
    "session_columns",
    "table_bytes",
    "table_digests",
    "values_at",
]


#: The files each node writes into its folder: a session that starts removes those of its role
#: that an earlier session left there, so that no table of that session is taken for its own.
ROLE_FILES = {
    "controller": ("controller.json", "controller.mcap", "ticks.csv"),
    "delay": ("delay.json", "delay.mcap", "releases.csv", "release_events.csv"),
    "robot": ("robot.json", "robot.mcap", "steps.csv", "states.csv", "applied.csv"),
}


@dataclass(frozen=True)
class SessionColumns:
    """The columns of a session's tables that hold the plant's coordinates and inputs, each
    named with its unit as the simulator's tables are (:mod:`delaytrack.units`): ``x_m``,
    ``x_dot_m_per_s`` and ``u1_Nm`` for the P3-DX; ``q1``, ``q1_dot`` and ``u1`` for a plant that
    declares no units (:func:`session_columns`)."""

    #: The coordinates' names (``q1 .. qn`` when the plant gives none).
    names: tuple[str, ...]
    coordinate_units: tuple[str | None, ...]
    input_units: tuple[str | None, ...]

    @property
    def states(self) -> list[str]:
        """``states.csv``'s positions, then velocities."""
        return state_columns(self.names, self.coordinate_units)

    @property
    def positions(self) -> list[str]:
        """``states.csv``'s positions."""
        return self.states[: len(self.names)]

    def inputs(self, role: str = "") -> list[str]:
        """The inputs' columns: ``u1_Nm`` (``ticks.csv``, ``steps.csv``), with a ``role``
        ``u1_live_Nm`` (``replay.csv``)."""
        return [input_column(j, unit, role) for j, unit in enumerate(self.input_units)]

    def in_table(self, table: SessionTable, kind: str) -> list[str]:
        """The columns ``kind`` (``"states"``, ``"positions"`` or ``"inputs"``) as ``table``
        names them: with their units, or without where the table has the plain name only (a
        session recorded by a delaytrack before its tables named units: ``q1``, ``q1_dot``,
        ``u1``)."""
        plain = SessionColumns(
            self.names, (None,) * len(self.names), (None,) * len(self.input_units)
        )
        named, old_names = (
            (self.inputs(), plain.inputs())
            if kind == "inputs"
            else (getattr(self, kind), getattr(plain, kind))
        )
        return [
            given if given in table.columns or old not in table.columns else old
            for given, old in zip(named, old_names, strict=True)
        ]

    def errors(self, role: str) -> list[str]:
        """The tracking errors' columns of ``replay.csv``: ``e1_x_live_m``."""
        return [
            with_unit(f"e1_{name}_{role}", unit)
            for name, unit in zip(self.names, self.coordinate_units, strict=True)
        ]


def session_columns(plant: Any) -> SessionColumns:
    """The :class:`SessionColumns` of ``plant`` (its ``coordinate_names``,
    ``coordinate_units`` and ``input_units``)."""
    units = coordinate_units(plant)
    return SessionColumns(
        tuple(units), tuple(units.values()), tuple(plant.input_units or (None,) * plant.m)
    )


def _written(folder: Path, role: str) -> list[str]:
    """The tables and the log the ``role`` node wrote into ``folder`` (its record aside)."""
    return [
        name
        for name in ROLE_FILES[role]
        if name.endswith((".csv", ".mcap")) and (folder / name).is_file()
    ]


def table_bytes(folder: Path, role: str) -> dict[str, int]:
    """The size in bytes of each table and log the ``role`` node wrote into ``folder``: what its
    record keeps, so that a table cut short (copied from another machine before it was whole)
    is refused (:func:`check_tables_whole`)."""
    return {name: (folder / name).stat().st_size for name in _written(folder, role)}


def table_digests(folder: Path, role: str) -> dict[str, str]:
    """The SHA-256 of each table and log the ``role`` node wrote into ``folder``
    (:func:`content_digest`): what its record keeps, so that a table changed after the session
    without changing its size (a number replaced by text of its length) is refused too."""
    return {name: content_digest(folder / name) for name in _written(folder, role)}


def content_digest(path: Path) -> str:
    """SHA-256 of the file ``path``, a CSV table's without its carriage returns (a copy may
    turn its ``\\r\\n`` line breaks into ``\\n``; no cell of a node's table holds one), read a
    MiB at a time."""
    digest = hashlib.sha256()
    text = path.suffix == ".csv"
    with path.open("rb") as handle:
        for chunk in iter(lambda: handle.read(2**20), b""):
            digest.update(chunk.replace(b"\r", b"") if text else chunk)
    return digest.hexdigest()


def check_nodes_ran(
    folder: Path, nodes: Mapping[str, Any], hashes: dict[str, str], given: str, remedy: str
) -> None:
    """Refuse a scenario (``given``, of ``hashes``) other than the one the nodes of the session
    in ``folder`` ran (the :func:`~delaytrack.live.transport.scenario_hashes` each node
    recorded in its record of ``nodes``), naming the parts that differ and ``remedy``."""
    for role, record in nodes.items():
        recorded = (record or {}).get("scenario_hashes")
        if not isinstance(recorded, dict):
            continue  # a node of an earlier version recorded none
        parts = differing_parts(hashes, recorded)
        if parts is not None:
            raise ValueError(
                f"{folder}: the {role} node ran another scenario than {given} (they differ in "
                f"{parts}); {remedy}"
            )


def check_one_session(folder: Path, nodes: Mapping[str, Any]) -> None:
    """Refuse node records of ``folder`` (``nodes``, role -> record or None) that are of
    different sessions: each records its session's name and start on the robot's clock, the
    same in every node of one session (a node of an earlier version recorded none)."""
    sessions: dict[str, dict[str, Any]] = {}
    for role, record in nodes.items():
        session = (record or {}).get("session")
        if isinstance(session, dict):
            sessions[role] = session
    if len({json.dumps(session, sort_keys=True) for session in sessions.values()}) > 1:
        shown = "; ".join(
            f"{role}: {session.get('name')!r} started at {session.get('t0_robot_clock')}"
            for role, session in sessions.items()
        )
        raise ValueError(
            f"{folder}: the node records are of different sessions ({shown} s on the robot's "
            "clock); put the files of one session's three nodes into one folder"
        )


def check_tables_whole(folder: Path, nodes: Mapping[str, Any]) -> None:
    """Refuse a table or log of ``folder`` whose size or content differs from the one its node
    recorded (``table_bytes`` and ``table_sha256`` in the node's record of ``nodes``, role ->
    record or None; a node of an earlier version recorded none or only the sizes), naming it."""
    again = "copy it again from the node's folder, with the node's record beside it"
    for role, names in ROLE_FILES.items():
        record = nodes.get(role) or {}
        written, digests = record.get("table_bytes"), record.get("table_sha256")
        if not isinstance(written, dict):
            continue
        for name in names:
            path = folder / name
            expected = written.get(name)
            if not (isinstance(expected, int) and path.is_file()):
                continue
            whole = (
                _same_size(path, expected)
                if name.endswith(".csv")
                else (path.stat().st_size == expected)
            )
            if not whole:
                raise ValueError(
                    f"{path} holds {path.stat().st_size} bytes where the {role} node wrote "
                    f"{expected}: it is not the table the node wrote (cut short or changed, or "
                    f"the folder's records are of another session); {again}"
                )
            digest = digests.get(name) if isinstance(digests, dict) else None
            if isinstance(digest, str) and content_digest(path) != digest:
                raise ValueError(
                    f"{path} holds other contents than the {role} node wrote (of the same size: "
                    f"changed after the session, or the folder's records are of another "
                    f"session); {again}"
                )


def _same_size(path: Path, expected: int) -> bool:
    """Whether the table ``path`` has the ``expected`` size as its node wrote it, its line
    breaks ``\\r\\n`` (CSV's), or with them turned into ``\\n`` by a copy."""
    size = path.stat().st_size
    if size == expected:
        return True
    if size >= expected:
        return False
    with path.open("rb") as handle:  # counted a MiB at a time
        breaks = sum(chunk.count(b"\n") for chunk in iter(lambda: handle.read(2**20), b""))
    return size + breaks == expected


class SessionTable:
    """A CSV table of the session folder read column by column (:func:`read_table`).

    ``rows`` rows under ``header``; ``table[name]`` the array of a column read: ``float64`` for
    numbers (NaN for an empty or unreadable cell, :func:`number`), ``int64`` for indices,
    ``object`` for text. Eight bytes a cell read, whatever the file holds: a table takes about
    the memory of its text, where rows of Python objects took some thirty times more.
    """

    def __init__(
        self, path: Path, header: list[str], rows: int, columns: dict[str, np.ndarray]
    ) -> None:
        self.path, self.header, self.rows, self.columns = path, header, rows, columns

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    def at(self, names: Sequence[str], rows: Any = None) -> np.ndarray:
        """The number columns ``names`` side by side at ``rows`` (:meth:`RowsByIndex.find`; all
        rows by default), NaN where a row is -1, ``(len(rows), len(names))``; a column the
        table lacks is a ValueError naming it, unless there is no table (no header): then
        nothing is known, NaN."""
        rows = np.arange(self.rows) if rows is None else np.asarray(rows)
        picked = []
        for name in names:
            if name in self.columns:
                picked.append(values_at(self.columns[name], rows))
            elif not self.header:  # a node that did not finish wrote no table
                picked.append(np.full(rows.shape, np.nan))
            else:
                raise _no_column(self.path, name, self.header)
        return np.stack(picked, axis=-1) if picked else np.empty((rows.size, 0))

    def required(self) -> SessionTable:
        """This table, or a ValueError naming it when it has no rows (or is missing)."""
        if not self.rows:
            raise ValueError(
                f"{self.path.parent}: {self.path.name} is missing or has no rows; a session "
                "whose nodes all finished holds it (a node stopped early writes no tables: its "
                "log, <role>.mcap, reads up to where it stopped)"
            )
        return self


def _no_column(path: Path, name: str, header: list[str]) -> ValueError:
    """The error of a table without the column ``name``."""
    return ValueError(
        f"{path}: no column {name!r} (it has {header}); a session folder written by delaytrack "
        "live run (or a node) holds the table whole"
    )


#: The array type of each kind of column read (a text column is kept as a list of texts).
_TYPES = {"number": "d", "index": "q"}

#: An index cell: ASCII digits, as every number read, blanks around; at most 18 of them (an
#: int64).
_INDEX = re.compile(r"\s*[0-9]{1,18}\s*")


def read_table(
    path: Path,
    numbers: Sequence[str] | None = (),
    *,
    indices: Sequence[str] = (),
    texts: Sequence[str] = (),
) -> SessionTable:
    """A CSV table of the session folder (:class:`SessionTable`; no rows when it is missing).

    Parameters
    ----------
    path : Path
        The table. A file that is not a regular file (:func:`~delaytrack._io.regular_file`),
        gives more bytes than its size (a file of ``/proc``), is not UTF-8 CSV text, has a line
        longer than :data:`~delaytrack._io.MAX_LINE_BYTES` or lacks a column asked for is a
        ValueError naming it. Its size is the session's, which the session's length bounds.
    numbers : sequence of str or None
        Columns read as numbers (:func:`number`); None: every column that is not an index or a
        text, in the table's order.
    indices : sequence of str
        Columns of indices: a cell that is not one is a ValueError naming the table, the line
        and the column.
    texts : sequence of str
        Columns kept as text.
    """
    if not path.exists():
        kinds = _kinds(numbers or (), indices, texts)
        return SessionTable(path, [], 0, {name: _column([], kind) for name, kind in kinds.items()})
    regular_file(path, "session table", largest=None)
    too_large = f"session table {str(path)!r} gives more bytes than its size: it is no table"
    try:
        with open_csv_text(path, path.stat().st_size, too_large) as handle:
            reader = csv.reader(handle)
            header: list[str] = next(reader, [])
            # Each name's last column, the names in the order they first come: as the rows of
            # csv.DictReader, which the readers took before, had them.
            positions = {name: position for position, name in enumerate(header)}
            kinds = _columns_of(path, list(positions), numbers, indices, texts)
            read: dict[str, Any] = {
                name: array.array(_TYPES[kind]) if kind in _TYPES else []
                for name, kind in kinds.items()
            }
            width, rows, held = len(header), 0, 0
            distinct: dict[str, str] = {}
            chunk: list[list[str]] = []  # rows converted a chunk at a time, column by column
            lines: list[int] = []
            for row in reader:
                if not row:  # a blank line, which csv.DictReader skipped too
                    continue
                if len(row) < width:  # cells missing at the end: empty
                    row += [""] * (width - len(row))
                chunk.append(row)
                lines.append(reader.line_num)
                held += len(row)
                if held >= _CHUNK_CELLS:
                    _convert(path, positions, kinds, chunk, lines, read, distinct)
                    rows, held = rows + len(chunk), 0
                    chunk, lines = [], []
            _convert(path, positions, kinds, chunk, lines, read, distinct)
            rows += len(chunk)
    except (UnicodeDecodeError, csv.Error) as error:
        raise ValueError(f"session table {str(path)!r} is not a CSV table ({error})") from None
    except OSError as error:  # a link to a file of /proc that refuses to be read as text
        raise ValueError(f"session table {str(path)!r} cannot be read: {error.strerror}") from None
    columns = {name: _column(read[name], kind) for name, kind in kinds.items()}
    return SessionTable(path, list(positions), rows, columns)


#: Cells held before a chunk of rows is converted (about a MiB of texts, however wide the rows).
_CHUNK_CELLS = 2**14


def _convert(
    path: Path,
    positions: dict[str, int],
    kinds: dict[str, str],
    chunk: list[list[str]],
    lines: list[int],
    read: dict[str, Any],
    distinct: dict[str, str],
) -> None:
    """Append the cells of the rows ``chunk`` (starting on ``lines``; a column's cells at its
    position in ``positions``) to the columns ``read``:
    numbers as :func:`number` reads them, indices checked, texts as their first object in
    ``distinct`` (one object for each distinct text)."""
    for name, kind in kinds.items():
        position = positions[name]
        cells = [row[position] for row in chunk]
        if kind == "number":
            try:  # the same conversion as float() a cell, at once
                read[name].frombytes(np.array(cells, dtype=np.float64).tobytes())
            except ValueError:  # an empty or unreadable cell among them: NaN
                read[name].extend(number(cell) for cell in cells)
        elif kind == "index":
            if not all(map(_INDEX.fullmatch, cells)):
                line, cell = next(
                    (line, cell)
                    for line, cell in zip(lines, cells, strict=True)
                    if not _INDEX.fullmatch(cell)
                )
                raise ValueError(
                    f"{path}, line {line}: column {name!r} holds {cell[:20]!r}, not an index (a "
                    "whole number of at most 18 digits)"
                )
            read[name].extend(map(int, cells))
        else:
            read[name].extend(distinct.setdefault(cell, cell) for cell in cells)


def _kinds(numbers: Sequence[str], indices: Sequence[str], texts: Sequence[str]) -> dict[str, str]:
    """Each column asked for, with its kind."""
    return {
        **dict.fromkeys(indices, "index"),
        **dict.fromkeys(numbers, "number"),
        **dict.fromkeys(texts, "text"),
    }


def _columns_of(
    path: Path,
    header: list[str],
    numbers: Sequence[str] | None,
    indices: Sequence[str],
    texts: Sequence[str],
) -> dict[str, str]:
    """The columns of ``header`` to read, with their kinds; a column asked for that the table
    lacks is a ValueError naming it."""
    if numbers is None:
        numbers = [name for name in header if name not in (*indices, *texts)]
    kinds = _kinds(numbers, indices, texts)
    present = set(header)
    for name in kinds:
        if name not in present:
            raise _no_column(path, name, header)
    return kinds


def _column(values: Any, kind: str) -> np.ndarray:
    """A column read, as an array of its kind's type."""
    if kind == "text":
        column = np.empty(len(values), dtype=object)
        column[:] = values
        return column
    dtype = np.float64 if kind == "number" else np.int64
    # the array's own memory, not a copy (nothing appends to it any more)
    return np.frombuffer(values, dtype=dtype) if len(values) else np.empty(0, dtype)


class RowsByIndex:
    """The row of each index of a table's index column: its last row (where rows read into a
    mapping by index kept the last), or its first (``first=True``).

    Parameters
    ----------
    indices : ndarray of int
        The table's index column.
    first : bool
        Keep each index's first row instead of its last.
    """

    def __init__(self, indices: np.ndarray, first: bool = False) -> None:
        order = np.argsort(indices, kind="stable")  # the rows of one index in their order
        ordered = indices[order]
        new = ordered[1:] != ordered[:-1]
        keep = np.r_[True, new] if first else np.r_[new, True]
        keep = keep[: ordered.size]
        #: The distinct indices, ascending, and the row kept for each.
        self.indices, self.rows = ordered[keep], order[keep]

    def find(self, wanted: Any) -> np.ndarray:
        """The row of each index in ``wanted``; -1 where the table has none."""
        wanted = np.asarray(wanted, dtype=np.int64)
        if not self.indices.size:
            return np.full(wanted.shape, -1)
        at = np.minimum(np.searchsorted(self.indices, wanted), self.indices.size - 1)
        return np.where(self.indices[at] == wanted, self.rows[at], -1)


def values_at(column: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """The numbers of ``column`` at ``rows`` (:meth:`RowsByIndex.find`); NaN where a row is -1."""
    values = np.full(rows.shape, np.nan)
    found = rows >= 0
    values[found] = column[rows[found]]
    return values


def json_table(path: Path, what: str) -> dict[str, Any]:
    """The JSON table in the session file ``path`` (a node's record, the summary), or a
    ValueError naming it as ``what`` (FileNotFoundError when it is missing)."""
    try:
        table = json.loads(read_file_bytes(path, what).decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ValueError(f"{path} is not a {what} (not JSON: {error})") from None
    except RecursionError:
        raise ValueError(f"{path} is not a {what}: its values nest too deep") from None
    if not isinstance(table, dict):
        raise ValueError(f"{path} is not a {what}: it holds no JSON table")
    return table


def node_record(path: Path) -> dict[str, Any] | None:
    """A node's record (``<role>.json``, :func:`json_table`), None when the file is missing."""
    return json_table(path, "node's record") if path.exists() else None


def number(text: str | None) -> float:
    """A cell as a number; NaN for an empty or unreadable one."""
    try:
        return float(text) if text not in (None, "") else math.nan
    except ValueError:
        return math.nan


def ms(value: Any) -> str:
    """A duration in ms for the summary and the report, or n/a."""
    return "n/a" if value is None or not math.isfinite(value) else f"{value:.3f} ms"


def per_second(value: Any) -> str:
    """A rate (per second, unit not written) for the summary and the report, or n/a where it
    was not measured (``null`` in a session's JSON)."""
    return "n/a" if value is None or not math.isfinite(value) else f"{value:.0f}"
