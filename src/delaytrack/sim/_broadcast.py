"""Small helpers that spread what ``simulate`` is given over its batch."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, TypeVar

import numpy as np

from delaytrack._validation import real_array

__all__ = ["as_batch", "broadcast", "positive_limits", "stack_padded"]

_T = TypeVar("_T")


def as_batch(name: str, value: _T | Sequence[_T], kind: type) -> list[_T]:
    """``value`` as a list (a list or tuple of items, or one item), each an instance of
    ``kind``; refusals name the argument ``name``."""
    items: list[Any] = list(value) if isinstance(value, list | tuple) else [value]  # checked below
    if not items:
        raise ValueError(f"{name} must not be empty")
    for i, item in enumerate(items):
        if not isinstance(item, kind):
            raise TypeError(
                f"{name}[{i}] must be an instance of {kind.__name__}; got {type(item).__name__}"
            )
    return items


def broadcast(name: str, items: list[_T], batch: int) -> list[_T]:
    """``items`` spread to ``batch`` entries: one for all, or one each."""
    if len(items) == batch:
        return items
    if len(items) == 1:
        return items * batch
    raise ValueError(
        f"{name} has {len(items)} entries but the batch has {batch}; give "
        + ("one" if batch == 1 else f"1 (for every run) or {batch}")
    )


def positive_limits(key: str, value: object, shape: tuple[int, ...], entries: str) -> np.ndarray:
    """``value`` broadcast to ``shape`` (a leading row of one spreads to every run), each entry
    ``> 0`` (``inf``: none); refusals name ``key`` and what ``entries`` it takes."""
    if (type(value) is float and value > 0) or (type(value) is int and 0 < value <= 2**53):
        return np.full(shape, float(value))  # one for all, the default
    try:
        array = real_array(key, value)
        if array.ndim == 2 and array.shape[0] == 1 and len(shape) == 2:
            array = array[0]
        # C order whatever was broadcast: another layout would be another engine to compile
        array = np.array(np.broadcast_to(array, shape), order="C")
    except (TypeError, ValueError):
        raise ValueError(
            f"{key} must be a number > 0 or {entries}; inf for none; got {value!r}"
        ) from None
    if np.any(np.isnan(array)) or np.any(array <= 0.0):
        raise ValueError(f"{key} must be > 0 (inf for none) in every entry; got {value!r}")
    return array


def stack_padded(vectors: list[np.ndarray]) -> np.ndarray:
    """The ``vectors`` as the rows of one array, padded with zeros to the longest (at least
    one column)."""
    width = max(1, max(vector.size for vector in vectors))
    out = np.zeros((len(vectors), width))
    for i, vector in enumerate(vectors):
        out[i, : vector.size] = vector
    return out
