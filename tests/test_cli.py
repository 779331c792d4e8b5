"""The ``delaytrack`` command: bound, simulate, help and error handling.

Error paths run in a subprocess (the real entry point, exit code, stderr, no traceback); the
simulation runs in-process through ``main(argv)`` to keep the suite fast.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from delaytrack._output import MANIFEST
from delaytrack._validation import ArgumentError
from delaytrack.analysis import razumikhin_bound
from delaytrack.cli import main
from delaytrack.scenario import Scenario, load_builtin

PAPER_H_M = 0.12487


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "delaytrack.cli", *args], capture_output=True, text=True, timeout=300
    )


def bound_json(capsys, *args: str) -> dict:
    assert main(["bound", *args, "--json"]) == 0
    out = capsys.readouterr().out
    assert out.count("\n") == 1, "--json must print exactly one line"
    return json.loads(out)


# ---- bound --------------------------------------------------------------------------------------


@pytest.mark.parametrize("n", [1, 5])
def test_bound_paper_value(capsys, n):
    data = bound_json(
        capsys, "--k1", "1", "--k2", "1", "--q", "1", "--beta", "1", "--r", "1.1", "--n", str(n)
    )
    assert data["h_m"] == pytest.approx(PAPER_H_M, abs=1e-5)
    assert data["n"] == n and data["beta"] == 1.0 and data["r"] == 1.1
    assert data["lambda_min_Q"] == 1.0
    assert data["E_norm"] == pytest.approx(1.0 / data["h_m"])


def test_bound_paper_value_through_the_entry_point():
    done = run_cli(
        "bound", "--k1", "1", "--k2", "1", "--q", "1", "--beta", "1", "--r", "1.1", "--json"
    )
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["h_m"] == pytest.approx(PAPER_H_M, abs=1e-5)


def test_bound_other_gains_against_the_library(capsys):
    data = bound_json(
        capsys, "--k1", "2,3", "--k2", "1.5,4", "--q", "1,2,0.5,3", "--beta", "0.7", "--r", "1.3"
    )
    direct = razumikhin_bound(
        np.diag([2.0, 3.0]), np.diag([1.5, 4.0]), np.diag([1, 2, 0.5, 3.0]), 0.7, 1.3
    )
    assert data["n"] == 2
    assert data["h_m"] == pytest.approx(direct.h_m, rel=1e-12)
    assert data["E_norm"] == pytest.approx(direct.E_norm, rel=1e-12)
    assert data["lambda_min_Q"] == pytest.approx(0.5)


def test_bound_scalars_with_n_equal_the_expanded_diagonal(capsys):
    scalar = bound_json(capsys, "--k1", "2", "--k2", "3", "--q", "0.5", "--n", "3")
    listed = bound_json(capsys, "--k1", "2,2,2", "--k2", "3,3,3", "--q", "0.5,0.5,0.5,0.5,0.5,0.5")
    assert scalar["h_m"] == pytest.approx(listed["h_m"], rel=1e-14)
    assert listed["n"] == 3


def test_bound_text_output(capsys):
    assert main(["bound", "--k1", "1", "--k2", "1", "--q", "1"]) == 0
    out = capsys.readouterr().out
    assert "h_m" in out and "0.12487 s" in out and "lambda_min(Q)" in out


def test_bound_shows_a_tiny_bound_in_a_unit_that_reads(capsys):
    """High gains certify about a nanosecond: shown so, not as "1e-06 ms"."""
    h_m = razumikhin_bound(1000.0, 1000.0).h_m  # Theorem 1, the paper's Q = I, beta, r
    assert 0.5e-9 < h_m < 1.5e-9  # about a nanosecond, to 4 digits "1 ns"
    assert main(["bound", "--k1", "1000", "--k2", "1000"]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.strip().startswith("h_m"))
    assert line.endswith(f"= {h_m:.6g} s ({1e9 * h_m:.4g} ns)") and "e-06" not in line


def test_bound_and_design_show_an_r_just_above_one_as_given(capsys):
    # six significant digits would print the refused r = 1
    r = "1.0000000000000002"
    assert main(["bound", "--k1", "1", "--k2", "1.5", "--r", r]) == 0
    assert "K2 = 1.5 I, Q = 1 I, beta = 1, r = 1.0000000000000002\n" in capsys.readouterr().out
    assert main(["design", "--r", r]) == 0
    assert "r = 1.0000000000000002\n" in capsys.readouterr().out


def test_bound_r_of_one_is_refused_without_traceback():
    done = run_cli("bound", "--k1", "1", "--k2", "1", "--q", "1", "--beta", "1", "--r", "1")
    assert done.returncode == 2
    assert "Traceback" not in done.stderr
    assert done.stderr.strip().splitlines() == [
        "error: --r must be > 1 (the Razumikhin factor in V(e(xi)) < r V(e(t))); got 1"
    ]


def test_bound_negative_gain_shows_its_eigenvalues():
    done = run_cli("bound", "--k1", "-1", "--k2", "1", "--q", "1")
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert (
        "error: --k1 must be symmetric positive definite; its eigenvalues are [-1]" in done.stderr
    )
    assert "(got --k1 -1)" in done.stderr


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (
            ["--k1", "abc", "--k2", "1", "--q", "1"],
            "--k1 must be a number or a comma-separated list of numbers in decimal notation "
            "such as 2, 0.5 or 1e-3; got 'abc'",
        ),
        (["--k1", "1", "--k2", "1", "--q", "1", "--beta", "0"], "--beta must be > 0"),
        (["--k1", "1", "--k2", "1", "--q", "1,2,3"], "--q has 3 entries"),
        (["--k1", "1,2", "--k2", "1,2,3", "--q", "1"], "the comma lists disagree on n"),
        (
            ["--k1", "1,2", "--k2", "1", "--q", "1", "--n", "3"],
            "--k1 has 2 entries; with n = 3 it needs 1",
        ),
        (
            ["--k1", "1", "--k2", "1", "--q", "-2"],
            "--q must be symmetric positive definite; its eigenvalues are [-2, -2]",
        ),
        (["--k1", "1", "--k2", "1", "--q", "1", "--n", "0"], "--n must be an integer from 1 to"),
        (["--k1", "1", "--k2", "1", "--q", "1", "--n", "100000"], "got 100000"),
        (["--k1", "1e300", "--k2", "1", "--q", "1"], "cannot be solved accurately"),
        (["--k1", "1", "--k2", "1", "--q", "1", "--r", "nan"], "--r must be finite"),
    ],
)
def test_bound_bad_input_messages(capsys, args, message):
    assert main(["bound", *args]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and message in err
    assert len(err.strip().splitlines()) == 1


def test_bound_beta_is_refused_in_the_librarys_words_with_its_flag(capsys):
    assert main(["bound", "--k1", "1", "--k2", "1", "--q", "1", "--beta", "-0.5"]) == 2
    with pytest.raises(ArgumentError) as refused:
        razumikhin_bound(1.0, 1.0, 1.0, beta=-0.5)
    assert refused.value.argument == "beta"
    err = capsys.readouterr().err
    # the library's words, without the text given to the flag again (they end with it)
    assert err == "error: --beta must be > 0; got -0.5\n"
    assert err == f"error: --beta {refused.value.problem}\n"


def test_missing_argument_is_a_usage_error():
    done = run_cli("bound", "--k2", "1", "--q", "1")
    assert done.returncode == 2 and "--k1" in done.stderr and "Traceback" not in done.stderr


@pytest.mark.parametrize(
    ("command", "help"),
    [
        (["simulate", "two_link_S1"], "delaytrack simulate --help"),
        (["bound", "--k1", "1", "--k2", "1"], "delaytrack bound --help"),
        (["live", "replay", "folder"], "delaytrack live replay --help"),
        (["--frobnicate", "simulate", "two_link_S1"], "delaytrack --help"),  # given to the top
    ],
)
def test_an_unknown_option_points_to_the_help_of_its_command(command, help, capsys):
    with pytest.raises(SystemExit) as stop:
        main(command if "--frobnicate" in command else [*command, "--frobnicate"])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert err == f"error: unrecognized arguments: --frobnicate (see {help})\n"


@pytest.mark.parametrize(
    ("command", "shortened"),
    [
        (["reproduce", "--duration", "0.01"], "--no-robustnes"),  # a letter missing
        (["bound", "--k1", "1", "--k2", "1"], "--js"),  # the start of --json
        (["live", "replay", "folder"], "--quie"),
    ],
)
def test_a_flag_is_taken_only_as_spelled_in_full(command, shortened, tmp_path, capsys):
    out = ["--out", str(tmp_path / "out")] if command[0] == "reproduce" else []
    with pytest.raises(SystemExit) as stop:
        main([*command, *out, shortened])
    assert stop.value.code == 2
    assert f"unrecognized arguments: {shortened}" in capsys.readouterr().err


def test_a_value_that_starts_with_a_minus_is_shown_how_to_be_written(capsys):
    """argparse takes ``-50%`` for a flag; the error shows the form it takes as a value, and
    says nothing of the kind where no value was given."""
    with pytest.raises(SystemExit) as stop:
        main(["tradeoff", "robot.toml", "--knowledge", "-50%"])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert "--knowledge: expected one argument" in err
    assert "a value that starts with '-' is written --knowledge=-50%" in err
    with pytest.raises(SystemExit):
        main(["simulate", "x.toml", "--out"])
    err = capsys.readouterr().err
    assert "--out: expected one argument (see" in err and "starts with" not in err


@pytest.mark.parametrize(
    "command", [[], ["bound"], ["simulate"], ["reproduce"], ["tune-baselines"]]
)
def test_help_on_every_command(command, capsys):
    with pytest.raises(SystemExit) as stop:
        main([*command, "--help"])
    assert stop.value.code == 0
    assert "usage: delaytrack" in capsys.readouterr().out


# ---- simulate -----------------------------------------------------------------------------------


@pytest.fixture
def short_scenario(tmp_path):
    scenario = load_builtin("two_link_S1").replace(name="short", duration=0.5)
    path = tmp_path / "short.toml"
    scenario.to_toml(path)
    return path


@pytest.mark.parametrize(("h", "warned"), [(50.0, True), (0.5, True), (0.45, False)])
def test_simulate_says_when_the_delay_outlasts_the_run(tmp_path, capsys, h, warned):
    """A delay of 50 meant as milliseconds: no command ever reaches the plant, and says so."""
    path = tmp_path / "slip.toml"
    load_builtin("two_link_S1").replace(duration=0.5, delay={"type": "constant", "h": h}).to_toml(
        path
    )
    assert main(["simulate", str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    err = capsys.readouterr().err
    line = f"warning: the delay is never shorter than {h:g} s, and the run lasts 0.5 s: no command"
    assert (line in err) == warned, err


def test_simulate_writes_every_promised_file(short_scenario, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["simulate", str(short_scenario), "--out", str(out), "--format", "both"]) == 0
    printed = capsys.readouterr().out
    assert str(out) in printed
    # AROLC's h_m of the scenario's gains, in s and in the unit that reads
    from delaytrack.sim.certified_bound import certified_bounds

    h_m = certified_bounds([load_builtin("two_link_S1").build().controller])[0]
    line = next(x for x in printed.splitlines() if x.startswith("AROLC's certified"))
    assert line.startswith(f"AROLC's certified delay bound h_m = {h_m:.6g} s (")
    assert f"{1e3 * h_m:.4g} ms), by Theorem 1 with the scenario's K1, K2, Q" in line
    expected = ["scenario.toml", "trajectories.parquet", "trajectories.csv", "metrics.csv"]
    expected += [
        f"figures/{name}.{ext}"
        for name in ("tracking", "error", "commands", "delay", "c_hat")
        for ext in ("png", "svg")
    ]
    for name in expected:
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name
    hidden = [p for p in out.rglob(".*") if p.is_file() and p.name != MANIFEST]
    assert not hidden, "temporary files left behind"

    metrics = pd.read_csv(out / "metrics.csv")
    assert len(metrics) == 1 and metrics.loc[0, "status"] == "ok"
    # each metric with its unit (the arm's joints in rad, its torques in N·m)
    expected = {"ae_q1_rad", "ae_q2_rad", "rms_q1_rad", "max_q2_rad", "tv_Nm", "t_stop_s"}
    assert expected <= set(metrics.columns)
    assert np.isfinite(metrics.loc[0, "ae_q1_rad"]) and metrics.loc[0, "ae_q1_rad"] > 0

    frame = pd.read_parquet(out / "trajectories.parquet")
    assert len(frame) == 251 and frame["t_s"].iloc[-1] == pytest.approx(0.5)
    # One convention: coordinates counted from 1 as in metrics.csv, units in the names, the
    # controller's bookkeeping left out.
    assert list(frame.columns[:7]) == [
        "run",
        "t_s",
        "h_s",
        "q1_rad",
        "q1_dot_rad_per_s",
        "q1_d_rad",
        "e1_q1_rad",
    ]
    assert {"u1_sent_Nm", "u2_applied_Nm", "c_hat"} <= set(frame.columns)
    assert not any("previous" in column for column in frame.columns)
    csv = pd.read_csv(out / "trajectories.csv")
    np.testing.assert_allclose(
        csv["e1_q1_rad"].to_numpy(), frame["e1_q1_rad"].to_numpy(), rtol=1e-12
    )

    as_run = Scenario.from_toml(out / "scenario.toml")
    assert as_run == Scenario.from_toml(short_scenario).resolved()
    # Re-running the saved scenario reproduces the metrics.
    assert as_run.run().e1[0, -1, 0] == pytest.approx(frame["e1_q1_rad"].iloc[-1], rel=1e-12)


def test_simulate_default_folder_and_builtin_name(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    scenario = load_builtin("two_link_S3_outer_loop").replace(name="tiny", duration=0.1)
    scenario.to_toml(tmp_path / "tiny.toml")
    assert main(["simulate", "tiny.toml"]) == 0
    assert (tmp_path / "results" / "tiny" / "trajectories.parquet").is_file()
    figures = tmp_path / "results" / "tiny" / "figures"
    assert not (figures / "c_hat.png").exists()  # no ĉ for the outer loop
    # The legends name the run by its scenario (matplotlib writes each text as a comment).
    assert "<!-- tiny -->" in (figures / "tracking.svg").read_text()
    capsys.readouterr()


def test_simulate_bad_scenario_exits_2_naming_the_key(tmp_path):
    text = load_builtin("two_link_S1").to_toml().replace("alpha = 2.0", 'alpha = "two"')
    assert 'alpha = "two"' in text
    path = tmp_path / "bad.toml"
    path.write_text(text)
    done = run_cli("simulate", str(path), "--out", str(tmp_path / "o"))
    assert done.returncode == 2
    assert "Traceback" not in done.stderr
    assert "scenario key 'controller.alpha' must be a number; got 'two'" in done.stderr
    assert not (tmp_path / "o").exists()


def test_simulate_missing_file_exits_2(tmp_path):
    done = run_cli("simulate", str(tmp_path / "missing.toml"))
    assert (
        done.returncode == 2 and "does not exist" in done.stderr and "Traceback" not in done.stderr
    )


def test_simulate_refusal_at_build_exits_2(tmp_path, capsys):
    text = load_builtin("two_link_S1").to_toml().replace("K1 = 1.0", "K1 = -1.0")
    path = tmp_path / "neg.toml"
    path.write_text(text)
    assert main(["simulate", str(path), "--out", str(tmp_path / "o")]) == 2
    assert (
        "scenario key 'controller.K1' must be symmetric positive definite"
        in capsys.readouterr().err
    )


# ---- one convention for every command ---------------------------------------------------------


def test_a_bare_call_prints_the_commands_and_succeeds(capsys):
    assert main([]) == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: delaytrack") and "reproduce" in out and "tune-baselines" in out
    assert run_cli().returncode == 0


def test_bound_defaults_q_like_margin_and_the_python_api(capsys):
    from delaytrack.analysis import razumikhin_bound

    assert main(["bound", "--k1", "1", "--k2", "1", "--json"]) == 0
    default = json.loads(capsys.readouterr().out)
    assert main(["bound", "--k1", "1", "--k2", "1", "--q", "1", "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == default
    assert default["h_m"] == razumikhin_bound(1.0, 1.0).h_m  # Q = I, beta = 1, r = 1.1


def _commands() -> list[str]:
    """Every command of ``delaytrack`` but the live loop's group."""
    from delaytrack.cli import build_parser

    choices = build_parser()._subparsers._group_actions[0].choices
    return [name for name in choices if name != "live"]


_REQUIRED = {
    "bound": ["--k1", "1", "--k2", "1"],
    "margin": ["--k1", "1", "--k2", "1"],
    "simulate": ["x"],
    "empirical": ["x", "--threshold", "1"],
    "sweep": ["x"],
    "tradeoff": ["x"],
}


@pytest.mark.parametrize("command", _commands())
def test_every_command_takes_quiet_and_still_accepts_progress(command):
    from delaytrack.cli import build_parser

    args = build_parser().parse_args(
        [command, *_REQUIRED.get(command, []), "--quiet", "--progress"]
    )
    assert args.quiet


def test_quiet_changes_nothing_where_nothing_runs_long(capsys):
    for command in (["bound", "--k1", "1", "--k2", "1"], ["margin", "--k1", "1", "--k2", "1"]):
        assert main(command) == 0
        loud = capsys.readouterr()
        assert main([*command, "--quiet"]) == 0
        assert capsys.readouterr() == loud


@pytest.mark.parametrize("command", _commands())
def test_every_scenario_positional_is_named_scenario_and_the_sweeps_sweep(command, capsys):
    with pytest.raises(SystemExit):
        main([command, "--help"])
    usage = capsys.readouterr().out.split("\n\n")[0]
    assert "scenario" not in usage.replace("SCENARIO", "") and " spec" not in usage.lower()
    if command == "sweep":
        assert "SWEEP" in usage


def test_tune_baselines_help_states_one_default_output(capsys):
    with pytest.raises(SystemExit):
        main(["tune-baselines", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert text.count("default results/baseline_gains.toml") == 2
    assert "default: the package" not in text


def test_theorem_1_gains_say_their_meaning_and_unit(capsys):
    with pytest.raises(SystemExit):
        main(["bound", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "derivative gain K2 of the outer loop, 1/s" in text
    assert "proportional gain K1 of the outer loop, 1/s^2" in text


def test_tune_baselines_never_writes_into_the_package_by_default():
    from delaytrack.cli import build_parser
    from delaytrack.experiments.tuning import default_gains_path

    out = Path(build_parser().parse_args(["tune-baselines"]).out)
    assert out == Path("results") / "baseline_gains.toml"
    assert out.resolve() != default_gains_path().resolve()


def test_reproduce_gains_must_be_a_complete_gains_file(tmp_path, capsys):
    from delaytrack.cli.reproduce import _checked_gains
    from delaytrack.experiments.tuning import default_gains_path

    assert _checked_gains(str(default_gains_path())) == default_gains_path().resolve()
    assert main(["reproduce", "--gains", str(tmp_path / "none.toml"), "--out", str(tmp_path)]) == 2
    assert "--gains" in capsys.readouterr().err
    partial = tmp_path / "partial.toml"
    partial.write_text("[AROLC.all]\nk = 1.0\n")
    assert main(["reproduce", "--gains", str(partial), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --gains") and len(err.strip().splitlines()) == 1


def test_simulate_prints_the_metrics(short_scenario, tmp_path, capsys):
    assert main(["simulate", str(short_scenario), "--out", str(tmp_path / "r"), "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "AE q1 (rad)" in out and "TV (N·m)" in out  # the arm's inputs are torques


def _fast_gains_scenario(tmp_path: Path, delay: float) -> Path:
    """The shipped two-link scenario with K1 = K2 = 4 (h_m = 13.1 ms) under a constant delay."""
    builtin = load_builtin("two_link_S1")
    controller = {**builtin.to_dict()["controller"], "K1": 4.0, "K2": 4.0}
    scenario = builtin.replace(
        name="fast",
        duration=0.5,
        controller=controller,
        delay={"type": "constant", "h": delay},
    )
    path = tmp_path / f"fast_{delay:g}.toml"
    scenario.to_toml(path)
    return path


def test_simulate_reports_h_m_and_warns_in_one_line_beyond_it(tmp_path, capsys):
    h_m = razumikhin_bound(4.0, 4.0).h_m
    beyond = _fast_gains_scenario(tmp_path, 0.04)
    assert main(["simulate", str(beyond), "--out", str(tmp_path / "b"), "--quiet"]) == 0
    captured = capsys.readouterr()
    assert f"h_m = {h_m:.6g} s" in captured.out
    warning = [line for line in captured.err.splitlines() if line.startswith("warning:")]
    assert len(warning) == 1
    assert "40 ms exceeds AROLC's certified bound h_m = 13.14 ms" in warning[0]
    assert "does not by itself mean instability" in warning[0]
    within = _fast_gains_scenario(tmp_path, 0.005)
    assert main(["simulate", str(within), "--out", str(tmp_path / "w"), "--quiet"]) == 0
    captured = capsys.readouterr()
    assert f"h_m = {h_m:.6g} s" in captured.out and "warning" not in captured.err


def test_simulate_says_nothing_of_h_m_for_a_controller_without_one(tmp_path, capsys):
    scenario = load_builtin("two_link_S1").replace(
        name="outer", duration=0.5, controller={"type": "outer-loop", "K1": 1.0, "K2": 1.0}
    )
    scenario.to_toml(tmp_path / "outer.toml")
    assert main(["simulate", str(tmp_path / "outer.toml"), "--out", str(tmp_path / "o")]) == 0
    captured = capsys.readouterr()
    assert "h_m" not in captured.out and "warning" not in captured.err


def test_live_replay_of_a_folder_that_is_not_there_says_so(tmp_path, capsys):
    assert main(["live", "replay", str(tmp_path / "nowhere")]) == 2
    err = capsys.readouterr().err
    folder = tmp_path / "nowhere"
    assert err == f"error: {folder} does not exist: give the folder of a live session\n"
    (tmp_path / "file").write_text("")
    assert main(["live", "replay", str(tmp_path / "file")]) == 2
    assert "is not a folder" in capsys.readouterr().err
