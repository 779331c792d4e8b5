"""The session folder's tables as the summary, the report and the replay read them."""

from __future__ import annotations

import csv
import json
import math
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from delaytrack._io import read_file_bytes, regular_file

__all__ = [
    "ROLE_FILES",
    "check_tables_whole",
    "index_cell",
    "json_table",
    "ms",
    "node_record",
    "number",
    "read_rows",
    "required_rows",
    "table_bytes",
]


#: The files each node writes into its folder: a session that starts removes those of its role
#: that an earlier session left there, so that no table of that session is taken for its own.
ROLE_FILES = {
    "controller": ("controller.json", "controller.mcap", "ticks.csv"),
    "delay": ("delay.json", "delay.mcap", "releases.csv", "release_events.csv"),
    "robot": ("robot.json", "robot.mcap", "steps.csv", "states.csv", "applied.csv"),
}


def table_bytes(folder: Path, role: str) -> dict[str, int]:
    """The size in bytes of each table the ``role`` node wrote into ``folder``: what its
    record keeps, so that a table cut short (copied from another machine before it was whole)
    is refused (:func:`check_tables_whole`)."""
    return {
        name: (folder / name).stat().st_size
        for name in ROLE_FILES[role]
        if name.endswith(".csv") and (folder / name).is_file()
    }


def check_tables_whole(folder: Path, nodes: Mapping[str, Any]) -> None:
    """Refuse a table of ``folder`` whose size differs from the one its node recorded
    (``table_bytes`` in the node's record of ``nodes``, role -> record or None; a node of an
    earlier version recorded none), naming it and both sizes."""
    for role, names in ROLE_FILES.items():
        written = (nodes.get(role) or {}).get("table_bytes")
        if not isinstance(written, dict):
            continue
        for name in names:
            path = folder / name
            expected = written.get(name)
            if isinstance(expected, int) and path.is_file() and not _same_size(path, expected):
                raise ValueError(
                    f"{path} holds {path.stat().st_size} bytes where the {role} node wrote "
                    f"{expected}: it is not the table the node wrote (cut short or changed, or "
                    "the folder's records are of another session); copy it again from the "
                    "node's folder, or run delaytrack live collect"
                )


def _same_size(path: Path, expected: int) -> bool:
    """Whether the table ``path`` has the ``expected`` size as its node wrote it, its line
    breaks ``\\r\\n`` (CSV's), or with them turned into ``\\n`` by a copy."""
    size = path.stat().st_size
    if size == expected:
        return True
    return size < expected and size + path.read_bytes().count(b"\n") == expected


def read_rows(path: Path, columns: tuple[str, ...] = ()) -> list[dict[str, str]]:
    """The rows of a CSV table of the session folder (none when the file is missing); a file
    that is not a regular file (:func:`~delaytrack._io.regular_file`; its size is the session's,
    which the session's length bounds), not UTF-8 text or without one of ``columns`` is a
    ValueError naming it."""
    if not path.exists():
        return []
    regular_file(path, "session table", largest=None)
    try:
        with open(path, newline="", encoding="utf-8") as handle:
            reader = csv.DictReader(handle)
            rows = list(reader)
    except (UnicodeDecodeError, csv.Error) as error:
        raise ValueError(f"session table {str(path)!r} is not a CSV table ({error})") from None
    except OSError as error:  # a link to a file of /proc that refuses to be read as text
        raise ValueError(f"session table {str(path)!r} cannot be read: {error.strerror}") from None
    missing = [column for column in columns if column not in (reader.fieldnames or ())]
    if missing:
        raise ValueError(
            f"{path}: no column {missing[0]!r} (it has {list(reader.fieldnames or ())}); a "
            "session folder written by delaytrack live run (or a node) holds the table whole"
        )
    return rows


def index_cell(row: dict[str, str], column: str, path: Path) -> int:
    """The integer index in ``column`` of a session table's ``row``, or a ValueError naming
    the table."""
    text = row.get(column) or ""
    if not re.fullmatch(r"[0-9]+", text.strip()):  # ASCII digits, as every number read
        raise ValueError(f"{path}: column {column!r} holds {text[:20]!r}, not an index")
    return int(text)


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


def required_rows(path: Path, columns: tuple[str, ...]) -> list[dict[str, str]]:
    """:func:`read_rows` of a table the replay needs: at least one row, and ``columns``."""
    rows = read_rows(path, columns)
    if not rows:
        raise ValueError(
            f"{path.parent}: {path.name} is missing or has no rows; a session folder written by "
            "delaytrack live run (or live collect) holds it"
        )
    return rows


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
