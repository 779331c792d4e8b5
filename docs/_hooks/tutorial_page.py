"""A MkDocs hook: the notebook ``docs/tutorial.ipynb`` becomes the site's page ``tutorial/``.

The notebook is kept without outputs (``tests/test_tutorial.py`` checks it), so its page shows
what a reader runs: the Markdown cells as they are, each code cell as a Python code block, and a
link to download the notebook. The page is made from the notebook at every build, so it cannot
drift from it; nothing is executed and nothing is loaded from the network.

The Markdown pages link the notebook itself, ``tutorial.ipynb``, so that the link works where
the sources are read (a clone, a repository's web view); on the site such a link leads to the
page instead (:func:`on_page_markdown`), and only the page's own download link to the notebook.

It is loaded by ``mkdocs.yml`` (``hooks``) and changes nothing in the package itself.
"""

from __future__ import annotations

from typing import Any

import nbformat
from mkdocs.structure.files import File, Files

#: The notebook in ``docs/`` and the page made from it.
NOTEBOOK = "tutorial.ipynb"
PAGE = "tutorial.md"

_OPEN = (
    "[Download this notebook]({notebook}) and open it in the environment where you installed"
    " `delaytrack[tutorial]`: `jupyter notebook {notebook}`. This page shows its text and code;"
    " running it draws the figures and prints the tables."
)


def notebook_markdown(source: str, notebook: str) -> str:
    """The Markdown page of a notebook: its first cell, the download note, then every cell.

    Parameters
    ----------
    source : str
        The notebook file's text (nbformat 4).
    notebook : str
        The notebook's file name, for the download link.

    Returns
    -------
    str
        Markdown cells verbatim and code cells as fenced ``python`` blocks, in order.
    """
    blocks = []
    for cell in nbformat.reads(source, as_version=4).cells:
        if cell.cell_type == "markdown":
            blocks.append(cell.source)
        elif cell.cell_type == "code":
            blocks.append(f"```python\n{cell.source}\n```")
    blocks.insert(1, _OPEN.format(notebook=notebook))
    return "\n\n".join(blocks) + "\n"


def on_files(files: Files, *, config: Any) -> Files:
    """Add the page made from the notebook to the site's files."""
    notebook = files.get_file_from_path(NOTEBOOK)
    if notebook is None:
        raise FileNotFoundError(f"docs/{NOTEBOOK} is missing")
    content = notebook_markdown(notebook.content_string, NOTEBOOK)
    files.append(File.generated(config, PAGE, content=content))
    return files


def on_page_markdown(markdown: str, *, page: Any, config: Any, files: Files) -> str:
    """On the site, a page's link to the notebook leads to the page made from it (the
    notebook's own page keeps its download link)."""
    if page.file.src_uri == PAGE:
        return markdown
    return markdown.replace(f"]({NOTEBOOK})", f"]({PAGE})").replace(f"]({NOTEBOOK}#", f"]({PAGE}#")
