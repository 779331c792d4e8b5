"""Large sweeps and large runs: a sweep at the run limit loads with each distinct table checked
and built once (every run's scenario still checked whole), and ``simulate`` and ``sweep`` say how
big the work is before it starts, unless ``--quiet``.

Tests check structure (counts of checks and constructions, the runs, the lines printed), never
time; the load times are measured in the change's notes.
"""

from __future__ import annotations

import itertools
import re
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import delaytrack.scenario.scenario as scenario_module
import delaytrack.sweeps.spec as spec_module
from delaytrack._spec import module_from_file
from delaytrack.cli import main
from delaytrack.scenario import Scenario
from delaytrack.sweeps import SweepError, SweepSpec
from delaytrack.sweeps.spec import MAX_RUNS, _apply, _check_runnable, _unit_hash, code_version
from test_scenario import base_dict

#: The tables a sweep's runs are made of.
TABLES = ("plant", "model", "controller", "delay", "reference")


def base_file(folder: Path, **changes) -> str:
    """A short two-link scenario as a file in ``folder``; its name, for a sweep's ``scenario``."""
    Scenario.from_dict({**base_dict(), **changes}).to_toml(folder / "base.toml")
    return "base.toml"


def counting(monkeypatch, name: str) -> list[object]:
    """Count the calls of ``scenario_module.<name>`` (what the scenario module checks and builds
    tables with)."""
    calls: list[object] = []
    original = getattr(scenario_module, name)

    def counted(*args, **kwargs):
        calls.append(args[0])
        return original(*args, **kwargs)

    monkeypatch.setattr(scenario_module, name, counted)
    return calls


# ---- the run limit -----------------------------------------------------------------------------


#: The run limit of the test below: the checks and builds it counts are those of the distinct
#: tables whatever the number of runs, so a sweep of the documented limit (``MAX_RUNS``, 100 000
#: runs, about 20 s of loading) is checked at this limit instead.
LIMIT = 4_000


def test_a_sweep_at_the_run_limit_loads_checking_each_distinct_table_once(tmp_path, monkeypatch):
    """LIMIT runs over 2 x 2 x 2 grid points and LIMIT / 8 draws: 9 distinct tables (2 plants,
    2 models, 2 controllers, 2 delays, 1 reference) and 4 controllers (each gain with each
    model). Each run is its own scenario (its own drawn seed) and every run is still checked
    whole."""
    assert MAX_RUNS == 100_000  # the documented limit
    monkeypatch.setattr(spec_module, "MAX_RUNS", LIMIT)
    base = base_file(tmp_path)
    checks = counting(monkeypatch, "check_table")
    controllers = counting(monkeypatch, "controller_from_spec")
    plants = counting(monkeypatch, "plant_from_spec")
    draws = LIMIT // 8
    data = {
        "scenario": base,
        "unit_size": LIMIT // 200,
        "draws": draws,
        "seed": 11,
        "grid": {
            "controller.K1": [1.0, 2.0],
            "delay": [{"type": "S1"}, {"type": "constant", "h": 0.05}],
            "model.fd1": [0.0, 1.0],
        },
        "random": {
            "plant.fd1": {"dist": "choice", "values": [2.0, 5.0]},
            "seed": {"dist": "integers", "low": 0, "high": 2**40},
        },
    }
    spec = SweepSpec.from_dict(data, root=tmp_path)
    runs = spec.runs
    assert len(runs) == LIMIT  # the limit itself is accepted
    assert [run.index for run in runs] == list(range(LIMIT))
    assert len(spec.units()) == 200
    # the base scenario's 5 checks, then each distinct table of the runs once: at least the 2
    # swept values of each of controller, delay, model and plant, at most one more
    assert len(TABLES) + 8 <= len(checks) <= len(TABLES) + 9
    assert len(controllers) == 4  # 2 gains x 2 models, each built once
    assert len(plants) == 4  # 2 plants, 2 models
    # each run has its own values (every grid point meets the same draws) and its own scenario
    assert len({run.values["seed"] for run in runs}) > 0.999 * draws
    keys = ("controller.K1", "model.fd1", "plant.fd1", "seed")
    distinct = {(run.values["delay"]["type"], *(run.values[key] for key in keys)) for run in runs}
    assert len(distinct) > 0.999 * LIMIT
    grid = list(itertools.product([1.0, 2.0], ["S1", "constant"], [0.0, 1.0]))
    for run in runs[:: LIMIT // 97]:
        K1, delay, fd1 = grid[run.index // draws]
        scenario = run.scenario
        assert (scenario.controller["K1"], scenario.delay["type"], scenario.model["fd1"]) == (
            K1,
            delay,
            fd1,
        )
        assert scenario.seed == run.values["seed"]
        assert scenario.plant["fd1"] == run.values["plant.fd1"]
    with pytest.raises(SweepError, match=f"{LIMIT + 8} runs .* at most {LIMIT} runs"):
        SweepSpec.from_dict({**data, "draws": draws + 1}, root=tmp_path)  # one more per point


def test_a_run_is_still_checked_whole_when_its_tables_were_met_before(tmp_path):
    """Every table of run 1 was checked with run 0; its own x0 is refused all the same."""
    data = {
        "scenario": base_file(tmp_path),
        "unit_size": 2,
        "grid": {"x0": [[0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]},
    }
    with pytest.raises(SweepError, match=r'grid\."x0" = \[0\.0, 0\.0, 0\.0\] \(run 1\).*2n = 4'):
        SweepSpec.from_dict(data, root=tmp_path)


def test_one_one_point_oh_and_true_are_three_tables(tmp_path):
    """Tables are told apart by their JSON text: K1 = 1 and K1 = 1.0 are both gains (each run
    keeps its own), K1 = true is refused although 1 and 1.0 were accepted before it."""
    data = {
        "scenario": base_file(tmp_path),
        "unit_size": 2,
        "grid": {"controller.K1": [1, 1.0, 1, True]},
    }
    message = r'grid\."controller\.K1" = True \(run 3\): scenario key .controller\.K1. must be'
    with pytest.raises(SweepError, match=message):
        SweepSpec.from_dict(data, root=tmp_path)
    data["grid"]["controller.K1"] = [1, 1.0, 1]
    runs = SweepSpec.from_dict(data, root=tmp_path).runs
    assert [type(run.scenario.controller["K1"]) for run in runs] == [int, float, int]


def test_a_factory_of_yours_is_called_for_every_run(tmp_path):
    """A factory may depend on more than its arguments: the runs do not share its component."""
    (tmp_path / "counted_delay.py").write_text(
        "from delaytrack.delays import ConstantDelay\n"
        "CALLS = []\n"
        "def make(h):\n"
        "    CALLS.append(h)\n"
        "    return ConstantDelay(h)\n"
    )
    factory = tmp_path / "counted_delay.py"
    spec = SweepSpec.from_dict(
        {
            "scenario": base_file(tmp_path, delay={"type": f"python:{factory}:make", "h": 0.01}),
            "unit_size": 3,
            "grid": {"controller.alpha": [1.0, 2.0, 3.0]},
        },
        root=tmp_path,
    )
    assert len(spec.runs) == 3
    assert module_from_file(factory).CALLS == [0.01] * 3


# ---- what remembering tables must not change -----------------------------------------------

_DELAYS = [
    {"type": "S1"},
    {"type": "constant", "h": 0.05},
    {"type": "constant", "h": 0.05},  # the same table again
    {"type": "random", "h_low": 0.01, "h_high": 0.05, "max_rate": 0.5},  # takes the seed
]


@settings(
    max_examples=15,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(
    gains=st.lists(st.sampled_from([1, 1.0, 2.0, [1.0, 2.0]]), min_size=1, max_size=3),
    delays=st.lists(st.sampled_from(range(len(_DELAYS))), min_size=1, max_size=3),
    seeds=st.lists(st.integers(0, 3), min_size=1, max_size=2),
    draws=st.integers(1, 3),
)
def test_the_runs_equal_those_built_one_by_one_without_remembering(
    tmp_path, gains, delays, seeds, draws
):
    """For generated grids with repeated values, each run (its resolved scenario, what the
    engine receives, its controller's size) and each unit hash equal those of the run built
    alone, outside any remembered block."""
    spec = SweepSpec.from_dict(
        {
            "scenario": base_file(tmp_path),
            "unit_size": 2,
            "draws": draws,
            "seed": 5,
            "grid": {
                "controller.K1": gains,
                "delay": [_DELAYS[i] for i in delays],
                "seed": seeds,
            },
            "random": {"plant.fd1": {"dist": "choice", "values": [1.0, 3.0]}},
        },
        root=tmp_path,
    )
    base = spec.base.to_dict()
    alone = []
    for run in spec.runs:
        scenario, built = Scenario.from_dict(_apply(base, dict(run.values))).resolved_and_built()
        _check_runnable(scenario, built)
        alone.append(type(run).of(run.index, run.values, scenario, built))
        assert run == alone[-1]
        assert run.scenario.to_dict() == scenario.to_dict()
    version = code_version()
    for unit in spec.units():
        assert unit.hash == _unit_hash(alone[unit.runs[0].index : unit.runs[-1].index + 1], version)


# ---- the size, said before the work ---------------------------------------------------------

_SIMULATING = re.compile(
    r"delaytrack: simulating 1 run of 200 steps \(dt = 0\.001 s\), n = 2 coordinates; "
    r"about [0-9.]+ MiB of trajectories \(101 samples per run\)"
)
_SWEEPING = re.compile(
    r"delaytrack: sweeping 4 runs in 2 units of up to 2, 200 plant steps each, n = 2 "
    r"coordinates \(base scenario\); metrics only, no trajectories recorded"
)


@pytest.mark.parametrize("quiet", [False, True])
def test_simulate_says_its_size_before_it_runs_unless_quiet(tmp_path, capsys, quiet):
    base_file(tmp_path)
    flags = ["--quiet"] if quiet else []
    out = str(tmp_path / "out")
    assert main(["simulate", str(tmp_path / "base.toml"), "--out", out, *flags]) == 0
    err = capsys.readouterr().err
    assert (_SIMULATING.search(err) is None) == quiet, err
    assert err.count("delaytrack: simulating") == (0 if quiet else 1)


@pytest.mark.parametrize("quiet", [False, True])
def test_sweep_says_its_size_before_it_runs_unless_quiet(tmp_path, capsys, quiet):
    base_file(tmp_path)
    (tmp_path / "sweep.toml").write_text(
        'scenario = "base.toml"\nunit_size = 2\n[grid]\n"controller.alpha" = [1.0, 2.0]\n'
        'delay = [{ type = "S1" }, { type = "constant", h = 0.05 }]\n'
    )
    flags = ["--quiet"] if quiet else []
    out = str(tmp_path / "out")
    assert main(["sweep", str(tmp_path / "sweep.toml"), "--out", out, *flags]) == 0
    err = capsys.readouterr().err
    assert (_SWEEPING.search(err) is None) == quiet, err
    assert ("delaytrack: simulating" in err) is False  # no line per unit
