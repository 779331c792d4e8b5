"""Results folders: checked before any computing, and never holding the files of two runs.

:func:`check_output_folder` is called before a command computes anything: the location must be
a folder that can be created and written, and a folder that already holds files must be one
this toolkit wrote (it keeps a list of them, :data:`MANIFEST`), so that a user's own files are
never overwritten. :func:`record_outputs` is called after a run has written its files: files of
the previous run in that folder that this run did not write again are removed, and the list is
replaced. A folder therefore holds the files of its latest run only.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from collections.abc import Iterable
from pathlib import Path

from delaytrack._io import write_text

__all__ = [
    "MANIFEST",
    "OutputFolderError",
    "check_output_folder",
    "check_writable_location",
    "record_outputs",
]

#: File (in each results folder) listing the files the latest run wrote, relative to it.
MANIFEST = ".delaytrack-files.json"


class OutputFolderError(ValueError):
    """A results location cannot be used; the message names the argument and the path."""


def _nearest_existing(path: Path) -> Path:
    for candidate in (path, *path.parents):
        if candidate.exists():
            return candidate
    return Path(".")


def check_writable_location(path: str | os.PathLike[str], argument: str) -> Path:
    """Check that ``path`` can be created as a folder or file: not empty, no file among its
    parents, and its nearest existing folder writable. Returns it as a :class:`Path`."""
    text = os.fspath(path)
    if not text.strip():
        raise OutputFolderError(f"{argument} must name a location; got {text!r}")
    try:
        target = Path(text).expanduser()
    except RuntimeError as error:  # "~user" of no such user
        raise OutputFolderError(f"{argument} {text!r}: {error}") from None
    too_long = [part for part in target.parts if len(os.fsencode(part)) > 255]
    if too_long:
        raise OutputFolderError(
            f"{argument} {text!r} has a name longer than 255 bytes ({too_long[0][:20]!r}...)"
        )
    for parent in target.parents:
        if parent.exists() and not parent.is_dir():
            raise OutputFolderError(
                f"{argument} {text!r} lies under {str(parent)!r}, which is a file, not a folder"
            )
    if target.is_symlink() and not target.exists():
        raise OutputFolderError(
            f"{argument} {text!r} is a link to nothing ({os.readlink(target)!r})"
        )
    existing = _nearest_existing(target if target.is_dir() else target.parent)
    try:  # the one reliable test (root passes os.access everywhere, /proc refuses files)
        probe = tempfile.NamedTemporaryFile(dir=existing, prefix=".delaytrack-probe-")
        probe.close()
    except OSError as error:
        raise OutputFolderError(
            f"{argument} {text!r} cannot be written: {error.strerror or error} in {str(existing)!r}"
        ) from None
    return target


def check_output_folder(
    folder: str | os.PathLike[str], argument: str = "folder", *, marks: tuple[str, ...] = ()
) -> Path:
    """Check a results folder before computing (module docstring); return it as a Path.

    ``marks`` are entries that also show a folder to be this toolkit's (a sweep's ``parts``).

    Raises
    ------
    OutputFolderError
        If ``folder`` is empty text, is a file, lies under a file, cannot be written, or already
        holds files that this toolkit did not write there. The message names ``argument``.
    """
    target = check_writable_location(folder, argument)
    if target.exists() and not target.is_dir():
        raise OutputFolderError(
            f"{argument} {os.fspath(folder)!r} is a file; it must name a folder (new or empty, "
            "or one that holds earlier results of this toolkit)"
        )
    ours = (target / MANIFEST).is_file() or any((target / mark).exists() for mark in marks)
    if target.is_dir() and not ours:
        foreign = sorted(entry.name for entry in target.iterdir())
        if foreign:
            shown = ", ".join(foreign[:3]) + (", ..." if len(foreign) > 3 else "")
            raise OutputFolderError(
                f"{argument} {os.fspath(folder)!r} already holds files that this toolkit did not "
                f"write ({shown}); choose a new or empty folder, so that nothing of yours is "
                "overwritten and the folder holds one run's results only (results of an earlier "
                "version of this toolkit: delete the folder)"
            )
    return target


def _listed(folder: Path) -> list[str]:
    try:
        data = json.loads((folder / MANIFEST).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return []
    files = data.get("files") if isinstance(data, dict) else None
    return [name for name in files if isinstance(name, str)] if isinstance(files, list) else []


def record_outputs(folder: str | os.PathLike[str], files: Iterable[str | os.PathLike[str]]) -> None:
    """After a run wrote ``files`` into ``folder``: remove the previous run's other files and
    record these (module docstring)."""
    root = Path(folder).resolve()
    written = sorted(
        {Path(file).resolve().relative_to(root).as_posix() for file in files if Path(file).exists()}
    )
    for name in set(_listed(root)) - set(written):
        stale = (root / name).resolve()
        if stale.is_relative_to(root) and stale.is_file():
            stale.unlink()
            if stale.parent != root:
                with contextlib.suppress(OSError):  # a subfolder left empty goes too
                    stale.parent.rmdir()
    write_text(root / MANIFEST, json.dumps({"files": written}, indent=1) + "\n")
