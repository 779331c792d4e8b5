"""Property-based tests of the input surfaces: a clear error or a finite, correct result.

Scenario tables, delay tables, trace files, sweep specs and command-line numbers are generated
by ``hypothesis`` from hostile values (NaN, infinities, huge and tiny numbers, wrong types,
ragged rows). The contract for each: either the input is refused with an error that names the
key or flag, or it is accepted and gives finite values that satisfy their definition. Every
example must finish in bounded time.

``make test`` runs a quick profile (a few dozen examples per test, the same ones every time);
set ``HYPOTHESIS_PROFILE=long`` for a thousand random ones per test.
"""

from __future__ import annotations

import math
import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from delaytrack.cli import main
from delaytrack.delays import TraceDelay, delay_from_spec
from delaytrack.scenario import Scenario, ScenarioError
from delaytrack.sweeps import SweepError, SweepSpec
from test_scenario import base_dict

settings.register_profile(
    "quick",
    max_examples=30,
    derandomize=True,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
settings.register_profile(
    "long",
    max_examples=1000,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "quick"))

#: Numbers a user may type, the hostile ones included.
numbers = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 1e-300, 1e300, -1e300, 5e-324, 1e-9, 1e9, 0.001, 0.002, 1.0]),
    st.integers(min_value=-(2**70), max_value=2**70),
)
#: Values of any TOML type.
anything = st.one_of(
    numbers,
    st.booleans(),
    st.text(max_size=5),
    st.lists(numbers, max_size=4),
    st.dictionaries(st.text(max_size=3), numbers, max_size=2),
)


def _finite_run(scenario: Scenario) -> None:
    """Run a scenario that is cheap enough; its metrics must be finite or NaN with a not-ok
    status."""
    if scenario.duration / scenario.dt > 400 or scenario.T_c / scenario.dt > 400:
        return
    try:
        result = scenario.run()
    except ScenarioError:
        return
    for name, values in result.metrics.items():
        ok = result.status == 0
        assert np.all(np.isfinite(values[ok])), name
        assert np.all(np.isnan(values[~ok])), name


@given(
    key=st.sampled_from(["duration", "dt", "T_c", "record_every", "error_bound", "x0", "seed"]),
    value=anything,
)
def test_scenario_top_level_values(key, value):
    data = {**base_dict(), "duration": 0.02, key: value}
    try:
        scenario = Scenario.from_dict(data)
    except ScenarioError as error:
        assert repr(key) in str(error) or f"'{key}" in str(error), str(error)
        return
    _finite_run(scenario)


@given(
    key=st.sampled_from(["K1", "K2", "Q", "alpha", "epsilon", "gamma", "c_hat0"]),
    value=anything,
)
def test_controller_table_values(key, value):
    data = base_dict()
    data["duration"] = 0.02
    data["controller"] = {**data["controller"], key: value}
    try:
        scenario = Scenario.from_dict(data)
        scenario.build()
    except ScenarioError as error:
        assert f"controller.{key}" in str(error) or "[controller]" in str(error), str(error)
        return
    _finite_run(scenario)


delay_tables = st.one_of(
    st.fixed_dictionaries({"type": st.just("constant"), "h": numbers}),
    st.fixed_dictionaries(
        {
            "type": st.just("abs-sine"),
            "offset": numbers,
            "amplitude": numbers,
            "frequency": numbers,
        }
    ),
    st.fixed_dictionaries(
        {
            "type": st.just("piecewise-constant"),
            "times": st.lists(numbers, max_size=5),
            "values": st.lists(numbers, max_size=5),
        }
    ),
    st.fixed_dictionaries(
        {
            "type": st.just("random"),
            "h_low": numbers,
            "h_high": numbers,
            "max_rate": numbers,
            "duration": numbers,
            "seed": st.integers(min_value=-5, max_value=2**64),
            "knot_spacing": numbers,
        }
    ),
)


@given(table=delay_tables)
def test_delay_tables(table):
    try:
        delay = delay_from_spec(table)
    except ScenarioError as error:
        assert "delay" in str(error)
        return
    times = np.linspace(0.0, 10.0, 101)
    values = delay.h(times)
    assert np.all(np.isfinite(values)) and np.all(values >= 0.0)
    assert np.all(values <= delay.h_max * (1 + 1e-12))
    _finite_run(Scenario.from_dict({**base_dict(), "duration": 0.02, "delay": table}))


cells = st.one_of(
    numbers.map(repr),
    st.sampled_from(["", "nan", "inf", "1e400", "t", "delay_ms", "h [s]", " 1 "]),
    st.text(max_size=4),
)


@given(
    header=st.one_of(st.none(), st.lists(cells, min_size=1, max_size=3)),
    rows=st.lists(st.lists(cells, min_size=0, max_size=3), max_size=6),
)
@settings(suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_trace_files(tmp_path, header, rows):
    path = tmp_path / "trace.csv"
    lines = ([",".join(header)] if header else []) + [",".join(row) for row in rows]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    try:
        trace = TraceDelay.from_csv(path)
    except ValueError as error:
        assert str(path) in str(error), str(error)
        return
    assert np.all(np.isfinite(trace.times)) and np.all(np.diff(trace.times) > 0)
    assert np.all(np.isfinite(trace.values)) and np.all(trace.values >= 0)


@given(
    draws=st.one_of(st.integers(min_value=-3, max_value=10), st.sampled_from([10**8, 10**30])),
    grid=st.lists(st.floats(min_value=0.1, max_value=3.0), min_size=1, max_size=3),
    unit_size=st.one_of(st.integers(min_value=-1, max_value=50), st.just(True)),
)
def test_sweep_specs(draws, grid, unit_size):
    data = {
        "scenario": "two_link_S1",
        "unit_size": unit_size,
        "draws": draws,
        "seed": 1,
        "grid": {"controller.alpha": grid},
        "random": {"seed": {"dist": "integers", "low": 0, "high": 9}},
    }
    try:
        spec = SweepSpec.from_dict(data)
    except SweepError as error:
        message = str(error)
        assert any(key in message for key in ("draws", "unit_size", "runs")), message
        return
    assert len(spec.runs) == len(grid) * draws


flag_text = st.one_of(
    numbers.map(repr),
    st.sampled_from(["nan", "inf", "-inf", "1e400", "abc", "1,2", "", "0", "-1", "1e-320"]),
)


@pytest.mark.parametrize("command", ["bound", "margin"])
@given(flag=st.sampled_from(["--k1", "--k2", "--q", "--beta", "--r"]), text=flag_text)
def test_command_line_numbers(command, flag, text, capsys):
    capsys.readouterr()
    args = {"--k1": "1", "--k2": "1", "--q": "1", "--beta": "1", "--r": "1.1", flag: text}
    code = main([command, *[f"{k}={v}" for k, v in args.items()], "--json"])
    out, err = capsys.readouterr()
    if code == 0:
        assert "nan" not in out.lower() and "infinity" not in out.lower(), out
        assert err == ""
        return
    assert code == 2
    assert err.startswith("error: ") and err.count("\n") == 1, err
    assert flag in err and "Traceback" not in err and "Warning" not in err, err


#: Per flag of ``delaytrack empirical``: whether a value starts a (long) search on
#: two_link_margins (30 s, default --upper 1 s and --resolution 0.005 s) instead of a refusal.
_STARTS_A_SEARCH = {
    "--threshold": lambda v: v > 0,
    "--frequency": lambda v: v > 0,
    "--settle": lambda v: 0 <= v < 30,
    "--resolution": lambda v: 1e-9 <= v < 1,
    "--upper": lambda v: 0.005 < v <= 30,
}


@given(flag=st.sampled_from(sorted(_STARTS_A_SEARCH)), text=flag_text)
@settings(max_examples=15)
def test_empirical_numbers_are_refused_at_once(flag, text, capsys):
    """Values that would start a search are left to the empirical-margin tests (long runs)."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if math.isfinite(value) and _STARTS_A_SEARCH[flag](value):
        return
    capsys.readouterr()
    args = ["empirical", "two_link_margins", "--threshold", "0.2", f"{flag}={text}", "--json"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1 and flag in err, err
