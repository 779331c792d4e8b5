"""The files of a scenario or sweep file: the TOML file itself, and the files its tables name
(trace and waypoint CSV files, the ``.py`` file of a factory), taken relative to it."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from delaytrack._io import (
    MAX_TOML_BYTES,
    UnusableValue,
    read_file_bytes,
    refuse_unusable_values,
    toml_data,
)
from delaytrack._spec import PYTHON_TYPE, factory_parts
from delaytrack._spec import SpecError as ScenarioError
from delaytrack._trust import Trust, check_factory


def read_toml_file(source: Path, what: str, error: type[ScenarioError]) -> dict[str, Any]:
    """The TOML data of the file ``source`` (a regular file of bounded size, a byte-order mark
    allowed), or ``error`` naming ``what`` (``"scenario file"``) and the file."""
    try:
        raw = read_file_bytes(source, what, error, largest=MAX_TOML_BYTES)
        text = raw.decode("utf-8-sig")  # a byte-order mark is not TOML
    except FileNotFoundError:
        raise error(f"{what} {str(source)!r} does not exist") from None
    except (OSError, UnicodeDecodeError) as problem:
        raise error(f"cannot read {what} {str(source)!r}: {problem}") from None
    try:
        data = toml_data(text)
    except tomllib.TOMLDecodeError as problem:
        raise error(f"{source}: not valid TOML: {problem}") from None
    try:
        refuse_unusable_values(data)
    except UnusableValue as problem:
        raise error(f"{source}: {problem}") from None
    return data


def resolve_file_keys(source: Path, table: str, value: object, trust: Trust) -> None:
    """Make the files a table names (``path``, and the file of a ``"python:<file.py>:..."``
    type) absolute, relative to the file ``source`` that holds it, in place; refuse a factory
    that is neither beside ``source`` (or below) nor trusted (:mod:`delaytrack._trust`), before
    anything is imported."""
    if not isinstance(value, dict):
        return
    kind = value.get("type")
    if isinstance(kind, str) and kind.startswith(PYTHON_TYPE):
        location, name = factory_parts(f"{table}.type", kind)
        if location.endswith(".py"):
            location = _absolute(source, f"{table}.type", location)
            value["type"] = f"{PYTHON_TYPE}{location}:{name}"
        check_factory(f"{table}.type", kind, location, source, trust)
    if isinstance(value.get("path"), str):
        value["path"] = _absolute(source, f"{table}.path", value["path"])


def _absolute(source: Path, key: str, text: str) -> str:
    try:
        path = Path(text).expanduser()
        return str(path if path.is_absolute() else (source.parent / path).resolve())
    except (OSError, RuntimeError, ValueError) as error:  # "~user" of no one, a loop, a NUL
        raise ScenarioError(f"scenario key {key!r} = {text!r}: {error}") from None
