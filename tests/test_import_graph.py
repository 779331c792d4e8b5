"""Arrows point down: the package's import graph, read from its source, has no circle, and no
module imports names back from the package root (which imports nearly everything).

Every ``import`` counts, at module level and inside functions alike (a lazy import is still an
arrow); imports under ``if TYPE_CHECKING:`` are annotations only and do not count. An arrow
goes where the import really runs code: importing ``a.b.c`` also runs the ``__init__`` of ``a``
and of ``a.b`` (unless the importer lives in them); a package whose ``__init__`` loads its names
when first used (``lazy_loader.attach_stub``) runs only its own imports, and a name read from it
(``from a.b import Name``, or ``a.b.Name``) loads the module its ``__init__.pyi`` names.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "delaytrack"


def _modules(package: Path = PACKAGE) -> dict[str, Path]:
    found = {}
    for path in package.rglob("*.py"):
        parts = path.relative_to(package.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        found[name] = path
    return found


MODULES = _modules()


def _imports(module: str, path: Path) -> list[tuple[str, list[str]]]:
    """``(imported module, names)`` for every import of the file, outside TYPE_CHECKING; a
    module imported whole also yields each dotted name read through it (``m.Name``), as
    ``("m.Name", [])``."""
    skipped: set[int] = set()
    tree = ast.parse(path.read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            skipped.update(id(child) for child in ast.walk(node))
    read = {
        dotted
        for node in ast.walk(tree)
        if isinstance(node, ast.Attribute) and id(node) not in skipped
        if (dotted := ast.unparse(node)).replace(".", "").isidentifier()
    }
    found = []
    package = module if path.stem == "__init__" else module.rpartition(".")[0]
    for node in ast.walk(tree):
        if id(node) in skipped:
            continue
        if isinstance(node, ast.Import):
            for alias in node.names:
                bound = alias.asname or alias.name.partition(".")[0]
                named = alias.name if alias.asname else bound
                found.append((alias.name, []))
                found += [
                    (named + dotted[len(bound) :], [])
                    for dotted in read
                    if dotted.startswith(f"{bound}.")
                ]
        elif isinstance(node, ast.ImportFrom):
            base = package.split(".")[: len(package.split(".")) - node.level + 1]
            target = ".".join(base + [node.module]) if node.level else (node.module or "")
            if node.level and not node.module:
                target = ".".join(base)
            found.append((target, [alias.name for alias in node.names]))
    return found


def _stub_names(modules: dict[str, Path]) -> dict[str, dict[str, str]]:
    """For each package whose ``__init__`` loads its names when first used
    (``lazy_loader.attach_stub``): each name of its ``__init__.pyi`` and the module that the stub
    imports it from."""
    lazy = {}
    for module, path in modules.items():
        stub = path.with_suffix(".pyi")
        if path.name == "__init__.py" and stub.exists() and "attach_stub" in path.read_text():
            lazy[module] = {
                name: target for target, names in _imports(module, stub) for name in names
            }
    return lazy


def _ancestors(module: str) -> set[str]:
    """The packages whose ``__init__`` importing ``module`` runs first: ``a`` and ``a.b`` for
    ``a.b.c``."""
    parts = module.split(".")
    return {".".join(parts[:end]) for end in range(1, len(parts))}


def _module_of(name: str, modules: dict[str, Path], stubs: dict[str, dict[str, str]]) -> str | None:
    """The package's module that importing or reading ``name`` (a module, or a name in one)
    loads: a name of a lazy package's stub is looked for where the stub imports it from."""
    module = name
    while module and module not in modules:
        module = module.rpartition(".")[0]
    if not module:
        return None
    first = name[len(module) + 1 :].partition(".")[0]
    if first in stubs.get(module, {}):
        return _module_of(f"{stubs[module][first]}.{first}", modules, stubs)
    return module


def _graph(modules: dict[str, Path] = MODULES) -> dict[str, set[str]]:
    """Each module's arrows: the modules its imports load, and the packages around them whose
    ``__init__`` those imports run (not the importer's own, which already run)."""
    stubs = _stub_names(modules)
    edges: dict[str, set[str]] = {name: set() for name in modules}
    for module, path in modules.items():
        for target, names in _imports(module, path):
            for name in names or [""]:
                found = _module_of(f"{target}.{name}" if name else target, modules, stubs)
                if found is not None:
                    runs = {found} | (_ancestors(found) & modules.keys())
                    edges[module] |= runs - _ancestors(module) - {module}
    return edges


def _circles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    circles: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(edges[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                circles.append(sorted(component))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return circles


@pytest.fixture(scope="module")
def package_graph() -> dict[str, set[str]]:
    """The package's import graph (:func:`_graph`), read once for the tests that only read it."""
    return _graph()


def test_the_import_graph_has_no_circle(package_graph):
    assert _circles(package_graph) == []


def test_the_check_finds_a_circle():
    assert _circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


#: A package ``__init__`` that imports its names when first used, as the package's are.
_LAZY_INIT = (
    "import lazy_loader\n"
    "__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)\n"
)


@pytest.mark.parametrize(
    ("sub_init", "low_imports", "circle"),
    [
        # Module to module, low -> sub.b is no circle; but it runs sub's __init__, which
        # imports sub.a, which imports low.
        (
            "from pkg.sub.a import A\n",
            "from pkg.sub.b import B",
            ["pkg.low", "pkg.sub", "pkg.sub.a"],
        ),
        # A lazy __init__ imports nothing ...
        (_LAZY_INIT, "from pkg.sub.b import B", []),
        # ... until a name is read from it: A is loaded from sub.a.
        (_LAZY_INIT, "from pkg.sub import A", ["pkg.low", "pkg.sub.a"]),
    ],
)
def test_the_check_finds_a_circle_through_a_package_init(
    tmp_path: Path, sub_init: str, low_imports: str, circle: list[str]
):
    """The graph counts the ``__init__`` that an import runs, and the module that a name read
    from a lazy package loads; Python agrees: importing ``pkg.low`` first fails on a circle."""
    sub = tmp_path / "pkg" / "sub"
    sub.mkdir(parents=True)
    (tmp_path / "pkg" / "__init__.py").write_text("")
    (sub / "__init__.py").write_text(sub_init)
    (sub / "__init__.pyi").write_text("from .a import A\nfrom .b import B\n")
    (sub / "a.py").write_text("from pkg.low import helper\n\nA = helper\n")
    (sub / "b.py").write_text("B = 2\n")
    (tmp_path / "pkg" / "low.py").write_text(f"{low_imports}\n\nhelper = 1\n")
    assert _circles(_graph(_modules(tmp_path / "pkg"))) == ([circle] if circle else [])
    first = subprocess.run(
        [sys.executable, "-c", "import pkg.low"], cwd=tmp_path, capture_output=True, text=True
    )
    assert ("ImportError" in first.stderr) == bool(circle), first.stderr


def test_no_module_imports_names_back_from_the_package_root():
    back = [
        f"{module}: {name}"
        for module, path in MODULES.items()
        if module != "delaytrack"
        for target, names in _imports(module, path)
        if target == "delaytrack"
        for name in names
        if f"delaytrack.{name}" not in MODULES
    ]
    assert back == []


def _within(module: str, package: str) -> bool:
    return module == package or module.startswith(f"{package}.")


def _reachable(edges: dict[str, set[str]], start: str) -> set[str]:
    """Every module that importing ``start`` imports, directly or through others."""
    seen: set[str] = set()
    stack = [start]
    while stack:
        for target in edges[stack.pop()]:
            if target not in seen:
                seen.add(target)
                stack.append(target)
    return seen


def _modules_in(package: str) -> list[str]:
    found = [module for module in MODULES if _within(module, package)]
    assert found, f"no module in {package}"
    return found


@pytest.mark.parametrize("package", ["delaytrack.sweeps", "delaytrack.scenario"])
def test_the_studies_stand_above_sweeps_and_scenarios(package: str, package_graph):
    """The studies (``experiments``) use sweeps and scenarios, never the other way round: no
    module of ``package`` reaches ``experiments``, not even through a third module."""
    edges = package_graph
    upward = sorted(
        f"{module} -> {target}"
        for module in _modules_in(package)
        for target in _reachable(edges, module)
        if _within(target, "delaytrack.experiments")
    )
    assert upward == []


def test_studies_return_results_and_jobs_write_their_reports(package_graph):
    """A study (``experiments``) returns its result and imports neither a report nor a job; a
    report renders results and reaches no job: :mod:`delaytrack.jobs` runs a study and writes
    its report. (A study reaches :mod:`delaytrack.report.figures` only through
    :mod:`delaytrack.sim`, whose ``SimResult.plot`` draws with it.)"""
    edges = package_graph
    upward = sorted(
        f"{module} -> {target}"
        for module in _modules_in("delaytrack.experiments")
        for target in edges[module]
        if _within(target, "delaytrack.report") or _within(target, "delaytrack.jobs")
    )
    upward += sorted(
        f"{module} -> {target}"
        for module in _modules_in("delaytrack.report")
        for target in _reachable(edges, module)
        if _within(target, "delaytrack.jobs")
    )
    assert upward == []


def test_a_scenario_is_read_built_and_run_without_the_packages_above_it(package_graph):
    """``scenario`` imports neither reports nor the packages that use scenarios. (Through
    :mod:`delaytrack.sim` it reaches :mod:`delaytrack.report.figures`: ``SimResult.plot`` draws
    with it.)"""
    above = ("experiments", "report", "sweeps", "cli", "live")
    edges = package_graph
    upward = sorted(
        f"{module} -> {target}"
        for module in _modules_in("delaytrack.scenario")
        for target in edges[module]
        if any(_within(target, f"delaytrack.{package}") for package in above)
    )
    assert upward == []


def test_the_floor_check_follows_imports_through_other_modules():
    edges = {"low.a": {"mid"}, "mid": {"high.b"}, "high.b": set()}
    assert _reachable(edges, "low.a") == {"mid", "high.b"}


@pytest.mark.parametrize("package", ["delaytrack.experiments", "delaytrack.report"])
def test_studies_and_reports_never_reach_into_the_compile_machinery(package: str, package_graph):
    """The compile machinery (``delaytrack._compile``) is the engine's business: the studies and
    their reports call :func:`delaytrack.sim.simulate` (and its public helpers such as
    ``compile_ahead``), never a module of ``_compile`` directly."""
    edges = package_graph
    direct = sorted(
        f"{module} -> {target}"
        for module in _modules_in(package)
        for target in edges[module]
        if _within(target, "delaytrack._compile")
    )
    assert direct == []


@pytest.mark.parametrize("module", ["delaytrack", "delaytrack.cli", "delaytrack.live.cli"])
def test_the_root_and_a_live_node_load_no_heavy_library(module: str):
    """The package root imports its names when first used (``__init__.pyi``): importing it, the
    command line's entry or a live node's loads neither pandas nor PyArrow, which only tables
    need, nor SciPy's linear algebra, optimisation, interpolation or statistics, which only a
    bound, a margin, a spline or a verdict needs (each half of a node's start-up time)."""
    heavy = {"pandas", "pyarrow"} | {
        f"scipy.{name}" for name in ("linalg", "optimize", "interpolate", "stats")
    }
    code = f"import sys, {module}; print(sorted(set(sys.modules) & {heavy!r}))"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"


def test_the_jobs_load_scipys_statistics_only_when_a_verdict_needs_them():
    """The jobs import the studies, whose intervals and tests use SciPy's statistics; those
    (0.4 s) wait for the first interval or test, not the jobs' import."""
    modules = "delaytrack.jobs.paper, delaytrack.experiments.decision_study"
    code = f"import sys, {modules}; print('scipy.stats' in sys.modules)"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "False"


def test_every_name_of_the_root_resolves():
    """Each name of ``delaytrack.__all__`` (from ``__init__.pyi``) is found where it lives (an
    import that fails raises here), among them the entry points the README's examples use."""
    import delaytrack

    assert {"simulate", "AROLC", "CompiledPlant", "razumikhin_bound"} <= set(delaytrack.__all__)
    for name in delaytrack.__all__:
        getattr(delaytrack, name)


#: Where the circle was (the engine and the compile machinery), and the lowest modules of the
#: components, which most of the package imports: each is imported first in
#: :func:`test_the_core_modules_can_be_imported_first`.
CORE = ("delaytrack._compile", "delaytrack.sim")
LOWEST = (
    "delaytrack.components",
    "delaytrack.plants.base",
    "delaytrack.controllers.arolc",
    "delaytrack.delays._kernel",
    "delaytrack.references.base",
)


def test_the_core_modules_can_be_imported_first():
    """Each module of the engine and the compile machinery, and the lowest of the components,
    imports as the first of a fresh interpreter: whatever ``__init__`` it runs first, no module
    meets another half-initialised (the static check above covers every module; this runs
    Python's own import on the modules where a circle was). One interpreter for all: the
    package's modules are forgotten before each, the libraries stay loaded."""
    names = sorted(
        name for name in MODULES if any(_within(name, package) for package in CORE)
    ) + list(LOWEST)
    code = (
        "import importlib, sys\n"
        f"for name in {names!r}:\n"
        "    for loaded in [m for m in sys.modules if m.partition('.')[0] == 'delaytrack']:\n"
        "        del sys.modules[loaded]\n"
        "    try:\n"
        "        importlib.import_module(name)\n"
        "    except Exception as error:\n"
        "        print(f'{name}: {type(error).__name__}: {error}')\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout == ""
