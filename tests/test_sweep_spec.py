"""Sweep specs: expansion, seeded draws, refusals that name the sweep key, unit hashes."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import delaytrack
import delaytrack.sweeps.spec
from delaytrack.scenario import load_builtin
from delaytrack.sweeps import SweepError, SweepSpec, Unit
from delaytrack.sweeps import spec as spec_module


def spec_dict(**changes) -> dict:
    data = {
        "scenario": "two_link_S1",
        "unit_size": 5,
        "grid": {
            "controller.K1": [0.5, 1.0],
            "delay": [{"type": "S1"}, {"type": "constant", "h": 0.05}],
        },
        "draws": 3,
        "seed": 7,
        "random": {
            "plant.fd1": {"dist": "uniform", "low": 1.0, "high": 5.0},
            "controller.gamma": {"dist": "loguniform", "low": 1e-4, "high": 1e-2},
            "controller.alpha": {"dist": "choice", "values": [1.0, 2.0, 3.0]},
            "seed": {"dist": "integers", "low": 0, "high": 2},
        },
    }
    data.update(changes)
    return data


def test_expansion_counts_order_and_indices():
    spec = SweepSpec.from_dict(spec_dict())
    assert len(spec.runs) == 2 * 2 * 3
    assert [run.index for run in spec.runs] == list(range(12))
    # Grid-major, first key outermost; draw index fastest.
    k1 = [run.values["controller.K1"] for run in spec.runs]
    assert k1 == [0.5] * 6 + [1.0] * 6
    delays = [run.scenario.delay["type"] for run in spec.runs]
    assert delays == (["S1"] * 3 + ["constant"] * 3) * 2
    assert spec.runs[3].scenario.delay["h"] == 0.05
    assert spec.runs[0].scenario.controller["K1"] == 0.5
    # Every grid point sees the same draws (common random numbers across the grid).
    fd1 = [run.scenario.plant["fd1"] for run in spec.runs]
    assert fd1[0:3] == fd1[3:6] == fd1[6:9] == fd1[9:12]
    # Untouched keys keep the base scenario's values.
    base = load_builtin("two_link_S1")
    assert spec.runs[0].scenario.model == base.model


def test_grid_only_and_random_only():
    grid = SweepSpec.from_dict(
        {"scenario": "two_link_S1", "unit_size": 1, "grid": {"T_c": [0.002, 0.004]}}
    )
    assert [run.scenario.T_c for run in grid.runs] == [0.002, 0.004]
    random = spec_dict()
    del random["grid"]
    assert len(SweepSpec.from_dict(random).runs) == 3


def test_expansion_is_deterministic():
    one, two = SweepSpec.from_dict(spec_dict()), SweepSpec.from_dict(spec_dict())
    assert [r.canonical() for r in one.runs] == [r.canonical() for r in two.runs]
    assert [u.hash for u in one.units()] == [u.hash for u in two.units()]


def test_draws_are_seeded_within_bounds_and_independent_per_key():
    runs = SweepSpec.from_dict(spec_dict()).runs[:3]
    fd1 = [run.values["plant.fd1"] for run in runs]
    gamma = [run.values["controller.gamma"] for run in runs]
    assert all(1.0 <= v <= 5.0 for v in fd1) and len(set(fd1)) == 3
    assert all(1e-4 <= v <= 1e-2 for v in gamma)
    assert all(run.values["controller.alpha"] in (1.0, 2.0, 3.0) for run in runs)
    assert all(
        run.values["seed"] in (0, 1, 2) and isinstance(run.values["seed"], int) for run in runs
    )

    data = spec_dict()
    data["seed"] = 8
    other = [run.values["plant.fd1"] for run in SweepSpec.from_dict(data).runs[:3]]
    assert other != fd1

    # Adding a key leaves the other keys' draws unchanged.
    data = spec_dict()
    data["random"] = {**data["random"], "plant.fd2": {"dist": "uniform", "low": 0.0, "high": 1.0}}
    assert [run.values["plant.fd1"] for run in SweepSpec.from_dict(data).runs[:3]] == fd1


def test_random_delay_takes_the_drawn_scenario_seed():
    data = spec_dict(
        grid={"delay": [{"type": "random", "h_low": 0.01, "h_high": 0.05, "max_rate": 0.5}]}
    )
    runs = SweepSpec.from_dict(data).runs
    assert [run.scenario.delay["seed"] for run in runs] == [run.values["seed"] for run in runs]
    assert all(run.scenario.delay["duration"] == 30.0 for run in runs)


def test_the_noise_seed_can_be_drawn_per_run():
    noise = {"quantization": 0.0, "position": 0.001, "velocity": 0.01, "seed": 0}
    data = spec_dict(
        grid={"measurement_noise": [noise]},
        random={"measurement_noise.seed": {"dist": "integers", "low": 0, "high": 10**6}},
    )
    data["draws"], data["seed"] = 4, 3
    runs = SweepSpec.from_dict(data).runs
    seeds = [run.scenario.measurement_noise["seed"] for run in runs]
    assert seeds == [run.values["measurement_noise.seed"] for run in runs]
    assert len(set(seeds)) == 4
    assert all(run.scenario.measurement_noise["position"] == 0.001 for run in runs)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        (
            {"grid": {"controller.K9": [1.0]}},
            "grid.\"controller.K9\" = 1.0 (run 0): unknown key 'controller.K9'",
        ),
        (
            {"grid": {"delay.h": [0.1]}},
            "grid.\"delay.h\" = 0.1 (run 0): unknown key 'delay.h' in scenario; valid keys in "
            "[delay] with type = 'S1' are ['type']",
        ),
        (
            {"grid": {"controller.K1": [1.0, -1.0]}},
            "grid.\"controller.K1\" = -1.0 (run 3): scenario key 'controller.K1' must be "
            "symmetric positive definite",
        ),
        (
            {"grid": {"delay": [{"type": "constant"}]}},
            "grid.\"delay\" = {'type': 'constant'} (run 0): scenario key 'delay.h' is missing",
        ),
        (
            {"grid": {"delay": ["S1"]}},
            "grid.\"delay\" = 'S1' (run 0): scenario key 'delay' must be a table ([delay]); "
            "got 'S1'",
        ),
        (
            {"random": {"delay": {"dist": "choice", "values": ["S1"]}}, "grid": {"delay.h": [0.1]}},
            'sweep key "delay.h" needs a [delay] table in the scenario or the sweep',
        ),
        (
            {"grid": {"measurement_noise.seed": [1]}},
            'sweep key "measurement_noise.seed" needs a [measurement_noise] table',
        ),
        ({"grid": {"foo": [1]}}, 'grid."foo": unknown key; a sweep key is'),
        ({"grid": {"controller.K1.x": [1]}}, 'grid."controller.K1.x": unknown key'),
        ({"grid": {"controller.K1": []}}, 'grid."controller.K1" must be a non-empty list'),
        ({"grid": {"controller.K1": 1.0}}, 'grid."controller.K1" must be a non-empty list'),
        ({"unit_size": 0}, "sweep key 'unit_size' must be a positive integer; got 0"),
        ({"unit_size": True}, "sweep key 'unit_size' must be a positive integer; got True"),
        ({"scenario": "nope"}, "sweep key 'scenario' = 'nope' is neither a file"),
        (
            {"scenario": "/dev/zero"},
            "sweep key 'scenario' = '/dev/zero' is not a file but a character device; it must "
            "be a regular file",
        ),
        (
            {"scenario": "/"},
            "sweep key 'scenario' = '/' is not a file but a folder; it must be a regular file",
        ),
        (
            {"scenario": 3},
            "sweep key 'scenario' must be a scenario file or a shipped scenario name",
        ),
        (
            {"extra": 1},
            "unknown sweep key 'extra'; valid keys are ['scenario', 'unit_size', 'draws', 'seed', "
            "'metrics', 'grid', 'random']",
        ),
        (  # a scenario file given as a sweep file: said so
            {"name": "arm"},
            "unknown sweep key 'name'; valid keys are ['scenario', 'unit_size', 'draws', 'seed', "
            "'metrics', 'grid', 'random']; this looks like a scenario file (run it with "
            "delaytrack simulate, or name it in a sweep file's 'scenario' key)",
        ),
        ({"random": {}}, "sweep table [random] is empty; give it at least one key or leave it"),
        ({"grid": {}}, "sweep table [grid] is empty; give it at least one key or leave it out"),
        (
            {"draws": 0},
            "sweep key 'draws' must be a positive integer; got 0",
        ),
        (
            {"seed": -1},
            "sweep key 'seed' must be an integer >= 0; got -1",
        ),
        (
            {"random": {"delay.h": 0.1}},
            "random.\"delay.h\" must be a table with 'dist'",
        ),
        (
            {"random": {"delay.h": {"dist": "normal"}}},
            "random.\"delay.h\": 'dist' must be one of ['uniform', 'loguniform', 'choice', "
            "'integers']; got 'normal'",
        ),
        (
            {"random": {"plant.fd1": {"dist": "uniform", "low": 1.0}}},
            "random.\"plant.fd1\": dist = 'uniform' takes exactly the keys ['dist', 'high', 'low']",
        ),
        (
            {
                "random": {
                    "plant.fd1": {"dist": "uniform", "low": 2.0, "high": 1.0},
                }
            },
            'random."plant.fd1": needs low < high with a finite difference; got low = 2.0, '
            "high = 1.0",
        ),
        (
            {
                "random": {
                    "plant.fd1": {"dist": "uniform", "low": "a", "high": 1.0},
                }
            },
            "random.\"plant.fd1\": 'low' must be a finite number; got 'a'",
        ),
        (
            {
                "random": {
                    "plant.fd1": {"dist": "loguniform", "low": 0.0, "high": 1.0},
                }
            },
            "random.\"plant.fd1\": dist = 'loguniform' needs low > 0",
        ),
        (
            {
                "random": {
                    "seed": {"dist": "integers", "low": 0.5, "high": 3},
                }
            },
            "random.\"seed\": dist = 'integers' needs integers low <= high (high inclusive)",
        ),
        (
            {"random": {"plant.fd1": {"dist": "choice", "values": []}}},
            "random.\"plant.fd1\": 'values' must be a non-empty list",
        ),
        (
            {
                "random": {
                    "controller.K1": {"dist": "choice", "values": [1.0]},
                }
            },
            'sweep key "controller.K1" is in both [grid] and [random]',
        ),
    ],
)
def test_bad_specs_are_refused_naming_the_key(changes, message):
    data = spec_dict(**changes)
    if "random" in changes and "grid" not in changes:
        data["grid"] = {"controller.K1": [1.0]}
    with pytest.raises(SweepError, match=re.escape(message)):
        SweepSpec.from_dict(data)


def test_random_needs_draws_and_seed():
    data = spec_dict()
    del data["draws"]
    with pytest.raises(SweepError, match=re.escape("has [random] and needs 'draws' (draws:")):
        SweepSpec.from_dict(data)
    del data["seed"]  # both missing: both named at once
    with pytest.raises(SweepError, match=re.escape("needs 'draws' and 'seed' (draws: how many")):
        SweepSpec.from_dict(data)


def test_spec_needs_grid_or_random():
    with pytest.raises(
        SweepError, match=re.escape("needs a [grid] table, a [random] table or both")
    ):
        SweepSpec.from_dict({"scenario": "two_link_S1", "unit_size": 1})


def test_units_split_runs_in_order():
    units = SweepSpec.from_dict(spec_dict()).units()
    assert [len(unit.runs) for unit in units] == [5, 5, 2]
    assert [run.index for unit in units for run in unit.runs] == list(range(12))
    assert units[1].part_name == f"part-00001-{units[1].hash[:12]}.parquet"
    assert len({unit.hash for unit in units}) == 3


@pytest.mark.parametrize(
    "change",
    [
        lambda d: d["grid"].update({"controller.K1": [0.7, 1.0]}),  # a swept value
        lambda d: d.update({"seed": 8}),  # the draws
        lambda d: d["grid"].update({"duration": [29.0]}),  # a scenario setting
        lambda d: d.update({"unit_size": 4}),  # which runs a unit holds
    ],
)
def test_unit_hash_changes_with_any_change(change):
    data = spec_dict()
    before = SweepSpec.from_dict(data).units()[0].hash
    change(data)
    assert SweepSpec.from_dict(data).units()[0].hash != before


def test_unit_hash_changes_with_the_package_version(monkeypatch):
    before = SweepSpec.from_dict(spec_dict()).units()[0].hash
    monkeypatch.setattr(delaytrack.sweeps.spec, "__version__", "99.0")  # the version it reads
    assert SweepSpec.from_dict(spec_dict()).units()[0].hash != before


def test_from_toml_resolves_the_scenario_path_and_names_the_file(tmp_path):
    load_builtin("two_link_S1").replace(duration=1.0).to_toml(tmp_path / "base.toml")
    path = tmp_path / "sweep.toml"
    path.write_text('scenario = "base.toml"\nunit_size = 2\n[grid]\n"controller.K1" = [1.0, 2.0]\n')
    spec = SweepSpec.from_toml(path)
    assert [run.scenario.duration for run in spec.runs] == [1.0, 1.0]
    path.write_text('scenario = "base.toml"\nunit_size = 2\n[grid]\n"controller.K9" = [1.0]\n')
    with pytest.raises(SweepError, match=re.escape(f'{path}: grid."controller.K9"')):
        SweepSpec.from_toml(path)
    with pytest.raises(SweepError, match="does not exist"):
        SweepSpec.from_toml(tmp_path / "missing.toml")


def test_example_sweep_loads():
    spec = SweepSpec.from_toml(Path(__file__).parents[1] / "examples" / "sweep_small.toml")
    assert len(spec.runs) == 24


def test_whole_table_values_are_not_shared_between_runs():
    """A dotted key writes into the run's own copy of a swept whole table (and of a choice)."""
    data = spec_dict(
        grid={"delay": [{"type": "constant", "h": 0.01}], "delay.h": [0.05, 0.1, 0.2]},
        random={
            "controller": {
                "dist": "choice",
                "values": [{"type": "outer-loop", "K1": 1.0, "K2": 1.0}],
            },
            "controller.K1": {"dist": "uniform", "low": 1.0, "high": 2.0},
        },
        unit_size=1,
    )
    spec = SweepSpec.from_dict(data)
    assert [run.scenario.delay["h"] for run in spec.runs[::3]] == [0.05, 0.1, 0.2]
    assert all(run.values["delay"] == {"type": "constant", "h": 0.01} for run in spec.runs)
    assert spec.grid["delay"] == ({"type": "constant", "h": 0.01},)
    assert all(run.values["controller"]["K1"] == 1.0 for run in spec.runs)
    assert len({run.scenario.controller["K1"] for run in spec.runs}) == 3
    # Changing the last grid value changes only the units of its runs.
    data["grid"]["delay.h"] = [0.05, 0.1, 0.3]
    changed = SweepSpec.from_dict(data)
    same = [a.hash == b.hash for a, b in zip(spec.units(), changed.units(), strict=True)]
    assert same == [True] * 6 + [False] * 3


def test_a_run_the_controller_cannot_take_is_refused_on_load():
    """PCON needs the delay within its history: checked when the spec loads, not at run time."""
    pcon = {"type": "pcon", "kappa": 1.0, "vartheta": 1.0, "k_b": 1.0, "history": 0.1, "T_c": 0.002}
    data = spec_dict(
        grid={"controller": [pcon], "delay": [{"type": "constant", "h": 0.2}]}, random={}
    )
    del data["draws"], data["seed"], data["random"]
    with pytest.raises(SweepError, match=r"\(run 0\): .*exceeds history = 0.1 s"):
        SweepSpec.from_dict(data)


@pytest.mark.parametrize(
    ("dist", "message"),
    [
        ({"dist": "integers", "low": 0, "high": 2**70}, "needs bounds within 64-bit integers"),
        ({"dist": "uniform", "low": -1e308, "high": 1e308}, "with a finite difference"),
    ],
)
def test_draws_beyond_numpy_ranges_are_refused(dist, message):
    with pytest.raises(SweepError, match=message):
        SweepSpec.from_dict(
            spec_dict(random={"plant.fd1": dist} if "uniform" in dist.values() else {"seed": dist})
        )


def test_label_keys_are_grid_and_choice_controller_keys():
    spec = SweepSpec.from_dict(spec_dict())
    assert spec.label_keys == ("controller.K1", "controller.alpha")


def test_unit_hash_changes_with_the_source_code(monkeypatch):
    """Parts made by other code (an edited engine, same version number) do not count."""
    before = SweepSpec.from_dict(spec_dict()).units()[0]
    payload = before.to_payload()
    monkeypatch.setattr(spec_module, "source_hash", lambda: "0123456789abcdef")
    after = SweepSpec.from_dict(spec_dict()).units()[0]
    assert after.hash != before.hash
    with pytest.raises(SweepError, match="install the same code on every Dask worker"):
        Unit.from_payload(payload)


def test_canonical_json_writes_non_finite_numbers_and_read_only_tables_as_toml_would():
    from types import MappingProxyType

    data = {"error_bound": float("inf"), "b": (float("nan"), -float("inf")), "a": 1}
    text = spec_module.canonical_json({"table": MappingProxyType(data)})
    assert text == '{"table":{"a":1,"b":["nan","-inf"],"error_bound":"inf"}}'
    # plain data takes json's own path, with the same layout
    assert spec_module.canonical_json({"b": [1.5, 2], "a": None}) == '{"a":null,"b":[1.5,2]}'
