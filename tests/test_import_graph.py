"""Arrows point down: the package's import graph, read from its source, has no circle, and no
module imports names back from the package root (which imports nearly everything).

Every ``import`` counts, at module level and inside functions alike (a lazy import is still an
arrow); imports under ``if TYPE_CHECKING:`` are annotations only and do not count.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "delaytrack"


def _modules() -> dict[str, Path]:
    found = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        found[name] = path
    return found


MODULES = _modules()


def _module_of(name: str) -> str | None:
    """The package's module that ``name`` (a module or a name in one) lives in."""
    while name and name not in MODULES:
        name = name.rpartition(".")[0]
    return name or None


def _imports(module: str, path: Path) -> list[tuple[str, list[str]]]:
    """``(imported module, names)`` for every import of the file, outside TYPE_CHECKING."""
    skipped: set[int] = set()
    tree = ast.parse(path.read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            skipped.update(id(child) for child in ast.walk(node))
    found = []
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    for node in ast.walk(tree):
        if id(node) in skipped:
            continue
        if isinstance(node, ast.Import):
            found += [(alias.name, []) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = package.split(".")[: len(package.split(".")) - node.level + 1]
            target = ".".join(base + [node.module]) if node.level else (node.module or "")
            if node.level and not node.module:
                target = ".".join(base)
            found.append((target, [alias.name for alias in node.names]))
    return found


def _graph() -> dict[str, set[str]]:
    edges: dict[str, set[str]] = {name: set() for name in MODULES}
    for module, path in MODULES.items():
        for target, names in _imports(module, path):
            for name in names or [""]:
                found = _module_of(f"{target}.{name}" if name else target)
                if found is not None and found != module:
                    edges[module].add(found)
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


def test_the_import_graph_has_no_circle():
    assert _circles(_graph()) == []


def test_the_check_finds_a_circle():
    assert _circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


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
def test_the_studies_stand_above_sweeps_and_scenarios(package: str):
    """The studies (``experiments``) use sweeps and scenarios, never the other way round: no
    module of ``package`` reaches ``experiments``, not even through a third module."""
    edges = _graph()
    upward = sorted(
        f"{module} -> {target}"
        for module in _modules_in(package)
        for target in _reachable(edges, module)
        if _within(target, "delaytrack.experiments")
    )
    assert upward == []


def test_a_scenario_is_read_built_and_run_without_the_packages_above_it():
    """``scenario`` imports neither reports nor the packages that use scenarios. (Through
    :mod:`delaytrack.sim` it reaches :mod:`delaytrack.report.figures`: ``SimResult.plot`` draws
    with it.)"""
    above = ("experiments", "report", "sweeps", "cli", "live")
    edges = _graph()
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
def test_studies_and_reports_never_reach_into_the_compile_machinery(package: str):
    """The compile machinery (``delaytrack._compile``) is the engine's business: the studies and
    their reports call :func:`delaytrack.sim.simulate` (and its public helpers such as
    ``compile_ahead``), never a module of ``_compile`` directly."""
    edges = _graph()
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


def test_every_name_of_the_root_resolves():
    """Each name of ``delaytrack.__all__`` (from ``__init__.pyi``) is found where it lives (an
    import that fails raises here), among them the entry points the README's examples use."""
    import delaytrack

    assert {"simulate", "AROLC", "CompiledPlant", "razumikhin_bound"} <= set(delaytrack.__all__)
    for name in delaytrack.__all__:
        getattr(delaytrack, name)
