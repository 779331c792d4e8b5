"""A scenario's ``u_init``: the input the plant receives before the first command arrives."""

from __future__ import annotations

import numpy as np
import pytest

from delaytrack.scenario import Scenario, ScenarioError, load_builtin


def scenario(**changes) -> Scenario:
    return load_builtin("two_link_S1").replace(name="held", duration=0.2, **changes)


def test_u_init_is_what_the_plant_receives_until_the_first_command_arrives():
    result = scenario(u_init=[0.5, -0.25], delay={"type": "constant", "h": 0.02}).run()
    before = result.t < 0.02
    assert before.sum() > 1
    np.testing.assert_array_equal(result.applied[0, before], [[0.5, -0.25]] * before.sum())
    zero = scenario(delay={"type": "constant", "h": 0.02}).run()
    np.testing.assert_array_equal(zero.applied[0, before], 0.0)  # zeros by default


def test_u_init_round_trips_through_a_scenario_file(tmp_path):
    path = tmp_path / "held.toml"
    scenario(u_init=[0.5, -0.25]).to_toml(path)
    assert "u_init = [0.5, -0.25]" in path.read_text()
    assert Scenario.from_toml(path).u_init == (0.5, -0.25)
    assert "u_init" not in scenario().to_toml()


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ([0.5], "'u_init' must have m = 2 entries"),
        ("0.5", "u_init"),
        ([float("nan"), 0.0], "u_init"),
    ],
)
def test_a_bad_u_init_is_refused_naming_the_key(value, message):
    with pytest.raises(ScenarioError, match=message):
        scenario(u_init=value).build()


def test_u_init_beyond_the_input_limits_is_refused_when_built():
    """Refused when the scenario is built (before any run, and before a live robot node would
    write it to its actuators), not only by the simulator."""
    with pytest.raises(ScenarioError, match="'u_init' must lie within input_limits"):
        scenario(u_init=[5.0, 0.0], input_limits=1.0).build()


def test_a_sweep_runs_the_scenarios_u_init(tmp_path):
    """Every place that runs a scenario passes its ``u_init``: a sweep's runs give the metrics of
    the scenario run alone, and runs with another ``u_init`` are simulated apart."""
    from delaytrack.sweeps import SweepSpec, run_sweep

    held = scenario(u_init=[0.5, -0.25], delay={"type": "constant", "h": 0.02})
    held.to_toml(tmp_path / "held.toml")
    alone = held.run()
    spec = SweepSpec.from_dict(
        {"scenario": "held.toml", "unit_size": 2, "grid": {"u_init": [[0.5, -0.25], [0.0, 0.0]]}},
        root=tmp_path,
    )
    runs = run_sweep(spec, tmp_path / "out", progress=False).runs.sort_values("run")
    assert runs.ae_q1.iloc[0] == pytest.approx(float(alone.metrics["ae"][0, 0]), rel=0, abs=0)
    assert runs.ae_q1.iloc[1] != runs.ae_q1.iloc[0]
