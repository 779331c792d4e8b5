"""A scenario or sweep file is not a program: the factories it may name, and factories that exit.

A factory (``type = "python:..."``) in a file read from disk runs only from a ``.py`` file in
that file's folder or below it (not in a hidden folder, a folder of installed code, a Python
environment or installation, nor where Python or this package is installed), or when the user
trusts it (``--trust``, ``trust=``); anything else is refused, naming the key, before anything
is imported. What runs is the file as read, never a ``.pyc`` shipped beside it, and numba's
disk cache of its kernels never binds them to another module. A factory that exits or is
interrupted is reported as that factory's.
"""

from __future__ import annotations

import importlib
import marshal
import os
import re
import subprocess
import sys
import sysconfig
import tempfile
import uuid
from pathlib import Path
from types import SimpleNamespace
from unittest import mock

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import delaytrack
from delaytrack import _spec, _trust
from delaytrack.cli import main
from delaytrack.scenario import Scenario, ScenarioError, dumps_toml
from delaytrack.sweeps import SweepError, SweepSpec
from test_hostile_inputs import one_line_error
from test_scenario import base_dict
from test_user_components import _CACHED_KERNEL

#: A factory that builds the package's two-link arm.
ARM_FACTORY = "import delaytrack as dt\n\ndef make():\n    return dt.TwoLinkArm()\n"


def scenario_file(folder: Path, plant: dict, name: str = "case.toml") -> Path:
    """A short two-link scenario in ``folder`` whose ``[plant]`` is ``plant``."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    path.write_text(dumps_toml({**base_dict(), "duration": 0.1, "plant": plant}))
    return path


def refused(capsys, argv: list[str], *words: str) -> str:
    """The command ends with exit 2 and one line naming ``words`` and why a factory is refused."""
    assert main(argv) == 2
    return one_line_error(capsys, *words, "Python code that runs with your rights", "--trust")


# ---- the campaign's two cases ------------------------------------------------------------------


def test_a_scenario_file_naming_a_shell_command_runs_nothing(tmp_path, capsys):
    touched = tmp_path / "touched"
    path = scenario_file(
        tmp_path / "sent",
        {"type": "python:subprocess:getoutput", "cmd": f"touch {touched}"},
    )
    refused(
        capsys,
        ["simulate", str(path), "--out", str(tmp_path / "out")],
        "'plant.type'",
        "'python:subprocess:getoutput'",
        "module 'subprocess', which is not trusted",
        "--trust subprocess",
    )
    with pytest.raises(ScenarioError, match=r"'plant.type' = 'python:subprocess:getoutput'"):
        Scenario.from_toml(path)
    assert main(["empirical", str(path), "--threshold", "1"]) == 2
    one_line_error(capsys, "'plant.type'", "not trusted")
    assert not touched.exists()
    assert not (tmp_path / "out").exists()


def test_a_scenario_file_naming_os_remove_deletes_nothing(tmp_path, capsys):
    thesis = tmp_path / "mine" / "thesis.tex"
    thesis.parent.mkdir()
    thesis.write_text("years of work\n")
    path = scenario_file(tmp_path / "sent", {"type": "python:os:remove", "path": str(thesis)})
    argv = ["simulate", str(path), "--out", str(tmp_path / "out")]
    refused(capsys, argv, "'plant.type' = 'python:os:remove'", "module 'os'")
    with pytest.raises(ScenarioError, match="not trusted"):
        Scenario.from_toml(path).build()
    assert thesis.read_text() == "years of work\n"


def test_a_sweep_file_naming_a_shell_command_runs_nothing(tmp_path, capsys):
    touched = tmp_path / "touched"
    sweep = tmp_path / "sent" / "sweep.toml"
    sweep.parent.mkdir()
    sweep.write_text(
        'scenario = "two_link_S1"\nunit_size = 1\n[grid]\n'
        f'plant = [{{type = "python:subprocess:getoutput", cmd = "touch {touched}"}}]\n'
    )
    refused(
        capsys,
        ["sweep", str(sweep), "--out", str(tmp_path / "out"), "--quiet"],
        'grid."plant"',
        "'python:subprocess:getoutput'",
    )
    sweep.write_text(
        'scenario = "two_link_S1"\nunit_size = 1\n[random]\n'
        '"delay.type" = {dist = "choice", values = ["S1", "python:delaytrack._io:write_text"]}\n'
        "draws = 2\nseed = 0\n"
    )
    with pytest.raises(
        SweepError, match=r"random.\"delay.type\": .*'delaytrack._io'.* not trusted"
    ):
        SweepSpec.from_toml(sweep)
    assert not touched.exists()


def test_a_function_a_trusted_file_imports_is_not_a_factory(tmp_path, capsys):
    """A file beside the scenario is trusted for the factories written in it; a scenario sent
    into that folder cannot reach what the file imported (``system`` here) to run a command."""
    touched = tmp_path / "touched"
    folder = tmp_path / "project"
    folder.mkdir()
    (folder / "helpers.py").write_text("from os import system\n\n" + ARM_FACTORY)
    path = scenario_file(
        folder, {"type": "python:helpers.py:system", "command": f"touch {touched}"}
    )
    assert main(["simulate", str(path), "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, "'system' is not defined in", "(it comes from 'posix')")
    assert not touched.exists()
    made = scenario_file(folder, {"type": "python:helpers.py:make"}, name="made.toml")
    assert Scenario.from_toml(made).build().plant.n == 2  # its own factory still runs


def test_a_partial_written_in_the_file_is_a_factory_and_a_dict_of_ones_own_may_name_imports(
    tmp_path, monkeypatch
):
    """The rule is for files someone may have sent: a partial of the file's own function is
    its factory, and a scenario made in Python (the user's own code) names what it likes."""
    folder = tmp_path / "project"
    folder.mkdir()
    (folder / "arms.py").write_text(
        ARM_FACTORY + "\n\nimport functools\n\nmake_again = functools.partial(make)\n"
    )
    again = scenario_file(folder, {"type": "python:arms.py:make_again"})
    assert Scenario.from_toml(again).build().plant.n == 2
    (folder / "uses.py").write_text("from arms import make\n")
    monkeypatch.syspath_prepend(str(folder))
    data = {**base_dict(), "duration": 0.1, "plant": {"type": f"python:{folder / 'uses.py'}:make"}}
    assert Scenario.from_dict(data).build().plant.n == 2
    imported = scenario_file(folder, {"type": "python:uses.py:make"}, name="uses.toml")
    with pytest.raises(ScenarioError, match=r"'make' is not defined in .*uses\.py.* 'arms'"):
        Scenario.from_toml(imported)


def test_a_package_may_name_a_factory_of_its_submodule_but_not_an_import(tmp_path, lab):
    (tmp_path / "site" / lab / "__init__.py").write_text(
        "from subprocess import getoutput\n\nfrom .robots import make\n"
    )
    reexported = scenario_file(tmp_path / "case", {"type": f"python:{lab}:make"})
    assert Scenario.from_toml(reexported, trust=[lab]).build().plant.n == 2
    imported = scenario_file(
        tmp_path / "case", {"type": f"python:{lab}:getoutput", "cmd": "true"}, name="x.toml"
    )
    with pytest.raises(ScenarioError, match=r"'getoutput' is not defined in .*'subprocess'"):
        Scenario.from_toml(imported, trust=[lab])


# ---- files: beside the scenario, or trusted ------------------------------------------------


def test_a_factory_file_beside_or_below_the_scenario_runs_without_trust(tmp_path, capsys):
    (tmp_path / "parts").mkdir()
    (tmp_path / "parts" / "arm_below.py").write_text(ARM_FACTORY)
    path = scenario_file(tmp_path, {"type": "python:parts/arm_below.py:make"})
    assert Scenario.from_toml(path).build().plant.n == 2


def test_a_factory_file_that_escapes_the_folder_is_refused_and_not_imported(tmp_path, capsys):
    marker = tmp_path / "imported"
    (tmp_path / "escape_evil.py").write_text(
        f"open({str(marker)!r}, 'w').close()\n\ndef make():\n    return None\n"
    )
    path = scenario_file(tmp_path / "sent", {"type": "python:../escape_evil.py:make"})
    err = refused(
        capsys,
        ["simulate", str(path), "--out", str(tmp_path / "out")],
        "'plant.type' = 'python:../escape_evil.py:make'",
        f"names {tmp_path / 'escape_evil.py'}",
        f"neither in {tmp_path / 'sent'}",
        f"--trust {tmp_path}",
    )
    assert err.count("\n") == 1
    with pytest.raises(ScenarioError, match="nor trusted"):
        Scenario.from_toml(path)
    assert not marker.exists()


def test_a_link_inside_the_folder_to_a_file_outside_is_refused(tmp_path, capsys):
    marker = tmp_path / "imported"
    outside = tmp_path / "elsewhere" / "linked_evil.py"
    outside.parent.mkdir()
    outside.write_text(f"open({str(marker)!r}, 'w').close()\n\ndef make():\n    return None\n")
    folder = tmp_path / "sent"
    folder.mkdir()
    (folder / "robot.py").symlink_to(outside)
    path = scenario_file(folder, {"type": "python:robot.py:make"})
    refused(capsys, ["simulate", str(path)], "'plant.type'", f"names {outside}")
    (folder / "lib").symlink_to(outside.parent, target_is_directory=True)
    path = scenario_file(folder, {"type": "python:lib/linked_evil.py:make"})
    with pytest.raises(ScenarioError, match="nor trusted"):
        Scenario.from_toml(path)
    assert not marker.exists()


def test_a_file_elsewhere_runs_when_its_folder_or_itself_is_trusted(tmp_path, capsys, monkeypatch):
    lab = tmp_path / "lab"
    lab.mkdir()
    (lab / "arm_elsewhere.py").write_text(ARM_FACTORY)
    factory = f"python:{lab / 'arm_elsewhere.py'}:make"
    path = scenario_file(tmp_path / "case", {"type": factory})
    with pytest.raises(ScenarioError, match="nor trusted"):
        Scenario.from_toml(path)
    for trust in ([str(lab)], [str(lab / "arm_elsewhere.py")], [f"{lab}/sub/.."]):
        assert Scenario.from_toml(path, trust=trust).plant["type"] == factory
    (lab / "other.py").write_text("")
    with pytest.raises(ScenarioError, match="nor trusted"):  # another file of that folder
        Scenario.from_toml(path, trust=[str(lab / "other.py")])
    # "lab" without a '/' is a module name; meant for the folder here, the message says so
    monkeypatch.chdir(tmp_path)
    with pytest.raises(
        ScenarioError, match=re.escape("the trusted name 'lab' was read as a module name")
    ):
        Scenario.from_toml(path, trust=["lab"])
    out = tmp_path / "out"
    assert main(["simulate", str(path), "--out", str(out), "--trust", str(lab), "--quiet"]) == 0
    capsys.readouterr()
    # The scenario as run names the file by absolute path: loading it again from its results
    # folder needs the trust the message names.
    refused(
        capsys,
        ["simulate", str(out / "scenario.toml"), "--out", str(out)],
        f"--trust {lab}",
        f"trust=['{lab}']",
    )
    assert (
        main(
            [
                "simulate",
                str(out / "scenario.toml"),
                "--out",
                str(out),
                "--trust",
                str(lab),
                "--quiet",
            ]
        )
        == 0
    )


def test_the_scenario_as_run_loads_again_where_its_factory_is_below_it(tmp_path, capsys):
    (tmp_path / "arm_as_run.py").write_text(ARM_FACTORY)
    path = scenario_file(tmp_path, {"type": "python:arm_as_run.py:make"})
    assert main(["simulate", str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    saved = tmp_path / "out" / "scenario.toml"
    moved = tmp_path / "again.toml"  # the factory is below this file's folder
    moved.write_text(saved.read_text())
    assert f"python:{tmp_path / 'arm_as_run.py'}:make" in moved.read_text()
    assert Scenario.from_toml(moved).build().plant.n == 2
    with pytest.raises(ScenarioError, match=re.escape(f"--trust {tmp_path}")):
        Scenario.from_toml(saved)


def test_a_sweep_checks_its_own_factories_and_its_scenarios_in_their_folders(tmp_path, capsys):
    (tmp_path / "scenarios").mkdir()
    (tmp_path / "scenarios" / "arm_of_scenario.py").write_text(ARM_FACTORY)
    scenario_file(tmp_path / "scenarios", {"type": "python:arm_of_scenario.py:make"})
    sweep = tmp_path / "sweeps" / "sweep.toml"
    sweep.parent.mkdir()
    (sweep.parent / "arm_of_sweep.py").write_text(ARM_FACTORY)
    sweep.write_text(
        'scenario = "../scenarios/case.toml"\nunit_size = 1\n[grid]\n'
        'model = [{type = "python:arm_of_sweep.py:make"}, '
        '{type = "python:../scenarios/arm_of_scenario.py:make"}]\n'
    )
    with pytest.raises(SweepError, match=r'grid."model": .*arm_of_scenario.py.* nor trusted'):
        SweepSpec.from_toml(sweep)
    spec = SweepSpec.from_toml(sweep, trust=[str(tmp_path / "scenarios")])
    assert len(spec.runs) == 2
    out = ["--out", str(tmp_path / "out"), "--quiet"]
    refused(capsys, ["sweep", str(sweep), *out], 'grid."model"', "arm_of_scenario.py")
    assert main(["sweep", str(sweep), *out, "--trust", str(tmp_path / "scenarios")]) == 0


# ---- below the folder, but not its own code ----------------------------------------------------


def marking(marker: Path) -> str:
    """A module that creates ``marker`` when it is imported and has a factory ``make``."""
    return f"open({str(marker)!r}, 'w').close()\n\ndef make(**keys):\n    return None\n"


@pytest.mark.parametrize(
    ("folders", "setup", "reason"),
    [
        # A scenario saved in a home folder naming Python's own library under ~/.pyenv
        ((".pyenv", "versions", "3.11.7", "lib", "python3.11"), None, "inside the hidden folder"),
        (
            ("env", "lib", "python3.11", "site-packages", "pkg"),
            "env/pyvenv.cfg",
            "it holds pyvenv.cfg",
        ),
        (("lab", "site-packages", "pkg"), None, "a folder of installed Python packages"),
        (("tools", "dist-packages"), None, "a folder of installed Python packages"),
        (("web", "node_modules", "pkg"), None, "a folder of installed packages"),
        (("robots", "__pycache__"), None, "a folder of compiled Python code"),
        (("python", "lib", "python3.12"), None, "a Python installation (it holds lib/python3.12)"),
        # An unpacked Python source tree, whose standard library a scenario could call into
        (
            ("Python-3.11.7", "Lib"),
            "Python-3.11.7/Lib/os.py",
            "a copy of Python's standard library (it holds os.py)",
        ),
        # An unpacked package downloaded from PyPI (setuptools' spawn runs a command)
        (
            ("setuptools-69.0.0", "setuptools", "_distutils"),
            "setuptools-69.0.0/PKG-INFO",
            "an unpacked source distribution (it holds PKG-INFO)",
        ),
        # pip install --target deps: the packages beside their records
        (
            ("deps",),
            "deps/nodeenv-1.12.0.dist-info/METADATA",
            "a folder of installed Python packages (it holds nodeenv-1.12.0.dist-info)",
        ),
        # PEP 582's local packages
        (("__pypackages__", "3.11", "lib"), None, "(PEP 582)"),
    ],
)
def test_a_file_below_the_folder_in_installed_or_hidden_code_is_refused(
    tmp_path, capsys, folders, setup, reason
):
    marker = tmp_path / "imported"
    below = tmp_path.joinpath(*folders)
    below.mkdir(parents=True)
    if setup:
        (tmp_path / setup).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / setup).write_text("home = /usr/bin\n")
    (below / "shutil_like.py").write_text(marking(marker))
    relative = "/".join([*folders, "shutil_like.py"])
    path = scenario_file(tmp_path, {"type": f"python:{relative}:make", "path": "victim"})
    file = below / "shutil_like.py"
    err = refused(
        capsys,
        ["simulate", str(path), "--out", str(tmp_path / "out")],
        f"'plant.type' = 'python:{relative}:make' names {file}",
        f"which is below {tmp_path} (the folder of case.toml) but",
        reason,
        f"--trust {file}",
    )
    assert "nor below" not in err
    with pytest.raises(ScenarioError, match=re.escape(reason)):
        Scenario.from_toml(path)
    assert not marker.exists()
    # Trusted, it is imported (its factory returns no plant).
    with pytest.raises(ScenarioError, match="must return an ELPlant"):
        Scenario.from_toml(path, trust=[str(file)]).build()
    assert marker.exists()


def test_a_file_where_python_or_this_package_is_installed_is_refused_below_the_folder(
    tmp_path, monkeypatch
):
    package = Path(delaytrack.__file__).resolve().parent
    stdlib = Path(sysconfig.get_paths()["stdlib"]).resolve()
    prefix = Path(sys.prefix).resolve()
    for folder, place, file, what in [
        # a scenario saved above the source of this package, naming its writing function
        (package.parent, package, package / "_io.py", "where delaytrack is installed"),
        (stdlib, stdlib, stdlib / "shutil.py", "Python's standard library"),
        (prefix, prefix, prefix / "any.py", "where this Python is installed (sys.prefix)"),
    ]:
        source = folder / "case.toml"  # only its folder is read
        with pytest.raises(_spec.SpecError, match=re.escape(f"but inside {place}, {what}")):
            _trust.check_factory("plant.type", "python:f.py:g", str(file), source, _trust.Trust())
    # From a scenario file: a folder of installed code that no name gives away.
    marker = tmp_path / "imported"
    (tmp_path / "lib").mkdir()
    (tmp_path / "lib" / "installed_mod.py").write_text(marking(marker))
    installed = ((tmp_path / "lib", "a folder of installed Python packages"),)
    monkeypatch.setattr(_trust, "installed_locations", lambda: installed)
    path = scenario_file(tmp_path, {"type": "python:lib/installed_mod.py:make"})
    with pytest.raises(
        ScenarioError, match=f"but inside {tmp_path / 'lib'}, a folder of installed"
    ):
        Scenario.from_toml(path)
    assert not marker.exists()


def test_the_example_folder_runs_without_trust():
    example = Path(__file__).resolve().parent.parent / "examples" / "user_arm"
    scenario = Scenario.from_toml(example / "arm_S1.toml")
    assert scenario.plant["type"] == f"python:{example / 'arm.py'}:make_arm"
    assert len(SweepSpec.from_toml(example / "sweep_arm.toml").runs) > 1


# ---- modules: trusted by name ----------------------------------------------------------------


@pytest.fixture
def lab(tmp_path, monkeypatch) -> str:
    """An importable package ``trustlab_<n>`` with a submodule ``robots`` holding ``make``."""
    name = f"trustlab_{uuid.uuid4().hex[:8]}"
    package = tmp_path / "site" / name
    package.mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "robots.py").write_text(ARM_FACTORY)
    monkeypatch.syspath_prepend(str(tmp_path / "site"))
    return name


def test_a_module_runs_only_when_it_or_its_package_is_trusted(tmp_path, lab, capsys):
    path = scenario_file(tmp_path / "case", {"type": f"python:{lab}.robots:make"})
    with pytest.raises(ScenarioError, match=f"module '{lab}.robots', which is not trusted"):
        Scenario.from_toml(path)
    with pytest.raises(ScenarioError, match="not trusted"):  # a name that merely starts alike
        Scenario.from_toml(path, trust=[lab[:-1]])
    with pytest.raises(ScenarioError, match="not trusted"):  # a submodule trusts no parent
        Scenario.from_toml(path, trust=[f"{lab}.robots.arm"])
    assert f"{lab}.robots" not in sys.modules
    for trust in ([lab], [f"{lab}.robots"]):
        assert Scenario.from_toml(path, trust=trust).build().plant.n == 2
    out = ["--out", str(tmp_path / "out"), "--quiet"]
    refused(capsys, ["simulate", str(path), *out], f"--trust {lab}.robots")
    assert main(["simulate", str(path), *out, "--trust", "os", "--trust", lab]) == 0


def test_the_packages_own_modules_are_not_trusted_by_default(tmp_path):
    written = tmp_path / "written"
    path = scenario_file(
        tmp_path / "sent",
        {"type": "python:delaytrack._io:write_text", "text": "x", "path": str(written)},
    )
    with pytest.raises(ScenarioError, match="module 'delaytrack._io', which is not trusted"):
        Scenario.from_toml(path)
    assert not written.exists()


@pytest.mark.parametrize(
    ("names", "message"),
    [
        ("mylab", r"trust must be a list of module names or paths"),
        (["my-lab"], r"trust 'my-lab' is neither a module name"),
        ([""], r"trust takes module names or paths \(text\); got ''"),
        ([3], r"trust takes module names or paths"),
        (["./no_such_folder"], r"trust './no_such_folder': no such file or folder"),
        (["case.toml.py"], r"no such file or folder"),
    ],
)
def test_trust_names_that_are_not_a_module_or_a_python_file_or_folder_are_refused(
    tmp_path, names, message
):
    path = scenario_file(tmp_path, {"type": "two-link-arm"})
    with pytest.raises(ValueError, match=message):
        Scenario.from_toml(path, trust=names)
    with pytest.raises(ValueError, match=message):
        SweepSpec.from_toml(tmp_path / "sweep.toml", trust=names)


def test_trust_options_that_are_not_a_module_or_a_python_file_or_folder_are_refused(
    tmp_path, capsys
):
    path = scenario_file(tmp_path, {"type": "two-link-arm"})
    for name, words in [
        ("my-lab", ["--trust 'my-lab' is neither a module name"]),
        (str(path), ["is a file but not Python (.py)"]),
        (str(tmp_path / "missing"), ["no such file or folder"]),
    ]:
        assert main(["simulate", str(path), "--trust", name]) == 2
        one_line_error(capsys, *words)
        assert main(["sweep", str(tmp_path / "sweep.toml"), "--trust", name]) == 2
        one_line_error(capsys, *words)


# ---- factories that exit or are interrupted --------------------------------------------------


def test_a_factory_that_exits_is_an_error_naming_it(tmp_path, capsys):
    (tmp_path / "exits_zero.py").write_text("def make():\n    raise SystemExit(0)\n")
    path = scenario_file(tmp_path, {"type": "python:exits_zero.py:make"})
    kind = f"python:{tmp_path / 'exits_zero.py'}:make"
    with pytest.raises(
        ScenarioError, match=re.escape(f"'plant.type' = '{kind}' raised SystemExit(0)")
    ):
        Scenario.from_toml(path).build()
    assert main(["simulate", str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    one_line_error(capsys, f"'plant.type' = '{kind}' raised SystemExit(0)", "must not exit")


def test_a_factory_module_that_exits_on_import_is_an_error_naming_it(tmp_path, capsys):
    (tmp_path / "exits_three.py").write_text("import sys\nsys.exit(3)\n")
    path = scenario_file(tmp_path, {"type": "python:exits_three.py:make"})
    with pytest.raises(ScenarioError, match=r"'plant.type' = .* raised SystemExit\(3\) while"):
        Scenario.from_toml(path)
    assert main(["simulate", str(path), "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, "'plant.type'", "exits_three.py:make' raised SystemExit(3)")
    assert "exits_three" not in sys.modules


def test_a_factory_interrupted_says_which_and_exits_130(tmp_path, capsys):
    (tmp_path / "interrupted_make.py").write_text("def make():\n    raise KeyboardInterrupt\n")
    (tmp_path / "interrupted_import.py").write_text("raise KeyboardInterrupt\n")
    for module, words in [
        ("interrupted_make", "interrupted in the factory of scenario key 'plant.type' = "),
        ("interrupted_import", "interrupted while importing "),
    ]:
        path = scenario_file(tmp_path, {"type": f"python:{module}.py:make"})
        with pytest.raises(KeyboardInterrupt, match=f"{words}.*{module}.py"):
            Scenario.from_toml(path).build()
        assert main(["simulate", str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 130
        err = capsys.readouterr().err
        assert err.startswith(words) and err.count("\n") == 1 and f"{module}.py" in err, err


# ---- what runs: the file as read, and kernels bound to their own module ---------------------


def shipped_pyc(source: Path, code: str) -> Path:
    """A ``__pycache__`` entry beside ``source`` whose header matches the source's time and size
    (Python's import runs it instead of the source) and whose code is ``code``."""
    stat = source.stat()
    pyc = Path(importlib.util.cache_from_source(str(source)))
    pyc.parent.mkdir(exist_ok=True)
    header = importlib.util.MAGIC_NUMBER + (0).to_bytes(4, "little")
    header += int(stat.st_mtime).to_bytes(4, "little") + (stat.st_size & 0xFFFFFFFF).to_bytes(
        4, "little"
    )
    pyc.write_bytes(header + marshal.dumps(compile(code, str(source), "exec")))
    return pyc


def test_a_pyc_shipped_beside_a_factory_file_or_its_neighbour_never_runs(tmp_path, monkeypatch):
    """A harmless ``.py`` (what one reviews, and trusts by path) with a harmful ``.pyc``."""
    monkeypatch.setattr(sys, "dont_write_bytecode", False)
    harmful = f"open({str(tmp_path / 'ran')!r}, 'w').close()\n"
    neighbour = f"pyc_neighbour_{uuid.uuid4().hex[:8]}"
    folder = tmp_path / "sent"
    folder.mkdir()
    (folder / f"{neighbour}.py").write_text("SIZE = 2\n")
    (folder / "pyc_arm.py").write_text(f"import {neighbour}\n\n{ARM_FACTORY}")
    shipped_pyc(folder / "pyc_arm.py", f"{harmful}import {neighbour}\n\n{ARM_FACTORY}")
    shipped_pyc(folder / f"{neighbour}.py", f"{harmful}SIZE = 2\n")
    # Imported the usual way, the .pyc runs: the trick works on this Python.
    spec = importlib.util.spec_from_file_location("pyc_probe", folder / f"{neighbour}.py")
    spec.loader.exec_module(importlib.util.module_from_spec(spec))
    assert (tmp_path / "ran").exists()
    (tmp_path / "ran").unlink()
    path = scenario_file(folder, {"type": "python:pyc_arm.py:make"})
    assert Scenario.from_toml(path).build().plant.n == 2
    assert sys.modules[neighbour].SIZE == 2
    assert not (tmp_path / "ran").exists()


#: Builds the factory of each folder's ``robot.py`` in turn and prints, for each, the name of
#: its module, whether numba loaded its kernel from the disk cache, and the file of the module
#: the loaded kernel is bound to.
_BUILD_EACH = (
    "import sys; from delaytrack._spec import user_factory\n"
    "for folder in sys.argv[1:]:\n"
    "    kernel = user_factory('plant', f'python:{folder}/robot.py:make')().kernel\n"
    "    (compiled,) = kernel.overloads.values()\n"
    "    print(kernel.py_func.__module__, sum(kernel.stats.cache_hits.values()),\n"
    "          compiled.environment.globals['__file__'])\n"
)


def test_a_cached_kernel_is_bound_to_its_own_file_whatever_name_its_module_had(tmp_path):
    """Two ``robot.py`` in one process (a sweep): the second is ``robot_<hash>``, and numba's
    cache entry of its kernel names that module. Alone, it is ``robot``: that entry failed with
    ModuleNotFoundError in every later process; and an entry made there, naming ``robot``, was
    bound to the other file's module when both ran again."""
    a, b = tmp_path / "A", tmp_path / "B"
    for folder in (a, b):
        folder.mkdir()
        (folder / "robot.py").write_text(_CACHED_KERNEL)  # a kernel cached on disk
    environment = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}

    def build(*folders: Path) -> list[list[str]]:
        completed = subprocess.run(
            [sys.executable, "-c", _BUILD_EACH, *map(str, folders)],
            cwd=tmp_path,
            env=environment,
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert completed.returncode == 0, completed.stderr[-2000:]
        return [line.split() for line in completed.stdout.splitlines()]

    first_a, first_b = build(a, b)
    assert first_a == ["robot", "0", str(a / "robot.py")]
    assert first_b[0].startswith("robot_") and first_b[1:] == ["0", str(b / "robot.py")]
    assert build(b) == [["robot", "0", str(b / "robot.py")]]  # compiled again, not an error
    # B's entry now names "robot", which is A here: it is not bound to A, B is compiled again.
    assert build(a, b) == [
        ["robot", "1", str(a / "robot.py")],
        [first_b[0], "0", str(b / "robot.py")],
    ]


# ---- the property ------------------------------------------------------------------------------

segments = st.lists(
    st.sampled_from(["..", ".", "lab", "sent", "deep", ".hidden", "site-packages"]), max_size=5
)
identifiers = st.from_regex(r"[a-z_][a-z0-9_]{0,6}", fullmatch=True)
#: Dotted names; one ending in ".py" would be a file.
dotted = (
    st.lists(identifiers, min_size=1, max_size=3)
    .map(".".join)
    .filter(lambda name: not name.endswith(".py"))
)


@settings(
    max_examples=60,
    derandomize=True,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
@given(
    parts=segments,
    module=dotted,
    trusted=st.lists(dotted, max_size=2),
)
def test_a_factory_is_imported_exactly_when_it_is_allowed(parts, module, trusted):
    """For any relative path and any module name, the factory is imported only when its file
    lies in the scenario's folder or below, and not in a hidden folder or a folder of installed
    packages on the way, or its module (or a package above it) is trusted; anything else is
    refused naming the key, with nothing imported."""
    imported = []

    def spy(location):
        imported.append(str(location))
        raise ImportError("spied")

    with tempfile.TemporaryDirectory() as root:
        folder = Path(root).resolve() / "sent"
        relative = "/".join([*parts, "factory.py"])
        file = Path(os.path.normpath(folder / relative))
        inside = file.is_relative_to(folder) and not (
            {".hidden", "site-packages"} & set(file.relative_to(folder).parts)
        )
        allowed = any(module == name or module.startswith(f"{name}.") for name in trusted)
        with (
            mock.patch.object(_spec, "module_from_file", spy),
            mock.patch.object(
                _spec, "importlib", SimpleNamespace(import_module=spy, util=importlib.util)
            ),
        ):
            for kind, expected in [
                (f"python:{relative}:make", inside),
                (f"python:{module}:make", allowed),
            ]:
                imported.clear()
                path = scenario_file(folder, {"type": kind})
                with pytest.raises(ScenarioError) as refusal:
                    Scenario.from_toml(path, trust=trusted)
                message = str(refusal.value)
                assert ("cannot import" in message) == expected, message
                assert bool(imported) == expected, (kind, imported)
                if not expected:
                    assert "'plant.type'" in message and "trust" in message


def test_a_session_folder_someone_sent_runs_no_code_for_lying_in_it(tmp_path, capsys):
    """``live replay DIR`` opens the folder's scenario.toml, a file the user did not name: a
    factory beside it runs only when trusted (the nodes name theirs by absolute path)."""
    session = tmp_path / "session"
    marker = tmp_path / "ran"
    (session / "helpers.py").parent.mkdir()
    (session / "helpers.py").write_text(
        f"from pathlib import Path\n\ndef f():\n    Path({str(marker)!r}).touch()\n"
        "    import delaytrack as dt\n    return dt.TwoLinkArm()\n"
    )
    scenario_file(session, {"type": "python:helpers.py:f"}, name="scenario.toml")
    (session / "summary.json").write_text("{}")
    refused(capsys, ["live", "replay", str(session)], "not trusted for being there")
    assert not marker.exists()
    # trusted, it is the user's choice: it loads (and the folder, holding no tables, is refused)
    assert main(["live", "replay", str(session), "--trust", str(session / "helpers.py")]) == 2
    assert marker.exists() and "not trusted" not in capsys.readouterr().err


def test_a_project_installed_for_development_keeps_its_own_code(tmp_path):
    """``pip install -e .`` leaves ``src/<name>.egg-info`` beside the project's own packages:
    not a folder of installed code (a ``*.dist-info`` beside them, as ``pip install --target``
    leaves, is: see the test above)."""
    (tmp_path / "src" / "lab.egg-info").mkdir(parents=True)
    (tmp_path / "src" / "lab.egg-info" / "PKG-INFO").write_text("Name: lab\n")
    (tmp_path / "src" / "arm.py").write_text(ARM_FACTORY)
    path = scenario_file(tmp_path, {"type": "python:src/arm.py:make"})
    assert Scenario.from_toml(path).plant["type"].endswith("arm.py:make")
