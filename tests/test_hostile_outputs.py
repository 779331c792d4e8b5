"""Results that cannot collide, and output folders that stay the user's.

Two classes of hostile input. Coordinate names whose result columns would share a name (``x``
and ``x_d`` in metres both give ``x_d_m``; ``run`` is the run index's column) are refused where
a plant accepts them, before a run, and where the table is built; MuJoCo joints with such names
fall back to ``q1 .. qn``. Output locations are resolved (``..``, links) before the ownership
check, a results folder is recognised by the toolkit's marker only, a name that becomes a folder
must be a plain name, and a run interrupted while writing leaves a folder the next run accepts.
Each case of the campaign is a regression test; a hypothesis property covers each class.
"""

from __future__ import annotations

import json
import os
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numba
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import delaytrack.report.figures as figures_module
import delaytrack.sweeps.runner as runner_module
from delaytrack._output import (
    MANIFEST,
    OutputFolderError,
    check_output_folder,
    check_results_root,
    claim_output_folder,
    plain_folder_name,
)
from delaytrack._result_columns import trajectory_columns
from delaytrack.cli import main
from delaytrack.controllers import AROLC
from delaytrack.delays import AbsSineDelay
from delaytrack.experiments import run_to_folder
from delaytrack.experiments.tuning import default_gains_path
from delaytrack.plants import CallablePlant, CompiledPlant, TwoLinkArm
from delaytrack.references import SinusoidalReference
from delaytrack.sim import SimResult, simulate
from delaytrack.sweeps import SweepInterrupted, SweepSpec, run_sweep
from delaytrack.units import with_unit
from test_hostile_inputs import one_line_error, short

ROOT = Path(__file__).resolve().parents[1]
SWEEP = ROOT / "examples" / "sweep_small.toml"

quick = settings(
    max_examples=60,
    derandomize=True,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)


def _callable_plant(names, units=None) -> CallablePlant:
    n = len(names)
    return CallablePlant(
        n,
        lambda q: np.eye(n),
        lambda q, qdot: np.zeros(n),
        coordinate_names=names,
        coordinate_units=units,
    )


@numba.njit(cache=True)
def _identity_terms(t, q, qdot, params, M, N, G):
    M[:, :] = 0.0
    N[:] = 0.0
    G[:, :] = 0.0
    for i in range(q.shape[0]):
        M[i, i] = 1.0
        G[i, i] = 1.0


@dataclass(frozen=True)
class _ArmWithClashingNames(TwoLinkArm):
    """The two-link arm (radians) with joints named ``a`` and ``a_d``: ``a_d_rad`` twice."""

    coordinate_names: ClassVar[tuple[str, ...]] = ("a", "a_d")


# ---- 1. columns that cannot collide ------------------------------------------------------------


@pytest.mark.parametrize(
    ("names", "units", "column"),
    [
        (["x", "x_d"], ["m", "m"], "'x_d_m'"),  # the campaign's case: x's reference overwritten
        (["run", "y"], None, "'run'"),  # the run index overwritten
        (["t", "y"], ["s", "m"], "'t_s'"),  # the time
        (["x", "e1_x"], None, "'e1_x'"),  # x's tracking error and e1_x's position
        (["u1_sent"], None, "'u1_sent'"),  # an input's column
    ],
)
def test_names_that_would_share_a_column_are_refused_by_a_user_plant(names, units, column):
    with pytest.raises(ValueError, match=f"two columns {column}") as refused:
        _callable_plant(names, units)
    message = str(refused.value)
    assert "\n" not in message and str(names) in message and "rename" in message
    with pytest.raises(ValueError, match=f"two columns {column}"):
        CompiledPlant(
            len(names),
            len(names),
            _identity_terms,
            coordinate_names=names,
            coordinate_units=units,
        )


@pytest.mark.parametrize(
    ("make_plant", "message"),
    [
        (_ArmWithClashingNames, r"two columns 'a_d_rad' \(the reference of coordinate "),
        (
            lambda: _callable_plant(["c_hat", "y"]),
            r"two columns 'c_hat'.*controller's state 'c_hat'",
        ),
    ],
    ids=["a plant class whose names clash", "a coordinate named like the controller's state"],
)
def test_clashing_names_are_refused_by_simulate_before_the_run(make_plant, message):
    plant = make_plant()
    controller = AROLC(plant, K1=1.0, K2=1.0, Q=1.0, alpha=2.0, epsilon=0.1, gamma=0.001)
    reference = SinusoidalReference([0.0, 0.0], amplitude=[0.5, 0.3], frequency=[0.5, 0.7])
    with pytest.raises(ValueError, match=message):
        simulate(
            plant,
            controller,
            AbsSineDelay.S1(),
            np.zeros(4),
            reference=reference,
            t1=0.1,
            dt=0.001,
            T_c=0.01,
        )


def _result(names, units, *, batch=2, records=3, inputs=1, states=("c_hat",), seed=0):
    """A result of random numbers with the given names (as a plant that was never checked)."""
    rng = np.random.default_rng(seed)
    n = len(names)
    return SimResult(
        t=np.arange(records) * 0.01,
        x=rng.normal(size=(batch, records, 2 * n)),
        reference=rng.normal(size=(records, 3, n)),
        commands=rng.normal(size=(batch, records, inputs)),
        applied=rng.normal(size=(batch, records, inputs)),
        h=rng.normal(size=(batch, records)),
        controller_state=rng.normal(size=(batch, records, len(states))),
        controller_state_names=tuple(states),
        status=np.zeros(batch, dtype=int),
        t_stop=np.ones(batch),
        coordinate_names=None if names is None else tuple(names),
        coordinate_units=None if units is None else tuple(units),
    )


def test_the_table_itself_refuses_two_columns_of_one_name():
    """A result made by any other path (here by hand) cannot give a table with x_d_m twice."""
    with pytest.raises(ValueError, match="two columns 'x_d_m'"):
        _result(["x", "x_d"], ["m", "m"]).to_frame()
    with pytest.raises(ValueError, match="state names repeat 'c_hat'"):
        _result(["x"], ["m"], states=("c_hat", "c_hat")).to_frame()


def test_mujoco_joints_whose_columns_would_clash_are_named_q1_to_qn(tmp_path):
    pytest.importorskip("mujoco")
    from delaytrack.plants import MujocoPlant as mujoco_plant

    text = (ROOT / "examples" / "mujoco_arm" / "arm3.xml").read_text()
    path = tmp_path / "arm.xml"
    path.write_text(text.replace('"elbow"', '"shoulder_d"'))
    plant = mujoco_plant(path)
    assert plant.coordinate_names is None  # shoulder's reference and shoulder_d: shoulder_d_rad
    columns = trajectory_columns(
        plant.coordinate_names, plant.coordinate_units, plant.n, plant.input_units, plant.m
    )
    assert "q1_rad" in columns and len(set(columns)) == len(columns)
    path.write_text(text.replace('"elbow"', '"elbow_joint"'))
    assert mujoco_plant(path).coordinate_names == ("shoulder", "elbow_joint", "wrist")


_NAME_PARTS = ["x", "x_d", "x_dot", "e1_x", "run", "t", "h", "u1_sent", "c_hat", "q1", "y", "d"]
_UNITS = ["m", "s", "rad", "d_m", "m/s", "N·m", "dot_m"]


@st.composite
def _names_and_units(draw):
    names = draw(
        st.lists(
            st.one_of(
                st.sampled_from(_NAME_PARTS), st.from_regex(r"[a-z][a-z0-9_]{0,5}", fullmatch=True)
            ),
            min_size=1,
            max_size=4,
            unique=True,
        )
    )
    units = draw(
        st.one_of(
            st.none(), st.lists(st.sampled_from(_UNITS), min_size=len(names), max_size=len(names))
        )
    )
    return names, units


@quick
@given(_names_and_units())
def test_names_are_refused_or_give_unique_columns_holding_their_data(names_and_units):
    """Either a one-line refusal naming the shared column, exactly when two of the columns
    (worked out here from the documented naming) would share a name; or a table whose columns
    are unique and hold the data they are named after."""
    names, units = names_and_units
    unit_of = units or [None] * len(names)
    expected = ["run", "t_s", "h_s"]
    for name, unit in zip(names, unit_of, strict=True):
        rate = f"{unit}/s" if unit else None
        expected += [
            with_unit(name, unit),
            with_unit(f"{name}_dot", rate),
            with_unit(f"{name}_d", unit),
            with_unit(f"e1_{name}", unit),
        ]
    for j in range(len(names)):  # the plant below has one input per coordinate (G = I)
        expected += [f"u{j + 1}_sent", f"u{j + 1}_applied"]
    clash = len(set(expected)) < len(expected)
    try:
        plant = _callable_plant(names, units)
    except ValueError as error:
        assert clash, error
        assert "two columns" in str(error) and "\n" not in str(error)
        return
    assert not clash
    result = _result(plant.coordinate_names, plant.coordinate_units, inputs=plant.m, states=())
    frame = result.to_frame()
    assert list(frame.columns) == expected and frame.columns.is_unique
    for i, (name, unit) in enumerate(zip(names, unit_of, strict=True)):
        np.testing.assert_array_equal(frame[with_unit(name, unit)], result.q[:, :, i].ravel())
        reference = np.tile(result.reference[:, 0, i], result.batch_size)
        np.testing.assert_array_equal(frame[with_unit(f"{name}_d", unit)], reference)
    np.testing.assert_array_equal(frame["run"], np.repeat([0, 1], 3))


# ---- 2. output folders that stay the user's ----------------------------------------------------


def _mine(tmp_path: Path) -> Path:
    mine = tmp_path / "MINE"
    mine.mkdir()
    (mine / "thesis.tex").write_text("my thesis")
    return mine


def _untouched(mine: Path) -> None:
    assert sorted(p.name for p in mine.iterdir()) == ["thesis.tex"]
    assert (mine / "thesis.tex").read_text() == "my thesis"


@pytest.mark.parametrize("command", ["simulate", "sweep"])
def test_dot_dot_is_resolved_before_the_ownership_check(tmp_path, capsys, command):
    mine = _mine(tmp_path)
    source = "two_link_S1" if command == "simulate" else str(SWEEP)
    out = str(tmp_path / "NEW" / ".." / "MINE")
    assert main([command, source, "--out", out, "--quiet"]) == 2
    one_line_error(capsys, "--out", "thesis.tex", f"that is, {str(mine)!r}")
    _untouched(mine)
    assert not (tmp_path / "NEW").exists()


def test_a_link_to_a_users_folder_is_refused_like_the_folder(tmp_path, capsys):
    mine = _mine(tmp_path)
    (tmp_path / "link").symlink_to(mine)
    assert main(["simulate", "two_link_S1", "--out", str(tmp_path / "link"), "--quiet"]) == 2
    one_line_error(capsys, "--out", "thesis.tex")
    _untouched(mine)


def test_a_parts_subfolder_does_not_make_a_sweep_folder(tmp_path, capsys):
    folder = tmp_path / "mine"
    (folder / "parts").mkdir(parents=True)
    (folder / "report.html").write_text("my report")
    (folder / "summary.csv").write_text("my,summary\n")
    assert main(["sweep", str(SWEEP), "--out", str(folder), "--quiet"]) == 2
    one_line_error(capsys, "--out", "parts", "report.html")
    assert (folder / "report.html").read_text() == "my report"
    assert (folder / "summary.csv").read_text() == "my,summary\n"
    assert sorted(p.name for p in folder.iterdir()) == ["parts", "report.html", "summary.csv"]


@pytest.mark.parametrize("stem", ["..", ".", ".hidden", " padded", "tab\there"])
def test_a_sweep_file_whose_stem_is_not_a_plain_name_is_refused(
    tmp_path, capsys, stem, monkeypatch
):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "notes.txt").write_text("mine")
    spec = tmp_path / f"{stem}.toml"
    shutil.copy(SWEEP, spec)
    assert main(["sweep", spec.name, "--quiet"]) == 2
    one_line_error(capsys, "sweep file", repr(stem), "not a plain name")
    assert sorted(p.name for p in (tmp_path / "results").iterdir()) == ["notes.txt"]


@pytest.mark.parametrize("name", ["", ".", "..", "...", "a/b", "a\\b", "nul\x00", " x", "x "])
def test_plain_folder_names(name):
    with pytest.raises(OutputFolderError, match="not a plain name"):
        plain_folder_name(name, "test")
    for good in ("sweep_small", "my sweep", "ablation-2.v3", "résumé"):
        assert plain_folder_name(good, "test") == good


def test_a_folder_left_by_an_interrupted_simulate_is_accepted_next_time(tmp_path, monkeypatch):
    folder = tmp_path / "run"
    scenario = short()

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    with monkeypatch.context() as patch:
        patch.setattr(figures_module, "write_run_figures", interrupted)
        with pytest.raises(KeyboardInterrupt):
            run_to_folder(scenario, folder, progress=False)
    assert (folder / MANIFEST).is_file() and (folder / "metrics.csv").is_file()
    assert check_output_folder(folder) == folder.resolve()
    output = run_to_folder(scenario, folder, progress=False)
    assert (folder / "figures").is_dir() and len(output.files) > 3
    listed = json.loads((folder / MANIFEST).read_text())["files"]
    assert "metrics.csv" in listed and "scenario.toml" in listed


def test_an_interrupted_sweep_folder_is_resumed_by_the_command(tmp_path, monkeypatch, capsys):
    spec = SweepSpec.from_toml(SWEEP)
    out = tmp_path / "sweep"
    real_write_part = runner_module.write_part

    def interrupted_write_part(frame, unit, folder):
        if unit.index == 1:
            raise KeyboardInterrupt
        return real_write_part(frame, unit, folder)

    with monkeypatch.context() as patch:
        patch.setattr(runner_module, "write_part", interrupted_write_part)
        with pytest.raises(SweepInterrupted):
            run_sweep(spec, out, progress=False)
    assert (out / MANIFEST).is_file()
    assert main(["sweep", str(SWEEP), "--out", str(out), "--quiet"]) == 0
    assert "1 found finished" in capsys.readouterr().out


def test_the_marker_is_never_written_into_a_folder_holding_anything(tmp_path, capsys):
    """An interrupted run's folder is accepted because the marker went in first; a library call
    into a user's folder (which does not check) does not make that folder the toolkit's."""
    mine = _mine(tmp_path)
    claim_output_folder(mine)
    _untouched(mine)
    with pytest.raises(OutputFolderError, match="thesis.tex"):
        check_output_folder(mine)
    fresh = claim_output_folder(tmp_path / "new" / "run")
    assert [p.name for p in fresh.iterdir()] == [MANIFEST]


def test_reproduce_out_follows_the_same_rule(tmp_path, capsys):
    mine = _mine(tmp_path)
    for job in ("two-link", "margins", "paper"):
        assert main(["reproduce", "--job", job, "--out", str(mine), "--duration", "1"]) == 2
        one_line_error(capsys, "--out", "thesis.tex")
    _untouched(mine)
    with pytest.raises(OutputFolderError, match="did not write"):
        check_results_root("/", "--out")  # what reproduce --out / now says, before writing


def test_a_results_root_of_this_toolkit_is_accepted(tmp_path):
    """``results/`` after simulate, sweep and tune-baselines holds only the toolkit's files."""
    root = tmp_path / "results"
    claim_output_folder(root / "two_link_S1")
    claim_output_folder(root / "sweeps" / "sweep_small")
    (root / "sweeps" / "empty").mkdir()
    shutil.copy(default_gains_path(), root / "baseline_gains.toml")
    assert check_results_root(root, "--out") == root.resolve()
    (root / "sweeps" / "notes.txt").write_text("mine")
    with pytest.raises(OutputFolderError, match=r"\(sweeps\)"):
        check_results_root(root, "--out")


def test_tune_baselines_does_not_overwrite_a_users_file(tmp_path, capsys):
    mine = _mine(tmp_path)
    assert main(["tune-baselines", "--out", str(mine / "thesis.tex"), "--quiet"]) == 2
    one_line_error(capsys, "--out", "did not write")
    _untouched(mine)


_STEPS = ["NEW", "..", "MINE", "EMPTY", "link", "."]


@quick
@given(st.lists(st.sampled_from(_STEPS), min_size=1, max_size=5))
def test_a_path_through_dot_dot_never_writes_into_a_foreign_folder(tmp_path_factory, steps):
    """Whatever the relative path, an accepted one names (resolved) the folder the system reaches
    by that path, and a run writing there leaves the user's folder as it was."""
    base = tmp_path_factory.mktemp("paths")
    mine = _mine(base)
    (base / "EMPTY").mkdir()
    (base / "link").symlink_to(mine)
    given_path = os.path.join(base, *steps)
    try:
        folder = check_output_folder(given_path, "--out")
    except OutputFolderError:
        _untouched(mine)
        return
    os.makedirs(given_path, exist_ok=True)
    assert os.path.samefile(given_path, folder)
    assert folder != mine.resolve() and folder != base.resolve()
    claim_output_folder(folder)
    (folder / "metrics.csv").write_text("a,b\n")
    assert (mine / "thesis.tex").read_text() == "my thesis"
    assert not (mine / "metrics.csv").exists() and not (mine / MANIFEST).exists()
