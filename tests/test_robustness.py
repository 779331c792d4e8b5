"""The robustness study (``delaytrack.experiments.robustness``): statistics, sweeps, a small run."""

from __future__ import annotations

import copy
import math

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from delaytrack.experiments import robustness, tuning
from delaytrack.experiments.intervals import median_interval, wilson_interval
from delaytrack.experiments.outcomes import delay_reach, outcome_table
from delaytrack.experiments.verdicts import claim_verdicts
from delaytrack.jobs.robustness import run_robustness
from test_verdicts import draws


def test_wilson_interval_matches_scipy():
    for k, n in ((0, 8), (3, 8), (8, 8), (17, 40)):
        expected = stats.binomtest(k, n).proportion_ci(method="wilson")
        assert wilson_interval(k, n) == pytest.approx((expected.low, expected.high), abs=1e-12)
    assert all(math.isnan(v) for v in wilson_interval(0, 0))


def test_median_interval_brackets_the_median():
    values = np.random.default_rng(1).normal(5.0, 1.0, 200)
    median, low, high = median_interval(values)
    assert median == np.median(values) and low < median < high and high - low < 0.6
    assert median_interval([2.0, 2.0, 2.0]) == (2.0, 2.0, 2.0)
    assert math.isnan(median_interval([])[0])


def test_a_claim_holds_fails_or_is_undecided_by_its_corrected_test():
    n = 20
    holds = claim_verdicts(draws([1.0] * n, [2.0] * n))
    assert set(holds[holds.claim == "AE below PCON"].accuracy_verdict) == {"holds"}
    fails = claim_verdicts(draws([3.0] * n, [2.0] * n))
    assert set(fails[fails.claim == "AE below PCON"].accuracy_verdict) == {"fails"}
    mixed = claim_verdicts(draws([1.0, 3.0] * (n // 2), [2.0] * n))
    assert set(mixed[mixed.claim == "AE below PCON"].accuracy_verdict) == {"undecided"}
    # A diverged baseline: AROLC stays on the path more often, and no accuracy is compared.
    lost = claim_verdicts(draws([1.0] * n, [math.inf] * n))
    row = lost[lost.claim == "AE below PCON"].iloc[0]
    assert row.survival_verdict == "holds"
    assert row.accuracy_verdict == "no decision (in no draw did both stay on the path)"
    # Draws where both diverged are counted, never dropped.
    both = claim_verdicts(draws([math.inf] * 15 + [3.0] * 5, [math.inf] * n))
    row = both[(both.claim == "AE below PCON")].iloc[0]
    assert (row.both_diverged, row.only_b_diverged, row.only_a_diverged) == (15, 5, 0)
    assert row.survival_verdict.startswith("no decision (one side diverged in only 5 draws")
    none = claim_verdicts(draws([math.inf] * n, [math.inf] * n))
    assert set(none.survival_verdict) == {"no decision (both diverged in every draw)"}
    # The effect size: the paired median difference, AROLC minus the baseline.
    assert holds.iloc[0].median_difference == -1.0


def test_the_reach_is_the_longest_delay_below_the_first_diverged_run():
    def cell(controller, delay, diverged, runs=4):
        return dict(
            controller=controller,
            scale=math.nan,
            delay_ms=delay,
            runs=runs,
            diverged=diverged,
            divergence_rate=diverged / runs,
        )

    table = pd.DataFrame(
        [
            cell("A", 60.0, 0),
            cell("A", 20.0, 0),
            cell("A", 100.0, 1),
            cell("A", 150.0, 0),  # clean again, but beyond a diverged run
            cell("A", 200.0, 2),
            cell("B", 20.0, 1),
            cell("B", 60.0, 0),
        ]
    )
    a, b = (row for _, row in delay_reach(table).iterrows())
    assert (a.controller, a.longest_clean_delay_ms, a.half_diverged_from_ms) == ("A", 60.0, 200.0)
    assert (a.smallest_delay_ms, a.largest_delay_ms, a.diverged, a.draws) == (20.0, 200.0, 3, 4)
    assert math.isnan(b.longest_clean_delay_ms) and math.isnan(b.half_diverged_from_ms)


def test_the_study_is_symmetric_and_uses_the_tuned_gains():
    sweeps = {s.name: s for s in robustness.study_specs(robustness.StudySize(1, 1, 1))}
    assert list(sweeps) == [
        "map",
        "knowledge-S1",
        "knowledge-S2",
        "claims-S1",
        "claims-S2",
        "claims-S3",
        "claims-S4",
        "actuators-S1",
        "actuators-S2",
        "actuators-S3",
        "actuators-S4",
    ]
    # The actuators' cases are the claims' cases, every run with the P3-DX's torque limit.
    for case in ("S1", "S2", "S3", "S4"):
        claims, limited = sweeps[f"claims-{case}"], sweeps[f"actuators-{case}"]
        assert limited.labels == claims.labels
        for plain, run in zip(claims.spec.runs, limited.spec.runs, strict=True):
            assert run.scenario.input_limits == robustness.WHEEL_TORQUE_LIMIT
            assert run.scenario.replace(input_limits=plain.scenario.input_limits) == plain.scenario
    gains = tuning.load_gains()
    # The map's PCONf is PCON's law with PCONf's "all" gains, told s h.
    runs = sweeps["map"].spec.runs
    labels = sweeps["map"].labels
    for run, label in zip(runs, labels, strict=True):
        controller = run.scenario.controller
        if label["controller"] == "PCONf":
            assert controller["kappa"] == gains["PCONf"]["all"]["kappa"]
            assert controller.get("delay_scale", 1.0) == label["scale"]
        if label["controller"] == "PCON-wheel":
            assert controller["space"] == "actuator"
    # Claims: every scenario pairs its class's baseline; the same draws for every controller.
    claims = sweeps["claims-S3"]
    names = [label["controller"] for label in claims.labels]
    assert "PCONf" in names and "PCON-wheel" in names
    seeds = {run.values["plant.seed"] for run in claims.spec.runs}
    assert len(seeds) == 1  # one draw: every controller and noise level sees the same robot


CELL = ["delay_ms", "controller", "scale"]


def test_a_run_wound_up_when_its_commands_ran_away_from_what_its_wheels_received():
    """Commanded TV more than WOUND_UP (100) times the TV received, or not finite."""
    received = np.array([1.0, 1.0, 1.0, 2.0])
    tv = np.array([100.0, 100.5, np.inf, 150.0])
    assert robustness.wound_up(tv, received).tolist() == [False, True, True, False]


def test_the_edge_is_where_some_runs_diverge_or_the_next_delay_differs():
    """Per controller over the true delays: a mixed cell, and the cells on either side of a
    change between none and some diverged; never a cell inside a clean or a diverged stretch."""
    delays = 1e3 * np.array(robustness.TRUE_DELAYS)
    # three controllers: A clean up to 120 ms then all diverged; B never; C as below
    a = [0, 0, 0, 0, 4, 4, 4, 4]
    b = [0] * 8
    c = [0, 0, 1, 4, 4, 4, 4, 4]  # a mixed cell at 100 ms
    rows = []
    for i, h in enumerate(delays):
        for name, diverged in (("A", a), ("B", b), ("C", c)):
            rows.append({"delay_ms": h, "controller": name, "runs": 4, "diverged": diverged[i]})
    cells = robustness.edge_cells(pd.DataFrame(rows))
    assert cells == [(delays[3], 0), (delays[4], 0), (delays[1], 2), (delays[2], 2)]


@pytest.mark.slow
def test_a_small_study_runs_resumes_and_writes_its_files(tmp_path):
    size = robustness.StudySize(map=1, knowledge=1, claims=2, map_edge=3)
    first = run_robustness(tmp_path, size=size, progress=False)
    # The map's cells at a divergence edge were run again with 3 draws, the others kept 1; the
    # first draw of a refined cell is the map's run of that cell, bit for bit.
    edges = robustness.edge_cells(outcome_table(first.runs["map"], CELL))
    assert first.refined_cells == len(edges) > 0
    assert set(first.map.runs) == {1, 3}
    assert (first.map.runs == 3).sum() == len(edges)
    for sweep, frame in first.runs.items():
        if sweep.startswith("map-edge-"):
            for (delay_ms, controller, scale), group in frame.groupby(CELL, dropna=False):
                original = first.runs["map"]
                same = original[
                    (original.delay_ms == delay_ms)
                    & (original.controller == controller)
                    & ((original.scale == scale) | (original.scale.isna() & pd.isna(scale)))
                ]
                assert len(group) == 3 and len(same) == 1
                first_draw = group[group.draw == 0]
                assert first_draw.ae_mm.iloc[0] == same.ae_mm.iloc[0] or (
                    np.isnan(first_draw.ae_mm.iloc[0]) and np.isnan(same.ae_mm.iloc[0])
                )
    for name in (
        "runs",
        "map",
        "knowledge",
        "knowledge_table",
        "claims",
        "verdicts",
        "attribution",
    ):
        assert (tmp_path / f"{name}.csv").is_file()
    assert (tmp_path / "figures" / "robustness_map.png").is_file()
    # The claims cases on torque-limited wheels: what was commanded beside what was received,
    # and a run wound up exactly when its commands ran away from what its wheels received.
    limited = pd.read_csv(tmp_path / "actuators.csv")
    assert {"median_tv_received_Nm", "wound_up"} <= set(limited.columns)
    runs = pd.concat(f for name, f in first.runs.items() if name.startswith("actuators-"))
    assert "tv_received_Nm" not in first.runs["claims-S1"]  # unlimited: nothing clipped
    kept = runs[~runs.diverged]
    assert limited.wound_up.sum() == kept.wound_up.sum()
    assert "torque-limited" in (tmp_path / "report.html").read_text()
    report = (tmp_path / "report.html").read_text()
    assert "Findings" in report and "data:image/png;base64" in report
    # AROLC never reads the delay: the map's non-predictors have no scale.
    assert first.map[first.map.controller == "AROLC (paper gains)"].scale.isna().all()
    assert first.computed > 0 and first.resumed == 0
    table = pd.read_csv(tmp_path / "knowledge_table.csv")
    assert len(table) == 6 + 3 * 3  # S1, S2 cases, two wrong constants, three delays x three
    row = table[(table.truth == "60 ms constant") & (table["predictor told"] == "h̄ = 120 ms")]
    cell = first.map[
        (first.map.delay_ms == 60.0) & (first.map.controller == "PCONf") & (first.map.scale == 2.0)
    ]
    assert row.predictor_divergence_rate.iloc[0] == cell.divergence_rate.iloc[0]
    again = run_robustness(tmp_path, size=size, progress=False)
    assert again.computed == 0 and again.resumed == first.computed
    pd.testing.assert_frame_equal(again.map, first.map)
    # Every verdict's numbers come from the runs: recompute one comparison's counts.
    claims = pd.read_csv(tmp_path / "runs.csv", keep_default_na=False, na_values=[""])
    # The map's first-pass runs a refined cell's edge sweep ran again are marked, one each.
    repeated = claims[claims.repeated_in.notna()]
    assert len(repeated) == len(edges) and set(repeated.sweep) == {"map"}
    assert set(repeated.repeated_in) <= {s for s in first.runs if s.startswith("map-edge-")}
    report = (tmp_path / "report.html").read_text()
    distinct = first.run_count - len(edges)
    assert f"Size: {first.run_count} runs of 60 s, {distinct} distinct" in report
    claims = pd.read_csv(tmp_path / "runs.csv")
    s1 = claims[(claims.sweep == "claims-S1") & (claims.noise == "off")]
    a = s1[s1.controller == "AROLC (paper gains)"].sort_values("draw")
    b = s1[s1.controller == "PCON"].sort_values("draw")
    a_diverged, b_diverged = a.diverged.to_numpy(), b.diverged.to_numpy()
    kept = ~a_diverged & ~b_diverged
    row = first.verdicts[
        (first.verdicts.scenario == "S1")
        & (first.verdicts.noise == "off")
        & (first.verdicts.claim == "AE below PCON")
        & (first.verdicts.controller == "AROLC (paper gains)")
    ].iloc[0]
    assert (row.both_stayed, row.only_a_diverged, row.only_b_diverged, row.both_diverged) == (
        kept.sum(),
        (a_diverged & ~b_diverged).sum(),
        (~a_diverged & b_diverged).sum(),
        (a_diverged & b_diverged).sum(),
    )
    assert row.a_lower == (a.ae_mm.to_numpy()[kept] < b.ae_mm.to_numpy()[kept]).sum()
    # The counts the reports quote are the study's, and account for every verdict.
    counts = first.verdict_counts
    every = counts[counts.noise == "all"].set_index("kind")
    assert every.loc["accuracy", "verdicts"] == len(first.verdicts)
    assert every.loc["survival", "verdicts"] == len(first.survival_verdicts)
    parts = counts[["holds", "fails", "undecided", "no_decision"]].sum(axis=1)
    assert (parts == counts.verdicts).all()
    # The tuning envelope stands beside every verdict whose scenario leaves it.
    envelope = first.tuning_envelope
    s4 = first.verdicts[first.verdicts.scenario == "S4"].iloc[0]
    assert s4.outside_tuning and s4.tuning_delay_max_ms == envelope["constant"][1] < 120.0
    assert f"tuned on {envelope['constant'][0]:.3g}–{envelope['constant'][1]:.3g} ms" in report


def test_the_tuning_envelope_comes_from_the_tuning_record():
    record = tuning.load_tuning_record()
    envelope = robustness.tuning_envelope(record)
    constant = [
        h
        for h, kind in zip(record["condition_h_bar"], record["condition_classes"], strict=True)
        if kind == "constant"
    ]
    assert envelope["constant"] == pytest.approx((1e3 * min(constant), 1e3 * max(constant)))
    low, high = envelope["varying"]
    varying = [c for c in tuning.CONDITIONS if c.delay_class == "varying"]
    assert high == pytest.approx(1e3 * max(c.delay.h_max for c in varying), abs=1e-3)
    assert low >= 5.0 and high <= 140.0  # the varying class's drawn range
    ranges = robustness.scenario_delay_ranges(robustness.load_builtin(robustness.BASE_SCENARIO))
    assert ranges["S2"] == pytest.approx((5.0, 125.0), abs=1e-6)
    assert ranges["S3"] == pytest.approx((60.0, 60.0))
    tampered = copy.deepcopy(dict(record))
    tampered["conditions"] = ["h = 1 ms constant"] * len(record["conditions"])
    with pytest.raises(ValueError, match="condition_seed"):
        robustness.tuning_envelope(tampered)


def test_the_study_uses_the_gains_it_is_given():
    # A gains record with another tuned AROLC: the study's tuned AROLC is that one.
    record = copy.deepcopy(dict(tuning.load_tuning_record()))
    record["AROLC"]["all"] |= {"k": 3.0, "zeta": 1.0, "alpha": 5.0}
    sweeps = robustness.study_specs(robustness.StudySize(1, 1, 1), record)
    first = sweeps[0]
    tuned = [
        run.scenario.controller
        for run, label in zip(first.spec.runs, first.labels, strict=True)
        if label["controller"] == "AROLC (tuned)"
    ]
    expected = tuning.arolc_gains(3.0, 1.0, 5.0)  # the given k, ζ, α as AROLC's gains
    assert tuned and all(
        (c["K1"], c["K2"], c["alpha"]) == (expected["K1"], expected["K2"], 5.0) for c in tuned
    )
    shipped = tuning.load_gains()["AROLC"]["all"]  # the study must not have read these
    assert (expected["K1"], expected["K2"]) != (shipped["K1"], shipped["K2"])


def test_the_drawn_columns_are_named_with_their_units_for_the_payload_robot_only():
    from delaytrack.experiments.drawn_robots import DRAWN_COLUMNS, drawn_columns
    from delaytrack.scenario import load_builtin

    assert drawn_columns(load_builtin("robot_S1")) == DRAWN_COLUMNS
    # another plant (a user's may have a "seed" of its own): not the payload's placement
    assert drawn_columns(load_builtin("two_link_S1")) == {}
