"""The ``delaytrack margin`` and ``delaytrack design`` commands: values, output, refused input."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from delaytrack._validation import ArgumentError
from delaytrack.analysis import design_gains, exact_delay_margin, razumikhin_bound
from delaytrack.cli import main

PAPER_H_M = 0.12487
IDENTITY_MARGIN = 0.711118648715793


def json_of(capsys, *args: str) -> dict:
    assert main([*args, "--json"]) == 0
    out = capsys.readouterr().out
    assert out.count("\n") == 1, "--json must print exactly one line"
    return json.loads(out)


# ---- margin -------------------------------------------------------------------------------------


def test_margin_readme_example_through_the_entry_point():
    done = subprocess.run(
        [sys.executable, "-m", "delaytrack.cli", "margin", "--k1", "1", "--k2", "1"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    assert "h_m (certified, Theorem 1)  = 0.12487 s" in done.stdout
    assert "h_exact (constant delay)    = 0.711119 s" in done.stdout
    assert "h_m / h_exact               = 0.1756" in done.stdout


def test_margin_json_for_the_paper_gains(capsys):
    data = json_of(capsys, "margin", "--k1", "1", "--k2", "1", "--n", "5")
    assert data["n"] == 5
    assert data["h_m"] == pytest.approx(PAPER_H_M, abs=1e-5)
    assert data["h_exact"] == pytest.approx(IDENTITY_MARGIN, rel=1e-12)
    assert data["omega_exact"] == pytest.approx(1.272019649514069, rel=1e-12)
    assert data["ratio"] == pytest.approx(data["h_m"] / data["h_exact"])


def test_margin_diagonal_lists_against_the_library(capsys):
    data = json_of(
        capsys, "margin", "--k1", "1,4", "--k2", "2,0.5", "--q", "1,2,1,3", "--beta", "0.7"
    )
    bound = razumikhin_bound([1.0, 4.0], [2.0, 0.5], [1.0, 2.0, 1.0, 3.0], 0.7, 1.1)
    exact = exact_delay_margin([1.0, 4.0], [2.0, 0.5])
    assert data["h_m"] == bound.h_m
    assert data["h_exact"] == exact.h
    assert data["crossing_omegas"] == list(exact.crossing_omegas)
    assert data["crossing_delays"] == list(exact.crossing_delays)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--k1", "-1", "--k2", "1"], "--k1 must be symmetric positive definite"),
        (["--k1", "1", "--k2", "0"], "--k2 must be symmetric positive definite"),
        (["--k1", "1", "--k2", "x"], "--k2 must be a number or a comma-separated list"),
        (["--k1", "1", "--k2", "1", "--r", "1"], "--r must be > 1"),
        (["--k1", "1", "--k2", "nan"], "--k2 must be finite"),
        (["--k1", "1,2", "--k2", "1,2,3"], "the comma lists disagree on n"),
    ],
)
def test_margin_bad_input_messages(capsys, args, message):
    assert main(["margin", *args]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and message in err
    assert len(err.strip().splitlines()) == 1


# ---- design -------------------------------------------------------------------------------------


def test_design_json_is_the_library_design(capsys):
    data = json_of(capsys, "design", "--n", "2", "--gain-bound", "1", "--seed", "0")
    design = design_gains(n=2, gain_bound=1.0, seed=0)
    assert data["n"] == 2
    assert data["h_m"] == design.h_m
    assert data["k1"] == design.K1[0, 0] and data["k2"] == design.K2[0, 0]
    assert data["h_exact"] == design.exact.h
    assert data["h_m"] >= PAPER_H_M and data["k1"] <= 1.0 and data["k2"] <= 1.0


def test_design_text_output(capsys):
    assert main(["design"]) == 0
    out = capsys.readouterr().out
    assert "every entry of K1 and K2 <= 1" in out
    assert "h_m = 0.126819 s" in out and "the paper's K1 = K2 = Q = I" in out
    assert "exact margin of these gains" in out


def test_design_with_a_least_bandwidth(capsys):
    data = json_of(capsys, "design", "--gain-bound", "10", "--min-bandwidth", "2")
    assert data["min_bandwidth"] == 2.0 and data["bandwidth_active"] and data["k1"] >= 4.0
    assert data["h_m"] == design_gains(gain_bound=10.0, min_bandwidth=2.0).h_m


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--gain-bound", "0"], "--gain-bound must be > 0"),
        (["--gain-bound", "inf"], "--gain-bound must be finite"),
        (["--gain-bound", "1,2"], "--gain-bound must be a single number"),
        (["--r", "0.5"], "--r must be > 1"),
        (["--seed", "-3"], "--seed must be a non-negative integer; got -3"),
        (["--n", "0"], "--n must be an integer from 1 to"),
        (["--min-bandwidth", "0"], "--min-bandwidth must be > 0 rad/s"),
        (["--min-bandwidth", "2"], "needs K1 entries >= 4, above --gain-bound = 1"),
    ],
)
def test_design_bad_input_messages(capsys, args, message):
    assert main(["design", *args]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and message in err
    assert len(err.strip().splitlines()) == 1


@pytest.mark.parametrize(
    ("args", "line"),
    [
        (["--gain-bound", "-0.5"], "error: --gain-bound must be > 0; got -0.5\n"),
        (
            ["--seed", "4294967296"],
            "error: --seed must be a non-negative integer; got 4294967296 (seeds run from 0 to "
            "2**32 - 1 = 4294967295)\n",
        ),
    ],
)
def test_design_leaves_the_gain_bound_and_seed_to_the_library(capsys, args, line):
    assert main(["design", *args]) == 2
    assert capsys.readouterr().err == line
    argument = args[0].removeprefix("--").replace("-", "_")
    value = float(args[1]) if argument == "gain_bound" else int(args[1])
    with pytest.raises(ArgumentError) as refused:
        design_gains(**{argument: value})
    assert refused.value.argument == argument
    assert line == f"error: {args[0]} {refused.value.problem}\n"  # the library's words


@pytest.mark.parametrize("command", ["margin", "design"])
def test_help(command, capsys):
    with pytest.raises(SystemExit) as stop:
        main([command, "--help"])
    assert stop.value.code == 0
    assert "usage: delaytrack" in capsys.readouterr().out


def test_readme_shows_what_margin_prints(capsys):
    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    assert main(["margin", "--k1", "1", "--k2", "1"]) == 0
    for line in capsys.readouterr().out.splitlines()[:5]:
        assert f"    {line}\n" in readme
