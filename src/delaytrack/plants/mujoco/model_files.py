"""The files a MuJoCo model names, checked before MuJoCo opens any of them.

MuJoCo reads the files a model names itself, in C: the files it includes (``<include file>``),
its meshes, textures, height fields and skins (``file``, and a cube texture's ``fileright`` ..
``fileback``), its sub-models (``<model file>``) and a URDF's meshes (``<mesh filename>``). A FIFO
among them makes it wait for a writer forever and a device never ends, so
:func:`check_model_files` finds them all first and passes each through
:func:`~delaytrack._io.regular_file`.

The XML's start tags are read as leniently as MuJoCo reads them (a comment holding ``--`` is
MuJoCo's, not XML's), in one pass whatever the text holds, expanding no entity. A name is
resolved every way MuJoCo may resolve it, and every file found is checked: absolute as it is, or
relative to the main model's folder, to the folder of the file that names it, and to the
compiler's ``meshdir``, ``texturedir`` and ``assetdir``, with and without its folders
(``strippath``, the default for URDF). Included XML files are read in turn, at most
:data:`MAX_INCLUDE_DEPTH` deep and :data:`MAX_MODEL_FILES` in all. A name that resolves to
nothing is left for MuJoCo to report.
"""

from __future__ import annotations

import math
import os
import re
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from delaytrack._io import read_file_bytes, regular_file

__all__ = [
    "MAX_GRID_POINTS",
    "MAX_INCLUDE_DEPTH",
    "MAX_MODEL_FILES",
    "MAX_REPLICATED",
    "check_model_files",
]

#: Deepest nesting of included files read (MuJoCo's own examples nest two or three).
MAX_INCLUDE_DEPTH = 20
#: Most XML files (the model and the files it includes) read for one model.
MAX_MODEL_FILES = 1000

#: Most points of one texture or height field (4096 x 4096): MuJoCo holds every one in memory
#: (a checker texture of 60 000 x 60 000 took 10.7 GB).
MAX_GRID_POINTS = 4096 * 4096
#: Most copies that the ``<replicate>`` elements of a model make, their counts multiplied (as
#: if nested: three nested replicates of 1000 took 3.6 GB before failing).
MAX_REPLICATED = 100_000
#: The attributes giving a grid's size, per element (a texture's width and height, a height
#: field's rows and columns).
_GRIDS = {"texture": ("width", "height"), "hfield": ("nrow", "ncol")}
#: The elements whose attributes :func:`_check_sizes` bounds.
_SIZED = (*_GRIDS, "flexcomp", "replicate", "mesh")

#: Elements whose file is MJCF, read in turn for the files it names.
_XML_ELEMENTS = ("include", "model")
#: Compiler attributes naming folders that asset files are relative to.
_ASSET_FOLDERS = ("meshdir", "texturedir", "assetdir")
#: An element's name after ``<``, an attribute up to its opening quote, a character reference.
_TAG_NAME = re.compile(r"[A-Za-z_:][\w.:-]*")
_ATTRIBUTE = re.compile(r"\s+([^\s=<>/\"']+)\s*=\s*([\"'])")
_REFERENCE = re.compile(r"&(?:#x([0-9a-fA-F]{1,6})|#([0-9]{1,7})|(amp|lt|gt|quot|apos));")
_NAMED = {"amp": "&", "lt": "<", "gt": ">", "quot": '"', "apos": "'"}


@dataclass(frozen=True)
class _Name:
    """A file name found in a model's XML: where, on which element and attribute, and depth."""

    source: Path
    line: int
    element: str
    attribute: str
    value: str
    depth: int


def check_model_files(path: Path) -> None:
    """Check every file the MuJoCo model (MJCF or URDF) at ``path`` names, before MuJoCo opens
    it, following included files.

    ``path`` itself is checked by the caller.

    Raises
    ------
    ValueError
        One line naming the model, where the name is (line and file) and why: a name resolving
        to a FIFO, device, socket or a file over the size bound, or includes nested or
        numbering beyond the bounds.
    """
    names: list[_Name] = []
    folders: list[str] = []
    read: set[str] = set()
    checked: set[str] = set()
    replicated: list[int] = []
    pending = [(path, 0)]
    while pending:
        for source, depth in pending:
            if os.path.realpath(source) in read:
                continue  # MuJoCo refuses a file included twice; its message says so
            if len(read) == MAX_MODEL_FILES:
                raise ValueError(
                    f"path {str(path)!r}: the model includes more than {MAX_MODEL_FILES} XML "
                    f"files; at most {MAX_MODEL_FILES} are read"
                )
            if depth > MAX_INCLUDE_DEPTH:
                raise ValueError(
                    f"path {str(path)!r}: {str(source)!r} is included {depth} levels deep; "
                    f"includes nest at most {MAX_INCLUDE_DEPTH} levels"
                )
            read.add(os.path.realpath(source))
            _scan(source, depth, names, folders, replicated)
        pending = []
        for name in names:
            for candidate in _candidates(path, name, folders):
                if candidate in checked:
                    continue
                checked.add(candidate)
                if not os.path.exists(candidate) or os.path.isdir(candidate):
                    continue  # MuJoCo says what is missing or not a file
                where = f"line {name.line}" + (
                    "" if name.source == path else f" of {str(name.source)!r}"
                )
                try:
                    regular_file(
                        candidate, f"path {str(path)!r}: {where}, <{name.element} {name.attribute}>"
                    )
                except FileNotFoundError:
                    continue  # removed meanwhile: MuJoCo says so
                points = _image_points(candidate) if name.element in _GRIDS else None
                if points is not None and points > MAX_GRID_POINTS:
                    raise ValueError(
                        f"path {str(path)!r}: {where}, <{name.element} {name.attribute}> "
                        f"{str(candidate)!r} is an image of {points:,} pixels; at most "
                        f"{MAX_GRID_POINTS:,} (4096 x 4096) are read, each held in memory"
                    )
                if name.element in _XML_ELEMENTS:
                    pending.append((Path(candidate), name.depth + 1))


def _scan(
    source: Path, depth: int, names: list[_Name], folders: list[str], replicated: list[int]
) -> None:
    """Add the file names and asset folders the XML file ``source`` holds, and the counts of
    its ``<replicate>`` elements to ``replicated``; refuse a texture or height field beyond
    :data:`MAX_GRID_POINTS` and replicates beyond :data:`MAX_REPLICATED` in all."""
    try:
        text = read_file_bytes(source, "MuJoCo model file").decode("utf-8-sig", "replace")
    except OSError:
        return  # unreadable: MuJoCo says why
    for line, element, attributes in _elements(text):
        for attribute, value in attributes:
            if attribute.startswith("file") and value.strip():
                names.append(_Name(source, line, element, attribute, value.strip(), depth))
            elif element == "compiler" and attribute in _ASSET_FOLDERS:
                folders.append(value.strip())
        if element in _SIZED:
            _check_sizes(f"line {line} of {str(source)!r}", element, dict(attributes), replicated)


def _check_sizes(
    where: str, element: str, attributes: dict[str, str], replicated: list[int]
) -> None:
    """Refuse an element whose attributes ask MuJoCo for more than it may hold: a texture or
    height field beyond :data:`MAX_GRID_POINTS` points (a cube or skybox texture is six
    squares of its width), a flex of more than :data:`MAX_REPLICATED` points, a built-in mesh
    of more than about :data:`MAX_REPLICATED` vertices (:func:`_builtin_vertices`), or replicates
    beyond :data:`MAX_REPLICATED` copies with those already in ``replicated`` (their counts,
    multiplied as if nested)."""
    counts = {name: _counts(value) for name, value in attributes.items()}
    if element in _GRIDS:
        first, second = ((counts.get(name) or [1])[0] for name in _GRIDS[element])
        points = first * second
        if element == "texture" and attributes.get("type", "").strip() in ("cube", "skybox"):
            points = 6 * first**2
        if points > MAX_GRID_POINTS:
            raise ValueError(
                f"{where}: <{element} {' '.join(_GRIDS[element])}> asks for {points:,} points; "
                f"at most {MAX_GRID_POINTS:,} (4096 x 4096) are read, each held in memory"
            )
    elif element == "flexcomp" and math.prod(counts.get("count", [])) > MAX_REPLICATED:
        raise ValueError(
            f"{where}: <flexcomp count> asks for {math.prod(counts['count']):,} points; at most "
            f"{MAX_REPLICATED:,} are made"
        )
    elif element == "mesh" and attributes.get("builtin", "").strip():
        vertices = _builtin_vertices(attributes["builtin"].strip(), attributes.get("params", ""))
        if vertices > MAX_REPLICATED:
            raise ValueError(
                f"{where}: <mesh builtin params> asks for about {vertices:,.0f} vertices; at "
                f"most {MAX_REPLICATED:,} are made"
            )
    elif element == "replicate" and counts.get("count"):
        replicated.append(counts["count"][0])
        if math.prod(replicated) > MAX_REPLICATED:
            raise ValueError(
                f"{where}: <replicate count> makes the model's replicates "
                f"{' x '.join(map(str, replicated))} = {math.prod(replicated):,} copies; at "
                f"most {MAX_REPLICATED:,} are made"
            )


#: Built-in meshes whose vertices grow with their first parameter alone (a cone's ``2 nedge``);
#: the others' grow with its square or with the product of the first two.
_LINEAR_BUILTINS = {"cone": 2.0}


def _builtin_vertices(builtin: str, params: str) -> float:
    """About how many vertices MuJoCo makes for a built-in mesh ``builtin`` of ``params``: for
    a cone ``2 nedge``; otherwise the square of its first parameter (a supersphere's resolution
    ``n`` makes ``n² - n + 2``), or the product of its first two (a wedge's or a plate's grid)
    when larger; 0 when they are not numbers (MuJoCo says what is wrong)."""
    try:
        leading = [abs(float(word)) for word in params.split()[:2]]
    except ValueError:
        return 0.0
    if not leading:
        return 0.0
    if not all(math.isfinite(value) for value in leading):
        return math.inf
    if builtin in _LINEAR_BUILTINS:
        return _LINEAR_BUILTINS[builtin] * leading[0]
    return max(leading[0] ** 2, math.prod(leading))


def _counts(value: str) -> list[int]:
    """The whole numbers of an attribute's value, read as MuJoCo reads them (a ``+`` and
    leading zeros allowed): empty when it holds anything else (MuJoCo says what is wrong)."""
    numbers = []
    for word in value.split():
        digits = word.removeprefix("+").lstrip("0") or "0"
        if not (digits.isascii() and digits.isdigit()):
            return []
        numbers.append(int(digits) if len(digits) < 19 else 10**19)  # a bound beyond any
    return numbers


def _image_points(path: str) -> int | None:
    """The pixels of the PNG image at ``path`` (width x height from its header), None when it
    is not a PNG that can be read."""
    try:
        with open(path, "rb") as handle:
            header = handle.read(24)
    except OSError:
        return None
    if len(header) < 24 or header[:8] != b"\x89PNG\r\n\x1a\n" or header[12:16] != b"IHDR":
        return None
    return int.from_bytes(header[16:20], "big") * int.from_bytes(header[20:24], "big")


def _elements(text: str) -> Iterator[tuple[int, str, list[tuple[str, str]]]]:
    """The start tags of the XML ``text``, each as its line, name and attributes (values with
    XML's character references replaced), skipping comments and CDATA sections.

    As lenient as MuJoCo's XML reader (tinyxml2), which reads ``--`` inside a comment, and
    linear in the text's length whatever it holds; it expands no entity.
    """
    position, line, counted = 0, 1, 0
    while (start := text.find("<", position)) >= 0:
        for opening, closing in (("<!--", "-->"), ("<![CDATA[", "]]>")):
            if text.startswith(opening, start):
                end = text.find(closing, start + len(opening))
                if end < 0:
                    return  # never closed: not XML that MuJoCo reads
                position = end + len(closing)
                break
        else:
            name = _TAG_NAME.match(text, start + 1)
            position = start + 1 if name is None else name.end()
            if name is None:
                continue
            attributes = []
            while (attribute := _ATTRIBUTE.match(text, position)) is not None:
                end = text.find(attribute.group(2), attribute.end())
                if end < 0:
                    return  # a value never closed
                value = _REFERENCE.sub(_character, text[attribute.end() : end])
                attributes.append((attribute.group(1), value))
                position = end + 1
            line += text.count("\n", counted, start)
            counted = start
            yield line, name.group(), attributes


def _character(reference: re.Match[str]) -> str:
    hexadecimal, decimal, named = reference.groups()
    if named is not None:
        return _NAMED[named]
    code = int(hexadecimal, 16) if hexadecimal is not None else int(decimal)
    return chr(code) if code <= sys.maxunicode else reference.group()


def _candidates(model: Path, name: _Name, folders: list[str]) -> list[str]:
    """Every path MuJoCo may read for ``name``: see the module docstring."""
    bases = [model.parent, name.source.parent]
    for folder in folders:
        bases += [Path(folder)] if os.path.isabs(folder) else [model.parent / folder]
    found = []
    for value in dict.fromkeys([name.value, os.path.basename(name.value)]):
        if not value:
            continue
        if os.path.isabs(value):
            found.append(value)
        else:
            found += [str(base / value) for base in bases]
    return list(dict.fromkeys(found))
