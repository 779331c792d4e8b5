"""Scenario files: round trip, every refusal names its key, building, seeds, running."""

from __future__ import annotations

import re
import tomllib

import numpy as np
import pandas as pd
import pytest

from delaytrack.controllers import AROLC
from delaytrack.delays import AbsSineDelay, RandomDelay, TraceDelay
from delaytrack.plants import TwoLinkArm
from delaytrack.scenario import (
    Scenario,
    ScenarioError,
    builtin_scenario_names,
    dumps_toml,
    load_builtin,
    run_batched,
)


def base_dict() -> dict:
    return {
        "name": "test-case",
        "duration": 0.2,
        "dt": 0.001,
        "T_c": 0.002,
        "plant": {"type": "two-link-arm"},
        "model": {"type": "two-link-arm", "fd1": 0.0, "fd2": 0.0},
        "controller": {
            "type": "arolc",
            "K1": [[2.0, 0.5], [0.5, 3.0]],
            "K2": [1.0, 2.0],
            "Q": 1,
            "alpha": 2.0,
            "epsilon": 0.1,
            "gamma": 0.001,
        },
        "delay": {"type": "abs-sine", "offset": 0.02, "amplitude": 0.08, "frequency": 1.0},
        "reference": {"offset": [0.0, 0.0], "amplitude": [0.8, 0.5], "frequency": [0.5, 0.7]},
    }


def refused(data: dict, pattern: str) -> None:
    with pytest.raises(ScenarioError, match=pattern):
        Scenario.from_dict(data)


# ---- round trip -------------------------------------------------------------------------------


def test_round_trip_through_a_file(tmp_path):
    data = base_dict() | {"seed": 7, "x0": [0.1, 0, 0, 0], "record_every": 2}
    scenario = Scenario.from_dict(data)
    path = tmp_path / "s.toml"
    scenario.to_toml(path)
    again = Scenario.from_toml(path)
    assert again.to_dict() == scenario.to_dict()
    assert again == scenario
    assert again.controller["K1"] == [[2.0, 0.5], [0.5, 3.0]]
    assert again.x0 == (0.1, 0.0, 0.0, 0.0)


@pytest.mark.parametrize("name", builtin_scenario_names())
def test_shipped_scenarios_load_round_trip_and_build(name, tmp_path):
    scenario = load_builtin(name)
    assert scenario.name == name
    path = tmp_path / f"{name}.toml"
    scenario.to_toml(path)
    assert Scenario.from_toml(path).to_dict() == scenario.to_dict()
    built = scenario.build()
    if not name.startswith("two_link"):
        return  # robot_S1: tests/test_robot_scenario.py
    # two_link_margins leaves the friction out on purpose (docs/decisions.md, D30).
    friction = 0.0 if name == "two_link_margins" else 5.3
    assert isinstance(built.plant, TwoLinkArm) and built.plant.fd1 == friction
    assert built.model.p1 == pytest.approx(0.8 * 3.473)
    assert built.model.fd1 == 0.0


def test_shipped_scenarios_cover_the_main_job():
    assert {
        "two_link_S1",
        "two_link_S1_outer_loop",
        "two_link_S3",
        "two_link_S3_outer_loop",
    } <= set(builtin_scenario_names())


def test_toml_writer_output_is_read_back_exactly():
    data = {
        "name": 'quote " and back\\slash and ü',
        "number": 1e-05,
        "integer": 3,
        "negative": -2.5,
        "big": 1e300,
        "whole": 4.0,
        "flag": True,
        "matrix": [[1.0, 2.0], [3.0, 4.0]],
        "table": {"key with space": [1, 2], "empty": []},
    }
    assert tomllib.loads(dumps_toml(data)) == data


# ---- refusals name the key ----------------------------------------------------------------------


def test_unknown_top_level_key():
    refused(
        base_dict() | {"dt_typo": 0.001}, r"unknown key 'dt_typo' in scenario; valid keys are \["
    )


def test_a_huge_value_is_quoted_in_a_short_message():
    """Two million numbers given for x0: the message shows the first 16 (it quoted all of them,
    a 310 MB line after minutes)."""
    with pytest.raises(ScenarioError) as refused:
        Scenario.from_dict(base_dict() | {"x0": [0.5] * 2_000_000}).build()
    message = str(refused.value)
    # quoted() shows 16 items of a list, then "..."
    assert message.count("0.5") == 16 and message.endswith(", 0.5, ...]"), message
    assert "scenario key 'x0' must have 2n = 4 entries" in message


def test_replace_refuses_an_unknown_key_naming_the_valid_ones():
    scenario = load_builtin("two_link_S1")
    with pytest.raises(ScenarioError, match=r"unknown key 'durration' in scenario; valid keys are"):
        scenario.replace(durration=2.0)


def test_unknown_key_in_controller_table():
    data = base_dict()
    data["controller"]["alfa"] = 2.0
    refused(
        data, r"unknown key 'controller\.alfa' in scenario; valid keys in \[controller\] .*'alpha'"
    )


def test_key_of_another_controller_type_is_unknown():
    data = base_dict()
    data["controller"] = {"type": "outer-loop", "K1": 1.0, "K2": 1.0, "alpha": 2.0}
    refused(data, r"unknown key 'controller\.alpha'.*type = 'outer-loop'")


def test_wrong_type_for_dt():
    refused(base_dict() | {"dt": "1ms"}, r"^scenario key 'dt' must be a number; got '1ms'$")


def test_wrong_type_for_a_controller_number():
    data = base_dict()
    data["controller"]["alpha"] = "two"
    refused(data, r"^scenario key 'controller\.alpha' must be a number; got 'two'$")


def test_wrong_type_for_a_gain():
    data = base_dict()
    data["controller"]["K1"] = "eye"
    refused(data, r"scenario key 'controller\.K1' must be a number \(a multiple of I\), a list")


def test_ragged_gain_matrix_is_refused():
    data = base_dict()
    data["controller"]["K1"] = [[1.0, 0.0], [0.0]]
    refused(data, r"scenario key 'controller\.K1' must be")


def test_boolean_is_not_a_number():
    refused(base_dict() | {"duration": True}, r"scenario key 'duration' must be a number; got True")


def test_missing_plant_table():
    data = base_dict()
    del data["plant"]
    refused(data, r"scenario is missing the required table \[plant\]")


def test_missing_top_level_key():
    data = base_dict()
    del data["T_c"]
    refused(data, r"scenario is missing the required key 'T_c'")


def test_missing_and_unknown_type():
    data = base_dict()
    del data["delay"]["type"]
    refused(data, r"scenario key 'delay\.type' is missing; \[delay\] needs a type, one of \[")
    data = base_dict()
    data["plant"]["type"] = "three-link-arm"
    refused(
        data,
        r"scenario key 'plant\.type' must be one of \['linear', 'mujoco', 'two-link-arm', "
        r"'wheeled-robot', 'wheeled-robot-mujoco', 'wheeled-robot-nominal', "
        r"'wheeled-robot-payload', 'wheeled-robot-printed'\] or a factory of yours, "
        r"'python:<module>:<function>'; got 'three-link-arm'",
    )


def test_table_given_as_a_value():
    refused(base_dict() | {"delay": 0.06}, r"scenario key 'delay' must be a table")


def test_unknown_reference_key():
    data = base_dict()
    data["reference"]["amplitdue"] = [1.0, 1.0]
    refused(data, r"unknown key 'reference\.amplitdue' in scenario")


def test_non_positive_step_and_bad_ratio():
    refused(base_dict() | {"dt": 0}, r"scenario key 'dt' must be > 0 \(seconds\); got 0")
    refused(
        base_dict() | {"T_c": 0.0025},
        r"scenario key 'T_c' must be a positive integer multiple of 'dt'",
    )
    refused(
        base_dict() | {"duration": 0.201},
        r"scenario key 'duration' must be a positive integer multiple of 'T_c'",
    )


def test_bad_name_record_every_and_seed():
    refused(
        base_dict() | {"name": "../evil"}, r"scenario key 'name' must start with a letter or digit"
    )
    refused(base_dict() | {"record_every": 0}, r"scenario key 'record_every' must be >= 1; got 0")
    refused(base_dict() | {"seed": 1.5}, r"scenario key 'seed' must be an integer; got 1.5")


def test_refusals_from_constructors_name_the_key():
    data = base_dict()
    data["controller"]["K1"] = -1.0
    with pytest.raises(
        ScenarioError,
        match=r"scenario key 'controller\.K1' must be symmetric positive definite; "
        r"its eigenvalues are \[-1, -1\]",
    ):
        Scenario.from_dict(data).build()


def test_dimension_mismatches_are_refused_at_build():
    with pytest.raises(ScenarioError, match=r"scenario key 'x0' must have 2n = 4 entries"):
        Scenario.from_dict(base_dict() | {"x0": [0.0, 0.0]}).build()
    data = base_dict()
    data["reference"]["offset"] = [0.0, 0.0, 0.0]
    data["reference"]["amplitude"] = [1.0, 1.0, 1.0]
    data["reference"]["frequency"] = [1.0, 1.0, 1.0]
    with pytest.raises(
        ScenarioError, match=r"\[reference\] gives n = 3 coordinates; the plant has n = 2"
    ):
        Scenario.from_dict(data).build()


def test_file_errors_name_the_file(tmp_path):
    with pytest.raises(ScenarioError, match=r"scenario file '.*nope\.toml' does not exist"):
        Scenario.from_toml(tmp_path / "nope.toml")
    broken = tmp_path / "broken.toml"
    broken.write_text("name = \n")
    with pytest.raises(ScenarioError, match=r"broken\.toml: not valid TOML"):
        Scenario.from_toml(broken)
    typo = tmp_path / "typo.toml"
    typo.write_text(dumps_toml(base_dict() | {"dt_typo": 1}))
    with pytest.raises(ScenarioError, match=r"typo\.toml: unknown key 'dt_typo'"):
        Scenario.from_toml(typo)
    # A value refused when the scenario is built names the file too, and keeps its key.
    gains = tmp_path / "gains.toml"
    data = base_dict()
    data["controller"]["K1"] = [1.0, 2.0, 3.0]
    gains.write_text(dumps_toml(data))
    scenario = Scenario.from_toml(gains)
    assert scenario.source == gains and scenario == Scenario.from_dict(data)
    with pytest.raises(
        ScenarioError, match=r"gains\.toml: scenario key 'controller\.K1'"
    ) as refused:
        scenario.build()
    assert refused.value.key == "controller.K1"
    with pytest.raises(ScenarioError, match=r"^scenario key 'controller\.K1'"):
        Scenario.from_dict(data).build()  # no file
    valid = tmp_path / "valid.toml"
    valid.write_text(dumps_toml(base_dict()))
    changed = Scenario.from_toml(valid).replace(controller=data["controller"])
    assert changed.source is None  # a value the file does not hold: not the file's refusal
    with pytest.raises(ScenarioError, match=r"^scenario key 'controller\.K1'"):
        changed.build()


# ---- building -----------------------------------------------------------------------------------


def test_gain_forms_number_list_and_matrix():
    built = Scenario.from_dict(base_dict()).build()
    assert isinstance(built.controller, AROLC)
    np.testing.assert_array_equal(built.controller.K1, [[2.0, 0.5], [0.5, 3.0]])
    np.testing.assert_array_equal(built.controller.K2, np.diag([1.0, 2.0]))
    np.testing.assert_array_equal(built.controller.Q, np.eye(4))
    assert isinstance(built.delay, AbsSineDelay) and built.delay.h_max == pytest.approx(0.1)
    np.testing.assert_array_equal(built.x0, np.zeros(4))


def random_delay(**extra) -> dict:
    return {"type": "random", "h_low": 0.01, "h_high": 0.05, "max_rate": 0.5} | extra


def test_random_delay_takes_the_scenario_seed_and_duration():
    scenario = Scenario.from_dict(base_dict() | {"seed": 42, "delay": random_delay()})
    delay = scenario.build().delay
    assert isinstance(delay, RandomDelay)
    assert delay.seed == 42 and delay.duration == pytest.approx(0.2)
    resolved = scenario.resolved()
    assert resolved.delay["seed"] == 42 and resolved.x0 == (0.0, 0.0, 0.0, 0.0)
    other = Scenario.from_dict(base_dict() | {"seed": 43, "delay": random_delay()}).build().delay
    assert not np.array_equal(delay.params, other.params)


def test_random_delay_own_seed_wins():
    scenario = Scenario.from_dict(base_dict() | {"seed": 42, "delay": random_delay(seed=5)})
    assert scenario.build().delay.seed == 5


def test_random_delay_without_any_seed_is_refused():
    with pytest.raises(
        ScenarioError, match=r"'delay\.seed' is missing and the scenario has no 'seed'"
    ):
        Scenario.from_dict(base_dict() | {"delay": random_delay()})


def test_relative_trace_path_is_resolved_against_the_file(tmp_path, monkeypatch):
    folder = tmp_path / "cases"
    folder.mkdir()
    (folder / "trace.csv").write_text("t,h\n0,0.01\n1,0.03\n")
    data = base_dict() | {"delay": {"type": "trace", "path": "trace.csv"}}
    (folder / "s.toml").write_text(dumps_toml(data))
    monkeypatch.chdir(tmp_path)
    scenario = Scenario.from_toml(folder / "s.toml")
    delay = scenario.build().delay
    assert isinstance(delay, TraceDelay) and delay.h_max == pytest.approx(0.03)
    assert scenario.delay["path"] == str((folder / "trace.csv").resolve())


# ---- running ------------------------------------------------------------------------------------


def test_run_and_batched_run_agree():
    s1 = load_builtin("two_link_S1").replace(duration=0.2)
    s3 = load_builtin("two_link_S3").replace(duration=0.2)
    single = s3.run()
    assert single.x.shape == (1, 101, 4) and single.status_names == ["ok"]
    batch = run_batched([s1, s3])
    assert batch.batch_size == 2
    np.testing.assert_array_equal(batch.x[1], single.x[0])
    np.testing.assert_array_equal(batch.h[0], AbsSineDelay.S1().h(batch.t))


def test_run_batched_refuses_scenarios_that_differ_in_more_than_the_delay():
    arolc = load_builtin("two_link_S1")
    outer = load_builtin("two_link_S1_outer_loop")
    with pytest.raises(ScenarioError, match=re.escape("differ in ['controller']")):
        run_batched([arolc, outer])


@pytest.mark.parametrize(
    ("table", "content", "key"),
    [
        ("delay", {"type": "constant"}, "delay.h"),
        ("delay", {"type": "abs-sine", "offset": 0.01, "amplitude": 0.02}, "delay.frequency"),
        ("delay", {"type": "trace", "times": [0.0, 1.0]}, "delay.values"),
        (
            "controller",
            {"type": "arolc", "K1": 1.0, "K2": 1.0, "Q": 1.0, "alpha": 2.0, "epsilon": 0.1},
            "controller.gamma",
        ),
        ("controller", {"type": "outer-loop", "K1": 1.0}, "controller.K2"),
        ("model", {"type": "linear", "damping": 1.0}, "model.mass"),
    ],
)
def test_missing_required_key_in_a_table(table, content, key):
    refused(
        base_dict() | {table: content}, rf"scenario key '{re.escape(key)}' is missing; \[{table}\]"
    )


def test_trace_takes_path_or_knots_not_both():
    content = {"type": "trace", "path": "x.csv", "times": [0.0], "values": [0.01]}
    refused(
        base_dict() | {"delay": content}, r"takes either 'path' or 'times' and 'values', not both"
    )


def test_input_limits_saturate_the_actuators_and_are_checked(tmp_path):
    data = base_dict()
    data["input_limits"] = [5.0, float("inf")]
    scenario = Scenario.from_dict(data)
    assert scenario.input_limits == (5.0, float("inf"))
    path = tmp_path / "limited.toml"
    scenario.to_toml(path)
    assert Scenario.from_toml(path).input_limits == (5.0, float("inf"))
    result = scenario.run()
    assert result.settings["input_limits"] == [5.0, float("inf")]
    assert np.all(np.abs(result.applied[0][:, 0]) <= 5.0)
    assert np.array_equal(
        Scenario.from_dict({**data, "input_limits": 1e9}).run().x,
        Scenario.from_dict(base_dict()).run().x,
    )
    # Its results folder has the TV received that its summary shows beside the TV.
    from delaytrack.jobs.scenario_run import run_to_folder

    written = run_to_folder(scenario, tmp_path / "out", figure_formats=())
    metrics = pd.read_csv(tmp_path / "out" / "metrics.csv")
    assert "TV received" in " ".join(written.result.summary().columns)
    assert metrics["tv_applied_Nm"][0] == written.result.metrics["tv_applied"][0]
    refused({**data, "input_limits": -1.0}, "'input_limits' must be a number > 0 or a list of them")
    with pytest.raises(ScenarioError, match="'input_limits' must be one number or m = 2 of them"):
        Scenario.from_dict({**data, "input_limits": [1.0, 2.0, 3.0]}).run()


def test_measurement_noise_is_a_table_of_the_scenario(tmp_path):
    data = base_dict() | {"measurement_noise": {"quantization": 0.01, "velocity": 0.05, "seed": 4}}
    scenario = Scenario.from_dict(data)
    path = tmp_path / "noisy.toml"
    scenario.to_toml(path)
    again = Scenario.from_toml(path)
    assert dict(again.measurement_noise) == {"quantization": 0.01, "velocity": 0.05, "seed": 4}
    result = again.run()
    assert result.settings["measurement_noise"] == [
        {"quantization": 0.01, "position": 0.0, "velocity": 0.05, "seed": 4}
    ]
    assert not np.array_equal(result.x, Scenario.from_dict(base_dict()).run().x)
    refused(
        data | {"measurement_noise": {"sigma": 0.1}},
        "'measurement_noise' must be a table with keys among",
    )
    refused(
        data | {"measurement_noise": {"position": -1.0}},
        "measurement_noise.position must be a number >= 0",
    )
    refused(data | {"measurement_noise": 0.1}, "'measurement_noise' must be a table")


def test_packet_loss_is_a_table_of_the_scenario(tmp_path):
    data = base_dict() | {"packet_loss": {"probability": 0.2, "seed": 1}}
    path = tmp_path / "lossy.toml"
    Scenario.from_dict(data).to_toml(path)
    again = Scenario.from_toml(path)
    assert dict(again.packet_loss) == {"probability": 0.2, "seed": 1}
    result = again.run()
    assert result.settings["packet_loss"] == [{"probability": 0.2, "seed": 1}]
    assert not np.array_equal(result.x, Scenario.from_dict(base_dict()).run().x)
    refused(data | {"packet_loss": {"rate": 0.1}}, "'packet_loss' must be a table with keys among")
    refused(data | {"packet_loss": {"probability": 1.5}}, r"packet_loss.probability must be")
    # a seed alone loses nothing: a probability was forgotten
    refused(data | {"packet_loss": {"seed": 5}}, "a seed without a probability, which loses")
    with pytest.raises(ScenarioError) as refusal:  # the value once, in the table given
        Scenario.from_dict(data | {"packet_loss": {"probability": 1.5, "seed": 1}})
    assert str(refusal.value).count("got") == 1
    assert str(refusal.value).endswith("got {'probability': 1.5, 'seed': 1}")


@pytest.mark.parametrize(
    "key, table",
    [("measurement_noise", {"velocity": 0.05}), ("packet_loss", {"probability": 0.3})],
)
def test_noise_and_losses_without_a_seed_of_their_own_take_the_scenarios(key, table):
    """As the README says of ``seed``: a sweep over the scenario's seed draws new noise and new
    losses each run (it drew the same, seed 0, for every run)."""
    seeds = {5: {"seed": 5}, 9: {"seed": 9}, None: {}}
    runs = {seed: Scenario.from_dict(base_dict() | {key: table} | seeds[seed]) for seed in seeds}
    simulated = f"simulated_{key}"
    assert [getattr(runs[seed], simulated).seed for seed in runs] == [5, 9, 0]
    assert dict(getattr(runs[5].resolved(), key)) == {**table, "seed": 5}
    assert getattr(runs[None].resolved(), key) == table  # no seed to write in
    x = {seed: runs[seed].run().x for seed in (5, 9)}
    assert not np.array_equal(x[5], x[9])
    np.testing.assert_array_equal(x[5], runs[5].resolved().run().x)  # the scenario as run
    own = Scenario.from_dict(base_dict() | {key: {**table, "seed": 7}, "seed": 5})
    assert getattr(own, simulated).seed == 7  # its own seed wins
    with pytest.raises(ScenarioError, match=rf"'seed' must be at most 4294967295 .*seeds {key}"):
        Scenario.from_dict(base_dict() | {key: table, "seed": 2**32})
    Scenario.from_dict(base_dict() | {key: {**table, "seed": 1}, "seed": 2**32})  # not used


def test_a_sweep_file_given_as_a_scenario_is_said_to_be_one():
    sweep = {"scenario": "two_link_S1", "unit_size": 4, "grid": {"controller.K2": [1.0]}}
    said = r"unknown key 'scenario' in scenario; valid keys .*; this looks like a sweep file"
    with pytest.raises(ScenarioError, match=said + r" \(run it with delaytrack sweep\)$"):
        Scenario.from_dict(sweep)
    with pytest.raises(ScenarioError, match=r"unknown key 'dt_typo' in scenario; valid keys .*\]$"):
        Scenario.from_dict(base_dict() | {"dt_typo": 1})


def test_the_scenario_names_stay_importable_from_experiments_and_the_package_root():
    import delaytrack
    import delaytrack.experiments as experiments
    import delaytrack.jobs.scenario_run as scenario_run
    import delaytrack.scenario as scenario

    for name in (
        "BuiltScenario",
        "Scenario",
        "ScenarioError",
        "builtin_scenario_names",
        "builtin_scenario_path",
        "load_builtin",
        "run_batched",
    ):
        assert getattr(experiments, name) is getattr(scenario, name)
    for name in ("Scenario", "ScenarioError", "load_builtin"):
        assert getattr(delaytrack, name) is getattr(scenario, name)
    assert delaytrack.run_to_folder is scenario_run.run_to_folder
