"""The documentation site: ``mkdocs build --strict`` (what ``make docs`` runs) passes, and the
pages and API entries a reader looks for are in it.

The build reads the docstrings statically (griffe), so it imports nothing from the package and
takes a few seconds. Any warning fails it: a broken link or anchor, a page missing from the
navigation, a docstring parameter that is not in the signature, an unresolved cross-reference.
"""

from __future__ import annotations

import importlib
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import delaytrack

ROOT = Path(__file__).resolve().parents[1]

#: API pages (docs/api/<page>.md) and the subpackage each documents.
SUBPACKAGES = (
    "sim",
    "controllers",
    "plants",
    "delays",
    "references",
    "analysis",
    "metrics",
    "scenario",
    "experiments",
    "sweeps",
    "report",
)


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The site built by ``mkdocs build --strict`` into a temporary folder."""
    out = tmp_path_factory.mktemp("site")
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    completed = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(out)],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    log = completed.stdout + completed.stderr
    assert completed.returncode == 0, f"mkdocs build --strict failed:\n{log}"
    assert "WARNING" not in log, log
    return out


def page(site: Path, name: str) -> str:
    path = site / name / "index.html" if name else site / "index.html"
    assert path.is_file(), f"{path.relative_to(site)} was not built"
    return path.read_text(encoding="utf-8")


def anchors(html: str) -> set[str]:
    return set(re.findall(r'id="([^"]+)"', html))


@pytest.mark.parametrize(
    "name",
    [
        "",
        "getting-started",
        "tutorial",
        "your-own-robot",
        "paper-symbols",
        "decisions",
        "margins",
        "robot",
        "performance",
        "sweeps",
        "robustness",
        "reliability",
        "api",
        "api/delaytrack",
        *(f"api/{sub}" for sub in SUBPACKAGES),
    ],
)
def test_page_is_built(site: Path, name: str) -> None:
    assert "delaytrack" in page(site, name)


def test_every_markdown_page_is_built(site: Path) -> None:
    for source in (ROOT / "docs").rglob("*.md"):
        relative = source.relative_to(ROOT / "docs").with_suffix("")
        if relative.name == "index":
            relative = relative.parent
        page(site, "" if relative == Path() else relative.as_posix())


def nav_pages() -> list[tuple[str, str]]:
    """``(title, file)`` of every page in ``mkdocs.yml``'s navigation, in order."""
    text = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    nav = text.split("\nnav:\n", 1)[1].split("\n\n", 1)[0]
    return re.findall(r"^\s+- ([^:\n]+): (\S+\.md)$", nav, re.M)


def test_the_tutorial_notebook_is_a_page_in_the_navigation(site: Path) -> None:
    """docs/tutorial.ipynb is rendered (its text and code, maths typeset) and in the menu, with
    the notebook itself beside it to download."""
    assert ("Tutorial", "tutorial.md") in nav_pages()
    html = page(site, "tutorial")
    assert "Tutorial: your own robot joint behind a late, jittery link" in html
    assert "error_loop_frequency_response" in html and 'class="arithmatex"' in html
    assert 'href="../tutorial.ipynb"' in html and (site / "tutorial.ipynb").is_file()
    # the guides link the notebook (a link that works in a clone); on the site, its page
    assert "](tutorial.ipynb)" in (ROOT / "docs" / "index.md").read_text()
    assert 'href="tutorial/"' in page(site, "") and 'href="tutorial.ipynb"' not in page(site, "")
    assert re.search(
        r'<a href="tutorial/" class="md-nav__link">\s*<span[^>]*>\s*Tutorial', page(site, "")
    )


def test_the_index_lists_each_page_once_by_its_title() -> None:
    """docs/index.md links every page of the menu once, by the menu's title (the API reference
    by its overview)."""
    text = (ROOT / "docs" / "index.md").read_text()
    # the notebook is linked as itself, which works in a clone; the site links its page
    links = [
        (title, target.replace(".ipynb", ".md"))
        for title, target in re.findall(r"\[([^\]]+)\]\(([^)#]+\.(?:md|ipynb))\)", text)
    ]
    assert len(links) == len({target for _, target in links}), links
    guides = [(title, path) for title, path in nav_pages() if not path.startswith("api/")]
    assert sorted(links) == sorted([*guides[1:], ("API reference", "api/index.md")])


def test_pages_load_nothing_from_the_network(site: Path) -> None:
    """No script, stylesheet or font from a CDN: the maths is typeset by the KaTeX copy the site
    serves itself, and the theme uses the reader's fonts."""
    for html_file in site.rglob("*.html"):
        html = html_file.read_text(encoding="utf-8")
        remote = re.findall(r'<(?:script|link|img)\b[^>]*(?:src|href)="(?:https?:)?//[^"]*"', html)
        assert not remote, f"{html_file.relative_to(site)} loads {remote[:2]}"
        assert "cdn" not in " ".join(re.findall(r"<script\b[^>]*>", html)).lower()
    margins = page(site, "margins")
    assert 'class="arithmatex"' in margins and "vendor/katex/katex.min.js" in margins
    for name in ("katex.min.js", "katex.min.css", "contrib/auto-render.min.js", "LICENSE"):
        assert (site / "vendor" / "katex" / name).is_file(), name
    fonts = {path.name for path in (site / "vendor" / "katex" / "fonts").glob("*.woff2")}
    needed = set(
        re.findall(
            r"url\(fonts/([^)]+\.woff2)\)",
            (site / "vendor" / "katex" / "katex.min.css").read_text(),
        )
    )
    assert needed and needed <= fonts


def test_the_sim_page_starts_with_simulate(site: Path) -> None:
    html = page(site, "api/sim")
    order = [
        html.index(f'id="{anchor}"')
        for anchor in (
            "delaytrack.sim.simulate.simulate",
            "delaytrack.sim.SimResult",
            "delaytrack.sim.MeasurementNoise",
            "delaytrack.sim.PacketLoss",
        )
    ]
    assert order == sorted(order)
    assert "module docstring" not in html
    # The class carries the model its module's docstring states.
    assert "Encoder quantisation and white noise on what the controller reads." in html
    assert "At controller tick" in html


@pytest.mark.parametrize(
    "name", ["controllers", "metrics", "plants", "experiments", "sweeps", "references", "sim"]
)
def test_no_api_page_points_at_a_module_docstring_it_does_not_show(site: Path, name: str) -> None:
    """A docstring's "(module docstring)" means the top of its source file; on the site it names
    the module instead (docs/_griffe/module_notes.py)."""
    assert "module docstring" not in page(site, f"api/{name}")


def test_module_names_in_tables_do_not_break(site: Path) -> None:
    css = (site / "stylesheets" / "extra.css").read_text()
    assert re.search(r"td:first-child code \{[^}]*white-space: nowrap", css)
    assert "stylesheets/extra.css" in page(site, "api")


def test_user_pages_work_outside_the_checkout() -> None:
    """The pages a user follows name commands as installed, never a path into the clone's
    .venv (they run in the environment where delaytrack is installed)."""
    for name in ("index.md", "getting-started.md", "your-own-robot.md", "tutorial.ipynb"):
        text = (ROOT / "docs" / name).read_text()
        assert not re.search(r"\.venv/bin/(?!activate\b)", text), name


def test_error_loop_is_reachable_from_the_package_root() -> None:
    from delaytrack.analysis import control_export

    for name in ("error_loop", "error_loop_frequency_response", "error_loop_sampled"):
        assert name in delaytrack.__all__
        assert getattr(delaytrack, name) is getattr(control_export, name)


def test_api_pages_document_the_main_entry_points(site: Path) -> None:
    sim = page(site, "api/sim")
    # griffe keeps the submodule sim/simulate.py under the name `simulate`, so the function
    # is rendered from its module (docs/api/sim.md).
    assert "delaytrack.sim.simulate.simulate" in anchors(sim)
    assert "delaytrack.sim.SimResult" in anchors(sim)
    assert "Parameters:" in sim and "t1" in sim and "T_c" in sim
    controllers = anchors(page(site, "api/controllers"))
    assert {"delaytrack.controllers.AROLC", "delaytrack.controllers.OuterLoop"} <= controllers
    analysis = anchors(page(site, "api/analysis"))
    assert {
        "delaytrack.analysis.razumikhin_bound",
        "delaytrack.analysis.exact_delay_margin",
        "delaytrack.analysis.design_gains",
        "delaytrack.analysis.ultimate_bounds.ultimate_bounds",
    } <= analysis


@pytest.mark.parametrize("sub", SUBPACKAGES)
def test_every_exported_name_is_documented(site: Path, sub: str) -> None:
    """Each name in a subpackage's ``__all__`` has an entry on its page (a name shadowed by a
    submodule of the same name is rendered from that submodule)."""
    ids = anchors(page(site, f"api/{sub}"))
    module = importlib.import_module(f"delaytrack.{sub}")
    missing = [
        name
        for name in module.__all__
        if f"delaytrack.{sub}.{name}" not in ids and f"delaytrack.{sub}.{name}.{name}" not in ids
    ]
    assert not missing, f"not documented on api/{sub}: {missing}"


def test_top_level_page_links_every_public_name(site: Path) -> None:
    html = page(site, "api/delaytrack")
    links = set(re.findall(r'href="[^"#]*#(delaytrack\.[^"]+)"', html))
    linked = {target.split(".")[-1] for target in links}
    missing = [name for name in delaytrack.__all__ if name != "__version__" and name not in linked]
    assert not missing, f"docs/api/delaytrack.md does not link {missing}"


def test_sphinx_roles_are_rendered_not_shown(site: Path) -> None:
    """The docstrings' Sphinx roles (``:class:`X```) become links or code on the site."""
    for sub in ("", *SUBPACKAGES):
        html = page(site, f"api/{sub}" if sub else "api/delaytrack")
        leaked = re.findall(r":(?:class|func|meth|attr|mod|data|exc|obj):`", html)
        assert not leaked, f"api/{sub} shows Sphinx roles: {leaked[:3]}"


def test_the_roles_extension_resolves_names_in_scope(tmp_path: Path) -> None:
    """docs/_griffe/sphinx_roles.py: a role becomes an optional autoref to the full path of the
    name as the docstring's module sees it; a function shadowed by its submodule is found."""
    import griffe

    package = tmp_path / "pkg"
    package.mkdir()
    (package / "__init__.py").write_text(
        '"""See :func:`run`, :class:`~pkg.things.Thing` and :mod:`pkg.things`."""\n'
        "from pkg.run import run\nfrom pkg.things import Thing\n"
    )
    (package / "run.py").write_text(
        'def run():\n    """Uses :class:`Unknown`::\n\n        x\n    """\n'
    )
    (package / "things.py").write_text('class Thing:\n    """A thing."""\n')
    extensions = griffe.load_extensions(
        str(ROOT / "docs" / "_griffe" / "sphinx_roles.py") + ":SphinxRoles"
    )
    loaded = griffe.load("pkg", search_paths=[tmp_path], extensions=extensions)
    text = loaded.docstring.value
    assert '<autoref identifier="pkg.run.run" optional><code>run()</code></autoref>' in text
    assert '<autoref identifier="pkg.things.Thing" optional><code>Thing</code></autoref>' in text
    assert '<autoref identifier="pkg.things" optional><code>pkg.things</code></autoref>' in text
    assert loaded["run"].members["run"].docstring.value.startswith("Uses `Unknown`:\n")


def test_pages_cite_the_paper(site: Path) -> None:
    for name in ("getting-started", "api"):
        text = " ".join(page(site, name).split())
        assert "S. Roy and I. N. Kar" in text
        assert "Adaptive-Robust Control of a Class of Nonlinear Systems with Unknown" in text
