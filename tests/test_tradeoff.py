"""The accuracy–delay-margin trade-off: its margins against independent exact margins, the
Pareto front by brute force, resuming after a lost part, and the command's refusals."""

from __future__ import annotations

import math
import re

import numpy as np
import pandas as pd
import pytest

from delaytrack.cli import main
from delaytrack.experiments.tradeoff import MARGIN_SEARCHES, pareto_front, run_tradeoff
from delaytrack.scenario import Scenario, load_builtin

#: A small linear plant of our own: a unit mass whose nominal model is 20 % light, tracking a
#: slow sine under a constant 50 ms delay.
PLANT = {
    "name": "light_mass",
    "duration": 8.0,
    "dt": 0.002,
    "T_c": 0.002,
    "x0": [0.0, 0.0],
    "plant": {"type": "linear", "mass": [1.0]},
    "model": {"type": "linear", "mass": [0.8]},
    "controller": {
        "type": "arolc",
        **{"K1": 1.0, "K2": 1.0, "Q": 1.0, "alpha": 2.0, "epsilon": 0.1, "gamma": 0.001},
    },
    "delay": {"type": "constant", "h": 0.05},
    "reference": {"type": "sinusoidal", "offset": [0.0], "amplitude": [0.5], "frequency": [0.5]},
}
OMEGAS = (0.7, 1.4)
ZETA = 0.8
DRAWS = {"plant.mass": {"dist": "uniform", "low": 0.8, "high": 1.2}}


def _study(out):
    return run_tradeoff(
        Scenario.from_dict(PLANT),
        out,
        zeta=ZETA,
        omegas=OMEGAS,
        draws=3,
        random=DRAWS,
        upper=2.0,
        resolution=0.05,
    )


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    return _study(tmp_path_factory.mktemp("tradeoff"))


def test_exact_margins_are_those_of_exact_delay_margin(study):
    rows = study.table[study.table.controller.isin(["arolc", "outer-loop"])]
    assert len(rows) == 2 * len(OMEGAS)
    for row in rows.itertuples():
        k1, k2 = row.omega_n**2, 2 * ZETA * row.omega_n  # K1 = w_n^2, K2 = 2 zeta w_n
        assert (row.k1, row.k2) == pytest.approx((k1, k2))
        # s^2 + (k2 s + k1) e^{-sh} on the imaginary axis: |k1 + j k2 w| = w^2 at the crossing
        # w_c, and the first delay is the phase of k1 + j k2 w_c over w_c.
        crossing = math.sqrt((k2**2 + math.sqrt(k2**4 + 4 * k1**2)) / 2)
        closed_form = math.atan2(k2 * crossing, k1) / crossing
        assert row.h_exact == pytest.approx(closed_form, rel=1e-9)
    assert study.table.loc[study.table.controller != "arolc", "h_m"].isna().all()
    assert set(study.families) == {"arolc", "outer-loop", "pcon", "pconf"}


def test_pareto_front_is_non_dominated_by_brute_force(study):
    table = study.table
    valid = table.ae_median.notna() & table.empirical_margin.notna()
    for i, row in table.iterrows():
        # a margin at the search limit is a lower bound: no other point is known to beat it
        dominated = row.margin_found and any(
            other.ae_median <= row.ae_median
            and other.empirical_margin >= row.empirical_margin
            and (other.ae_median < row.ae_median or other.empirical_margin > row.empirical_margin)
            for j, other in table[valid].iterrows()
            if j != i
        )
        assert row.pareto == (bool(valid[i]) and not dominated)
    assert table.pareto.any()


def test_the_front_lists_tied_margins_by_their_accuracy():
    """Lower bounds at the search limit tie: the front's line reaches the most accurate first."""
    from types import SimpleNamespace

    from delaytrack.experiments.tradeoff import TradeoffStudy

    table = pd.DataFrame(
        {
            "empirical_margin": [1.0, 0.3, 1.0, 1.0],
            "ae_median": [0.17, 0.005, 0.02, 0.06],
            "pareto": [True, True, True, True],
        }
    )
    front = TradeoffStudy.front.fget(SimpleNamespace(table=table))
    assert list(front.ae_median) == [0.005, 0.02, 0.06, 0.17]


def test_pareto_front_small_cases():
    assert pareto_front([1, 2, 3], [1, 2, 3]).tolist() == [True, True, True]
    assert pareto_front([1, 2, np.nan], [3, 2, 5]).tolist() == [True, False, False]
    assert pareto_front([1, 1], [2, 2]).tolist() == [True, True]
    # the second margin is a lower bound (no failure up to the limit): never dominated
    assert pareto_front([1, 2], [3, 3], [True, False]).tolist() == [True, True]
    assert pareto_front([1, 2], [3, 3], [False, True]).tolist() == [True, False]


def test_resuming_after_deleting_a_part_gives_the_same_table(tmp_path):
    first = _study(tmp_path)
    parts = sorted((tmp_path / "sweep" / "parts").glob("part-*.parquet"))
    assert parts
    parts[0].unlink()
    again = _study(tmp_path)
    assert again.computed == 1 and again.resumed == len(parts) - 1
    pd.testing.assert_frame_equal(first.table, again.table)
    pd.testing.assert_frame_equal(first.runs, again.runs)


def test_command_writes_the_table_figure_and_page(tmp_path, capsys):
    scenario = tmp_path / "light_mass.toml"
    Scenario.from_dict(PLANT).to_toml(scenario)
    out = tmp_path / "out"
    args = ["tradeoff", str(scenario), "--omega", "0.7", "1.4", "2", "--upper", "2"]
    assert main([*args, "--zeta", str(ZETA), "--out", str(out), "--draws", "3", "--quiet"]) == 0
    table = pd.read_csv(out / "tradeoff.csv")
    assert {"omega_n_rad_per_s", "k1_per_s2", "h_m_s", "h_exact_s", "empirical_margin_s"} <= set(
        table.columns
    )
    assert (out / "figures" / "pareto.png").is_file() and (out / "report.html").is_file()
    printed = capsys.readouterr().out
    assert "Pareto front" in printed
    assert re.search(r"omega_n = \S+ +rad/s  margin = \S+ s  AE = \S+", printed), printed
    # A margin shown as a lower bound ("2+ s") is explained, and only then.
    assert ("+ s  AE" in printed) == (
        "+: a lower bound: the loop did not leave the path" in printed
    )
    # The linear plant draws nothing: one run per point, and the line says why not three.
    assert (
        "1 draw each (not the 3 of --draws: the scenario draws nothing, so every draw would be "
        "the same run)"
    ) in printed


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--zeta", "-1"], "--zeta: must be a damping ratio > 0; got '-1'"),
        (["--draws", "0"], "--draws: must be an integer >= 1; got '0'"),
        (["--omega", "2", "1", "3"], "--omega must be LO HI N with 0 < LO <= HI"),
        (["--omega", "1", "2", "100000000"], "N an integer from 1 to 1000"),
        (["--omega", "1", "1e308", "3"], "--omega must give the gains K1 = omega_n² and K2"),
        (["--zeta", "1e308"], "with --zeta = 1e+308 gives K1 = "),
        (["--upper", "1e-300"], "--upper must be larger than the margin searches' resolution"),
        (["--omega", "1", "2", "x"], "--omega must be LO HI N"),
        # equal ends give one point: three copies of it would count its runs three times
        (["--omega", "2", "2", "3"], "N > 1 needs LO < HI"),
        (["--threshold", "0"], "--threshold"),
        (["--threshold", "1,2"], "--threshold must be a number > 0 or one per scored coordinate"),
        (["--scheduler", "nowhere"], "--scheduler must be"),
        (["--envelope", "0.1", "--knowledge", "often"], "--knowledge must be exact, ±X%"),
        (["--envelope", "0.1", "--knowledge", "150%"], "got '150%'"),
        (["--envelope", "-1"], "--envelope: must be a largest delay > 0 (s); got '-1'"),
        (  # 300 meant as ms; refused before the trade-off runs
            ["--envelope", "300"],
            "--envelope must be less than the scenario's duration 8 s (under a delay that long "
            "no command reaches the plant); got 300",
        ),
        (["--envelope", "8"], "--envelope must be less than the scenario's duration 8 s"),
        (["--knowledge", "exact"], "--knowledge exact needs --envelope H_MAX"),
        (["--decision-draws", "5"], "--decision-draws 5 needs --envelope H_MAX"),
        (
            ["--envelope", "0.1", "--decision-draws", "0"],
            "--decision-draws: must be an integer >= 1; got '0'",
        ),
    ],
)
def test_bad_flags_exit_2_with_one_line(tmp_path, capsys, extra, message):
    scenario = tmp_path / "light_mass.toml"
    Scenario.from_dict(PLANT).to_toml(scenario)
    try:  # argparse's own refusals exit; the command's return
        code = main(["tradeoff", str(scenario), "--out", str(tmp_path / "o"), *extra])
    except SystemExit as exit_:
        code = exit_.code
    assert code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: ") and message in err, err


@pytest.mark.parametrize(("extra", "decision_draws"), [([], 8), (["--decision-draws", "80"], 80)])
def test_the_decision_draws_its_own_robots_or_the_trade_offs(
    tmp_path, monkeypatch, extra, decision_draws
):
    """``--decision-draws`` sets the decision's draws per condition; without it the decision
    draws as many as the trade-off (``--draws``)."""
    from delaytrack.experiments import decision, tradeoff

    seen = {}
    monkeypatch.setattr(tradeoff, "run_tradeoff", lambda *a, draws, **k: seen.update(front=draws))

    def run_decision(*arguments, draws, **options):
        seen["decision"] = draws
        raise KeyboardInterrupt  # the command stops here, as on Ctrl-C

    monkeypatch.setattr(decision, "run_decision", run_decision)
    scenario = tmp_path / "light_mass.toml"
    Scenario.from_dict(PLANT).to_toml(scenario)
    command = ["tradeoff", str(scenario), "--out", str(tmp_path / "o"), "--draws", "8"]
    assert main([*command, "--envelope", "0.3", *extra, "--quiet"]) == 130
    assert seen == {"front": 8, "decision": decision_draws}


def test_more_gain_points_than_a_study_can_search_are_refused_before_any_work(tmp_path):
    with pytest.raises(ValueError, match=r"omegas must be at most 1000 natural frequencies"):
        run_tradeoff(Scenario.from_dict(PLANT), tmp_path / "o", zeta=ZETA, omegas=[1.0] * 1001)
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"omegas": [1.0, 2.0, 1.0]}, "omegas must be distinct natural frequencies"),
        ({"beta": -1.0}, "beta"),
        ({"beta": math.nan}, "beta"),
        ({"r": 0.5}, "r must be a number > 1"),
        ({"r": math.inf}, "r must be a number > 1"),
        ({"threshold": [0.1, 0.1]}, "one per scored coordinate (1: q1)"),
    ],
)
def test_arguments_that_would_miscount_or_give_nan_are_refused_before_any_work(
    tmp_path, options, message
):
    arguments = {"zeta": ZETA, "omegas": OMEGAS, **options}
    with pytest.raises(ValueError, match=re.escape(message)):
        run_tradeoff(Scenario.from_dict(PLANT), tmp_path / "o", **arguments)
    assert not (tmp_path / "o").exists()


def test_a_threshold_for_a_coordinate_the_scenario_does_not_score_is_refused(tmp_path):
    """The robot's error_bound scores x and y: five bounds would drop three without a word."""
    robot = load_builtin("robot_S1")
    with pytest.raises(ValueError, match=r"one per scored coordinate \(2: x, y\); the other"):
        run_tradeoff(robot, tmp_path / "o", omegas=[1.0], threshold=[1, 1, 1e-9, 1e-9, 1e-9])


def test_a_search_that_misses_the_rule_without_delay_is_not_called_a_lower_bound(tmp_path):
    from delaytrack.experiments.tradeoff import _evaluated, _search_outcome

    assert _search_outcome(True, None) == "rule missed without delay"
    assert _search_outcome(False, None) == "not searched"
    assert set(MARGIN_SEARCHES) >= {"rule missed without delay", "no failure up to the limit"}
    # no search kept a point: the table still has its columns
    empty = _evaluated({"arolc": [None]}, (1.0,), ("x",), ("m",), (True,))
    assert empty.empty and {"omega_n", "controller", "value", "metric_m", "status"} <= set(
        empty.columns
    )


def test_the_table_counts_every_run_off_the_path_by_reason(study):
    table = study.table
    assert (table.on_path + table.stopped + table.over_threshold == table.runs).all()
    assert (table.stopped >= 0).all() and (table.over_threshold >= 0).all()
    assert table.margin_search.isin(list(MARGIN_SEARCHES)).all()
    assert (table.margin_found == (table.margin_search == "failure found")).all()


def test_every_metric_column_of_the_evaluated_points_has_its_unit():
    """A robot's positions (m) are scored, its heading (rad) is not: each coordinate's metric
    carries its unit, and the combined metric is the largest of the scored ones, in metres —
    not the heading's larger number in radians."""
    from delaytrack.experiments.empirical_margin import EmpiricalMargin
    from delaytrack.experiments.tradeoff import _evaluated

    names, units, scored = ("x", "y", "phi"), ("m", "m", "rad"), (True, True, False)
    search = EmpiricalMargin(
        margin=0.1,
        failure_found=True,
        first_failure=0.2,
        profile="constant",
        frequency=1.0,
        metric="mean_abs_e1",
        threshold=(0.05, 0.05, float(np.finfo(float).max)),
        settle=0.0,
        resolution=0.1,
        upper=1.0,
        values=np.array([0.1, 0.2, 0.3]),
        statuses=np.array([0, 0, 1]),
        coordinate_metrics=np.array([[0.01, 0.02, 3.0], [0.07, 0.01, 2.0], [np.nan] * 3]),
        coordinate_names=names,
        scenario="robot",
        controller="arolc",
        simulations=3,
        rounds=1,
    )

    def metric_columns(*arguments):
        frame = _evaluated({"arolc": [search]}, (1.0,), names, *arguments)
        return frame, [column for column in frame if column.startswith("metric")]

    frame, columns = metric_columns(units, scored)
    assert columns == ["metric_m", "metric_x_m", "metric_y_m", "metric_phi_rad"]
    np.testing.assert_array_equal(frame["metric_m"], [0.02, 0.07, np.nan])
    assert list(frame["passes"]) == [True, False, False]
    # Scored coordinates of different units have no combined metric.
    _, columns = metric_columns(units, (True, False, True))
    assert columns == ["metric_x_m", "metric_y_m", "metric_phi_rad"]
    # A plant without units: each coordinate's metric and the largest of the scored ones,
    # without a unit; one scored coordinate: its own.
    frame, columns = metric_columns((None,) * 3, scored)
    assert columns == ["metric", "metric_x", "metric_y", "metric_phi"]
    np.testing.assert_array_equal(frame["metric"], [0.02, 0.07, np.nan])
    alone = _evaluated({"arolc": [search, None]}, (1.0, 2.0), names, units, (False,) * 2 + (True,))
    np.testing.assert_array_equal(alone["metric_rad"], [3.0, 2.0, np.nan])
    assert list(alone["omega_n"]) == [1.0] * 3  # a point without a search has no rows


def test_command_counts_the_points_with_no_run_on_the_path(tmp_path, capsys):
    scenario = tmp_path / "light_mass.toml"
    Scenario.from_dict(PLANT).to_toml(scenario)
    out = tmp_path / "out"
    args = ["tradeoff", str(scenario), "--omega", "20", "80", "2", "--upper", "2"]
    assert main([*args, "--zeta", str(ZETA), "--out", str(out), "--quiet"]) == 0
    table = pd.read_csv(out / "tradeoff.csv")
    off = int((table.on_path == 0).sum())
    assert 0 < off < len(table)  # fast gains beside a 50 ms delay: some points never stay on
    assert (
        f"  {off} of {len(table)} points (gain point x controller) had no run on the path"
    ) in capsys.readouterr().out


def test_the_figure_labels_each_point_with_its_gain_and_says_which_family_it_leaves_out(study):
    from delaytrack.experiments.tradeoff import LOWER_BOUND, MARGIN_SEARCHES
    from delaytrack.report.tradeoff import pareto_figure

    ax = pareto_figure(study).axes[0]
    table = study.table
    placed = table[table.margin_found | (table.margin_search == LOWER_BOUND)]
    labels = sorted(text.get_text() for text in ax.texts)
    assert labels == sorted(f"{omega:.4g}" for omega in placed.omega_n)
    legend = [text.get_text() for text in ax.get_legend().get_texts()]
    assert f"PCONf (told h̄): not shown, {MARGIN_SEARCHES['not searched']}" in legend
    assert "numbers: ω_n (rad/s)" in legend


def test_draws_beyond_what_a_sweep_holds_are_refused_naming_draws_before_any_search(
    tmp_path, capsys, monkeypatch
):
    """The payload robot draws its robots: 20 000 draws at 2 gain points are more runs than a
    sweep holds. Refused at once, naming --draws and its largest value here (it was refused
    after the margin searches, in a sweep's words: "split it into several sweep files")."""
    from delaytrack.experiments import tradeoff as tradeoff_module

    def no_search(*_args, **_kwargs):
        raise AssertionError("a margin search ran before the refusal")

    monkeypatch.setattr(tradeoff_module, "_family_margins", no_search)
    args = ["tradeoff", "robot_S1", "--omega", "1", "2", "2", "--draws", "20000"]
    assert main([*args, "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err
    from delaytrack.sweeps.spec import MAX_RUNS

    # 2 gain points x 4 controllers (the robot's families) x 20 000 draws
    assert err.startswith("error: --draws = 20000 makes 160000 runs") and err.count("\n") == 1
    assert f"more than a sweep holds ({MAX_RUNS}); give at most {MAX_RUNS // 8} draws" in err
