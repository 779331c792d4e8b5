"""Hostile inputs end in a clear error or a correct result, in bounded time and memory.

One test (or a few) per failure class: resources an input asks for, searches that must end,
metrics that must be exact, experiments that must not change silently, output folders, and the
"left the path" rule.
"""

from __future__ import annotations

import importlib
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import delaytrack as dt
from delaytrack._validation import real_array
from delaytrack.cli import main
from delaytrack.delays import ConstantDelay, RandomDelay, TraceDelay
from delaytrack.experiments import empirical_margin
from delaytrack.jobs.scenario_run import run_to_folder
from delaytrack.metrics import mean_absolute_error, metrics_table, total_variation
from delaytrack.plants.robot import PayloadRobot
from delaytrack.scenario import Scenario, ScenarioError, load_builtin
from delaytrack.sim import simulate
from delaytrack.sim.history import history_capacity
from delaytrack.sweeps import SweepError, SweepSpec
from test_scenario import base_dict


def short(**changes) -> Scenario:
    return Scenario.from_dict({**base_dict(), **changes})


def one_line_error(capsys, *words: str) -> str:
    err = capsys.readouterr().err
    # A first compile's notes ("delaytrack: compiling ...") come or not with the cache's state,
    # before the run that then fails: the error is the rest.
    err = "".join(
        line for line in err.splitlines(keepends=True) if not line.startswith("delaytrack: ")
    )
    assert err.startswith("error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err
    for word in words:
        assert word in err, (word, err)
    return err


# ---- 1. resources ----------------------------------------------------------------------------


@pytest.mark.parametrize("command", ["simulate", "sweep", "gains"])
def test_values_nested_hundreds_deep_are_refused_not_a_recursion_error(tmp_path, capsys, command):
    deep = tmp_path / "deep.toml"
    deep.write_text('scenario = "two_link_S1"\nx = ' + "[" * 600 + "1" + "]" * 600 + "\n")
    argv = {
        "simulate": ["simulate", str(deep)],
        "sweep": ["sweep", str(deep), "--quiet"],
        "gains": ["reproduce", "--gains", str(deep), "--duration", "0.1"],
    }[command]
    assert main([*argv, "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, "deep.toml", "nested more than 32 levels deep")


@pytest.mark.parametrize(
    "line",
    [
        ".".join(["a"] * 5000) + " = 1",  # a dotted key
        "[" + ".".join(['"a"'] * 5000) + "]",  # a table's name, of quoted parts
        "x = { " + ".".join(["a"] * 5000) + " = 1 }",  # an inline table's key
    ],
    ids=["key", "table", "inline"],
)
def test_a_dotted_key_of_thousands_of_parts_is_refused_before_it_is_parsed(tmp_path, capsys, line):
    """Python's TOML parser takes time and memory growing with the square of a dotted key's
    parts (100 000 parts, 200 KB, took 24 GB): such a key is refused before parsing."""
    deep = tmp_path / "deep.toml"
    deep.write_text(f'scenario = "two_link_S1"\n{line}\n')
    assert main(["simulate", str(deep), "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, "deep.toml", "a dotted key of more than 32 parts (line 2)")


def test_a_long_dotted_text_in_a_value_is_no_key():
    from delaytrack._io import toml_data

    text = 'name = "' + ".".join(["w"] * 100) + '"\nx = [1.5, 2.5, 3.5]\n'
    assert toml_data(text)["name"].count(".") == 99


def test_control_characters_of_a_file_name_are_shown_escaped(tmp_path, capsys):
    # A folder's name may hold a line break, a carriage return or a terminal's escape: an error
    # that names the file must not let them act ("FAKE: all runs ok" over the line's start).
    folder = tmp_path / "x\n\x1b[31mFAKE: all 100 runs ok\x1b[0m\ry"
    folder.mkdir()
    path = folder / "case.toml"
    path.write_text("bogus = 1\n" + short().to_toml())
    assert main(["simulate", str(path), "--out", str(tmp_path / "out")]) == 2
    err = one_line_error(capsys, "'bogus'", "x\\n\\x1b[31mFAKE: all 100 runs ok\\x1b[0m\\ry")
    assert "\x1b" not in err and "\r" not in err


@pytest.mark.parametrize(
    ("command", "table", "where"),
    [
        ("simulate", '[delay]\ntype = "trace"\npath = "a\\u0000.csv"\n', "delay.path"),
        ("simulate", '[delay]\ntype = "trace"\npath = "/tmp/a\\u0000.csv"\n', "delay.path"),
        ("simulate", '[plant]\ntype = "python:a\\u0000.py:make"\n', "plant.type"),
        ("sweep", '[grid]\n"delay.path" = ["a\\u0000.csv"]\n', "grid.delay.path[0]"),
    ],
)
def test_a_text_holding_a_nul_character_is_refused_naming_where(
    tmp_path, capsys, command, table, where
):
    """A NUL is valid in TOML's text, but not in a path: the operating system's refusal was a
    traceback."""
    path = tmp_path / "nul.toml"
    if command == "simulate":  # the scenario's own table of that name left out
        header = table.partition("\n")[0]
        text = re.sub(
            rf"^{re.escape(header)}\n(?:[^\[\n].*\n|\n)*", "", short().to_toml(), flags=re.M
        )
        path.write_text(text + "\n" + table)
    else:
        path.write_text('scenario = "two_link_S1"\nunit_size = 8\n' + table)
    argv = [command, str(path), "--out", str(tmp_path / "out")]
    assert main(argv) == 2
    one_line_error(capsys, "nul.toml", where, "a text holding a NUL character")


@pytest.mark.parametrize("command", ["simulate", "sweep"])
def test_an_integer_beyond_the_largest_float_is_refused_naming_where(tmp_path, capsys, command):
    """TOML's integers have no bound; no number of a scenario or sweep file may exceed the
    largest float (the conversions raised Python's OverflowError, with a traceback). A gains
    file names its own (``tests/test_hostile_outputs.py``)."""
    huge = "1" + "0" * 400
    path = tmp_path / "huge.toml"
    if command == "simulate":
        text = short().to_toml()
        assert "\nx0 = " not in text
        path.write_text(f"x0 = [{huge}, 0, 0, 0]\n" + text)
        where = "x0[0]"
    else:
        path.write_text(
            'scenario = "two_link_S1"\nunit_size = 8\ndraws = 2\nseed = 1\n[random]\n'
            f'"controller.K1" = {{dist = "uniform", low = 1, high = {huge}}}\n'
        )
        where = "random.controller.K1.high"
    argv = {"simulate": ["simulate", str(path)], "sweep": ["sweep", str(path), "--quiet"]}
    assert main([*argv[command], "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, "huge.toml", where, "an integer of 401 digits")
    # the same file without the huge number is a valid one
    path.write_text(path.read_text().replace(huge, "2"))
    assert main([*argv[command], "--out", str(tmp_path / "out")]) == 0


@pytest.mark.parametrize(
    "make",
    [
        lambda huge: ConstantDelay(huge),
        lambda huge: dt.AbsSineDelay(huge, 0.01, 1.0),
        lambda huge: dt.TwoLinkArm(p1=huge),
        lambda huge: dt.MeasurementNoise(position=huge),
        lambda huge: short(x0=[huge, 0, 0, 0]),
        lambda huge: short(error_bound=huge),
        lambda huge: simulate(
            dt.TwoLinkArm(),
            dt.OuterLoop(dt.TwoLinkArm(), K1=1.0, K2=1.0),
            ConstantDelay(0.01),
            [0, 0, 0, 0],
            reference=dt.SinusoidalReference([0.0, 0.0]),
            t1=huge,
            dt=1e-3,
            T_c=1e-2,
        ),
    ],
    ids=[
        "ConstantDelay",
        "AbsSineDelay",
        "TwoLinkArm",
        "MeasurementNoise",
        "scenario x0",
        "scenario error_bound",
        "simulate t1",
    ],
)
def test_an_integer_beyond_the_largest_float_is_refused_by_the_library(make):
    with pytest.raises(ValueError, match=r"must be (finite|a number (>|>=) 0)"):
        make(10**400)


@pytest.mark.parametrize("h_max", [1e6, 1e300, math.inf])
def test_history_is_bounded_by_the_run_not_by_the_delay(h_max):
    # min(ceil(h_max / T_c), ticks) + 3: a run of 100 ticks never needs more than its 101
    # commands (+ 2 of slack), while 0.1 s at T_c = 2 ms needs ceil(50) + 3.
    assert history_capacity(h_max, 0.002, 100) == 103
    assert history_capacity(0.1, 0.002, 100) == 53


def test_a_delay_longer_than_the_run_never_delivers_a_command():
    """The plant keeps u_init: the same run as with an infinite delay, in little memory."""
    scenario = short(x0=[0.1, 0.0, 0.0, 0.0])
    code = (
        "import resource, sys; sys.path.insert(0, sys.argv[1]);"
        "from test_hostile_inputs import short;"
        "r = short(delay={'type': 'constant', 'h': 1e6}, x0=[0.1, 0, 0, 0]).run();"
        "print(r.status_names[0], resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)"
    )
    out = subprocess.run(
        [sys.executable, "-c", code, str(Path(__file__).parent)],
        capture_output=True,
        text=True,
        check=True,
        timeout=600,
    ).stdout.split()
    assert out[0] == "ok"
    assert int(out[1]) < 2 * 2**20  # kB: under 2 GiB (the unbounded buffer took 8 GB)
    far = scenario.replace(delay={"type": "constant", "h": 1e300}).run()
    never = scenario.replace(delay={"type": "constant", "h": 0.3}).run()  # beyond the 0.2 s run
    np.testing.assert_array_equal(far.x, never.x)
    np.testing.assert_array_equal(far.applied[0, :-1], 0.0)


def test_a_trace_with_an_enormous_delay_runs(tmp_path):
    path = tmp_path / "trace.csv"
    path.write_text("t,h\n0,0.01\n0.1,1e300\n1,1e300\n")
    result = short(delay={"type": "trace", "path": str(path)}).run()
    assert result.status_names == ["ok"]


def test_a_sweep_beyond_the_run_limit_is_refused_before_expanding():
    data = {
        "scenario": "two_link_S1",
        "unit_size": 10,
        "draws": 100_000_000,
        "seed": 1,
        "random": {"seed": {"dist": "integers", "low": 0, "high": 10}},
    }
    with pytest.raises(SweepError, match=r"100000000 runs .* at most 100000 runs"):
        SweepSpec.from_dict(data)


def test_a_run_of_too_many_steps_is_refused():
    with pytest.raises(
        ScenarioError, match=r"'duration' must be at most 1e\+08 plant steps of 'dt'"
    ):
        short(duration=1e7, dt=0.001, T_c=0.002)
    built = short().build()
    with pytest.raises(ValueError, match=r"t1 - t0 must be at most 1e\+08 plant steps"):
        simulate(
            built.plant,
            built.controller,
            built.delay,
            built.x0,
            reference=built.reference,
            t1=1e7,
            dt=1e-3,
            T_c=2e-3,
        )


def test_a_random_walk_of_too_many_knots_is_refused():
    with pytest.raises(ValueError, match="duration must be at most 1e"):
        RandomDelay(0.0, 0.1, 1.0, duration=1e9, seed=1)


# ---- 2. searches end ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"resolution": 1e-300}, "resolution must be at least 1e-09 s"),
        ({"upper": 1e300}, "upper must be at most the scenario's duration"),
        ({"upper": 1e6}, "upper must be at most the scenario's duration"),
        ({"grid": 10**9}, "grid must be at most 10000"),
    ],
)
def test_searches_that_could_not_end_are_refused(options, message):
    with pytest.raises(ValueError, match=message):
        empirical_margin(short(), threshold=1.0, **{"upper": 0.1, **options})


@pytest.mark.parametrize("flag", [["--resolution", "1e-300"], ["--upper", "1e300"]])
def test_empirical_cli_refuses_them_naming_the_flag(flag, capsys):
    assert main(["empirical", "two_link_margins", "--threshold", "0.2", *flag]) == 2
    one_line_error(capsys, flag[0], f"got {float(flag[1]):g}")


# ---- 3 and 8. exact metrics, one summation order ------------------------------------------------


def test_metrics_count_every_tick_whatever_is_recorded(tmp_path):
    scenario = short()
    exact = metrics_table(scenario.run())
    sparse = scenario.replace(record_every=1000).run()
    assert sparse.t.size == 1
    table = metrics_table(sparse)
    columns = [c for c in exact if c.startswith(("ae_", "rms_", "max_")) or c == "tv"]
    assert (exact[columns].to_numpy() > 0).all()
    np.testing.assert_array_equal(table[columns].to_numpy(), exact[columns].to_numpy())
    case = _file(tmp_path, scenario.replace(record_every=1000))
    assert main(["simulate", str(case), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    assert (tmp_path / "out" / "metrics.csv").is_file()


def _file(tmp_path, scenario):
    path = tmp_path / "case.toml"
    scenario.to_toml(path)
    return path


def test_a_window_over_sparse_records_is_refused():
    result = short(record_every=10).run()
    with pytest.raises(ValueError, match="record_every=1"):
        mean_absolute_error(result, t_from=0.1)


def test_batch_and_single_give_the_same_bits_with_and_without_trajectories():
    built = short().build()
    delays = [ConstantDelay(h) for h in (0.0, 0.013, 0.05, 0.07, 0.1)]
    settings = {"reference": built.reference, "t1": 0.2, "dt": 0.001, "T_c": 0.002}
    batch = simulate(built.plant, built.controller, delays, built.x0, **settings)
    lean = simulate(built.plant, built.controller, delays, built.x0, trajectories=False, **settings)
    for i, delay in enumerate(delays):
        alone = simulate(built.plant, built.controller, delay, built.x0, **settings)
        for t_from in (None, 0.05):
            np.testing.assert_array_equal(
                total_variation(batch, t_from=t_from)[i], total_variation(alone, t_from=t_from)[0]
            )
            np.testing.assert_array_equal(
                mean_absolute_error(batch, t_from=t_from)[i],
                mean_absolute_error(alone, t_from=t_from)[0],
            )
    pd.testing.assert_frame_equal(metrics_table(batch), metrics_table(lean), check_exact=True)


def test_margins_job_refuses_a_duration_that_makes_its_margins_meaningless(tmp_path, capsys):
    args = ["reproduce", "--job", "margins", "--out", str(tmp_path), "--duration", "0.002"]
    assert main([*args, "--quiet"]) == 2
    one_line_error(capsys, "--duration must be at least 4 s", "0.002")


# ---- 4. no silent change of the experiment ------------------------------------------------------


def test_a_trace_shorter_than_the_run_is_refused_unless_held(tmp_path):
    path = tmp_path / "trace.csv"
    path.write_text("t,h\n0,0.01\n0.1,0.02\n")
    delay = {"type": "trace", "path": str(path)}
    with pytest.raises(ScenarioError, match=r"defined up to t = 0.1 s, but the run lasts until"):
        short(delay=delay).run()
    held = short(delay={**delay, "beyond": "hold"}).run()
    assert held.status_names == ["ok"]
    np.testing.assert_array_equal(held.h[0, held.t > 0.1], 0.02)


def test_a_trace_that_starts_after_the_run_is_refused(tmp_path, capsys):
    """A delay log stamped with Unix times starts long after the run's t0 = 0: its first value
    would have been held over the whole run."""
    path = tmp_path / "epoch.csv"
    path.write_text("t,h\n1700000000.0,0.02\n1700000000.5,0.08\n1700000002.0,0.05\n")
    scenario = tmp_path / "epoch.toml"
    scenario.write_text(short(delay={"type": "trace", "path": str(path)}).to_toml())
    assert main(["simulate", str(scenario), "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, "delay[0] (TraceDelay) starts at t = 1.7e+09 s", "t0 = 0 s")
    late = TraceDelay([0.5, 2.0], [0.02, 0.03])
    with pytest.raises(ScenarioError, match=r"starts at t = 0.5 s, after the run's start"):
        short(delay=late.to_spec()).run()
    # From its first sample on, the same trace runs.
    settings = dict(reference=dt.SinusoidalReference([0.0, 0.0]), t1=1.0, dt=1e-3, T_c=0.01)
    arm = dt.TwoLinkArm()
    run = simulate(arm, dt.OuterLoop(arm, K1=1.0, K2=1.0), late, [0, 0, 0, 0], t0=0.5, **settings)
    assert run.status_names == ["ok"]


def test_a_random_delay_shorter_than_the_run_is_refused_unless_held():
    delay = {"type": "random", "h_low": 0.0, "h_high": 0.05, "max_rate": 0.5, "seed": 3}
    assert short(delay=delay).run().status_names == ["ok"]  # takes the scenario's duration
    with pytest.raises(ScenarioError, match=r"defined up to t = 0.1 s"):
        short(delay={**delay, "duration": 0.1}).run()
    assert short(delay={**delay, "duration": 0.1, "beyond": "hold"}).run().status_names == ["ok"]


def test_a_payload_schedule_shorter_than_the_run_is_refused_unless_held():
    scenario = load_builtin("robot_S1").replace(duration=20.0)
    short_schedule = {**scenario.plant, "duration": 6.0}  # one placement: 5 s on from t = 5 s
    with pytest.raises(ScenarioError, match=r"PayloadRobot\) is defined up to t = 15 s"):
        scenario.replace(plant=short_schedule).run()
    held = scenario.replace(plant={**short_schedule, "beyond": "hold"}).build().plant
    assert held.horizon == math.inf
    plant = PayloadRobot(seed=1, duration=100.0)
    assert plant.horizon >= 100.0
    assert PayloadRobot(seed=1, duration=1.0, beyond="hold").horizon == math.inf
    with pytest.raises(ValueError, match="beyond must be one of"):
        PayloadRobot(seed=1, duration=1.0, beyond="loop")


def test_a_trace_in_milliseconds_is_caught_and_read_with_its_unit(tmp_path):
    path = tmp_path / "log.csv"
    path.write_text("t_s,delay_ms\n0,20\n1,100\n")
    with pytest.raises(ValueError, match=r"delay\) names a unit \(ms:.*delay_unit = 'ms'"):
        TraceDelay.from_csv(path)
    trace = TraceDelay.from_csv(path, delay_unit="ms")
    np.testing.assert_allclose(trace.values, [0.02, 0.1])
    spec = short(delay={"type": "trace", "path": str(path), "delay_unit": "ms", "beyond": "hold"})
    assert spec.resolved().delay["delay_unit"] == "ms"


def test_a_log_with_extra_columns_is_read_by_naming_them(tmp_path):
    path = tmp_path / "log.csv"
    path.write_text("stamp,delay,seq\n0,0.02,1\n0.5,0.04,2\n1,0.03,3\n")
    with pytest.raises(ValueError, match="name the time and delay columns"):
        TraceDelay.from_csv(path)
    trace = TraceDelay.from_csv(path, time_column="stamp", delay_column="delay")
    np.testing.assert_array_equal(trace.times, [0.0, 0.5, 1.0])
    with pytest.raises(ValueError, match=r"delay_column = 'lag' is not in the header"):
        TraceDelay.from_csv(path, time_column="stamp", delay_column="lag")


# ---- 5. output folders ------------------------------------------------------------------------


def test_output_locations_are_checked_before_computing(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    a_file = tmp_path / "file.txt"
    a_file.write_text("mine")
    for out in ("", str(a_file), str(a_file / "below")):
        assert main(["simulate", "two_link_S1", "--out", out]) == 2
        one_line_error(capsys, "--out")
        assert main(["tune-baselines", "--out", str(tmp_path) if out == "" else out + "/x"]) == 2
        one_line_error(capsys, "--out")
    assert main(["reproduce", "--out", str(a_file)]) == 2
    one_line_error(capsys, "--out")
    assert list(tmp_path.iterdir()) == [a_file]


def test_a_folder_of_someone_else_is_not_written_and_stale_files_go(tmp_path, capsys):
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep")
    scenario = _file(tmp_path, short())
    assert main(["simulate", str(scenario), "--out", str(mine)]) == 2
    one_line_error(capsys, "--out", "notes.txt")
    folder = tmp_path / "run"
    assert main(["simulate", str(scenario), "--out", str(folder), "--format", "csv"]) == 0
    assert (folder / "trajectories.csv").is_file()
    assert main(["simulate", str(scenario), "--out", str(folder)]) == 0
    assert (folder / "trajectories.parquet").is_file()
    assert not (folder / "trajectories.csv").exists()


# ---- 9. the "left the path" rule ----------------------------------------------------------------


def test_a_run_beyond_its_error_bound_left_the_path():
    scenario = short(error_bound=0.01)
    result = scenario.run()
    assert result.status_names == ["left the path"]
    assert 0.0 < result.t_stop[0] < 0.2
    assert np.isnan(metrics_table(result)["ae_q1"]).all()
    per_coordinate = short(error_bound=[0.01, math.inf]).run()
    assert per_coordinate.status_names == ["left the path"]
    assert short(error_bound=[math.inf, math.inf]).run().status_names == ["ok"]
    with pytest.raises(ScenarioError, match="error_bound"):
        short(error_bound=[1.0, 1.0, 1.0]).build()
    with pytest.raises(ScenarioError, match="error_bound"):
        short(error_bound=-1.0)


def test_sweeps_count_runs_that_left_the_path_as_divergence():
    from delaytrack.sweeps.summary import summary_table

    runs = pd.DataFrame(
        {
            "controller_type": ["pcon"] * 3,
            "delay_type": ["constant"] * 3,
            "h_max": [0.1] * 3,
            "status": ["ok", "left the path", "diverged"],
            "ae_q1": [0.01, np.nan, np.nan],
            "tv": [1.0, np.nan, np.nan],
        }
    )
    row = summary_table(runs).iloc[0]
    assert (row["diverged"], row["divergence_rate"], row["failed"]) == (2, 2 / 3, 0)


def test_the_robot_scenario_carries_the_paper_jobs_rule():
    scenario = load_builtin("robot_S1")
    assert scenario.error_bound == (10.0, 10.0, math.inf, math.inf, math.inf)


def test_a_predictor_history_beyond_its_limit_is_refused():
    data = {"type": "pcon", "kappa": 1.0, "vartheta": 1.0, "k_b": 1.0, "T_c": 0.002}
    with pytest.raises(ScenarioError, match=r"'controller.history' must be at most 1e\+07"):
        short(controller={**data, "history": 1e6}).build()


def test_sweep_output_and_workers_are_checked_before_anything_runs(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    spec = tmp_path / "sweep.toml"
    spec.write_text('scenario = "two_link_S1"\nunit_size = 1\n[grid]\n"controller.K1" = [1.0]\n')
    assert main(["sweep", str(spec), "--out", ""]) == 2
    one_line_error(capsys, "--out")
    assert main(["sweep", str(spec), "--out", str(spec)]) == 2
    one_line_error(capsys, "--out")
    assert main(["sweep", str(spec), "--out", "s", "--workers", "100000"]) == 2
    one_line_error(capsys, "--workers", "at most", "100000")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sweep.toml"]


def test_working_memory_beyond_the_machine_is_refused_before_allocating(monkeypatch):
    plan_module = importlib.import_module("delaytrack.sim._plan")
    monkeypatch.setattr(plan_module, "physical_memory", lambda: 2.0**20)
    data = {"type": "pcon", "kappa": 1.0, "vartheta": 1.0, "k_b": 1.0, "T_c": 0.002}
    scenario = short(controller={**data, "history": 1000.0}, record_every=100)
    with pytest.raises(ScenarioError, match=r"working memory needs .* GiB.*predictor's history"):
        scenario.run()


@pytest.mark.parametrize(
    "delay",
    [
        {"type": "abs-sine", "offset": 0.0, "amplitude": 0.05, "frequency": 1e300},
        {"type": "abs-sine", "offset": 0.0, "amplitude": 1e-3, "frequency": 1e12},
    ],
    ids=["fast", "fast-small"],
)
def test_a_delay_that_would_split_steps_without_end_is_refused(delay):
    with pytest.raises(ScenarioError, match=r"may switch the applied command up to .* times") as e:
        short(delay=delay).run()
    count = re.search(r"up to (\S+) times", str(e.value)).group(1)
    assert len(count) <= 16, count  # 2.53e+302, not three hundred digits


def test_a_run_of_too_many_ticks_is_told_to_shorten_not_to_slow_its_delay():
    """Every tick's command comes into force once, whatever the delay: beyond the limit by its
    ticks alone, the advice is about the run, and the counts differ where they are printed.
    1e5 s at T_c = 1 ms is 10⁸ ticks; a constant delay's bound is the ticks plus one
    (``delays._kernel.switch_bound``), one more than the limit of 10⁸."""
    with pytest.raises(
        ValueError,
        match=r"100,000,001 times .* more than 100,000,000: .* "
        r"100,000,000 controller ticks alone .* shorten the run or lengthen T_c",
    ):
        _arm_run(t1=1e5, dt=1e-3, T_c=1e-3, record_every=10**8)


def _arm_run(**settings):
    """The two-link arm under the outer loop and a constant 10 ms delay, at rest on a zero
    reference, simulated with ``settings``."""
    arm = dt.TwoLinkArm()
    return simulate(
        arm,
        dt.OuterLoop(arm, K1=1.0, K2=1.0),
        ConstantDelay(0.01),
        [0, 0, 0, 0],
        reference=dt.SinusoidalReference([0.0, 0.0]),
        **settings,
    )


def test_record_every_beyond_the_run_records_the_start_and_keeps_exact_metrics():
    exact = metrics_table(short().run())
    result = short(record_every=2**70).run()
    assert result.t.tolist() == [0.0] and result.settings["record_every"] == 2**70
    pd.testing.assert_frame_equal(metrics_table(result), exact, check_exact=True)


# ---- cases of an independent campaign, one per class ------------------------------------------


def test_numbers_beyond_what_numpy_or_a_float_takes_are_refused_naming_the_key(tmp_path):
    with pytest.raises(ValueError, match="max_rate must be at most 1e"):
        RandomDelay(0.01, 0.13, 1e308, duration=1.0, seed=1)
    with pytest.raises(ScenarioError, match="'duration' must be a finite number"):
        short(duration=10**400)
    with pytest.raises(ValueError, match="placements"):
        PayloadRobot(seed=1, duration=10.0, time_on=1e-300, time_off=1e-300)
    with pytest.raises(ValueError, match="seed must be an integer from 0"):
        PayloadRobot(seed=-5, duration=1.0)
    path = tmp_path / "case.toml"
    text = short().to_toml()
    text = text[: text.index("[delay]")] + '[delay]\ntype = "trace"\npath = "~nosuchuser/x.csv"\n'
    path.write_text(text + "\n[reference]\noffset = [0.0, 0.0]\n")
    with pytest.raises(ScenarioError, match="delay.path"):
        Scenario.from_toml(path)


def test_unwritable_locations_are_refused_before_computing(tmp_path, capsys):
    link = tmp_path / "dangling"
    link.symlink_to(tmp_path / "nowhere")
    for out in ("/proc/delaytrack-x", str(link), str(tmp_path / ("x" * 300))):
        assert main(["simulate", "two_link_S1", "--out", out]) == 2
        one_line_error(capsys, "--out")
    assert main(["tune-baselines", "--out", "/proc/gains.toml", "--quiet"]) == 2
    one_line_error(capsys, "--out")


def test_files_of_a_user_are_never_overwritten(tmp_path, capsys):
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "metrics.csv").write_text("my own table")
    assert main(["simulate", str(_file(tmp_path, short())), "--out", str(mine)]) == 2
    one_line_error(capsys, "--out", "metrics.csv")
    spec = tmp_path / "sweep.toml"
    spec.write_text('scenario = "two_link_S1"\nunit_size = 1\n[grid]\n"controller.K1" = [1.0]\n')
    (mine / "report.html").write_text("mine too")
    assert main(["sweep", str(spec), "--out", str(mine)]) == 2
    one_line_error(capsys, "--out")
    assert (mine / "metrics.csv").read_text() == "my own table"


def test_trace_files_with_a_bom_or_spelled_out_units(tmp_path):
    bom = tmp_path / "bom.csv"
    bom.write_bytes("\ufeff0,0.05\n0.5,0.06\n2,0.05\n".encode())
    np.testing.assert_array_equal(TraceDelay.from_csv(bom).values, [0.05, 0.06, 0.05])
    spelled = tmp_path / "spelled.csv"
    spelled.write_text("t,delay_milliseconds\n0,50\n1,60\n")
    with pytest.raises(ValueError, match=r"names a unit \(ms: milliseconds\)"):
        TraceDelay.from_csv(spelled)
    nano = tmp_path / "nano.csv"
    nano.write_text("t,delay_ns\n0,5e7\n1,6e7\n")
    np.testing.assert_allclose(TraceDelay.from_csv(nano, delay_unit="ns").values, [0.05, 0.06])
    log = tmp_path / "log.csv"
    log.write_text("stamp,delay\n0,0.05\n1,0.06\n")
    with pytest.raises(ValueError, match="two different columns"):
        TraceDelay.from_csv(log, time_column="stamp", delay_column="stamp")
    with pytest.raises(ValueError, match="is not a file"):
        TraceDelay.from_csv(tmp_path)


def test_the_empirical_margin_keeps_the_scenarios_error_bound():
    with pytest.raises(ValueError, match="missed already without delay: .* 'left the path'") as e:
        empirical_margin(short(error_bound=1e-300), threshold=1.0, upper=0.1)
    # not the advice for a run that finished above the threshold
    assert "larger threshold would not help" in str(e.value) and "later settle" not in str(e.value)


def test_api_values_that_would_change_the_experiment_are_refused():
    built = short().build()
    settings = {"reference": built.reference, "dt": 1e-3, "T_c": 2e-3}
    with pytest.raises(TypeError, match="x0 must be an array of real numbers"):
        simulate(built.plant, built.controller, built.delay, built.x0 + 1j, t1=0.2, **settings)
    with pytest.raises(ValueError, match="small enough for dt to be resolved"):
        simulate(
            built.plant, built.controller, built.delay, built.x0, t0=1e15, t1=1e15 + 1, **settings
        )
    result = short().run()
    with pytest.raises(ValueError, match="different entries"):
        metrics_table(result, coordinate_names=["a", "a"])
    with pytest.raises(ValueError, match="t_from must be a time"):
        mean_absolute_error(result, t_from=True)


@pytest.mark.parametrize(
    ("key", "value", "error", "message"),
    [
        ("t1", "0.2", TypeError, "t1 must be a real number; got '0.2'"),
        ("t1", True, TypeError, "t1 must be a real number; got True"),
        ("t0", np.bool_(False), TypeError, "t0 must be a real number"),
        ("t0", math.nan, ValueError, "t0 must be finite"),
        ("t1", math.inf, ValueError, "t1 must be finite"),
        ("t1", np.array([0.2]), ValueError, "t1 must be 0-dimensional"),
        ("metrics_from", "0.1", TypeError, "metrics_from must be a real number; got '0.1'"),
        ("t1", b"0.2", TypeError, "t1 must be a real number; got b'0.2'"),
        ("t1", np.array("0.2"), TypeError, "t1 must be an array of real numbers"),
    ],
)
def test_times_that_are_not_finite_real_numbers_are_refused_naming_them(key, value, error, message):
    built = short().build()
    times = {"t0": 0.0, "t1": 0.2, key: value}
    settings = {"reference": built.reference, "dt": 1e-3, "T_c": 2e-3}
    with pytest.raises(error, match=re.escape(message)):
        simulate(built.plant, built.controller, built.delay, built.x0, **settings, **times)


@pytest.mark.parametrize(
    "value", [10**400, "5", ["5", "5"], [b"5", b"5"], np.array([True, True]), [1j, 1.0]]
)
def test_input_limits_that_are_not_positive_real_numbers_are_one_clear_error(value):
    # A string, bytes or a boolean would convert to a float; an int beyond the floats would
    # overflow converting.
    built = short().build()
    settings = {"reference": built.reference, "dt": 1e-3, "T_c": 2e-3, "t1": 0.01}
    with pytest.raises(ValueError, match="input_limits must be a number > 0 or 2 of them"):
        simulate(
            built.plant, built.controller, built.delay, built.x0, input_limits=value, **settings
        )


def test_arrays_of_strings_bytes_booleans_or_none_are_not_read_as_numbers():
    strings = (["1", "2"], [b"1"], [True, False], np.array(["0.2"]), [np.datetime64(1, "s")])
    for value in (*strings, [0.0, None], [[1.0], [None]]):  # a None is not read as NaN
        with pytest.raises(TypeError, match="x0 must be an array of real numbers"):
            real_array("x0", value)
    assert real_array("x0", [1, 2.5, np.float32(3)]).tolist() == [1.0, 2.5, 3.0]


def test_a_payload_placed_at_a_string_or_a_boolean_is_refused():
    for value in ("0.2", True):
        with pytest.raises(TypeError, match=f"plate_center must be a real number; got {value!r}"):
            PayloadRobot(seed=1, duration=10.0, plate_center=value)


def test_times_as_int_float_or_numpy_numbers_give_the_same_run():
    built = short().build()
    settings = {"reference": built.reference, "dt": 1e-3, "T_c": 2e-3, "trajectories": False}
    runs = [
        simulate(
            built.plant, built.controller, built.delay, built.x0, t0=t0, t1=t1, **settings
        ).metrics["ae"]
        for t0, t1 in ((0, 1), (0.0, 1.0), (np.float64(0.0), np.int64(1)))
    ]
    for other in runs[1:]:
        assert np.array_equal(other, runs[0])


def test_a_key_with_a_newline_still_gives_one_line(tmp_path, capsys):
    path = _file(tmp_path, short())
    path.write_text(path.read_text().replace("[controller]\n", '[controller]\n"bad\\nkey" = 1\n'))
    assert main(["simulate", str(path), "--out", str(tmp_path / "o")]) == 2
    one_line_error(capsys, "bad")


def test_a_file_with_a_byte_order_mark_and_a_frequency_too_high(tmp_path, capsys):
    path = _file(tmp_path, short())
    path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    assert Scenario.from_toml(path) == short()
    args = ["empirical", "two_link_margins", "--threshold", "0.2", "--profile", "abs-sine"]
    assert main([*args, "--frequency", "1e300"]) == 2
    one_line_error(capsys, "--frequency", "1e+300")


@pytest.mark.parametrize(
    ("key", "value", "bound"),
    [("alpha", 1e308, "must be <= 1e"), ("gamma", 1e308, "must be <= 1e")]
    + [("c_hat0", 1e300, "must be <= 1e"), ("epsilon", 1e-300, "must be >= 1e-100")],
)
def test_arolc_parameters_beyond_double_precision_are_refused(key, value, bound):
    # Accepted, they made every run "diverged" at its first ticks.
    controller = {**base_dict()["controller"], key: value}
    with pytest.raises(ScenarioError, match=rf"'controller.{key}' {bound}"):
        short(controller=controller).build()


def test_a_q_whose_sliding_gain_overflows_is_refused_naming_the_gain():
    # Q = 1e300 was accepted and every run "diverged" at its first ticks. P solves
    # AᵀP + PA = -Q, so it scales with Q: the gain named is 1e300 times that of Q = I, whose
    # largest entry of BᵀP (B = [0; I]: P's lower rows) the built controller shows.
    unit = short(controller={**base_dict()["controller"], "Q": 1.0}).build().controller
    n = unit.P.shape[0] // 2
    expected = 1e300 * np.abs(unit.P[n:]).max()
    with pytest.raises(ScenarioError) as refused:
        short(controller={**base_dict()["controller"], "Q": 1e300}).build()
    message = str(refused.value)
    assert "'controller.Q' with K1 and K2 gives s = B^T P e a gain of " in message
    assert "it must be <= 1e+100" in message
    named = float(re.search(r"a gain of (\S+) ", message).group(1))
    assert named == pytest.approx(expected, rel=1e-5)  # shown to six digits


def test_sweep_scheduler_is_checked_before_the_spec_is_read(tmp_path, capsys):
    missing = tmp_path / "absent.toml"  # would be refused too, but only after the flags
    assert main(["sweep", str(missing), "--out", str(tmp_path / "o"), "--scheduler", "x"]) == 2
    one_line_error(capsys, "--scheduler", "'x'")


@pytest.mark.parametrize("text", ["1_000", "0x10", "1,2_0", "٣"])
def test_cli_numbers_are_plain_decimals(text, capsys):
    assert main(["bound", "--k1", text, "--k2", "2", "--q", "1"]) == 2
    one_line_error(capsys, "--k1", "decimal notation")


def test_cli_integers_are_plain_decimal_digits(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["bound", "--k1", "1", "--k2", "2", "--q", "1", "--n", "1_0"])
    assert exit_.value.code == 2
    assert "--n" in capsys.readouterr().err
    assert main(["sweep", "x.toml", "--workers", "1_0"]) == 2
    one_line_error(capsys, "--workers")
    assert main(["sweep", "x.toml", "--workers", "+0"]) == 2
    one_line_error(capsys, "--workers must be a positive integer; got '+0'")


def test_cli_workers_follow_the_integer_rule_of_every_count(tmp_path, capsys):
    # "+2" is an integer for --n and --seed, so for --workers too: the refusal is the file's.
    missing = tmp_path / "absent.toml"
    assert main(["sweep", str(missing), "--out", str(tmp_path / "o"), "--workers", "+2"]) == 2
    err = one_line_error(capsys, str(missing))
    assert "--workers" not in err


def test_an_empty_reference_offset_is_blamed_on_the_offset():
    with pytest.raises(ScenarioError, match=r"reference.*offset.*empty"):
        short(reference={"offset": []}).build()


def test_a_path_that_is_not_utf8_is_refused_before_running(tmp_path):
    folder = tmp_path / "caf\udce9"  # the byte 0xE9 of a Latin-1 name, as Python shows it
    try:
        folder.mkdir()
    except (UnicodeEncodeError, OSError):
        pytest.skip("this file system takes only UTF-8 names")
    (folder / "trace.csv").write_text("t,h\n0,0.01\n1,0.01\n")
    scenario = folder / "case.toml"
    text = short().to_toml()
    text = text[: text.index("[delay]")] + '[delay]\ntype = "trace"\npath = "trace.csv"\n'
    scenario.write_text(text + "\n[reference]\noffset = [0.0, 0.0]\n")
    out = tmp_path / "out"
    with pytest.raises(ScenarioError, match="not UTF-8"):
        run_to_folder(Scenario.from_toml(scenario), out)
    assert not out.exists() or not any(out.iterdir())


# ---- what an audit of every command's inputs found ----------------------------------------


@pytest.mark.parametrize(
    ("key", "value"), [("half_track", 1e200), ("d", 1e160), ("com_lateral", 1e155)]
)
def test_a_robot_too_large_for_a_float_is_refused_in_one_line(tmp_path, capsys, key, value):
    """Its parallel-axis inertia overflowed Python's floats: a traceback (OverflowError)."""
    scenario = load_builtin("robot_S1").replace(duration=0.1)
    text = scenario.to_toml()
    path = tmp_path / "huge_robot.toml"
    path.write_text(text.replace("[plant]\n", f"[plant]\n{key} = {value}\n", 1))
    assert main(["simulate", str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    one_line_error(capsys, "[plant]", "beyond the largest float", "metres")
    from delaytrack.plants import NominalRobot

    with pytest.raises(ValueError, match="give the robot's lengths in metres"):
        NominalRobot(**{key: value})


def test_a_swept_integer_a_part_cannot_store_is_refused_before_any_unit_runs(tmp_path, capsys):
    """A seed of 2**64 ran its unit, then failed writing it, every time the sweep resumed."""
    path = tmp_path / "big_seed.toml"
    path.write_text(
        'scenario = "two_link_S1"\nunit_size = 2\n[grid]\nduration = [0.1]\n'
        'delay = [{ type = "random", h_low = 0.01, h_high = 0.05, max_rate = 0.1, seed = 0 }]\n'
        f'"delay.seed" = [1, {2**64}]\n'
    )
    assert main(["sweep", str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    one_line_error(capsys, 'grid."delay.seed"[1] = 18446744073709551616', "64-bit integer")
    assert not list((tmp_path / "out").rglob("part-*.parquet"))
    # inside a table it is JSON text, whatever its size
    table = {"type": "random", "h_low": 0.01, "h_high": 0.05, "max_rate": 0.1, "seed": 2**64}
    SweepSpec.from_dict({"scenario": "two_link_S1", "unit_size": 2, "grid": {"delay": [table]}})


@pytest.mark.parametrize(("n", "m"), [(10**7, 1), (1, 10**7)])
def test_a_compiled_plant_of_millions_of_coordinates_is_refused_at_once(n, m):
    """It took 19-39 s and 6-8 GB before numpy's or a column check's refusal."""
    import numba

    @numba.njit
    def terms(t, q, qdot, params, M, N, G):
        M[0, 0] = 1.0
        N[0] = 0.0
        G[0, 0] = 1.0

    with pytest.raises(ValueError, match="is more than a plant may have: at most 1000"):
        dt.CompiledPlant(n, m, terms, [1.0])


@pytest.mark.parametrize(
    "make",
    [
        lambda: dt.AbsSineDelay(0.02, 0.08, 1.0, phase=1e308),
        lambda: dt.SinusoidalReference([0.0], amplitude=[1.0], frequency=[1.0], phase=[1e16]),
    ],
    ids=["delay", "reference"],
)
def test_a_phase_that_swallows_the_sines_variation_is_refused(make):
    """At 1e308 the delay was a constant; at 1e16 it took two values over 2 s."""
    with pytest.raises(ValueError, match="phase must be at most 1e\\+06 rad in magnitude"):
        make()
    dt.AbsSineDelay(0.02, 0.08, 1.0, phase=1e6)  # the bound itself


@pytest.mark.parametrize(
    ("given", "named"),
    [({"amplitude": [1.0]}, "only amplitude"), ({"phase": [0.5]}, "only phase")],
)
def test_a_harmonic_given_in_part_is_refused_not_flattened(given, named):
    """An amplitude without frequency drew a constant: a run with AE 0 that tracked nothing."""
    with pytest.raises(
        ValueError, match=f"a harmonic needs both amplitude and frequency; got {named}"
    ):
        dt.SinusoidalReference([0.0], **given)


def test_empirical_refuses_a_frequency_its_profile_has_not(capsys):
    args = ["empirical", "two_link_margins", "--threshold", "0.2", "--frequency", "7"]
    assert main([*args, "--json"]) == 2
    one_line_error(capsys, "--frequency 7", "--profile constant has none")


def test_run_to_folder_checks_what_it_is_given_before_running(tmp_path):
    scenario = short()
    with pytest.raises(TypeError, match="figure_formats must be a sequence of format names"):
        run_to_folder(scenario, tmp_path / "a", figure_formats="png")
    with pytest.raises(ValueError, match=r"figure_formats \['bmp'\] are not formats matplotlib"):
        run_to_folder(scenario, tmp_path / "b", figure_formats=["png", "bmp"])
    with pytest.raises(TypeError, match="scenario must be a Scenario .*got str"):
        run_to_folder("case.toml", tmp_path / "c")
    assert not any((tmp_path / name).exists() for name in "abc")
    written = run_to_folder(scenario, tmp_path / "d", figure_formats=("PNG",))  # as savefig
    assert {path.suffix for path in (tmp_path / "d" / "figures").iterdir()} == {".PNG"}
    assert written.folder == tmp_path / "d"


@pytest.mark.parametrize(
    ("path", "error", "message"),
    [
        (None, TypeError, "path must be a file name .*got NoneType"),
        (b"case.toml", TypeError, "path must be a file name .*got bytes"),
        ("", ScenarioError, "the scenario file's name is empty"),
    ],
)
def test_from_toml_names_a_path_it_cannot_read(path, error, message):
    with pytest.raises(error, match=message):
        Scenario.from_toml(path)


def test_an_empty_scenario_name_on_the_command_line_is_not_the_current_folder(tmp_path, capsys):
    assert main(["simulate", "", "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, "the scenario is an empty name", "two_link_S1")


def test_simulate_refuses_more_threads_than_four_per_core():
    from delaytrack.sim._machine import available_cores

    with pytest.raises(ValueError, match=r"workers must be at most \d+ \(4 per core"):
        _arm_run(t1=0.1, dt=1e-3, T_c=1e-2, workers=4 * available_cores() + 1)
