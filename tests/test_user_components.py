"""Components of your own in scenario and sweep files: plants, models, controllers, references,
delay profiles.

The shipped example ``examples/user_arm`` (a vertical two-link arm of its own, PD with gravity
compensation as a controller of its own, a spline reference) runs through every command; the
failure cases of a factory end in an error naming the table.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import subprocess
import sys
import uuid
from pathlib import Path

import numba
import numpy as np
import pandas as pd
import pytest
from scipy.interpolate import CubicSpline

import delaytrack as dt
from delaytrack._compile.native_entries import evaluate_step
from delaytrack.cli import main
from delaytrack.scenario import Scenario, ScenarioError
from delaytrack.sweeps import SweepError, SweepSpec
from delaytrack.sweeps.spec import engine_inputs

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "user_arm"


@pytest.fixture
def example(tmp_path: Path) -> Path:
    """A copy of the example folder, for tests that edit it.

    Tests that only read it use ``EXAMPLE`` itself: numba keys its disk cache by the kernel
    file's path, so every test that runs the shipped files shares one compiled engine.
    """
    folder = tmp_path / "user_arm"
    shutil.copytree(EXAMPLE, folder, ignore=shutil.ignore_patterns("__pycache__"))
    return folder


def short(folder: Path, into: Path | None = None, **changes) -> Path:
    """The example scenario, 1 s long, with ``changes`` to its tables, written into ``into``
    (beside it by default; its files are named by absolute path)."""
    scenario = Scenario.from_toml(folder / "arm_S1.toml")
    data = scenario.to_dict()
    data["duration"] = 1.0
    data["reference"] = {
        "type": "spline",
        "times": [0.0, 0.5, 1.0],
        "values": [[-1.2, 0.6], [-1.0, 0.8], [-0.9, 0.7]],
    }
    for key, value in changes.items():
        data[key] = value
    path = (into or folder) / "short.toml"
    path.write_text(Scenario.from_dict(data).to_toml())
    return path


def test_a_user_plant_model_and_reference_run_compiled_from_a_scenario_file(tmp_path):
    scenario = Scenario.from_toml(EXAMPLE / "arm_S1.toml")
    assert scenario.plant["type"] == f"python:{EXAMPLE / 'arm.py'}:make_arm"  # made absolute
    built = scenario.build()
    assert type(built.plant).__name__ == "CompiledPlant"
    assert built.plant.coordinate_names == ("shoulder", "elbow")
    assert built.model.params[0] == pytest.approx(0.8 * built.plant.params[0])
    # The scenario in tmp_path names the example's files: trusted, or they would be refused.
    result = Scenario.from_toml(short(EXAMPLE, tmp_path), trust=[str(EXAMPLE)]).run()
    assert result.settings["compiled"] and result.status_names == ["ok"]


def test_simulate_empirical_and_sweep_commands_take_them(tmp_path, capsys):
    path = short(EXAMPLE, tmp_path)
    out = tmp_path / "run"
    trust = ["--trust", str(EXAMPLE)]  # the files are the example's, not beside the scenario
    assert main(["simulate", str(path), "--out", str(out), *trust]) == 0
    metrics = pd.read_csv(out / "metrics.csv")
    assert {"ae_shoulder_rad", "ae_elbow_rad"} <= set(metrics.columns)
    assert (
        main(["empirical", str(path), "--threshold", "0.5", "--upper", "0.5", "--json", *trust])
        == 0
    )
    margin = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert margin["margin"] > 0
    text = (EXAMPLE / "sweep_arm.toml").read_text().replace("draws = 6", "draws = 1")
    text = text.replace('scenario = "arm_S1.toml"', 'scenario = "short.toml"')
    for name in ("pd_gravity.py", "congested_link.py"):  # the sweep is beside short.toml
        text = text.replace(f"python:{name}", f"python:{EXAMPLE / name}")
    sweep = tmp_path / "sweep_arm.toml"
    sweep.write_text(text)
    assert main(["sweep", str(sweep), "--out", str(tmp_path / "sweep"), "--quiet", *trust]) == 0
    summary = pd.read_csv(tmp_path / "sweep" / "summary.csv")
    assert set(summary["controller"]) == {"arolc", "make_pd_gravity"}
    assert (summary["runs"] > 0).all()


def test_the_user_controller_runs_compiled_and_matches_its_law(tmp_path):
    scenario = Scenario.from_toml(short(EXAMPLE, tmp_path), trust=[str(EXAMPLE)])
    table = {"type": "python:pd_gravity.py:make_pd_gravity", "K_P": [10.0, 2.0], "K_D": 1.0}
    data = scenario.to_dict()
    data["controller"] = {**table, "type": f"python:{EXAMPLE / 'pd_gravity.py'}:make_pd_gravity"}
    built = Scenario.from_dict(data).build()
    controller = built.controller
    assert controller.compiled
    q, qdot = np.array([0.3, -0.2]), np.array([0.1, 0.4])
    qd, qd_dot = np.array([0.5, 0.1]), np.array([0.0, 0.2])
    command, _ = controller.step(0.0, q, qdot, (qd, qd_dot, np.zeros(2)), np.zeros(0), T_c=0.002)
    gravity = built.model.nonlinear_terms(q, np.zeros(2))[0]
    expected = gravity + np.diag([10.0, 2.0]) @ (qd - q) + (qd_dot - qdot)
    np.testing.assert_allclose(command, expected, rtol=1e-13)


@pytest.mark.parametrize(
    ("kind", "message"),
    [
        ("python:arm.py", r"must name a factory as 'python:<module>:<function>'"),
        ("python:no_such_module_xyz:make", r"cannot import 'no_such_module_xyz'"),
        ("python:arm.py:make_robot", r"'.*arm.py' has no function 'make_robot'"),
        ("python:arm.py:GRAVITY", r"has no function 'GRAVITY'"),
        ("python:broken.py:make", r"cannot import .*ZeroDivisionError"),
        ("python:wrong.py:make", r"returned a float; a \[plant\] factory must return an ELPlant"),
        ("python:raises.py:make", r"\[plant\]: python:.* raised KeyError"),
    ],
)
def test_a_factory_that_cannot_be_used_is_refused_naming_the_table(example, kind, message):
    (example / "broken.py").write_text("1 / 0\n")
    (example / "wrong.py").write_text("def make():\n    return 3.0\n")
    (example / "raises.py").write_text("def make():\n    raise KeyError('mass')\n")
    path = short(example)
    path.write_text(path.read_text().replace(f"python:{example / 'arm.py'}:make_arm", kind, 1))
    trust = "no_such_module_xyz"  # a module is imported only when trusted
    with pytest.raises(ScenarioError, match=message):
        Scenario.from_toml(path, trust=[trust]).build()
    assert main(["simulate", str(path), "--out", str(example / "out"), "--trust", trust]) == 2


@pytest.mark.parametrize(
    ("factory", "key", "message"),
    [
        (
            "arm.py:make_arm",
            "mass_scael = 0.8",
            r"unknown key 'plant.mass_scael' in scenario; python:.*arm.py:make_arm takes the "
            r"keys \[.*'mass_scale'",
        ),
        (
            "checks.py:make",
            "kp = -1.0",
            r"^\S*short\.toml: scenario table \[plant\]: python:.*checks.py:make raised "
            r"ValueError: kp and kd "
            r"must be positive; got -1.0, 1.0$",
        ),
    ],
)
def test_a_factorys_keys_and_own_errors_are_reported_with_the_factory(
    example, factory, key, message
):
    """A key the factory does not take is refused with those it takes; the factory's own
    ValueError keeps its text (not rewritten into a key) and names the factory."""
    (example / "checks.py").write_text(
        "def make(kp=1.0, kd=1.0):\n"
        "    raise ValueError(f'kp and kd must be positive; got {kp}, {kd}')\n"
    )
    path = short(example)
    kind = f"python:{example / factory}"
    text = path.read_text().replace(f"python:{example / 'arm.py'}:make_arm", kind)
    path.write_text(text.replace(f'{kind}"\n', f'{kind}"\n{key}\n', 1))
    with pytest.raises(ScenarioError, match=message):
        Scenario.from_toml(path).build()


def test_sweep_parts_follow_the_controller_law_and_the_parameters(example):
    sweep = example / "sweep_arm.toml"
    hashes = [unit.hash for unit in SweepSpec.from_toml(sweep).units()]
    law = example / "pd_gravity.py"
    law.write_text(law.read_text().replace("tau[i] = nonlinear[i]", "tau[i] = 0.5 * nonlinear[i]"))
    changed = [unit.hash for unit in SweepSpec.from_toml(sweep).units()]
    assert [a == b for a, b in zip(hashes, changed, strict=True)] == [
        not any("make_pd_gravity" in str(run.scenario.controller["type"]) for run in unit.runs)
        for unit in SweepSpec.from_toml(sweep).units()
    ]
    arm = example / "arm.py"
    arm.write_text(arm.read_text().replace("m1: float = 1.0", "m1: float = 1.1"))
    massive = [unit.hash for unit in SweepSpec.from_toml(sweep).units()]
    assert not set(changed) & set(massive)
    link = example / "congested_link.py"
    link.write_text(link.read_text().replace("base + burst * 0.5 *", "base + burst * 0.4999 *"))
    units = SweepSpec.from_toml(sweep).units()
    assert [a == unit.hash for a, unit in zip(massive, units, strict=True)] == [
        not any("make_congested_link" in str(run.scenario.delay["type"]) for run in unit.runs)
        for unit in units
    ]


def test_a_users_file_neither_shadows_a_module_nor_misses_its_neighbours(example, tmp_path):
    import statistics

    (example / "statistics.py").write_text(
        "from arm import make_arm\n\ndef make(**keys):\n    return make_arm(**keys)\n"
    )
    path = short(example)
    path.write_text(path.read_text().replace("arm.py:make_arm", "statistics.py:make", 1))
    built = Scenario.from_toml(path).build()
    assert built.plant.coordinate_names == ("shoulder", "elbow")
    assert sys.modules["statistics"] is statistics


_CACHED_KERNEL = """
import numba
import delaytrack as dt

@numba.njit(cache=True)
def terms(t, q, qdot, params, M, N, G):
    M[0, 0] = params[0]
    N[0] = 0.0
    G[0, 0] = 1.0

def make(mass=2.0):
    return dt.CompiledPlant(1, 1, terms, [mass])
"""
#: The kernel's file run as a scenario names it, and as a session imports it; each prints
#: M(0) and how many times numba loaded the kernel from its disk cache.
_THROUGH_A_SCENARIO = (
    "import sys, numpy as np; from delaytrack._spec import user_factory; "
    "plant = user_factory('plant', 'python:' + sys.argv[1] + '/robot.py:make')(); "
    "print(plant.mass_matrix(np.zeros(1))[0, 0, 0], sum(plant.kernel.stats.cache_hits.values()))"
)
_IMPORTED = (
    "import sys, numpy as np; sys.path.insert(0, sys.argv[1]); import robot; "
    "print(robot.make().mass_matrix(np.zeros(1))[0, 0, 0], "
    "sum(robot.terms.stats.cache_hits.values()))"
)


@pytest.mark.parametrize(
    "order", [(_IMPORTED, _THROUGH_A_SCENARIO), (_THROUGH_A_SCENARIO, _IMPORTED)]
)
def test_a_cached_kernel_loads_in_a_scenario_and_in_a_session_whichever_compiled_it(
    order, tmp_path
):
    """numba's cache of a ``cache=True`` kernel names the kernel's module: a file named in a
    scenario is imported under the name that importing it gives, so either may use the other's
    compiled code (under another name, the second process failed with ModuleNotFoundError)."""
    folder = tmp_path / "user"
    folder.mkdir()
    (folder / "robot.py").write_text(_CACHED_KERNEL)
    environment = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    printed = []
    for code in order:
        completed = subprocess.run(
            [sys.executable, "-c", code, str(folder)],
            cwd=tmp_path,
            env=environment,
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert completed.returncode == 0, completed.stderr[-2000:]
        printed.append(completed.stdout.split())
    # The first compiles the kernel; the second loads what the first compiled.
    assert printed == [["2.0", "0"], ["2.0", "1"]]


def test_a_file_the_user_imported_is_that_module_in_a_scenario(example, monkeypatch):
    """Not a second copy: the scenario's plant uses the user's own kernel and classes."""
    monkeypatch.syspath_prepend(str(example))
    monkeypatch.delitem(sys.modules, "arm", raising=False)
    import arm

    built = Scenario.from_toml(short(example)).build()
    assert built.plant.kernel is arm.arm_terms
    assert sys.modules["arm"] is arm


def test_swept_files_are_relative_to_the_sweep_file(example):
    (example / "poses.csv").write_text("t,a,b\n0,-1.2,0.6\n0.5,-1.0,0.8\n1,-0.9,0.7\n")
    short(example)
    sweep = example / "files.toml"
    sweep.write_text(
        'scenario = "short.toml"\nunit_size = 1\n[grid]\n"reference.path" = ["poses.csv"]\n'
        '"reference.type" = ["spline"]\n'
    )
    with pytest.raises(SweepError, match="either"):  # times/values of the base and a path
        SweepSpec.from_toml(sweep)
    text = short(example).read_text()
    text = text[: text.index("[reference]")] + '[reference]\ntype = "spline"\npath = "x.csv"\n'
    (example / "short.toml").write_text(text)
    (example / "x.csv").write_text("t,a,b\n0,0,0\n1,0,0\n")
    spec = SweepSpec.from_toml(sweep)
    assert spec.runs[0].scenario.reference["path"] == str(example / "poses.csv")


def _scenario_with_a_law_numba_cannot_compile(example: Path) -> Path:
    """A scenario of the arm under ``pd_gravity.py`` with a misspelt name."""
    law = example / "pd_gravity.py"
    law.write_text(law.read_text().replace("tau[i] = nonlinear[i]", "tau[i] = nonlinaer[i]"))
    path = short(example)
    data = Scenario.from_toml(path).to_dict()
    data["controller"] = {
        "type": f"python:{law}:make_pd_gravity",
        "K_P": 1.0,
        "K_D": 1.0,
    }
    path.write_text(Scenario.from_dict(data).to_toml())
    return path


def test_a_kernel_numba_cannot_compile_is_a_one_line_error(example, capsys):
    path = _scenario_with_a_law_numba_cannot_compile(example)
    assert main(["simulate", str(path), "--out", str(example / "out")]) == 2
    err = capsys.readouterr().err
    assert "numba could not compile PDGravity's step on " in err and "Traceback" not in err
    assert "\x1b[" not in err  # numba's terminal colour codes are left out
    # The error is one line, the last; before it only the compile notice and the progress bar
    # (shown by default) may stand.
    lines = err.strip().splitlines()
    assert [line for line in lines if line.startswith("error:")] == [lines[-1]]
    assert main(["simulate", str(path), "--out", str(example / "out"), "--quiet"]) == 2
    quiet = capsys.readouterr().err.strip().splitlines()
    assert quiet[-1].startswith("error: ") and len(quiet) <= 2  # the notice, then the error


@pytest.mark.slow
def test_a_kernel_the_compile_helper_cannot_compile_is_reported_here(example, capsys, monkeypatch):
    from delaytrack._compile import helper_process as compile_helper
    from delaytrack._compile import stage as compiling

    # A new arm (another fingerprint at every run, never in the cache): its integrator and the
    # failing step both to compile, the step handed to a helper, which fails on it; this process
    # names it and stops the helper.
    arm = example / "arm.py"
    token = uuid.uuid4().int % 10**12
    unique = f"c2 = math.cos(q[1]) + 0.0 * params[0] * {token}"  # not folded: in the code
    arm.write_text(arm.read_text().replace("c2 = math.cos(q[1])", unique))
    monkeypatch.setenv(compile_helper.ENVIRONMENT, "1")
    started = []
    # A helper whatever the costs say, and the step is left to it: this process never claims
    # it (otherwise whichever process is free first takes it).
    steps: list[int] = []
    monkeypatch.setattr(compile_helper, "share", lambda costs, movable, start_up: list(steps))
    claim = compile_helper.Helper.claim
    monkeypatch.setattr(
        compile_helper.Helper,
        "claim",
        lambda self, position: position not in steps and claim(self, position),
    )

    def spy(jobs, ahead=lambda: None):
        steps[:] = [i for i, job in enumerate(jobs) if job.function is evaluate_step]
        helper, given = compile_helper.start(jobs, ahead)
        started.append((helper, given))
        return helper, given

    monkeypatch.setattr(compiling, "start_helper", spy)
    path = _scenario_with_a_law_numba_cannot_compile(example)
    assert main(["simulate", str(path), "--out", str(example / "out")]) == 2
    err = capsys.readouterr().err
    assert "numba could not compile PDGravity's step on " in err and "Traceback" not in err
    if not compile_helper.spare_core():
        pytest.skip("one core, or no lock on numba's cache: no helper")
    [(helper, given)] = started
    assert helper is not None and set(steps) <= set(given)  # the step went to the helper
    assert helper.process.returncode == 1  # it failed on the step and was waited for
    assert "(once in two processes;" in err  # the notice says so


@pytest.mark.slow  # compiles a new arm's integrator and two steps (about 15 s each)
@pytest.mark.parametrize("helper", ["0", "1"])
def test_steps_asked_for_ahead_are_compiled_at_the_first_compile(
    example, capsys, monkeypatch, helper
):
    from delaytrack._compile import helper_process as compile_helper
    from delaytrack._compile import interpret_first
    from delaytrack._compile.ahead import parts_ahead
    from delaytrack._compile.native_parts import controller_step_part
    from delaytrack._spec import module_from_file

    # A new arm and a new law (another fingerprint at every run, never in the cache): AROLC's
    # run compiles the arm's parts and, asked for ahead, the law's step, in one process or with
    # a helper; and a law that numba cannot compile, whose error is left to its own run.
    monkeypatch.setenv(compile_helper.ENVIRONMENT, helper)
    token = uuid.uuid4().int % 10**12
    arm = example / "arm.py"
    unique = f"c2 = math.cos(q[1]) + 0.0 * params[0] * {token}"  # not folded: in the code
    arm.write_text(arm.read_text().replace("c2 = math.cos(q[1])", unique))
    law = example / "pd_gravity.py"
    text = law.read_text().replace(
        "tau[i] = nonlinear[i]", f"tau[i] = nonlinear[i] + 0.0 * params[0] * {token}"
    )
    law.write_text(text)
    (example / "bad_law.py").write_text(text.replace("tau[i] = nonlinear", "tau[i] = nonlinaer"))
    built = Scenario.from_toml(short(example)).build()
    rival = module_from_file(law).make_pd_gravity(built.model, 16.0, 8.0)
    bad = module_from_file(example / "bad_law.py").make_pd_gravity(built.model, 16.0, 8.0)
    n, m = built.plant.n, built.plant.m
    step = controller_step_part(rival.engine_kernel, rival.model.engine_kernel, n, m)
    assert not step.ready()
    settings = dict(reference=built.reference, t1=0.2, dt=0.001, T_c=0.002)
    with monkeypatch.context() as interpreting_on:  # a short first run, compiled as asked
        interpreting_on.delenv(interpret_first.INTERPRETING)
        with dt.sim.compile_ahead([rival, bad], n, m):
            first = dt.simulate(built.plant, built.controller, built.delay, built.x0, **settings)
    notice = capsys.readouterr().err
    assert "PDGravity's step on " in notice and "AROLC's step on " in notice
    assert step.ready()  # compiled with the first run's parts
    assert np.all(np.isfinite(first.metrics["ae"]))
    second = dt.simulate(built.plant, rival, built.delay, built.x0, **settings)
    assert "PDGravity's step" not in capsys.readouterr().err  # nothing left to compile
    assert np.all(np.isfinite(second.metrics["ae"]))
    with pytest.raises(ValueError, match="numba could not compile PDGravity's step on "):
        dt.simulate(built.plant, bad, built.delay, built.x0, **settings)
    assert parts_ahead() == ()  # the context is left
    # Inlined into the step's part, which runs without numba's runtime, an array the law makes
    # cannot be freed: the error says so (a kernel that is not inlined frees its own).
    inlined = text.replace(
        '@numba.njit(cache=True, error_model="numpy")', "@numba.njit(inline='always')"
    )
    # numba words the two apart: "Only accept returning of array...", "NRT required..."
    for number, array in enumerate(("np.zeros(q.shape[0])", "q * 2.0")):
        law = example / f"allocating_law_{number}.py"
        law.write_text(
            inlined.replace(
                "    n = q.shape[0]\n",
                f"    scratch = {array}\n    n = q.shape[0] + 0 * int(scratch[0])\n",
                1,
            )
        )
        allocating = module_from_file(law).make_pd_gravity(built.model, 16.0, 8.0)
        with pytest.raises(ValueError, match="inlined into the simulator's loop .* new array"):
            dt.simulate(built.plant, allocating, built.delay, built.x0, **settings)


_FAULTY_PLANT = """
import numba
import numpy as np
import delaytrack as dt
from arm import arm_terms, make_arm

@numba.njit  # numba's default error model: an integer division by zero raises
def faulty_terms(t, q, qdot, params, M, N, G):
    arm_terms(t, q, qdot, params, M, N, G)
    if t > 0.05:
        if params[5] > 0.0:
            raise ValueError("sensor fault")
        N[0] += 1 // int(params[5])

def make_faulty(fault=0.0):
    return dt.CompiledPlant(2, 2, faulty_terms, np.append(make_arm().params, fault))
"""


@pytest.mark.slow  # compiles the engine around the faulty kernel (about 15 s)
def test_an_error_a_kernel_raises_during_the_run_is_one_line_naming_it(example, capsys):
    (example / "faulty.py").write_text(_FAULTY_PLANT)
    faulty = f"python:{example / 'faulty.py'}:make_faulty"
    # The files' modules have their own names, or <name>_<hash> when a module of that name is
    # loaded already (in this process: from another test's copy of the example).
    kernels = r"one of your kernels \(arm(_\w{8})?:arm_terms, faulty(_\w{8})?:faulty_terms\)"
    for fault, raised in [
        (0.0, r"ZeroDivisionError during the run: integer division by zero \(a kernel compiled"),
        (1.0, "ValueError during the run: sensor fault"),
    ]:
        path = short(example, plant={"type": faulty, "fault": fault})
        assert main(["simulate", str(path), "--out", str(example / "out"), "--quiet"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert "Traceback" not in "\n".join(err)
        assert re.match(f"error: scenario 'arm_S1': {kernels} raised {raised}", err[-1]), err


def test_sweep_parts_follow_the_users_code(example):
    sweep = example / "sweep_arm.toml"
    before = SweepSpec.from_toml(sweep).units()[0].hash
    assert SweepSpec.from_toml(sweep).units()[0].hash == before
    arm = example / "arm.py"
    arm.write_text(arm.read_text().replace("GRAVITY = 9.81", "GRAVITY = 9.80665"))
    assert SweepSpec.from_toml(sweep).units()[0].hash != before
    arm.write_text(arm.read_text() + "\n# a comment outside the code it runs\n")
    third = SweepSpec.from_toml(sweep).units()[0].hash
    arm.write_text(arm.read_text() + "\n# another\n")
    assert SweepSpec.from_toml(sweep).units()[0].hash == third


# ---- the spline reference --------------------------------------------------------------------

TIMES = np.array([0.0, 0.7, 1.5, 2.0, 3.2])
VALUES = np.array([[0.0, 1.0], [0.5, -0.2], [0.1, 0.3], [-0.4, 0.0], [0.2, 0.6]])


@pytest.mark.parametrize("boundary", ["clamped", "natural", "not-a-knot"])
def test_spline_reference_is_scipys_spline_with_its_derivatives(boundary):
    reference = dt.SplineReference(TIMES, VALUES, boundary=boundary)
    spline = CubicSpline(TIMES, VALUES, bc_type=boundary)
    times = np.linspace(0.0, 3.2, 97)
    qd, qd_dot, qd_ddot = reference.evaluate(times)
    for values, order in ((qd, 0), (qd_dot, 1), (qd_ddot, 2)):
        np.testing.assert_allclose(values, spline(times, order), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(qd[[0, -1]], VALUES[[0, -1]], atol=1e-14)
    if boundary == "clamped":
        np.testing.assert_allclose(qd_dot[[0, -1]], 0.0, atol=1e-12)


def test_spline_reference_beyond_its_samples_is_refused_or_held():
    plant = dt.TwoLinkArm()
    controller = dt.OuterLoop(plant, K1=1.0, K2=1.0)
    settings = dict(t1=4.0, dt=1e-3, T_c=2e-3, trajectories=False)
    with pytest.raises(ValueError, match=r"reference\[0\] \(SplineReference\) is defined up to"):
        dt.simulate(
            plant,
            controller,
            dt.ConstantDelay(0.01),
            np.zeros(4),
            reference=dt.SplineReference(TIMES, VALUES),
            **settings,
        )
    held = dt.SplineReference(TIMES, VALUES, beyond="hold")
    result = dt.simulate(
        plant, controller, dt.ConstantDelay(0.01), np.zeros(4), reference=held, **settings
    )
    assert result.status_names == ["ok"] and result.settings["compiled"]
    qd, qd_dot, qd_ddot = held.evaluate(np.array([3.5, 10.0]))
    np.testing.assert_allclose(qd, np.tile(VALUES[-1], (2, 1)), atol=1e-12)
    assert not qd_dot.any() and not qd_ddot.any()
    late = dt.SplineReference(TIMES + 0.5, VALUES)
    with pytest.raises(ValueError, match=r"starts at t = 0.5 s, after the run's start t0 = 0"):
        dt.simulate(
            plant,
            controller,
            dt.ConstantDelay(0.01),
            np.zeros(4),
            reference=late,
            t1=1.0,
            dt=1e-3,
            T_c=2e-3,
        )


def test_spline_reference_from_a_csv_file_and_a_scenario_table(tmp_path):
    path = tmp_path / "poses.csv"
    rows = ["stamp,shoulder,elbow,note"] + [
        f"{t},{a},{b},x" for t, (a, b) in zip(TIMES, VALUES, strict=True)
    ]
    path.write_text("\n".join(rows) + "\n")
    read = dt.SplineReference.from_csv(path, columns=["shoulder", "elbow"])
    np.testing.assert_array_equal(read.params, dt.SplineReference(TIMES, VALUES).params)
    with pytest.raises(ValueError, match=r"columns names 'wrist', which is not in the header"):
        dt.SplineReference.from_csv(path, columns=["wrist"])
    scenario = tmp_path / "case.toml"
    base = Scenario.from_toml(EXAMPLE / "arm_S1.toml").to_dict()
    base["duration"] = 3.2
    base["x0"] = [0.0, 1.0, 0.0, 0.0]
    base["reference"] = {"type": "spline", "path": "poses.csv", "columns": ["shoulder", "elbow"]}
    scenario.write_text(Scenario.from_dict(base).to_toml())
    loaded = Scenario.from_toml(scenario, trust=[str(EXAMPLE)])
    assert loaded.reference["path"] == str(path)
    np.testing.assert_array_equal(loaded.build().reference.params, read.params)


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        ({"times": [0.0], "values": [[1.0]]}, "times must hold 2 to"),
        ({"times": [0.0, 0.0], "values": [1.0, 2.0]}, "times must be strictly increasing"),
        ({"times": [0.0, 1.0], "values": [[1.0, 2.0]]}, r"values must have shape \(K, n\)"),
        ({"times": [0.0, 1.0], "values": [1.0, 2.0], "boundary": "cubic"}, "boundary must be"),
        ({"times": [0.0, 1.0], "values": [1.0, 2.0], "beyond": "loop"}, "beyond must be"),
        ({"times": [0.0, float("nan")], "values": [1.0, 2.0]}, "times must be finite"),
    ],
)
def test_spline_reference_refuses_bad_samples(arguments, message):
    with pytest.raises(ValueError, match=message):
        dt.SplineReference(**arguments)


def test_results_carry_the_plants_coordinate_names(tmp_path):
    result = Scenario.from_toml(short(EXAMPLE, tmp_path), trust=[str(EXAMPLE)]).run()
    assert result.coordinate_names == ("shoulder", "elbow")
    table = dt.metrics_table(result)
    assert {"ae_shoulder", "rms_elbow", "max_shoulder"} <= set(table.columns)
    assert result[0].coordinate_names == ("shoulder", "elbow")
    plain = dt.simulate(
        dt.TwoLinkArm(),
        dt.OuterLoop(dt.TwoLinkArm(), K1=1.0, K2=1.0),
        dt.ConstantDelay(0.01),
        np.zeros(4),
        reference=dt.SinusoidalReference(offset=[0.0, 0.0]),
        t1=0.1,
        dt=1e-3,
        T_c=2e-3,
    )
    assert plain.coordinate_names is None and "ae_q1" in dt.metrics_table(plain).columns


def test_a_delay_kernel_of_ones_own_runs_from_a_scenario_file():
    scenario = Scenario.from_toml(EXAMPLE / "arm_congested.toml")
    built = scenario.build()
    assert isinstance(built.delay, dt.CompiledDelay)
    assert built.delay.h_max == pytest.approx(0.12)
    times = np.array([0.0, 0.5, 0.8, 1.1, 2.8, 3.2])
    expected = [0.02, 0.02, 0.12, 0.02, 0.12, 0.02]
    np.testing.assert_allclose(built.delay.h(times), expected, atol=1e-12)
    data = scenario.to_dict()
    data["duration"] = 1.5
    result = Scenario.from_dict(data).run()
    assert result.status_names == ["ok"]
    np.testing.assert_array_equal(result.h[0], built.delay.h(result.t))
    # The sweep unit of such a run follows the kernel's code.
    assert ":congested_link_delay#" in engine_inputs(built)[0][-1]


@numba.njit
def _linear_delay(t, params):
    return params[0] + params[1] * t if params[1] >= -0.5 else np.sqrt(params[0] - t)


def _point_mass_run(delay, **changes):
    settings = dict(reference=dt.SinusoidalReference([0.0]), t1=1.0, dt=1e-3, T_c=0.01, **changes)
    plant = dt.LinearPlant(mass=1.0)
    return dt.simulate(plant, dt.OuterLoop(plant, K1=1.0, K2=2.0), delay, [0.1, 0.0], **settings)


@pytest.mark.parametrize(
    ("params", "h_max", "message"),
    [
        (
            [0.05, -0.1],
            0.1,
            r"CompiledDelay 'ramp': its kernel \S*:_linear_delay gives h = -0.0001 s at "
            r"t = 0.5\d* s; it must be a number from 0",
        ),
        ([0.05, 0.1], 0.1, r"gives h = 0.1001 s at t = 0.501 s"),
        ([0.5, -1.0], 1.0, r"gives h = nan s at t = 0.501 s"),
    ],
)
def test_a_delay_kernel_out_of_its_range_is_refused_before_running(params, h_max, message):
    delay = dt.CompiledDelay(_linear_delay, params, h_max=h_max, name="ramp")
    with pytest.raises(ValueError, match=message):
        _point_mass_run(delay)


def test_a_delay_kernel_must_be_compiled_and_one_per_batch():
    with pytest.raises(TypeError, match="kernel must be a numba-compiled function"):
        dt.CompiledDelay(lambda t, params: 0.01, h_max=0.01)
    with pytest.raises(ValueError, match="h_max must be >= 0"):
        dt.CompiledDelay(_linear_delay, [0.0, 0.0], h_max=-1.0)
    other = numba.njit(lambda t, params: params[0])
    first = dt.CompiledDelay(_linear_delay, [0.01, 0.0], h_max=0.01)
    second = dt.CompiledDelay(other, [0.01], h_max=0.01)
    with pytest.raises(ValueError, match=r"delay\[2\] has another kernel than delay\[0\]"):
        _point_mass_run([first, dt.ConstantDelay(0.01), second])
    # One kernel with built-in profiles: each run as alone, bit for bit.
    both = _point_mass_run([first, dt.ConstantDelay(0.01)])
    np.testing.assert_array_equal(both.x[0], _point_mass_run(first).x[0])
    np.testing.assert_array_equal(both.x[1], _point_mass_run(dt.ConstantDelay(0.01)).x[0])


def test_a_delay_kernel_runs_the_same_in_the_plain_python_engine():
    delay = dt.CompiledDelay(_linear_delay, [0.012, 0.03], h_max=0.05)
    compiled = _point_mass_run(delay)
    python = _point_mass_run(delay, engine="python")
    np.testing.assert_array_equal(python.x, compiled.x)
    np.testing.assert_array_equal(python.applied, compiled.applied)


@numba.njit(fastmath=True)
def fused_ripple(t, params, qd, qd_dot, qd_ddot):
    """A reference of a user's compiled with fastmath: compiled, its numbers may differ from
    its plain-Python version's in the last bits."""
    for i in range(qd.shape[0]):
        qd[i] = params[0] * t * t + params[1] * t + 0.1 * math.sin(3.0 * t + i)
        qd_dot[i] = 2.0 * params[0] * t + params[1] + 0.3 * math.cos(3.0 * t + i)
        qd_ddot[i] = 2.0 * params[0] - 0.9 * math.sin(3.0 * t + i)


@pytest.mark.parametrize("kind", ["spline", "sinusoidal"])
@pytest.mark.parametrize("engine, workers", [("compiled", 1), ("compiled", 2), ("python", 1)])
@pytest.mark.parametrize("first_stops", [True, False])
def test_recorded_reference_is_what_the_controller_read(kind, engine, workers, first_stops):
    """The engine records q_d, q̇_d, q̈_d as it computes them at the recorded ticks (run 0 of
    the batch); the rows after run 0 stops are evaluated afterwards: the same numbers."""
    plant = dt.TwoLinkArm()
    controller = dt.OuterLoop(plant, K1=1.0, K2=1.0)
    if kind == "spline":
        reference = dt.SplineReference(TIMES, VALUES)
    else:
        reference = dt.SinusoidalReference([0.0, 1.0], amplitude=[0.3, 0.2], frequency=[2, 3])
    start = np.concatenate([reference.evaluate(0.0)[0], [0.0, 0.0]])
    thrown = start + [0.0, 0.0, 0.0, 20.0]  # thrown off the path: leaves it
    result = dt.simulate(
        plant,
        controller,
        dt.ConstantDelay(0.01),
        np.array([thrown if first_stops else start, thrown, start, start]),
        reference=reference,
        t1=0.3 if engine == "python" else 3.0,
        dt=1e-3,
        T_c=2e-3,
        record_every=7,
        error_bound=0.5,
        engine=engine,
        workers=workers,
    )
    assert result.status_names[1:] == ["left the path", "ok", "ok"]
    assert (result.status_names[0] == "left the path") == first_stops
    if first_stops:
        assert 0.0 < result.t_stop[0] < result.t[-1]
    expected = np.stack(reference.evaluate(result.t), axis=1)
    assert result.reference.shape == (result.t.size, 3, 2)
    np.testing.assert_array_equal(result.reference, expected)


class FusedRipple(dt.Reference):
    """Two coordinates following :func:`fused_ripple`."""

    n = 2
    params = np.array([0.7, 0.3])
    reference_kernel = staticmethod(fused_ripple)

    def to_spec(self):
        return {"type": "fused-ripple"}


class WholeRipple(FusedRipple):
    """:class:`FusedRipple` with integer parameters, as a user may write them."""

    params = np.array([1, 0])


def test_a_reference_with_integer_parameters_runs_as_with_floats():
    # The compiled parts take float64 vectors: integers are converted, not refused by numba.
    plant = dt.TwoLinkArm()
    controller = dt.OuterLoop(plant, K1=1.0, K2=1.0)
    floats = type("FloatRipple", (FusedRipple,), {"params": np.array([1.0, 0.0])})
    whole, same, other = (
        dt.simulate(
            plant,
            controller,
            dt.ConstantDelay(0.01),
            np.zeros(4),
            reference=kind(),
            t1=0.05,
            dt=1e-3,
            T_c=2e-3,
        )
        for kind in (WholeRipple, floats, FusedRipple)
    )
    assert whole.status_names == ["ok"]
    np.testing.assert_array_equal(whole.x, same.x)
    assert not np.array_equal(other.x, same.x)  # the parameters matter


def test_the_plain_python_engine_records_the_reference_its_kernel_gives():
    """A reference whose compiled and plain-Python versions differ in the last bits: the
    plain-Python engine's record holds the plain-Python numbers in every row, those after the
    first run stopped included."""
    plant = dt.TwoLinkArm()
    controller = dt.OuterLoop(plant, K1=1.0, K2=1.0)
    reference = FusedRipple()
    start = np.concatenate([reference.evaluate(0.0)[0], reference.evaluate(0.0)[1]])
    result = dt.simulate(
        plant,
        controller,
        dt.ConstantDelay(0.01),
        np.array([start + [0.0, 0.0, 0.0, 20.0], start]),
        reference=reference,
        t1=0.2,
        dt=1e-3,
        T_c=2e-3,
        error_bound=0.5,
        engine="python",
    )
    assert result.status_names == ["left the path", "ok"]
    expected = np.empty((result.t.size, 3, 2))
    for row, t in enumerate(result.t):
        fused_ripple.py_func(float(t), reference.params, *expected[row])
    np.testing.assert_array_equal(result.reference, expected)


@numba.njit
def _three_coefficients(t, q, qdot, params, mass, nonlinear, input_map):
    mass[0, 0] = params[0]
    nonlinear[0] = params[1] * qdot[0] + params[2] * q[0]
    input_map[0, 0] = 1.0


def test_a_compiled_plant_refuses_parameters_shorter_than_its_kernel_reads():
    # Compiled, the kernel would read past the end of params and run on with whatever lies there.
    with pytest.raises(
        ValueError, match=r"kernel reads beyond an array .*index 2 .*parameters has 2 entries"
    ):
        dt.CompiledPlant(1, 1, _three_coefficients, [1.0, 0.5])
    assert dt.CompiledPlant(1, 1, _three_coefficients, [1.0, 0.5, 2.0]).params.size == 3


@numba.njit
def _terms_without_input_map(t, q, qdot, params, mass, nonlinear):
    mass[0, 0] = 1.0
    nonlinear[0] = 0.0


@numba.njit
def _reference_without_acceleration(t, params, qd, qd_dot):
    qd[0] = 0.0
    qd_dot[0] = 0.0


@numba.njit
def _step_without_work(t, q, qdot, qd, qd_dot, qd_ddot, T_c, h, params, state, model, mp, u):
    u[0] = 0.0


class _ShortReference(dt.Reference):
    n = 1
    params = np.zeros(0)
    reference_kernel = staticmethod(_reference_without_acceleration)

    def to_spec(self):
        return {"type": "short"}


class _ShortStep(dt.OuterLoop):
    @property
    def step_kernel(self):
        return _step_without_work


def test_a_kernel_with_the_wrong_arguments_is_refused_by_name_before_compiling():
    with pytest.raises(
        ValueError,
        match=r"CompiledPlant: its terms kernel must take the 7 arguments \(t, q, qdot, params, "
        r"mass, nonlinear, input_map\); _terms_without_input_map takes \(t, q, qdot, params, "
        r"mass, nonlinear\)",
    ):
        dt.CompiledPlant(1, 1, _terms_without_input_map)
    with pytest.raises(ValueError, match=r"CompiledDelay: its delay kernel must take the 2"):
        dt.CompiledDelay(numba.njit(lambda t: 0.01), h_max=0.01)
    plant = dt.LinearPlant(mass=1.0)
    with pytest.raises(
        ValueError, match=r"^reference: its reference kernel must take the 5 arguments"
    ):
        dt.simulate(
            plant,
            dt.OuterLoop(plant, 1.0, 2.0),
            dt.ConstantDelay(0.01),
            [0.1, 0.0],
            reference=_ShortReference(),
            t1=0.1,
            dt=1e-3,
            T_c=0.01,
        )
    with pytest.raises(ValueError, match=r"^controller: its step kernel must take the 14"):
        dt.simulate(
            plant,
            _ShortStep(plant, 1.0, 2.0),
            dt.ConstantDelay(0.01),
            [0.1, 0.0],
            reference=dt.SinusoidalReference([0.0]),
            t1=0.1,
            dt=1e-3,
            T_c=0.01,
        )


def test_numbas_colour_codes_are_left_out_of_the_cause():
    from delaytrack.sim._kernel_errors import numba_cause

    error = TypeError(
        "Failed in nopython mode\n\x1b[1m\x1b[1mNameError: name 'x' is not defined\x1b[0m"
    )
    assert numba_cause(error) == (
        "NameError: name 'x' is not defined (call a kernel of yours alone, compiled, to see "
        "numba's whole message)"
    )


@pytest.mark.parametrize(
    "words", ["Only accept returning of array passed into the function as argument", "NRT required"]
)
def test_an_array_made_in_the_loop_is_named_whatever_numba_calls_it(words):
    from delaytrack.sim._kernel_errors import numba_cause

    error = TypeError(f"Failed in nopython mode\n\x1b[1m{words} but not enabled\x1b[0m")
    assert numba_cause(error).startswith("code of yours inlined into the simulator's loop")


@numba.njit(inline="always")
def _allocating_terms(t, q, qdot, params, M, N, G):
    scratch = np.zeros(2)
    scratch[0] = 2.0 * math.sin(q[0])
    M[0, 0] = 0.3
    N[0] = scratch[0] + 0.2 * qdot[0]
    G[0, 0] = 1.0


def test_a_kernel_that_allocates_gives_the_plants_state_derivative():
    # Called from Python, a plant's right-hand side is compiled with numba's runtime, so a
    # kernel of yours that makes an array (here inlined into its caller) works there; only the
    # simulator's loop, compiled without the runtime, refuses it.
    plant = dt.CompiledPlant(1, 1, _allocating_terms)
    x = np.array([0.3, 0.2])
    derivative = plant.state_derivative(x, np.array([0.7]), t=0.1)
    acceleration = (0.7 - 2.0 * math.sin(0.3) - 0.2 * 0.2) / 0.3
    np.testing.assert_allclose(derivative, [[0.2, acceleration]], rtol=1e-12)
