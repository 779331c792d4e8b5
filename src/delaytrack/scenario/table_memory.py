"""Tables met again: within a :func:`remembered_tables` block, a scenario table already checked or
built is neither checked nor built again (a sweep's runs share a few distinct tables)."""

from __future__ import annotations

import json
from collections import OrderedDict
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from contextvars import ContextVar
from types import MappingProxyType
from typing import Any, TypeVar

_T = TypeVar("_T")

#: Most checked tables and built components a :func:`remembered_tables` block keeps, the least
#: recently used dropped first: a sweep's runs share a few distinct values per key, and a table
#: drawn anew for every run is not met again. A check is remembered as a name; a component may
#: hold a model file's arrays, so fewer of them are kept.
_REMEMBERED_TABLES = MappingProxyType({"checked": 4096, "built": 256})
_REMEMBERED: ContextVar[dict[str, OrderedDict[tuple[str, ...], Any]] | None] = ContextVar(
    "_REMEMBERED", default=None
)
#: The text that identifies tables: JSON with sorted keys (a float's exact digits; 1, 1.0 and
#: true apart).
_identity_text = json.JSONEncoder(sort_keys=True, separators=(",", ":")).encode


def table_identity(form: object) -> str | None:
    """How :func:`remembered_tables` tells a table apart: its content as JSON text with sorted
    keys, None when it is not JSON data (a date: never taken for another table)."""
    try:
        return _identity_text(dict(form) if isinstance(form, Mapping) else form)
    except (TypeError, ValueError):
        return None


@contextmanager
def remembered_tables() -> Iterator[None]:
    """Within the block, a scenario table met again is neither checked nor built again.

    Tables are the same when their name and content are (compared as JSON text with sorted
    keys); a ``[delay]`` is compared with the defaults it takes from the scenario written in, a
    ``[controller]`` with its ``[model]``. The rest of every scenario is checked every time. A
    table whose type is a factory of yours is checked once but its factory is called for every
    scenario (it may depend on more than its arguments). A file a table names is read when the
    table is first built: the block is for one load (a sweep's expansion), not for a session.
    """
    token = _REMEMBERED.set({kind: OrderedDict() for kind in _REMEMBERED_TABLES})
    try:
        yield
    finally:
        _REMEMBERED.reset(token)


def remembered(
    make: Callable[[], _T],
    kind: str,
    identities: Callable[[], Mapping[str, str | None]],
    *tables: str,
) -> _T:
    """``make()``, or what it returned earlier in the :func:`remembered_tables` block for the
    same ``tables`` (names and contents) of a scenario, among the ``kind`` ("checked", "built")
    it keeps; a refusal is never remembered.

    ``identities()`` gives the :func:`table_identity` of each of the scenario's tables; it is
    called only within a block.
    """
    memories = _REMEMBERED.get()
    if memories is None:
        return make()
    identity = identities()
    contents = [identity[table] for table in tables]
    if None in contents:
        return make()
    key = (*tables, *(str(content) for content in contents))
    memory = memories[kind]
    if key in memory:
        memory.move_to_end(key)
        return memory[key]
    value = memory[key] = make()
    if len(memory) > _REMEMBERED_TABLES[kind]:
        memory.popitem(last=False)
    return value
