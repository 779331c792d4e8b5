"""Results folders: checked before any computing, marked before any writing, and never
holding the files of two runs.

:func:`check_output_folder` is called before a command computes anything: the location, with
``..`` and links resolved (``NEW/../MINE`` is ``MINE``), must be a folder that can be created
and written, and a folder that already holds files must be one this toolkit wrote. A folder is
this toolkit's when it holds the toolkit's marker, :data:`MANIFEST`, and nothing else makes it
so (a ``parts`` subfolder does not). :func:`claim_output_folder` writes the marker before a run
writes its first file, so that a run interrupted half-way (Ctrl-C while figures are drawn) leaves
a folder the next run accepts; it marks only a folder that is new or empty, so it never adopts a
folder holding anything else. :func:`record_outputs` is called after a run has written its
files: files of the previous run in that folder that this run did not write again are removed,
and the marker lists the new ones. A folder therefore holds the files of its latest run only.

This toolkit never writes a symbolic link. A results folder that holds one, at the top or in a
subfolder (``figures -> ../elsewhere``, ``parts -> ~``), was changed by someone else, and
writing or cleaning up through it would act outside the folder: each of the three functions
looks for links (without following any, :data:`LINK_DEPTH` levels deep) and refuses the folder,
naming the link and its target, so that the check is made again right before the first file is
written and before the previous run's files are removed.

``reproduce --out`` names the folder that holds its jobs' results folders
(:func:`check_results_root`): it must be new, empty, or hold only what this toolkit writes there
(results folders, folders of them, a gains file of ``tune-baselines``). A name that becomes a
folder's name (a sweep file's stem) must be a plain name (:func:`plain_folder_name`).
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from collections.abc import Iterable
from pathlib import Path

from delaytrack._io import read_file_bytes, write_text

__all__ = [
    "LINK_DEPTH",
    "MANIFEST",
    "OutputFolderError",
    "check_output_folder",
    "check_results_root",
    "check_writable_location",
    "claim_output_folder",
    "is_gains_file",
    "plain_folder_name",
    "record_outputs",
]

#: The toolkit's marker in each results folder: the files the latest run wrote, relative to it.
MANIFEST = ".delaytrack-files.json"

#: How a gains file written by ``tune-baselines`` begins (its first key).
_GAINS_FILE_START = b'generated_by = "delaytrack tune-baselines'

#: How deep :func:`check_results_root` looks for results folders (``results/sweeps/<name>``).
_ROOT_DEPTH = 2

#: Levels of subfolders of a results folder searched for links: the deepest the toolkit writes
#: is ``robustness/sweeps/<name>/parts/<part>``.
LINK_DEPTH = 4
#: Entries examined at most: more than a results folder of this toolkit holds (a sweep has at
#: most 100 000 runs, so at most as many parts).
_LINK_ENTRIES = 1_000_000


class OutputFolderError(ValueError):
    """A results location cannot be used; the message names the argument and the path."""


def _nearest_existing(path: Path) -> Path:
    for candidate in (path, *path.parents):
        if candidate.exists():
            return candidate
    return Path(".")


def _shown(names: list[str]) -> str:
    return ", ".join(names[:3]) + (", ..." if len(names) > 3 else "")


def check_writable_location(path: str | os.PathLike[str], argument: str) -> Path:
    """Check that ``path`` can be created as a folder or file: not empty, no file among its
    parents, and its nearest existing folder writable. Returns it as an absolute
    :class:`Path` with ``..`` and links resolved: the location that will be written."""
    text = os.fspath(path)
    if not text.strip():
        raise OutputFolderError(f"{argument} must name a location; got {text!r}")
    try:
        given = Path(text).expanduser()
    except RuntimeError as error:  # "~user" of no such user
        raise OutputFolderError(f"{argument} {text!r}: {error}") from None
    too_long = [part for part in given.parts if len(os.fsencode(part)) > 255]
    if too_long:
        raise OutputFolderError(
            f"{argument} {text!r} has a name longer than 255 bytes ({too_long[0][:20]!r}...)"
        )
    if given.is_symlink() and not given.exists():
        raise OutputFolderError(
            f"{argument} {text!r} is a link to nothing ({os.readlink(given)!r})"
        )
    try:
        target = given.resolve()
    except (OSError, RuntimeError) as error:  # a loop of links
        raise OutputFolderError(f"{argument} {text!r} cannot be resolved: {error}") from None
    for parent in target.parents:
        if parent.exists() and not parent.is_dir():
            raise OutputFolderError(
                f"{argument} {text!r} lies under {str(parent)!r}, which is a file, not a folder"
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


def check_output_folder(folder: str | os.PathLike[str], argument: str = "folder") -> Path:
    """Check a results folder before computing (module docstring); return it, resolved.

    Raises
    ------
    OutputFolderError
        If ``folder`` is empty text, is a file, lies under a file, cannot be written, or already
        holds files without this toolkit's marker. The message names ``argument``.
    """
    target = check_writable_location(folder, argument)
    if target.exists() and not target.is_dir():
        raise OutputFolderError(
            f"{argument} {os.fspath(folder)!r} is a file; it must name a folder (new or empty, "
            "or one that holds earlier results of this toolkit)"
        )
    if target.is_dir() and not (target / MANIFEST).is_file():
        foreign = sorted(entry.name for entry in target.iterdir())
        if foreign:
            raise OutputFolderError(
                f"{argument} {os.fspath(folder)!r}{_resolved(folder, target)} already holds "
                f"files that this toolkit did not write ({_shown(foreign)}); choose a new or "
                "empty folder, so that nothing of yours is overwritten and the folder holds one "
                "run's results only (results of an earlier version of this toolkit: delete the "
                "folder)"
            )
    if target.is_dir():
        _refuse_links(target, argument, folder)
    return target


def _refuse_links(folder: Path, argument: str, given: str | os.PathLike[str]) -> None:
    """Raise :class:`OutputFolderError` when ``folder`` (given as ``given``, for the message) or
    its subfolders down to :data:`LINK_DEPTH` levels hold a symbolic link, naming it and its
    target; links are never followed."""
    pending = [(folder, "", 1)]
    examined = 0
    while pending:
        current, relative, depth = pending.pop()
        try:
            entries = sorted(os.scandir(current), key=lambda entry: entry.name)
        except OSError:
            continue  # unreadable: writing there fails with its own error
        examined += len(entries)
        if examined > _LINK_ENTRIES:
            raise OutputFolderError(
                f"{argument} {os.fspath(given)!r} holds more than {_LINK_ENTRIES} entries, more "
                "than a results folder of this toolkit holds; choose a new or empty folder"
            )
        for entry in entries:
            inner = f"{relative}{entry.name}"
            if entry.is_symlink():
                try:
                    target = repr(os.readlink(entry.path))
                except OSError as error:
                    target = f"(unreadable: {error.strerror})"
                link = os.path.join(os.fspath(given), inner)
                raise OutputFolderError(
                    f"{argument} {os.fspath(given)!r} holds the symbolic link {link!r} -> "
                    f"{target}; this toolkit never writes links, and writing or cleaning up "
                    "through it would act outside the folder: remove it"
                )
            if depth < LINK_DEPTH and entry.is_dir(follow_symlinks=False):
                pending.append((Path(entry.path), f"{inner}/", depth + 1))


def _resolved(given: str | os.PathLike[str], target: Path) -> str:
    """`` (that is, <target>)`` when ``given`` names ``target`` through ``..`` or a link."""
    plain = Path(os.fspath(given)).expanduser().absolute()
    return "" if plain == target else f" (that is, {str(target)!r})"


def is_gains_file(path: Path) -> bool:
    """Whether ``path`` is a gains file written by ``tune-baselines`` (by its first key)."""
    if path.is_symlink() or not path.is_file() or path.suffix != ".toml":
        return False
    try:
        with open(path, "rb") as handle:
            return handle.read(len(_GAINS_FILE_START)) == _GAINS_FILE_START
    except OSError:
        return False


def _ours(entry: Path, depth: int) -> bool:
    """Whether ``entry`` is what this toolkit writes in a results root: a results folder, a
    folder of them (up to ``depth`` levels), an empty folder, or a gains file."""
    if entry.is_symlink() or not entry.is_dir():
        return is_gains_file(entry)
    if (entry / MANIFEST).is_file():
        return True
    try:
        return depth > 0 and all(_ours(inner, depth - 1) for inner in entry.iterdir())
    except OSError:
        return False


def check_results_root(folder: str | os.PathLike[str], argument: str) -> Path:
    """Check the folder of a command's results folders (``reproduce --out``) before computing:
    new, empty, or holding only what this toolkit writes there (module docstring); return it,
    resolved.

    Raises
    ------
    OutputFolderError
        As :func:`check_output_folder`, naming the entries this toolkit did not write.
    """
    target = check_writable_location(folder, argument)
    if target.exists() and not target.is_dir():
        raise OutputFolderError(
            f"{argument} {os.fspath(folder)!r} is a file; it must name a folder (new or empty, "
            "or one that holds results folders of this toolkit)"
        )
    if target.is_dir():
        foreign = sorted(e.name for e in target.iterdir() if not _ours(e, _ROOT_DEPTH))
        if foreign:
            raise OutputFolderError(
                f"{argument} {os.fspath(folder)!r}{_resolved(folder, target)} holds entries that "
                f"this toolkit did not write ({_shown(foreign)}); choose a new or empty folder, "
                "or one that holds only results of this toolkit, so that the results do not "
                "land among files of yours"
            )
    return target


def plain_folder_name(name: str, what: str) -> str:
    """``name`` when it can name a folder as it is: not empty, not starting with ``.`` (``.``,
    ``..``, a hidden folder), no ``/``, ``\\`` or control characters, no space at either end.
    ``what`` says where it comes from, for the message."""
    plain = (
        name.strip() == name
        and name
        and not name.startswith(".")
        and not any(c in "/\\" or ord(c) < 32 or ord(c) == 127 for c in name)
        and len(os.fsencode(name)) <= 255
    )
    if not plain:
        raise OutputFolderError(
            f"{what} gives the folder name {name!r}, which is not a plain name: a folder name "
            "must not be empty, start with '.', hold '/', '\\' or control characters, or "
            "begin or end with a space; rename the file or choose the folder with --out"
        )
    return name


def claim_output_folder(folder: str | os.PathLike[str]) -> Path:
    """Before a run writes its first file into ``folder`` (checked by
    :func:`check_output_folder`): create it and put the toolkit's marker in it when it is new
    or empty, so that an interrupted run leaves a folder the next run accepts. A folder that
    holds anything else without the marker is left unmarked. Returns the folder.

    Raises
    ------
    OutputFolderError
        When the folder holds a symbolic link (module docstring), naming it and its target.
    """
    root = Path(folder)
    root.mkdir(parents=True, exist_ok=True)
    _refuse_links(root, "results folder", root)
    if not (root / MANIFEST).is_file() and not any(root.iterdir()):
        write_text(root / MANIFEST, json.dumps({"files": []}, indent=1) + "\n")
    return root


#: Largest marker read (16 MiB, about 200 000 file names): one that someone made larger is
#: taken as listing nothing, as an unreadable one.
_LARGEST_MANIFEST = 16 * 2**20


def _listed(folder: Path) -> list[str]:
    try:
        text = read_file_bytes(folder / MANIFEST, "results list", largest=_LARGEST_MANIFEST)
        data = json.loads(text.decode("utf-8"))
    except (OSError, ValueError):
        return []
    files = data.get("files") if isinstance(data, dict) else None
    return [name for name in files if isinstance(name, str)] if isinstance(files, list) else []


def record_outputs(
    folder: str | os.PathLike[str],
    files: Iterable[str | os.PathLike[str]],
    *,
    remove_others: bool = True,
) -> None:
    """After a run wrote ``files`` into ``folder``: remove the previous run's other files and
    record these (module docstring). With ``remove_others`` False, record them and remove
    nothing: for a process that writes its part of a folder while other processes write
    theirs, so that a file another one renames into place meanwhile is not taken for a stale
    one.

    Raises
    ------
    OutputFolderError
        When the folder holds a symbolic link (module docstring) or a file lies outside it.
    """
    root = Path(folder).resolve()
    _refuse_links(root, "results folder", folder)
    written = sorted({_inside(root, Path(file).resolve()) for file in files if Path(file).exists()})
    for name in set(_listed(root)) - set(written) if remove_others else ():
        stale = (root / name).resolve()
        if stale.is_relative_to(root) and stale.is_file():
            stale.unlink()
            if stale.parent != root:
                with contextlib.suppress(OSError):  # a subfolder left empty goes too
                    stale.parent.rmdir()
    write_text(root / MANIFEST, json.dumps({"files": written}, indent=1) + "\n")


def _inside(root: Path, file: Path) -> str:
    """``file``'s path relative to ``root`` (both resolved), or :class:`OutputFolderError`."""
    if not file.is_relative_to(root):
        raise OutputFolderError(
            f"results folder {str(root)!r}: the file {str(file)!r} lies outside it (a symbolic "
            "link on its way was there while the run was writing); remove the link and run again"
        )
    return file.relative_to(root).as_posix()
