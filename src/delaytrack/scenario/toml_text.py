"""Scenario data as TOML text.

The standard library reads TOML but does not write it; scenarios only hold strings, integers,
floats, booleans, (nested) lists of those and one level of tables, which this small writer covers
with one-line arrays (readable matrices).
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping
from typing import Any

from delaytrack._spec import SpecError as ScenarioError

_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


def _toml_key(key: str) -> str:
    return key if _BARE_KEY.fullmatch(key) else json.dumps(key)


def _toml_value(value: Any, key: str) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        text = repr(value)
        return text if any(c in text for c in ".en") else f"{text}.0"
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(item, key) for item in value) + "]"
    raise ScenarioError(f"scenario key {key!r} cannot be written to TOML; got {value!r}")


def dumps_toml(data: Mapping[str, Any]) -> str:
    """Render scenario data (scalars, lists, one level of tables) as TOML text."""
    lines = [
        f"{_toml_key(key)} = {_toml_value(value, key)}"
        for key, value in data.items()
        if not isinstance(value, Mapping)
    ]
    for table, content in data.items():
        if not isinstance(content, Mapping):
            continue
        lines += ["", f"[{_toml_key(table)}]"]
        for key, value in content.items():
            if isinstance(value, Mapping):
                raise ScenarioError(f"scenario key '{table}.{key}' cannot be a nested table")
            lines.append(f"{_toml_key(key)} = {_toml_value(value, f'{table}.{key}')}")
    return "\n".join(lines) + "\n"
