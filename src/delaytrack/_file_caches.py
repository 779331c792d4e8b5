"""numba's disk caches of the functions in a file named in a scenario: an entry is used only when
it loads into that file's own module.

numba keeps a ``cache=True`` function's compiled code in a folder keyed by the function's file,
and the code refers to the function's module by name: loading an entry imports that name. A
file named in a scenario is imported under its stem, or under ``<stem>_<hash of its path>`` when
another module has that name (:func:`delaytrack._spec.module_from_file`), so a process may find
an entry that names a module it does not have (``ModuleNotFoundError`` from the factory, in
every later process: two ``arm.py`` in one sweep, then one of them alone), or one that it gives
another file (its compiled code was bound to the other file's module). :func:`guard_caches`
makes such an entry a miss: the function is compiled again and its entry replaced.
"""

from __future__ import annotations

from types import ModuleType
from typing import Any

from numba.core.caching import FunctionCache
from numba.core.dispatcher import Dispatcher
from numba.core.environment import Environment

__all__ = ["guard_caches"]


class _OwnModuleCache(FunctionCache):
    """numba's cache of one function whose entries must load into the function's module (it
    replaces numba's ``Cache._load_overload``, not a public interface of numba's)."""

    def _load_overload(self, sig: Any, target_context: Any) -> Any:
        """numba's own, but an entry naming a module that cannot be imported, or bound to
        another module's globals than the function's, is not loaded (None: compiled again)."""
        if not self._enabled:
            return None
        key = self._index_key(sig, target_context.codegen())
        try:
            data = self._cache_file.load(key)
        except ImportError:
            return None
        if data is None or not _binds_to(data, self._py_func.__globals__):
            return None
        return self._impl.rebuild(target_context, data)


def _binds_to(data: tuple, module_globals: dict) -> bool:
    """Whether the environments of a loaded entry (numba's reduced compile result) hold
    ``module_globals``."""
    environments = [item for item in data if isinstance(item, Environment)]
    return all(environment.globals is module_globals for environment in environments)


def guard_caches(module: ModuleType) -> None:
    """Have each function of ``module`` with a numba disk cache (``njit(cache=True)`` at its top
    level) load only entries that load into ``module`` (:class:`_OwnModuleCache`)."""
    for value in vars(module).values():
        if (
            isinstance(value, Dispatcher)
            and getattr(value.py_func, "__globals__", None) is vars(module)
            and type(getattr(value, "_cache", None)) is FunctionCache
        ):
            # numba's Dispatcher sets ``_cache`` at run time; its typing does not declare it
            value._cache.__class__ = _OwnModuleCache  # type: ignore[attr-defined]
