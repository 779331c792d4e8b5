"""Which factories a scenario or sweep file may name.

A table's ``type = "python:<file.py>:<function>"`` or ``"python:<module>:<function>"`` is Python
code that runs with the user's rights when the file is loaded, and a file someone sent could
name any function (``python:os:remove``). In a file read from disk a factory is therefore
allowed only when

- its file, after resolving ``..`` and symbolic links, lies in the folder of the scenario or
  sweep file that names it, or below it, and is that folder's own code: no folder on the way
  down is hidden (``.pyenv``), a folder of installed or generated code (``site-packages``,
  ``dist-packages``, ``node_modules``, ``__pypackages__``, ``__pycache__``, or one holding a
  ``*.dist-info`` record, as ``pip install --target`` leaves), a Python
  environment (it holds ``pyvenv.cfg``) or a Python installation (``lib/python3.*``), and the
  file is not where this Python, its packages or this package are installed
  (:func:`installed_locations`); or
- the user trusts it: a module name (that module and its submodules) or a path (a ``.py`` file,
  or a folder and every file below it), given as ``--trust NAME`` on the command line or
  ``trust=[NAME, ...]`` in Python.

No module is trusted by default, not even this package's own. The check runs before anything is
imported. A file the user only opens, not names (a live session folder's ``scenario.toml``),
gets no trust for its folder: only what the user trusts runs.
"""

from __future__ import annotations

import os
import shlex
import site
import sys
import sysconfig
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from delaytrack._spec import SpecError, is_module_name
from delaytrack._validation import quoted

__all__ = ["Trust", "check_factory", "installed_locations"]

#: Why a factory must be allowed, in every refusal.
_WHY = (
    "a factory is Python code that runs with your rights, and a file you were sent could name "
    "any function"
)

#: Folders of installed or generated code, by name, and what they are.
_CODE_FOLDERS = {
    "site-packages": "a folder of installed Python packages",
    "dist-packages": "a folder of installed Python packages",
    "node_modules": "a folder of installed packages",
    "__pypackages__": "a folder of installed Python packages (PEP 582)",
    "__pycache__": "a folder of compiled Python code",
}

#: A file of Python's standard library, which marks a folder holding it (an unpacked source
#: tree's ``Lib``, a copy of an installation's library): a scenario could name any of its
#: functions (``subprocess.py:getoutput``).
_STANDARD_LIBRARY_MARK = "os.py"
_STANDARD_LIBRARY = f"a copy of Python's standard library (it holds {_STANDARD_LIBRARY_MARK})"


def _is_path(name: str) -> bool:
    """A trust name with a path separator, a leading ``.`` or ``~``, or ending in ``.py``."""
    separators = {os.sep, "/", *([os.altsep] if os.altsep else [])}
    return any(s in name for s in separators) or name.startswith((".", "~")) or name.endswith(".py")


@dataclass(frozen=True)
class Trust:
    """What the user trusts beyond a file's own folder: modules and paths (resolved)."""

    modules: tuple[str, ...] = ()
    paths: tuple[Path, ...] = ()
    #: Whether a factory is allowed for lying in the folder of the file that names it (False
    #: for a file the user did not write and only opened, such as a live session folder's).
    own_folder: bool = True

    @classmethod
    def of(cls, names: Iterable[str], option: str = "trust") -> Trust:
        """Read trust names: a module name (``mylab.robots``), or a path to a ``.py`` file or a
        folder when it has a ``/``, starts with ``.`` or ``~`` or ends in ``.py``
        (``./robots``, ``~/lab``, ``arm.py``); relative paths from the working folder.

        Raises
        ------
        ValueError
            Naming ``option`` (``--trust``) for a name of neither form, a path that does not
            exist or a file that is not a ``.py`` file.
        """
        if isinstance(names, str | bytes) or not isinstance(names, Iterable):
            raise ValueError(
                f"{option} must be a list of module names or paths, such as ['mylab.robots', "
                f"'./robots']; got {quoted(names)}"
            )
        modules, paths = [], []
        for name in names:
            if not isinstance(name, str) or not name.strip():
                raise ValueError(f"{option} takes module names or paths (text); got {name!r}")
            if not _is_path(name):
                if not is_module_name(name):
                    raise ValueError(
                        f"{option} {name!r} is neither a module name (mylab.robots) nor a path "
                        "(a path has a '/' or ends in .py: ./robots, robots/arm.py)"
                    )
                modules.append(name)
                continue
            try:
                path = Path(name).expanduser().resolve()
            except (OSError, RuntimeError) as error:  # "~user" of no such user, a link loop
                raise ValueError(f"{option} {name!r}: {error}") from None
            if not path.exists():
                raise ValueError(f"{option} {name!r}: no such file or folder ({path})")
            if not path.is_dir() and path.suffix != ".py":
                raise ValueError(
                    f"{option} {name!r} is a file but not Python (.py); trust a .py file, a "
                    "folder or a module name"
                )
            paths.append(path)
        return cls(tuple(modules), tuple(paths))

    def allows_module(self, name: str) -> bool:
        """Whether the module ``name`` is trusted (it or a package above it is)."""
        return any(name == module or name.startswith(f"{module}.") for module in self.modules)

    def allows_file(self, path: Path) -> bool:
        """Whether the resolved file ``path`` is trusted (it, or a folder above it, is)."""
        return any(path == trusted or path.is_relative_to(trusted) for trusted in self.paths)


def installed_locations() -> tuple[tuple[Path, str], ...]:
    """Where this package, Python's standard library, the installed packages and this Python
    itself are installed (resolved), most specific first, each with what it is."""
    paths = sysconfig.get_paths()
    places: list[tuple[str | Path, str]] = [
        (Path(__file__).parent, "where delaytrack is installed"),
        (paths["stdlib"], "Python's standard library"),
        (paths["platstdlib"], "Python's standard library"),
        *((folder, "a folder of installed Python packages") for folder in site.getsitepackages()),
        (site.getusersitepackages(), "your folder of installed Python packages"),
        (sys.prefix, "where this Python is installed (sys.prefix)"),
        (sys.exec_prefix, "where this Python is installed (sys.exec_prefix)"),
        (sys.base_prefix, "where this Python is installed (sys.base_prefix)"),
    ]
    return tuple((Path(place).resolve(), what) for place, what in places)


def _installed_here(folder: Path) -> str | None:
    """Why ``folder`` holds installed packages (a ``*.dist-info`` record, as ``pip install
    --target`` leaves beside them), or None. (A ``*.egg-info`` is not one: ``pip install -e .``
    leaves it in a project's own source folder.)"""
    record = next(folder.glob("*.dist-info"), None)
    if record is not None:
        return f"inside {folder}, a folder of installed Python packages (it holds {record.name})"
    return None


def _not_its_own(path: Path, folder: Path) -> str | None:
    """Why the file ``path`` (resolved, below the resolved ``folder``) is not that folder's own
    code: a place where Python or this package is installed, else the first folder on the way
    down from ``folder`` (itself included) that is hidden, of installed or generated code, a
    Python environment, a Python installation or a copy of its standard library; None when it
    is its own."""
    for place, what in installed_locations():
        if path.is_relative_to(place):
            return f"inside {place}, {what}"
    current = folder
    if (current / _STANDARD_LIBRARY_MARK).is_file():
        return f"inside {current}, {_STANDARD_LIBRARY}"
    installed = _installed_here(current)
    if installed is not None:
        return installed
    for name in path.parent.relative_to(folder).parts:
        current = current / name
        if name.startswith("."):
            return f"inside the hidden folder {current}"
        if name in _CODE_FOLDERS:
            return f"inside {current}, {_CODE_FOLDERS[name]}"
        if (current / _STANDARD_LIBRARY_MARK).is_file():
            return f"inside {current}, {_STANDARD_LIBRARY}"
        installed = _installed_here(current)
        if installed is not None:
            return installed
        if (current / "PKG-INFO").is_file():
            return f"inside {current}, an unpacked source distribution (it holds PKG-INFO)"
        if (current / "pyvenv.cfg").is_file():
            return f"inside {current}, a Python environment (it holds pyvenv.cfg)"
        library = next(current.glob("lib/python3.*"), None)
        if library is not None:
            return f"inside {current}, a Python installation (it holds lib/{library.name})"
        if name.startswith("python3.") and current.parent.name == "lib":
            return f"inside {current}, a Python installation's library"
    return None


def check_factory(key: str, kind: str, location: str, source: Path, trust: Trust) -> None:
    """Refuse the factory ``kind`` of scenario key ``key`` (``plant.type``) unless it is allowed.

    ``location`` is its file (absolute) or module, ``source`` the scenario or sweep file that
    names it. Nothing is imported.

    Raises
    ------
    SpecError
        Naming the key and the value, saying why a factory must be allowed and how.
    """
    if not location.endswith(".py"):
        if trust.allows_module(location):
            return
        raise SpecError(
            f"scenario key {key!r} = {kind!r} names the module {location!r}, which is not "
            f"trusted: {_WHY}; if you trust that code, pass --trust {shlex.quote(location)} "
            f"(in Python: trust=[{location!r}])"
        )
    folder = source.expanduser().parent
    try:
        path = Path(location).resolve()
        folder = folder.resolve()
    except (OSError, RuntimeError) as error:  # a link loop
        raise SpecError(f"scenario key {key!r} = {kind!r}: {error}") from None
    if trust.allows_file(path):
        return
    if path.is_relative_to(folder) and not trust.own_folder:
        raise SpecError(
            f"scenario key {key!r} = {kind!r} names {path}, in the folder of {source.name}, "
            f"whose code is not trusted for being there ({source.name} was opened from a "
            f"folder you did not name as yours, such as a session folder someone sent): "
            f"{_WHY}; if you trust that file, pass --trust {shlex.quote(str(path))} (in "
            f"Python: trust=[{str(path)!r}])"
        )
    if path.is_relative_to(folder):
        reason = _not_its_own(path, folder)
        if reason is None:
            return
        raise SpecError(
            f"scenario key {key!r} = {kind!r} names {path}, which is below {folder} (the "
            f"folder of {source.name}) but {reason}, and is not trusted: {_WHY}; if you trust "
            f"that file, pass --trust {shlex.quote(str(path))} (in Python: trust=[{str(path)!r}])"
            + _read_as_modules(trust)
        )
    raise SpecError(
        f"scenario key {key!r} = {kind!r} names {path}, which is neither in {folder} (the "
        f"folder of {source.name}) nor below it, nor trusted: {_WHY}; if you trust the code in "
        f"{path.parent}, pass --trust {shlex.quote(str(path.parent))} (in Python: "
        f"trust=[{str(path.parent)!r}])" + _read_as_modules(trust)
    )


def _read_as_modules(trust: Trust) -> str:
    """A note for the trusted names read as module names that are also folders here (``--trust
    robots`` meant for the folder ``./robots``): "" when there is none."""
    folders = [name for name in trust.modules if Path(name).is_dir()]
    if not folders:
        return ""
    return "".join(
        f"; the trusted name {name!r} was read as a module name (a folder needs a '/': "
        f"--trust ./{name}, trust=['./{name}'])"
        for name in folders
    )
