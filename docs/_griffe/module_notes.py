"""A griffe extension for the documentation site: "(module docstring)" becomes that text, or
names the module.

A few public classes state their model in their module's docstring and point at it from their
own summary (``Lost command packets (module docstring).``): a reader of the source finds it at
the top of the file. The site documents such a class on its own, away from its module, so this
extension removes the pointer and puts the module docstring's body (everything after its
summary line) right after the class's summary. Anywhere else the pointer names its module
(``(see module `delaytrack.sim.integrator`)``), whose page or source holds the text.

It is loaded by ``mkdocs.yml`` (``extensions`` of the Python handler) and changes nothing in the
package itself.
"""

from __future__ import annotations

from typing import Any

import griffe

#: The pointer, as the docstrings write it.
POINTER = " (module docstring)"


def with_module_notes(summary_and_rest: str, module_docstring: str) -> str:
    """The docstring without the pointer, the module docstring's body after its summary.

    Parameters
    ----------
    summary_and_rest : str
        A docstring whose summary paragraph holds :data:`POINTER`.
    module_docstring : str
        The docstring of the module that defines it.

    Returns
    -------
    str
        ``summary + module body + rest``, paragraphs separated by blank lines.
    """
    summary, _, rest = summary_and_rest.replace(POINTER, "", 1).partition("\n\n")
    _, _, body = module_docstring.partition("\n\n")
    return "\n\n".join(part for part in (summary, body.strip(), rest) if part)


def _walk(obj: griffe.Object, seen: set[int]) -> None:
    if id(obj) in seen:
        return
    seen.add(id(obj))
    docstring = obj.docstring
    if docstring is not None and obj.is_class and obj.module.docstring is not None:
        summary = docstring.value.partition("\n\n")[0]
        if POINTER in summary:
            docstring.value = with_module_notes(docstring.value, obj.module.docstring.value)
    if docstring is not None and POINTER in docstring.value:  # anywhere else: say which module
        docstring.value = docstring.value.replace(POINTER, f" (see module `{obj.module.path}`)")
    for member in obj.members.values():
        if not member.is_alias:
            _walk(member, seen)


class ModuleNotes(griffe.Extension):
    """Inline the module docstring a public class points at (see the module docstring)."""

    def on_package(self, *, pkg: griffe.Module, **kwargs: Any) -> None:
        _walk(pkg, set())
