"""Which factories a scenario or sweep file may name.

A table's ``type = "python:<file.py>:<function>"`` or ``"python:<module>:<function>"`` is Python
code that runs with the user's rights when the file is loaded, and a file someone sent could
name any function (``python:os:remove``). In a file read from disk a factory is therefore
allowed only when

- its file, after resolving ``..`` and symbolic links, lies in the folder of the scenario or
  sweep file that names it, or below it; or
- the user trusts it: a module name (that module and its submodules) or a path (a ``.py`` file,
  or a folder and every file below it), given as ``--trust NAME`` on the command line or
  ``trust=[NAME, ...]`` in Python.

No module is trusted by default, not even this package's own. The check runs before anything is
imported.
"""

from __future__ import annotations

import os
import shlex
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from delaytrack._spec import SpecError, is_module_name

__all__ = ["Trust", "check_factory"]

#: Why a factory must be allowed, in every refusal.
_WHY = (
    "a factory is Python code that runs with your rights, and a file you were sent could name "
    "any function"
)


def _is_path(name: str) -> bool:
    """A trust name with a path separator, a leading ``.`` or ``~``, or ending in ``.py``."""
    separators = {os.sep, "/", *([os.altsep] if os.altsep else [])}
    return any(s in name for s in separators) or name.startswith((".", "~")) or name.endswith(".py")


@dataclass(frozen=True)
class Trust:
    """What the user trusts beyond a file's own folder: modules and paths (resolved)."""

    modules: tuple[str, ...] = ()
    paths: tuple[Path, ...] = ()

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
                f"'./robots']; got {names!r}"
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
    if path.is_relative_to(folder) or trust.allows_file(path):
        return
    raise SpecError(
        f"scenario key {key!r} = {kind!r} names {path}, which is neither in {folder} (the "
        f"folder of {source.name}) nor below it, nor trusted: {_WHY}; if you trust the code in "
        f"{path.parent}, pass --trust {shlex.quote(str(path.parent))} (in Python: "
        f"trust=[{str(path.parent)!r}])"
    )
