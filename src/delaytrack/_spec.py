"""Plain-data specs (scenario tables) of plants, controllers and delays.

Each registry declares, once per type, the constructor, the keys it accepts with their value
kinds, and the keys it needs (:class:`TypeSpec`). :func:`build_from_table` checks a table against
that declaration and builds the object; every refusal is a :class:`SpecError` naming the key
(``"scenario key 'controller.alpha' must be a number; got 'two'"``).
"""

from __future__ import annotations

import contextlib
import contextvars
import functools
import hashlib
import importlib
import importlib.util
import inspect
import keyword
import math
import sys
import threading
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

from delaytrack._compile.disk_cache import cache_directory
from delaytrack._file_caches import guard_caches
from delaytrack._io import read_file_bytes
from delaytrack._validation import ArgumentError, is_real_number, quoted

__all__ = [
    "PYTHON_TYPE",
    "Check",
    "SpecError",
    "TypeSpec",
    "array",
    "build_from_table",
    "check_table",
    "factory_parts",
    "gain",
    "integer",
    "is_module_name",
    "module_from_file",
    "named_in_a_file",
    "number",
    "own_bytecode",
    "string",
    "user_factory",
    "vector",
]

#: A value check: returns an error phrase ("must be ...") or None when the value fits.
Check = Callable[[object], "str | None"]


class SpecError(ValueError):
    """A scenario file or table is not valid; the message names the key and what is valid.

    An error about the value of one key (:meth:`of_key`) carries the key (``key``, dotted:
    ``controller.alpha``) and what is wrong with its value (``problem``), so that a caller that
    sets the key another way (the command line's ``--duration``) can name it so; other errors
    have ``key = None``.
    """

    key: str | None = None
    problem: str | None = None

    @classmethod
    def of_key(cls, key: str, problem: str) -> SpecError:
        """The error ``"scenario key '<key>' <problem>"``, carrying ``key`` and ``problem``."""
        error = cls(f"scenario key {key!r} {problem}")
        error.key, error.problem = key, problem
        return error

    def in_file(self, source: object) -> SpecError:
        """The same error, its message starting with the file ``source`` it is about."""
        error = type(self)(f"{source}: {self}")
        error.key, error.problem = self.key, self.problem
        return error


def _is_vector(value: object) -> bool:
    return isinstance(value, list) and all(is_real_number(item) for item in value)


def _is_matrix(value: object) -> bool:
    if not isinstance(value, list) or not value or not all(_is_vector(row) for row in value):
        return False
    return len({len(row) for row in value}) == 1


def number(value: object) -> str | None:
    if not is_real_number(value):
        return "must be a number"
    try:
        finite = math.isfinite(value)
    except OverflowError:  # an integer beyond any float
        finite = False
    if not finite:
        return "must be a finite number"
    return None


def integer(value: object) -> str | None:
    return None if isinstance(value, int) and not isinstance(value, bool) else "must be an integer"


def string(value: object) -> str | None:
    return None if isinstance(value, str) else "must be a string"


def vector(value: object) -> str | None:
    return None if _is_vector(value) else "must be a list of numbers"


def gain(value: object) -> str | None:
    if is_real_number(value) or _is_vector(value) or _is_matrix(value):
        return None
    return (
        "must be a number (a multiple of I), a list of numbers (a diagonal) or a list of "
        "equally long lists of numbers (a matrix)"
    )


def array(value: object) -> str | None:
    if _is_vector(value) or _is_matrix(value):
        return None
    return "must be a list of numbers or a list of equally long lists of numbers"


@dataclass(frozen=True)
class TypeSpec:
    """How a table with a given ``type`` becomes an object.

    Attributes
    ----------
    build : callable
        Constructor called with the table's values as keyword arguments.
    keys : mapping
        Table key -> (constructor argument, value check).
    required : tuple of str
        Keys the table must have.
    alternatives : tuple of tuple of str
        Groups of keys of which exactly one group must be given, complete (for example a trace's
        ``("path",)`` or ``("times", "values")``).
    """

    build: Callable[..., Any]
    keys: Mapping[str, tuple[str, Check]] = field(default_factory=dict)
    required: tuple[str, ...] = ()
    alternatives: tuple[tuple[str, ...], ...] = ()


#: Prefix of a table type naming a user's factory: ``"python:<module>:<function>"`` (an
#: importable module) or ``"python:<file.py>:<function>"`` (a file, in a scenario file relative
#: to it). The factory is called with the table's other keys as keyword arguments.
PYTHON_TYPE = "python:"

#: Modules loaded from a file, by path: ``(sha256 of the file, module)``.
_FILE_MODULES: dict[Path, tuple[str, ModuleType]] = {}
#: Held while a file is loaded: one at a time (``sys.pycache_prefix`` is the process's).
_LOADING = threading.RLock()


def _module_name(path: Path) -> str:
    """The name the Python file ``path`` is imported under: its stem, the name that ``import
    <stem>`` from its folder gives it, unless another module has that name (loaded, or
    importable from ``sys.path``); then ``<stem>_<hash of its path>``.

    numba's disk cache of a kernel with ``cache=True`` refers to the kernel's module by name, so
    that a kernel compiled in a session that imported the file itself loads here, and the other
    way round, only when both use the same name.
    """
    stem = path.stem
    if stem.isidentifier() and not keyword.iskeyword(stem):
        loaded = sys.modules.get(stem)
        if loaded is not None:
            origin = getattr(loaded, "__file__", None)
        else:
            try:
                spec = importlib.util.find_spec(stem)
            except (ImportError, ValueError):
                spec = None
            # A folder of that name (a namespace package, no origin) is not a module to keep.
            origin = path if spec is None or spec.origin is None else spec.origin
        if origin is not None and Path(origin).resolve() == path:
            return stem
    return f"{stem}_{hashlib.sha256(str(path).encode()).hexdigest()[:8]}"


def module_from_file(path: Path, name: str | None = None) -> ModuleType:
    """Import the Python file ``path`` (again when its content changed since the last import).

    It is imported under ``name``, by default :func:`_module_name` (its stem, never shadowing
    another module), with its folder first on ``sys.path`` while it runs, so that it can import
    its neighbours. What runs is the file's content as read and hashed here, compiled from the
    source: never a ``.pyc`` from a ``__pycache__`` beside it, neither its own nor, while it
    runs, a neighbour's it imports (:func:`own_bytecode`). Its functions and its neighbours'
    with a numba disk cache load only entries bound to their own module
    (:mod:`delaytrack._file_caches`). A file the user imported already is that module, not a
    second copy.
    """
    path = path.expanduser().resolve()
    with _LOADING:
        source = read_file_bytes(path, "factory file")
        content = hashlib.sha256(source).hexdigest()
        known = _FILE_MODULES.get(path)
        if known is not None and known[0] == content:
            return known[1]
        name = name or _module_name(path)
        loaded = sys.modules.get(name)
        if known is None and loaded is not None:  # imported by the user: the same objects
            _FILE_MODULES[path] = (content, loaded)
            return loaded
        spec = importlib.util.spec_from_file_location(name, path)
        if spec is None:
            raise ImportError(f"{str(path)!r} is not a Python file")
        module = importlib.util.module_from_spec(spec)
        code = compile(source, str(path), "exec", dont_inherit=True)
        previous = sys.modules.get(name)
        before = set(sys.modules)
        sys.modules[name] = module
        sys.path.insert(0, str(path.parent))
        try:
            with own_bytecode():
                exec(code, vars(module))  # the user's file, allowed by delaytrack._trust
        except BaseException:
            if previous is None:
                del sys.modules[name]
            else:
                sys.modules[name] = previous
            raise
        finally:
            sys.path.remove(str(path.parent))
        neighbours = [sys.modules[other] for other in set(sys.modules) - before]
        for found in [module, *neighbours]:
            if _file_below(found, path.parent):
                guard_caches(found)
        _FILE_MODULES[path] = (content, module)
        return module


def _file_below(module: ModuleType, folder: Path) -> bool:
    """Whether ``module`` was loaded from a file in ``folder`` or below it."""
    file = getattr(module, "__file__", None)
    return isinstance(file, str) and Path(file).resolve().is_relative_to(folder)


@contextlib.contextmanager
def own_bytecode() -> Iterator[None]:
    """While inside, Python reads and writes the bytecode of what it imports in this package's
    cache folder (``sys.pycache_prefix``), not in a ``__pycache__`` beside the source: a
    ``.pyc`` shipped there, whose header matches its source's time and size, is not run instead
    of the source."""
    previous = sys.pycache_prefix
    sys.pycache_prefix = str(_bytecode_folder())
    try:
        yield
    finally:
        sys.pycache_prefix = previous


@functools.cache
def _bytecode_folder() -> Path:
    """The folder of the bytecode of what the files that scenarios name import
    (:func:`own_bytecode`), beside numba's cache folders (any version of this package)."""
    return cache_directory().parent / "bytecode"


def is_module_name(text: str) -> bool:
    """Whether ``text`` is a dotted module name (``mylab.robots``)."""
    return all(part.isidentifier() for part in text.split("."))


def factory_parts(key: str, kind: str) -> tuple[str, str]:
    """The location (a ``.py`` file or a module name) and the function of the factory type
    ``kind`` (:data:`PYTHON_TYPE`) given as scenario key ``key`` (``plant.type``).

    Raises
    ------
    SpecError
        When ``kind`` has neither form.
    """
    location, colon, name = kind[len(PYTHON_TYPE) :].rpartition(":")
    if colon and name.isidentifier() and (location.endswith(".py") or is_module_name(location)):
        return location, name
    raise SpecError(
        f"scenario key {key!r} must name a factory as 'python:<module>:<function>' "
        f"or 'python:<file.py>:<function>'; got {kind!r}"
    )


def user_factory(table: str, kind: str) -> Callable[..., Any]:
    """The factory named by the type ``kind`` (:data:`PYTHON_TYPE`) of ``[table]``.

    Its module is imported here, unchecked: the factories of a file read from disk are checked
    against what the user trusts (:mod:`delaytrack._trust`) before.

    Raises
    ------
    SpecError
        Naming ``<table>.type`` when the name is malformed, the module cannot be imported (with
        the error it raised, ``SystemExit`` included) or has no such function.
    KeyboardInterrupt
        Saying which factory's module was being imported.
    """
    location, name = factory_parts(f"{table}.type", kind)
    try:
        if location.endswith(".py"):
            module = module_from_file(Path(location))
        else:
            module = importlib.import_module(location)
    except Exception as error:  # noqa: BLE001 - anything the user's module raises is reported
        raise SpecError(
            f"scenario key '{table}.type' = {kind!r}: cannot import {location!r} "
            f"({type(error).__name__}: {error})"
        ) from None
    except KeyboardInterrupt:
        raise KeyboardInterrupt(
            f"interrupted while importing {location!r} for scenario key '{table}.type' = {kind!r}"
        ) from None
    except BaseException as error:  # SystemExit: the module's, not the command's
        raise SpecError(
            f"scenario key '{table}.type' = {kind!r} raised {error!r} while importing "
            f"{location!r} (a factory's module must not exit)"
        ) from None
    factory = getattr(module, name, None)
    if not callable(factory):
        raise SpecError(
            f"scenario key '{table}.type' = {kind!r}: {location!r} has no function {name!r}"
        )
    if _NAMED_IN_A_FILE.get():
        _check_defined_there(f"scenario key '{table}.type' = {kind!r}", location, module, factory)
    return factory


#: Whether the factory types being checked come from a scenario or sweep file (which someone
#: may have sent) rather than from a dict of the user's own code (:func:`named_in_a_file`).
_NAMED_IN_A_FILE: contextvars.ContextVar[bool] = contextvars.ContextVar(
    "factories_named_in_a_file", default=False
)


@contextlib.contextmanager
def named_in_a_file() -> Iterator[None]:
    """Within it, a factory type ``python:<location>:<function>`` read from a file must name a
    function written in that file (or package, or one of its submodules), not one it imports:
    trusting a file trusts its factories, not whatever it imported (a file with ``from os
    import system`` would let a scenario sent into its folder call ``system(...)``)."""
    token = _NAMED_IN_A_FILE.set(True)
    try:
        yield
    finally:
        _NAMED_IN_A_FILE.reset(token)


def _check_defined_there(
    named: str, location: str, module: ModuleType, factory: Callable[..., Any]
) -> None:
    """Refuse a ``factory`` (a partial of one: its function) not written in ``module``, the
    module of ``location``; ``named`` starts the message."""
    function = factory
    while isinstance(function, functools.partial):
        function = function.func
    home = getattr(function, "__module__", None)
    package = module.__name__
    if home == package or (not location.endswith(".py") and f"{home}".startswith(f"{package}.")):
        return
    name = getattr(function, "__qualname__", type(function).__name__)
    raise SpecError(
        f"{named}: {name!r} is not defined in {location!r} (it comes from {home!r}); a factory "
        "that a file names must be written in the file or package it names, not imported there"
    )


def _any_value(value: object) -> str | None:
    return None


def fail(key: str, phrase: str, value: object) -> SpecError:
    """The error for ``key`` whose ``value`` does not fit ``phrase`` ("must be ...")."""
    return SpecError.of_key(key, f"{phrase}; got {quoted(value)}")


def check_table(table: str, value: object, types: Mapping[str, TypeSpec]) -> TypeSpec:
    """Check a typed table: a ``type`` among ``types``, only its keys; return its spec."""
    if not isinstance(value, Mapping):
        raise fail(table, f"must be a table ([{table}])", value)
    valid_types = sorted(types)
    if "type" not in value:
        raise SpecError(
            f"scenario key '{table}.type' is missing; [{table}] needs a type, one of {valid_types}"
        )
    kind = value["type"]
    if isinstance(kind, str) and kind.startswith(PYTHON_TYPE):
        keys = {key: (key, _any_value) for key in value if key != "type"}
        return TypeSpec(user_factory(table, kind), keys)
    if not isinstance(kind, str) or kind not in types:
        raise SpecError(
            f"scenario key '{table}.type' must be one of {valid_types} or a factory of yours, "
            f"'python:<module>:<function>'; got {kind!r}"
        )
    spec = types[kind]
    for key, item in value.items():
        if key == "type":
            continue
        if key not in spec.keys:
            raise SpecError(
                f"unknown key '{table}.{key}' in scenario; valid keys in [{table}] with "
                f"type = {kind!r} are {['type', *sorted(spec.keys)]}"
            )
        phrase = spec.keys[key][1](item)
        if phrase is not None:
            raise fail(f"{table}.{key}", phrase, item)
    if spec.alternatives:
        _check_alternatives(table, kind, value, spec.alternatives)
    missing = [key for key in spec.required if key not in value]
    if missing:
        raise SpecError(
            f"scenario key '{table}.{missing[0]}' is missing; [{table}] with type = {kind!r} "
            f"needs {list(spec.required)}"
        )
    return spec


def _check_alternatives(
    table: str, kind: str, value: Mapping[str, Any], groups: tuple[tuple[str, ...], ...]
) -> None:
    described = " or ".join(" and ".join(repr(key) for key in group) for group in groups)
    touched = [group for group in groups if any(key in value for key in group)]
    if len(touched) > 1:
        raise SpecError(
            f"scenario table [{table}] with type = {kind!r} takes either {described}, not both"
        )
    group = touched[0] if touched else groups[0]
    missing = [key for key in group if key not in value]
    if missing:
        raise SpecError(
            f"scenario key '{table}.{missing[0]}' is missing; [{table}] with type = {kind!r} "
            f"needs {described}"
        )


def _check_factory_keys(
    table: str, kind: str, factory: Callable[..., Any], arguments: Mapping[str, Any]
) -> None:
    """Refuse a key of ``[table]`` that the user's factory does not take, listing those it
    takes (nothing is checked for a factory with ``**kwargs`` or no readable signature)."""
    try:
        parameters = inspect.signature(factory).parameters.values()
    except (TypeError, ValueError):
        return
    if any(parameter.kind is parameter.VAR_KEYWORD for parameter in parameters):
        return
    named = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    takes = [parameter.name for parameter in parameters if parameter.kind in named]
    for key in arguments:
        if key not in takes:
            raise SpecError(
                f"unknown key '{table}.{key}' in scenario; {kind} takes the keys {takes}"
            )


def build_from_table(
    table: str,
    value: object,
    types: Mapping[str, TypeSpec],
    returns: type | None = None,
    **extra: Any,
) -> Any:
    """Check ``value`` with :func:`check_table` and build it (``extra`` goes to the constructor).

    A refusal by the constructor is re-raised naming the table, and the key when it is an
    :class:`~delaytrack._validation.ArgumentError` about the constructor argument of one
    (``ArgumentError("K1", "must be ...")`` becomes ``"scenario key 'controller.K1' must be
    ..."``, a :class:`SpecError` carrying the key). A user's factory (:data:`PYTHON_TYPE`) may
    raise anything, reported with its type (``SystemExit`` too, as a :class:`SpecError`; a
    ``KeyboardInterrupt`` is raised again naming the factory); it must return an instance of
    ``returns``.
    """
    spec = check_table(table, value, types)
    assert isinstance(value, Mapping)  # check_table refuses anything else
    kind = value["type"]
    user = kind.startswith(PYTHON_TYPE)
    arguments = {spec.keys[key][0]: item for key, item in value.items() if key != "type"}
    if user:
        _check_factory_keys(table, kind, spec.build, arguments)
    try:
        built = spec.build(**extra, **arguments)
    except SpecError:
        raise
    except Exception as error:
        if user:  # the factory's own message, whole, with the factory that raised it
            raise SpecError(
                f"scenario table [{table}]: {kind} raised {type(error).__name__}: {error}"
            ) from None
        if not isinstance(error, ValueError | TypeError | FileNotFoundError | ImportError):
            raise
        # ImportError: an optional extra the type needs is not installed (the message says how).
        raise _refusal(table, spec, error) from None
    except KeyboardInterrupt:
        if not user:
            raise
        raise KeyboardInterrupt(
            f"interrupted in the factory of scenario key '{table}.type' = {kind!r}"
        ) from None
    except BaseException as error:  # SystemExit: the factory's, not the command's
        if not user:
            raise
        raise SpecError(
            f"scenario key '{table}.type' = {kind!r} raised {error!r} (a factory returns "
            f"{_with_article(returns.__name__) if returns else 'its component'}; it must not exit)"
        ) from None
    if returns is not None and not isinstance(built, returns):
        raise SpecError(
            f"scenario table [{table}]: {kind} returned {_with_article(type(built).__name__)}; "
            f"a [{table}] factory must return {_with_article(returns.__name__)}"
        )
    return built


def _refusal(table: str, spec: TypeSpec, error: Exception) -> SpecError:
    """The :class:`SpecError` for ``error``, raised by the constructor of ``[table]``: about the
    key whose constructor argument an :class:`~delaytrack._validation.ArgumentError` names (the
    arguments it mentions called by their keys too), else about the table.

    A plain error from code that carries no argument (a check shared with other callers) is
    matched by the start of its message, ``"<argument> ..."``.
    """
    keys = {argument: key for key, (argument, _) in spec.keys.items()}
    if isinstance(error, ArgumentError):
        if error.argument in keys:
            key = keys[error.argument]
            return SpecError.of_key(f"{table}.{key}", error.spelled(keys)[len(key) + 1 :])
    else:
        message = str(error)
        for argument, key in keys.items():
            if message.startswith(f"{argument} "):
                return SpecError.of_key(f"{table}.{key}", message[len(argument) + 1 :])
    return SpecError(f"scenario table [{table}]: {error}")


def _with_article(name: str) -> str:
    """``name`` after its indefinite article: "a float", "an ELPlant", "an int"."""
    return f"{'an' if name[:1].lower() in 'aeiou' else 'a'} {name}"
