"""Names that moved: a module's ``__getattr__`` that still finds them, with a warning.

A module whose public names moved elsewhere sets ``__getattr__ = moved_names(__name__, {...})``;
reading an old name warns (:class:`DeprecationWarning`, naming the new place) and returns the
object from where it lives now. The new place is imported only when an old name is read.
"""

from __future__ import annotations

import importlib
import warnings
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["moved_names", "moved_object"]


def moved_names(module: str, moved: Mapping[str, str]) -> Callable[[str], Any]:
    """A module ``__getattr__`` for ``moved``: old name -> ``"new.module:attribute"``.

    Parameters
    ----------
    module : str
        The old module's name (``__name__``), for the messages.
    moved : mapping of str to str
        Each old name and where it lives now.

    Returns
    -------
    callable
        ``__getattr__(name)``: the moved object after a :class:`DeprecationWarning`, or
        :class:`AttributeError` for a name that never lived here.
    """

    def __getattr__(name: str) -> Any:
        if name not in moved:
            raise AttributeError(f"module {module!r} has no attribute {name!r}")
        return moved_object(f"{module}.{name}", moved[name])

    return __getattr__


def moved_object(old: str, new: str) -> Any:
    """The object at ``new`` (``"new.module:attribute"``), imported now, after a
    :class:`DeprecationWarning` that ``old`` (its dotted old name) moved there, pointed at the
    old name's reader (the caller of the function calling this one: a module's
    ``__getattr__``, a deprecated property)."""
    where, _, attribute = new.partition(":")
    warnings.warn(
        f"{old} moved to {where}.{attribute}; import it from there "
        f"(the old name will be removed in a later release)",
        DeprecationWarning,
        stacklevel=3,
    )
    return getattr(importlib.import_module(where), attribute)
