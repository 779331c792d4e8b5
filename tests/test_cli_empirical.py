"""The ``delaytrack empirical`` command and ``delaytrack reproduce --job margins``."""

from __future__ import annotations

import json
import math

import pandas as pd
import pytest

from delaytrack.analysis.razumikhin import PAPER_BETA, PAPER_R, razumikhin_bound
from delaytrack.cli import main
from delaytrack.experiments.margins import GAINS, SCENARIO, SEARCH
from delaytrack.scenario import load_builtin
from test_empirical_margin import TOLERANCE, double_integrator

IDENTITY_MARGIN = 0.711118648715793


@pytest.fixture
def scenario_file(tmp_path):
    path = tmp_path / "double_integrator.toml"
    double_integrator(1.0, 1.0).to_toml(path)
    return str(path)


def test_empirical_json_agrees_with_the_exact_margin(scenario_file, capsys):
    args = ["empirical", scenario_file, "--threshold", "1", "--metric", "max", "--upper", "1.6"]
    assert main([*args, "--resolution", "0.002", "--json"]) == 0
    out = capsys.readouterr().out
    assert out.count("\n") == 1
    data = json.loads(out)
    assert data["failure_found"] is True
    assert data["h_exact"] == pytest.approx(IDENTITY_MARGIN, rel=1e-12)
    assert abs(data["margin"] - IDENTITY_MARGIN) <= 0.002 + TOLERANCE
    assert data["h_m"] < data["margin"]
    # Theorem 1 with the paper's beta and r, K1 = K2 = 1 and Q = I (an outer loop has no Q).
    assert data["h_m"] == razumikhin_bound(1.0, 1.0, 1.0, PAPER_BETA, PAPER_R).h_m
    assert (data["threshold"], data["metric"], data["resolution"]) == (1.0, "max", 0.002)


def test_empirical_text_states_threshold_resolution_and_the_analytic_margins(scenario_file, capsys):
    args = ["empirical", scenario_file, "--threshold", "1", "--metric", "max", "--upper", "1.6"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "Empirical delay margin of 'double_integrator' (outer-loop; constant delay h)" in out
    assert "max <= 1 (in each coordinate's unit) after t = 50 s; resolution 0.005 s" in out
    assert "h_exact     = 0.711119 s" in out
    assert "h_m         = " in out
    assert f"; beta = {PAPER_BETA:g}, r = {PAPER_R:g})\n" in out


def test_empirical_reports_no_failure_below_upper(scenario_file, capsys):
    assert main(["empirical", scenario_file, "--threshold", "10", "--upper", "0.3"]) == 0
    assert "no failure up to upper = 0.3 s" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--threshold", "-1"], "error: --threshold must be > 0; got -1"),
        (["--threshold", "x"], "error: --threshold must be a number"),
        (
            ["--threshold", "1,2"],
            "error: --threshold must be a number > 0, or a list of one number > 0 per coordinate "
            "(1: q1); got [1, 2]",
        ),
        (["--threshold", "1", "--resolution", "2"], "error: --resolution must be smaller than"),
        (["--threshold", "1", "--settle", "500"], "error: --settle must be below the scenario"),
    ],
)
def test_empirical_refuses_bad_options(scenario_file, capsys, extra, message):
    assert main(["empirical", scenario_file, *extra]) == 2
    assert message in capsys.readouterr().err


def test_a_default_upper_longer_than_the_run_says_it_is_the_default(tmp_path, capsys):
    path = tmp_path / "short.toml"
    double_integrator(1.0, 1.0, duration=0.5).to_toml(path)
    assert main(["empirical", str(path), "--threshold", "1"]) == 2
    err = capsys.readouterr().err
    assert "--upper must be at most the scenario's duration 0.5 s" in err
    assert err.endswith("got 1 (the default of --upper; give a smaller --upper S)\n")
    assert main(["empirical", str(path), "--threshold", "1", "--upper", "1"]) == 2
    assert capsys.readouterr().err.endswith("got 1\n")


def test_a_default_upper_beyond_a_predictors_history_says_so_once(tmp_path, capsys):
    """The library's advice in the command's flag, and that it is the default, once each (it
    read "give a smaller upper (the default of --upper; give a smaller --upper S)")."""
    pcon = {"type": "pcon", "kappa": 1.0, "vartheta": 1.0, "k_b": 1.0, "T_c": 0.002}
    path = tmp_path / "pcon.toml"
    scenario = load_builtin("two_link_S1").replace(controller={**pcon, "history": 0.2})
    scenario.replace(duration=4.0).to_toml(path)
    assert main(["empirical", str(path), "--threshold", "0.3"]) == 2
    err = capsys.readouterr().err
    assert "--upper = 1 s searches delays up to 1 s, under which PCON cannot run" in err
    assert err.endswith("; give a smaller --upper (the default of --upper)\n")
    assert err.count("give a smaller") == 1


def test_empirical_needs_a_threshold_and_a_scenario(capsys):
    with pytest.raises(SystemExit) as stop:
        main(["empirical", "two_link_margins"])
    assert stop.value.code == 2
    assert "--threshold" in capsys.readouterr().err
    assert main(["empirical", "no_such_scenario", "--threshold", "1"]) == 2
    assert "nor is it a built-in scenario" in capsys.readouterr().err


def test_margins_job_writes_its_files(tmp_path, capsys):
    args = ["reproduce", "--job", "margins", "--out", str(tmp_path), "--duration", "6", "--quiet"]
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert "margins job done" in printed
    lines = printed.splitlines()
    at = next(i for i, line in enumerate(lines) if "k1_per_s2" in line.split())
    header = lines[at].split()
    assert header[:4] == ["k1_per_s2", "k2_per_s", "h_m_s", "h_exact_s"]  # as margins.csv
    first = next(i for i, line in enumerate(lines) if line.startswith("K1 = k1 I"))
    legend = " ".join(lines[first:at])
    for column in header[2:8]:  # every margin's column is said in words above the table
        assert f"{column}: " in legend, column
    assert f"no failure found up to {SEARCH['upper']:g} s" in legend  # the search's limit
    folder = tmp_path / "margins"
    for name in ("margins.csv", "evaluated.csv", "scenario.toml", "report.html"):
        assert (folder / name).is_file(), name
    for suffix in ("png", "svg"):
        assert (folder / "figures" / f"margins.{suffix}").is_file()
    table = pd.read_csv(folder / "margins.csv")  # units in the column names
    assert len(table) == len(GAINS) ** 2
    # On the terminal an empirical margin is never above the one found, nor shown to more
    # decimals than the search's resolution has (0.005 s: 3).
    decimals = math.ceil(-math.log10(SEARCH["resolution"]))
    rows = [line.split() for line in lines[at + 1 : at + 1 + len(table)]]
    column = header.index("arolc_abs_sine_s")
    for row, found in zip(rows, table["arolc_abs_sine_s"], strict=True):
        if row[column] != "—":
            assert float(row[column]) <= found < float(row[column]) + 10.0**-decimals
            assert len(row[column].split(".")[1]) == decimals
    assert (table["h_m_s"] < table["h_exact_s"]).all()
    assert {"k1_per_s2", "k2_per_s", "arolc_abs_sine_s", "h_m_over_h_exact"} <= set(table)
    evaluated = pd.read_csv(folder / "evaluated.csv")
    assert {"k1_per_s2", "delay_s", "metric_rad", "metric_q1_rad", "status"} <= set(evaluated)
    html = (folder / "report.html").read_text()
    assert "data:image/png;base64," in html and "What the gap means" in html
    shown = html.replace("<wbr>", "")  # the page's tables may break a name at its "_"
    assert ">k1_per_s2</th>" in shown and ">h_exact_s</th>" in shown  # units, as the file
    # every gain pair is counted once: within 15 % of h_exact, above, below, or unbounded
    outer = table["outer_loop_constant_s"] / table["h_exact_s"] - 1.0
    close, above = int((outer.abs() <= 0.15).sum()), int((outer > 0.15).sum())
    below, unbounded = int((outer < -0.15).sum()), int(outer.isna().sum())
    assert close + above + below + unbounded == len(table)
    assert f"in {close} of {len(table)} gain pairs" in html and f"higher in {above}" in html
    assert f"It is lower in {below};" in html
    assert ("no failure up to the search limit in" in html) == (unbounded > 0)


def test_margins_job_too_short_for_its_tracking_rule_is_a_usage_error(tmp_path, capsys):
    """The job has no --threshold: the error names the flag that mends it, --duration."""
    args = ["reproduce", "--job", "margins", "--out", str(tmp_path), "--duration", "4", "--quiet"]
    assert main(args) == 2
    err = capsys.readouterr().err
    # the search's first gain pair, (GAINS[0], GAINS[0]), misses the rule in 4 s
    first = f"AROLC at K1 = {GAINS[0]:g} I, K2 = {GAINS[0]:g} I"
    assert f"error: margins job: --duration = 4 s is too short: {first}" in err
    assert "already without delay (ae of q1 = " in err
    own = load_builtin(SCENARIO).duration
    assert f"give a longer --duration (the job's own, {own:g} s, meets it)" in err
    assert "threshold" not in err


def test_empirical_takes_a_threshold_per_coordinate(tmp_path, capsys):
    path = tmp_path / "two_axes.toml"
    double_integrator([1.0, 1.0], [1.0, 1.0], duration=10.0, x0=[1.0, 10.0, 0.0, 0.0]).to_toml(path)
    args = ["empirical", str(path), "--threshold", "0.5, 5", "--metric", "max", "--upper", "1"]
    assert main([*args, "--json", "--quiet"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["threshold"] == [0.5, 5.0] and data["coordinate_names"] == ["q1", "q2"]
    assert main([*args, "--quiet"]) == 0
    assert "max <= (q1 0.5, q2 5) (each in its coordinate's unit)" in capsys.readouterr().out


def test_a_margin_with_no_failure_up_to_the_limit_is_drawn_hatched_to_the_limit():
    """A NaN margin of a searched series (no failure up to the search limit) is a lower bound,
    not a small margin: its bar reaches the limit, hatched and unfilled, and the legend says
    what that means; a NaN of a series not searched is not drawn."""
    import numpy as np

    from delaytrack.report.figures import margins_figure

    margins = {
        "h_m": [np.nan, 0.12, 0.05],
        "empirical": [0.6, np.nan, 0.5],
        "other": [0.3, 0.7, np.nan],
    }
    limits = {"empirical": 2.0, "other": 1.5}
    ax = margins_figure(margins, ["a", "b", "c"], xlabel="gains", at_least=limits).axes[0]
    hatched = [bar for bar in ax.patches if bar.get_hatch() and np.isfinite(bar.get_height())]
    assert [bar.get_height() for bar in hatched] == [2.0, 1.5]  # not h_m's NaN
    assert not any(bar.get_fill() for bar in hatched)
    legend = [text.get_text() for text in ax.get_legend().get_texts()]
    assert legend[-1] == "hatched: no failure up to the search limit (at least that)"
    known = margins_figure({"h_m": [0.1, 0.12]}, ["a", "b"], xlabel="gains", at_least=limits)
    assert not any(bar.get_hatch() for bar in known.axes[0].patches)  # nothing unknown: no hatch
