"""The scenarios shipped with the package (``src/delaytrack/scenarios/*.toml``)."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from delaytrack._spec import SpecError as ScenarioError
from delaytrack.scenario.scenario import Scenario


def builtin_scenario_names() -> list[str]:
    """Names (file stems) of the scenario files shipped with the package."""
    folder = resources.files("delaytrack").joinpath("scenarios")
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def builtin_scenario_path(name: str) -> Path:
    """Path of a shipped scenario file, e.g. ``builtin_scenario_path("two_link_S1")``."""
    names = builtin_scenario_names()
    if name not in names:
        raise ScenarioError(f"no built-in scenario {name!r}; the built-in scenarios are {names}")
    return Path(str(resources.files("delaytrack").joinpath("scenarios", f"{name}.toml")))


def load_builtin(name: str) -> Scenario:
    """Load a shipped scenario by name (see :func:`builtin_scenario_names`)."""
    return Scenario.from_toml(builtin_scenario_path(name))


def scenario_file_or_builtin(text: str) -> Path:
    """The scenario file ``text`` names: a path (any existing file, or one ending in ``.toml``,
    which then says it is missing when read), else the shipped scenario of that name.

    Raises
    ------
    ScenarioError
        When ``text`` is neither, naming the shipped scenarios.
    """
    names = builtin_scenario_names()
    if not text:  # Path("") is the current folder
        raise ScenarioError(
            f"the scenario is an empty name; give a scenario file or one of {names}"
        )
    path = Path(text)
    if path.exists() or path.suffix == ".toml":
        return path
    if text in names:
        return builtin_scenario_path(text)
    raise ScenarioError(
        f"scenario file {text!r} does not exist (nor is it a built-in scenario; those are {names})"
    )
