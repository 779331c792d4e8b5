"""Results that cannot collide, output folders that stay the user's, and gains files that run.

Coordinate names whose result columns would share a name (``x`` and ``x_d`` in metres both give
``x_d_m``; ``run`` is the run index's column; ``é`` and ``e`` with a combining accent are one
name after NFKC), or units that are not plain unit text (``max_m`` gave a sweep's summary two
columns ``ae_x_mean_max_m``), are refused where a plant accepts them, before a run, and where
the tables are built; MuJoCo joints with such names fall back to ``q1 .. qn``, announced, and
never to another joint's name. Output locations are resolved (``..``, links) before the
ownership check, a results folder is recognised by the toolkit's marker only and refused when it
holds a symbolic link, a name that becomes a folder must be a plain name, and a run interrupted
while writing leaves a folder the next run accepts. A gains file is checked value by value when
it is read. Each case of the campaign is a regression test; a hypothesis property covers each
class.
"""

from __future__ import annotations

import copy
import json
import math
import os
import re
import shutil
import tomllib
import unicodedata
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numba
import numpy as np
import pandas as pd
import pytest
import tomli_w
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import delaytrack.experiments.tuning as tuning
import delaytrack.report.figures as figures_module
import delaytrack.sweeps.runner as runner_module
from delaytrack._output import (
    MANIFEST,
    OutputFolderError,
    check_output_folder,
    check_results_root,
    claim_output_folder,
    plain_folder_name,
    record_outputs,
)
from delaytrack._result_columns import trajectory_columns
from delaytrack.cli import main
from delaytrack.controllers import AROLC
from delaytrack.delays import AbsSineDelay
from delaytrack.experiments.tuning import default_gains_path
from delaytrack.jobs.scenario_run import run_to_folder
from delaytrack.plants import CallablePlant, CompiledPlant, TwoLinkArm
from delaytrack.references import SinusoidalReference
from delaytrack.report.figures import FigureNotDrawnWarning
from delaytrack.scenario import load_builtin
from delaytrack.sim import SimResult, simulate
from delaytrack.sweeps import SweepInterrupted, SweepSpec, run_sweep
from delaytrack.sweeps.summary import STATISTICS
from delaytrack.units import with_unit
from test_hostile_inputs import one_line_error, short

ROOT = Path(__file__).resolve().parents[1]
SWEEP = ROOT / "examples" / "sweep_small.toml"

#: The shipped gains file as read (for the gains property, which changes copies of it).
_SHIPPED_RECORD = tomllib.loads(default_gains_path().read_text(encoding="utf-8"))

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


def _arm_with_joints(tmp_path: Path, shoulder: str, elbow: str, wrist: str) -> Path:
    """The example three-link arm with its joints (and their motors) renamed."""
    text = (ROOT / "examples" / "mujoco_arm" / "arm3.xml").read_text()
    for old, new in (("shoulder", shoulder), ("elbow", elbow), ("wrist", wrist)):
        text = text.replace(f'"{old}"', f'"{new}"')
    path = tmp_path / "arm.xml"
    path.write_text(text)
    return path


def test_mujoco_joints_whose_columns_would_clash_are_named_q1_to_qn(tmp_path):
    pytest.importorskip("mujoco")
    from delaytrack.plants import MujocoPlant as mujoco_plant
    from delaytrack.plants.mujoco.plant import JointNamesWarning

    path = _arm_with_joints(tmp_path, "shoulder", "shoulder_d", "wrist")
    with pytest.warns(
        JointNamesWarning, match=r"\['shoulder', 'shoulder_d', 'wrist'\].* q1 \.\. q3"
    ):
        plant = mujoco_plant(path)  # shoulder's reference and shoulder_d: shoulder_d_rad
    assert plant.coordinate_names == ("q1", "q2", "q3")
    columns = trajectory_columns(
        plant.coordinate_names, plant.coordinate_units, plant.n, plant.input_units, plant.m
    )
    assert "q1_rad" in columns and len(set(columns)) == len(columns)
    path = _arm_with_joints(tmp_path, "shoulder", "elbow_joint", "wrist")
    assert mujoco_plant(path).coordinate_names == ("shoulder", "elbow_joint", "wrist")


_NAME_PARTS = [
    "x",
    "x_d",
    "x_dot",
    "x_mean",
    "e1_x",
    "run",
    "t",
    "h",
    "u1_sent",
    "c_hat",
    "q1",
    "y",
    "d",
    "\u00e9",  # é as one character
    "e\u0301",  # é as e and a combining accent: the same name after NFKC
    "\ufb01",  # the ligature ﬁ: fi after NFKC
    "fi",
]
_UNITS = ["m", "s", "rad", "d_m", "m/s", "N·m", "dot_m", "max_m", "m s", "µm", "m^-1", "kg*m²"]


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


def _shares_a_name(columns: list[str]) -> bool:
    """Whether two of ``columns`` are one name as Python compares identifiers (NFKC)."""
    return len({unicodedata.normalize("NFKC", column) for column in columns}) < len(columns)


@quick
@given(_names_and_units())
def test_names_are_refused_or_give_unique_columns_holding_their_data(names_and_units):
    """Either a one-line refusal, exactly when a unit is not plain unit text (it holds '_' or a
    space) or when two of the columns of the table or of a sweep's summary (worked out here from
    the documented naming) would share a name after NFKC normalisation; or a table whose columns
    are unique and hold the data they are named after."""
    names, units = names_and_units
    unit_of = units or [None] * len(names)
    not_plain = any(unit and ("_" in unit or " " in unit) for unit in unit_of)
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
    summary = [
        with_unit(f"{prefix}_{name}_{statistic}", unit)
        for prefix in ("ae", "rms", "max")
        for name, unit in zip(names, unit_of, strict=True)
        for statistic in ("mean", "median", "p95", "max")
    ]
    clash = _shares_a_name(expected) or _shares_a_name(summary)
    try:
        plant = _callable_plant(names, units)
    except ValueError as error:
        assert "\n" not in str(error)
        if not_plain:
            assert "not plain unit text" in str(error)
            return
        assert clash, error
        assert "two columns" in str(error)
        return
    assert not clash and not not_plain
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
    one_line_error(capsys, "--out", "must end in .toml")
    _untouched(mine)
    settings_file = tmp_path / "settings.toml"
    settings_file.write_text("mine = true\n")
    assert main(["tune-baselines", "--out", str(settings_file), "--quiet"]) == 2
    one_line_error(capsys, "--out", "did not write")
    assert settings_file.read_text() == "mine = true\n"


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


# ---- 3. links in results folders -------------------------------------------------------------


def _marked(folder: Path) -> Path:
    """A results folder of this toolkit (its marker, nothing else)."""
    folder.mkdir(parents=True)
    (folder / MANIFEST).write_text('{"files": []}\n')
    return folder


def _victim(tmp_path: Path) -> Path:
    victim = tmp_path / "V"
    victim.mkdir()
    (victim / "bashrc").write_text("mine")
    return victim


def _victim_untouched(victim: Path) -> None:
    assert [p.name for p in victim.iterdir()] == ["bashrc"]
    assert (victim / "bashrc").read_text() == "mine"


@pytest.mark.parametrize(
    ("command", "link"),
    [("simulate", "figures"), ("sweep", "parts"), ("sweep", "figures"), ("simulate", "sub/deep")],
)
def test_a_link_in_a_results_folder_is_refused_before_anything_is_written(
    tmp_path, capsys, command, link
):
    """The campaign's case: a marker and ``figures -> ../V`` made simulate draw its figures in
    V and end in a traceback; a sweep's ``parts -> ../V2`` took its parts (and its start-up
    clean-up of ``parts/.part-*``) into V2."""
    folder = _marked(tmp_path / "P")
    victim = _victim(tmp_path)
    (victim / ".part-left").write_text("mine too")  # what a sweep's clean-up would delete
    (folder / link).parent.mkdir(parents=True, exist_ok=True)
    (folder / link).symlink_to(victim)
    source = "two_link_S1" if command == "simulate" else str(SWEEP)
    assert main([command, source, "--out", str(folder), "--quiet"]) == 2
    one_line_error(
        capsys, "--out", f"symbolic link {str(folder / link)!r} -> {str(victim)!r}", "remove it"
    )
    assert sorted(p.name for p in victim.iterdir()) == [".part-left", "bashrc"]
    assert (victim / ".part-left").read_text() == "mine too"


def test_a_link_to_a_file_in_a_results_folder_is_refused(tmp_path):
    folder = _marked(tmp_path / "P")
    victim = _victim(tmp_path)
    (folder / "metrics.csv").symlink_to(victim / "bashrc")
    with pytest.raises(OutputFolderError, match="P/metrics.csv' -> .*bashrc"):
        check_output_folder(folder, "--out")
    _victim_untouched(victim)


def test_the_check_is_made_again_right_before_writing_and_cleaning_up(tmp_path):
    """A library call that skips the command's check (run_sweep, claim_output_folder) and a
    link made after the check are refused at the first write and before the clean-up."""
    victim = _victim(tmp_path)
    (victim / ".part-left").write_text("mine too")
    folder = _marked(tmp_path / "S")
    (folder / "parts").symlink_to(victim)
    with pytest.raises(OutputFolderError, match="S/parts' -> "):
        run_sweep(SweepSpec.from_toml(SWEEP), folder, progress=False)
    with pytest.raises(OutputFolderError, match="S/parts' -> "):
        claim_output_folder(folder)
    assert sorted(p.name for p in victim.iterdir()) == [".part-left", "bashrc"]
    # record_outputs: the previous run listed figures/bashrc; a link made meanwhile points
    # figures at the victim's folder.
    run = _marked(tmp_path / "run")
    (run / MANIFEST).write_text(json.dumps({"files": ["figures/bashrc"]}))
    (run / "figures").symlink_to(victim)
    with pytest.raises(OutputFolderError, match="run/figures' -> "):
        record_outputs(run, [])
    (victim / ".part-left").unlink()
    _victim_untouched(victim)


def test_a_link_made_while_simulate_writes_ends_in_one_line_not_a_traceback(
    tmp_path, capsys, monkeypatch
):
    """The traceback of the campaign (ValueError: '.../V/tracking.png' is not in the subpath)
    came from recording files written through a link; such a run now ends in one line."""
    victim = _victim(tmp_path)
    folder = tmp_path / "run"

    def figures_through_a_link(result, figures, **options):
        figures.symlink_to(victim)
        return [figures / "bashrc"]

    monkeypatch.setattr(figures_module, "write_run_figures", figures_through_a_link)
    path = tmp_path / "short.toml"
    path.write_text(short().to_toml())
    assert main(["simulate", str(path), "--out", str(folder), "--quiet"]) == 2
    one_line_error(capsys, "results folder", "symbolic link", "remove it")
    _victim_untouched(victim)
    with pytest.raises(OutputFolderError, match="lies outside it"):
        record_outputs(_marked(tmp_path / "other"), [victim / "bashrc"])


_TREE = ["figures", "parts", "sweeps", "sweeps/a", "sweeps/a/parts", "sweeps/a/parts/x"]


@quick
@given(st.sets(st.sampled_from(_TREE)), st.one_of(st.none(), st.sampled_from(_TREE)))
def test_a_results_folder_is_accepted_exactly_when_it_holds_no_link(
    tmp_path_factory, folders, link
):
    """Folders of ours at any depth the toolkit writes, with or without a link somewhere in
    them: the folder is refused, naming that link, exactly when there is one; nothing outside
    is touched."""
    base = tmp_path_factory.mktemp("links")
    victim = _victim(base)
    folder = _marked(base / "P")
    for inner in sorted(folders - {link}):
        (folder / inner).mkdir(parents=True, exist_ok=True)
    if link is not None and not (folder / link).exists():
        (folder / link).parent.mkdir(parents=True, exist_ok=True)
        (folder / link).symlink_to(victim)
    planted = next((p for p in folder.rglob("*") if p.is_symlink()), None)
    try:
        checked = check_output_folder(folder, "--out")
        claim_output_folder(folder)
    except OutputFolderError as error:
        assert planted is not None and f"{str(planted)!r} -> " in str(error)
    else:
        assert planted is None and checked == folder.resolve()
    _victim_untouched(victim)


# ---- 4. units, Unicode names and MuJoCo joint names --------------------------------------------


def test_the_campaigns_units_that_gave_two_summary_columns_are_refused():
    """``x`` in ``max_m`` and ``x_mean`` in ``m`` gave a sweep's summary.csv two columns
    ``ae_x_mean_max_m`` (exit 0); a unit is plain unit text, without ``_``."""
    with pytest.raises(ValueError, match=r"unit 'max_m', which is not plain unit text") as refused:
        _callable_plant(["x", "x_mean"], ["max_m", "m"])
    assert "coordinate_units ['max_m', 'm']" in str(refused.value)
    for unit in ("m s", "_m", "m\t", "m,s", "(m)"):
        with pytest.raises(ValueError, match="not plain unit text"):
            _callable_plant(["x"], [unit])
    for unit in ("N·m", "m/s^2", "µm", "kg*m²", "m^-1", "%", "°", "N.m"):
        assert _callable_plant(["x"], [unit]).coordinate_units == (unit,)


def test_the_summary_columns_are_built_by_one_function_that_refuses_duplicates():
    from delaytrack._result_columns import summary_columns
    from delaytrack.report.sweep import with_units

    units = {"ae_x": "max_m", "ae_x_mean": "m"}  # a plant that was never checked
    with pytest.raises(ValueError, match=r"two columns 'ae_x_mean_max_m' \(the mean of ae_x"):
        summary_columns(units)
    summary = pd.DataFrame(
        {f"{metric}_{statistic}": [1.0] for metric in units for statistic in STATISTICS}
    )
    with pytest.raises(ValueError, match="two columns 'ae_x_mean_max_m'"):
        with_units(summary, units)
    assert list(with_units(summary, {"ae_x": "m", "ae_x_mean": "m"}).columns) == [
        f"{metric}_{statistic}_m" for metric in units for statistic in STATISTICS
    ]


@pytest.mark.parametrize("names", [["\u00e9", "e\u0301"], ["\ufb01", "fi"], ["\u212b", "\u00c5"]])
def test_names_equal_after_unicode_normalisation_are_refused(names):
    """``é`` as one character and as ``e`` with a combining accent gave two columns shown as
    ``é``; Python compares identifiers after NFKC, and so do result columns."""
    with pytest.raises(ValueError, match="one name after Unicode normalisation") as refused:
        _callable_plant(names)
    assert "\n" not in str(refused.value)


def test_remembered_columns_are_the_callers_own_and_unhashable_names_are_still_checked():
    """The columns are remembered between calls (every simulate call asks for them): a caller
    that changes the list it got must not change the next caller's."""
    first = trajectory_columns(["x", "y"], ["m", "m"], 2, ["N"], 1)
    first.append("changed")
    assert trajectory_columns(("x", "y"), ("m", "m"), 2, ("N",), 1) == first[:-1]
    # names given as a list of lists cannot be remembered: still checked, not a TypeError
    with pytest.raises(ValueError, match="coordinate_units must have 2 entries"):
        trajectory_columns(["x", "y"], [["m"]], 2, None, 1)


def test_a_mujoco_fallback_never_names_a_coordinate_after_another_joint(tmp_path):
    """Joints ``q2``, ``q1``, ``w x`` fell back to ``q1 .. q3``: column q1 held the joint named
    q2. The fallback avoids every joint name of the model and is announced."""
    pytest.importorskip("mujoco")
    from delaytrack.plants import MujocoPlant as mujoco_plant
    from delaytrack.plants.mujoco.plant import JointNamesWarning

    path = _arm_with_joints(tmp_path, "q2", "q1", "w x")
    with pytest.warns(JointNamesWarning, match=r"'w x' is not a name.*qq1 \.\. qq3") as caught:
        plant = mujoco_plant(path)
    announced = [str(w.message) for w in caught if w.category is JointNamesWarning]
    assert len(announced) == 1 and "q1 .. q3 are names of the model's joints" in announced[0]
    assert plant.coordinate_names == ("qq1", "qq2", "qq3")
    path = _arm_with_joints(tmp_path, "qq1", "q1", "w-x")
    with pytest.warns(JointNamesWarning, match="qqq1 .. qqq3"):
        assert mujoco_plant(path).coordinate_names == ("qqq1", "qqq2", "qqq3")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # usable names: no warning
        assert mujoco_plant(_arm_with_joints(tmp_path, "q2", "q1", "q3")).coordinate_names == (
            "q2",
            "q1",
            "q3",
        )


# ---- 5. gains files --------------------------------------------------------------------------


def test_tune_baselines_refuses_an_out_that_is_not_toml_before_tuning(
    tmp_path, capsys, monkeypatch
):
    """``--out g.txt`` was accepted once, then refused as "a file tune-baselines did not write"."""

    def never(*args, **kwargs):
        raise AssertionError("tuning started")

    monkeypatch.setattr(tuning, "tune_controllers", never)
    out = tmp_path / "g.txt"
    assert main(["tune-baselines", "--out", str(out), "--quiet"]) == 2
    one_line_error(capsys, "--out", repr(str(out)), "must end in .toml")
    assert not out.exists()


def _gains_file(tmp_path: Path, table: str, key: str, value: object) -> Path:
    """The shipped gains file with ``[table] key = value`` (``value`` None: the key removed)."""
    record = tomllib.loads(default_gains_path().read_text(encoding="utf-8"))
    kind, gain_set = table.split(".")
    if value is None:
        del record[kind][gain_set][key]
    else:
        record[kind][gain_set][key] = value
    path = tmp_path / "g.toml"
    path.write_text(tomli_w.dumps(record), encoding="utf-8")
    return path


@pytest.mark.parametrize(
    ("table", "key", "value", "words"),
    [
        ("AROLC.varying", "k", "1_0", ["k = '1_0' is text"]),  # a TypeError traceback before
        ("PCON.varying", "k_b", "nan", ["k_b = 'nan' is text"]),  # a ValueError traceback
        ("AROLC.varying", "alpha", -54.0, ["alpha = -54.0 is negative"]),  # a traceback
        ("PCON.varying", "k_b", True, ["k_b = true is true/false"]),  # ran with k_b = 1
        ("PCONf.constant", "c", math.inf, ["c = inf is not finite"]),
        ("PCON-wheel.all", "kappa", math.nan, ["kappa = nan is not finite"]),
        ("PCON.all", "kappa", 0, ["kappa = 0 is zero"]),
        ("AROLC.constant", "zeta", 10**400, ["is not finite"]),
        ("AROLC.all", "alpha", 1e200, ["AROLC refuses these gains", "alpha must be <= 1e+100"]),
        ("AROLC.all", "h_m", "0.1", ["h_m = '0.1' is text"]),
        ("PCONf.varying", "c", None, ["lacks c"]),
    ],
)
def test_reproduce_refuses_a_gains_value_it_cannot_run_before_anything_runs(
    tmp_path, capsys, table, key, value, words
):
    path = _gains_file(tmp_path, table, key, value)
    out = tmp_path / "o"
    arguments = ["--duration", "0.01", "--no-robustness", "--no-dt-check", "--no-contact"]
    command = ["reproduce", "--job", "paper", *arguments, "--gains", str(path), "--out", str(out)]
    assert main(command) == 2
    one_line_error(capsys, f"--gains {str(path)!r}: [{table}]", *words, "must be")
    assert not out.exists()
    with pytest.raises(
        tuning.GainsFileError, match=re.escape(f"gains file {str(path)!r}: [{table}]")
    ):
        tuning.load_gains(path)


_GAIN_VALUES = st.one_of(
    st.floats(min_value=0.05, max_value=20.0),
    st.integers(min_value=-10, max_value=20),
    st.sampled_from(
        [math.nan, math.inf, -math.inf, -1.5, 0.0, -0.0, 10**400, True, False, None, [1.0]]
    ),
    st.sampled_from(["1_0", "6.0", "nan", "inf", "\u0669", ""]),
)


@quick
@given(st.sampled_from(tuning.KINDS), st.sampled_from(tuning.GAIN_SETS), st.data())
def test_a_gains_record_is_accepted_exactly_when_every_gain_is_a_finite_positive_number(
    kind, gain_set, data
):
    """Any value in any gain of any set: accepted exactly when it is a TOML number (not a bool),
    finite and > 0 (the positive numbers drawn lie within the controllers' own bounds), and
    then read as that number."""
    key = data.draw(st.sampled_from(tuning.GAIN_NAMES[kind]))
    value = data.draw(_GAIN_VALUES)
    record = copy.deepcopy(dict(_SHIPPED_RECORD))
    record[kind][gain_set][key] = value
    number = not isinstance(value, bool) and isinstance(value, int | float)
    valid = number and 0 < value <= 20  # finite, positive, within the controllers' bounds
    try:
        gains = tuning.load_gains(record)
    except tuning.GainsFileError as error:
        assert not valid, error
        assert f"[{kind}.{gain_set}] {key} = " in str(error) and "\n" not in str(error)
        return
    assert valid
    assert gains[kind][gain_set][key] == float(value)


@pytest.mark.parametrize(
    ("changes", "figure"),
    [
        ({"delay": {"type": "constant", "h": 1e306}}, "delay"),  # 1e309 ms
        (
            {
                "reference": {
                    "type": "sinusoidal",
                    "offset": [0.0, 0.0],
                    "amplitude": [1e308, 0.5],
                    "frequency": [0.5, 0.7],
                }
            },
            "commands",
        ),  # an axis spanning 2e308
    ],
)
def test_a_figure_matplotlib_cannot_draw_is_left_out_with_a_warning(
    tmp_path, capsys, changes, figure
):
    """The run's tables and its other figures are written; the command ends well."""
    path = tmp_path / "huge.toml"
    load_builtin("two_link_S1").replace(duration=0.1, **changes).to_toml(path)
    out = tmp_path / "out"
    with warnings.catch_warnings():
        warnings.simplefilter("always", FigureNotDrawnWarning)  # the suite makes warnings errors
        assert main(["simulate", str(path), "--out", str(out), "--quiet"]) == 0
    err = capsys.readouterr().err
    assert f"warning: figure {figure!r} not drawn: its values are beyond what matplotlib" in err
    assert "Traceback" not in err and "RuntimeWarning" not in err, err
    assert (out / "metrics.csv").is_file() and (out / "trajectories.parquet").is_file()
    drawn = {p.stem for p in (out / "figures").glob("*.png")}
    assert figure not in drawn and {"tracking", "error"} <= drawn


def test_a_results_list_made_larger_than_any_run_writes_is_not_read(tmp_path):
    """The marker of a results folder someone sent may be made huge: past 16 MiB it is taken
    as listing nothing (as an unreadable one), not parsed (at about 11 times its size)."""
    from delaytrack._output import _listed

    names = [f"part-{i:09d}.parquet" for i in range(800_000)]
    (tmp_path / MANIFEST).write_text(json.dumps({"files": names}))
    assert (tmp_path / MANIFEST).stat().st_size > 16 * 2**20
    assert _listed(tmp_path) == []
    (tmp_path / MANIFEST).write_text(json.dumps({"files": names[:3]}))
    assert _listed(tmp_path) == names[:3]
