"""A griffe extension for the documentation site: Sphinx roles in docstrings become links.

The package's docstrings use Sphinx's cross-reference roles (``:class:`SimResult```,
``:func:`~delaytrack.sim.simulate```). Markdown has no such syntax, so this extension rewrites
each role into an optional cross-reference of mkdocs-autorefs: a link when the target is on the
site, plain code when it is not (a private module, a name from another library), never a
warning. Names are resolved in the scope of the docstring's object, as Python would find them
(members, imports, enclosing class and module). Sphinx's literal-block marker ``::`` at the end
of a line becomes ``:``, since Markdown shows the indented block as code already.

It is loaded by ``mkdocs.yml`` (``extensions`` of the Python handler) and changes nothing in the
package itself.
"""

from __future__ import annotations

import html
import re
from typing import Any

import griffe

_ROLE = re.compile(
    r":(?:py:)?(?P<role>class|func|meth|attr|mod|data|exc|obj|const|type):"
    r"`(?P<tilde>~?)(?P<name>[^`<>]+?)`(?:\\ )?"
)
_LITERAL_MARKER = re.compile(r"(?<=\S)::[ \t]*$", flags=re.MULTILINE)
_BARE_LITERAL_MARKER = re.compile(r"^[ \t]*::[ \t]*$", flags=re.MULTILINE)


def _resolve(obj: griffe.Object, name: str, role: str) -> str | None:
    """The full path of ``name`` as seen from ``obj``, or None."""
    name = name.strip().rstrip("()")
    if name.startswith(f"{obj.package.name}."):
        path = name
    else:
        head, _, rest = name.partition(".")
        try:
            path = obj.resolve(head)
        except (griffe.NameResolutionError, griffe.AliasResolutionError, KeyError):
            return None
        path = f"{path}.{rest}" if rest else path
    return _unshadow(obj.package, path) if role != "mod" else path


def _unshadow(package: griffe.Module, path: str) -> str:
    """``a.b.f.f`` for ``a.b.f`` when ``a/b/f.py`` defines ``f`` and ``a.b`` imports it.

    Griffe keeps the submodule where Python keeps the imported function (a known limitation of
    its object tree), so a role that names the function would point at the module.
    """
    head, _, rest = path.partition(".")
    if head != package.name or not rest:
        return path
    try:
        target = package[rest]
    except (KeyError, griffe.AliasResolutionError, griffe.CyclicAliasError):
        return path
    if target.is_module and target.name in target.members:
        return f"{path}.{target.name}"
    return path


def _rewrite(obj: griffe.Object, text: str) -> str:
    def replace(match: re.Match[str]) -> str:
        name = match["name"].strip()
        shown = name.rsplit(".", 1)[-1] if match["tilde"] else name
        if match["role"] in ("func", "meth") and not shown.endswith(")"):
            shown += "()"
        path = _resolve(obj, name, match["role"])
        if path is None:
            return f"`{shown}`"
        return (
            f'<autoref identifier="{html.escape(path)}" optional>'
            f"<code>{html.escape(shown)}</code></autoref>"
        )

    text = _ROLE.sub(replace, text)
    text = _BARE_LITERAL_MARKER.sub("", text)
    return _LITERAL_MARKER.sub(":", text)


def _walk(obj: griffe.Object, seen: set[int]) -> None:
    if id(obj) in seen:
        return
    seen.add(id(obj))
    if obj.docstring is not None:
        obj.docstring.value = _rewrite(obj, obj.docstring.value)
    for member in obj.members.values():
        if not member.is_alias:
            _walk(member, seen)


class SphinxRoles(griffe.Extension):
    """Rewrite Sphinx roles in every docstring of a loaded package (see the module docstring)."""

    def on_package(self, *, pkg: griffe.Module, **kwargs: Any) -> None:
        _walk(pkg, set())
