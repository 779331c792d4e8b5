"""The paper's robot experiment (``delaytrack.experiments.paper``) and the baseline tuning."""

from __future__ import annotations

import base64
import contextlib
import importlib.util
import itertools
import math
import re
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from delaytrack import razumikhin_bound
from delaytrack.cli import main
from delaytrack.experiments import paper, paper_findings, tuning
from delaytrack.experiments.contact import contact_findings
from delaytrack.jobs.paper import run_paper
from delaytrack.report import paper as paper_report
from delaytrack.report.contact import contact_paragraphs
from delaytrack.scenario import load_builtin

ROWS = [
    ("S1", "AROLC"),
    ("S1", "PCON"),
    ("S1", "OuterLoop"),
    ("S2", "AROLC"),
    ("S2", "PCON"),
    ("S2", "OuterLoop"),
    ("S3", "AROLC"),
    ("S3", "PCONf"),
    ("S3", "OuterLoop"),
    ("S4", "AROLC"),
    ("S4", "PCONf"),
    ("S4", "OuterLoop"),
]
FIGURES = ("path_S1", "error_S1_S2", "error_S3_S4", "c_hat", "delay")
COLUMNS = (
    "scenario,controller,ae_x_mm,ae_y_mm,pct_ae_x,pct_ae_y,tv_Nm,rms_x_mm,rms_y_mm,max_x_mm,"
    "max_y_mm,status,t_stop_s"
)


@pytest.mark.slow
def test_short_run_writes_every_promised_file(tmp_path):
    study = run_paper(tmp_path, duration=2.0, progress=False, check_dt=False)
    summary_text = (tmp_path / "summary.csv").read_text().splitlines()
    assert summary_text[0] == COLUMNS
    summary = pd.read_csv(tmp_path / "summary.csv")
    assert list(summary[["scenario", "controller"]].itertuples(index=False, name=None)) == ROWS
    assert (study.status.status == "ok").all()
    assert (summary.status == "ok").all() and (summary.t_stop_s == 2.0).all()
    assert np.all(np.isfinite(summary.iloc[:, 2:-2].to_numpy()))
    np.testing.assert_allclose(summary.pct_ae_x, summary.ae_x_mm / 2500 * 100)
    tuned_text = (tmp_path / "summary_tuned_arolc.csv").read_text().splitlines()
    assert tuned_text[0] == COLUMNS
    tuned = pd.read_csv(tmp_path / "summary_tuned_arolc.csv")
    assert list(tuned[["scenario", "controller"]].itertuples(index=False, name=None)) == [
        (case, "AROLC-tuned") for case in ("S1", "S2", "S3", "S4")
    ]
    assert np.all(np.isfinite(tuned.iloc[:, 2:-2].to_numpy()))
    for name in FIGURES:
        for ext in ("png", "svg"):
            assert (tmp_path / "figures" / f"{name}.{ext}").stat().st_size > 1000

    tables = (tmp_path / "tables.md").read_text()
    for values in paper.PAPER_TABLE.values():
        for value in values:
            assert f"{value:.2f}" in tables
    assert "Table I" in tables and "Table II" in tables and "Table III" in tables

    report = (tmp_path / "report.html").read_text()
    images = re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', report)
    assert len(images) == len(FIGURES)
    assert base64.b64decode(images[0])[:8] == b"\x89PNG\r\n\x1a\n"
    assert "<script" not in report and 'src="http' not in report and "<link" not in report
    for text in (
        "Claims check",
        "payload",
        "seed 2024",
        "T_c",
        "Literal path",
        "PCONf",
        "AROLC tuned by the same procedure",
        "The tuned AROLC is certified for",
        "Which conclusion holds for which AROLC",
    ):
        assert text in report
    assert "Not run (check_dt = False)" in report

    # The same runs on the robot with real wheels (MuJoCo is installed for the tests).
    contact = pd.read_csv(tmp_path / "summary_contact.csv")
    assert list(contact.contact_time_constant_s.unique()) == list(paper.CONTACT_TIME_CONSTANTS)
    runs = ROWS + [(case, "AROLC-tuned") for case in ("S1", "S2", "S3", "S4")]
    for _, rows in contact.groupby("contact_time_constant_s"):
        pairs = list(rows[["scenario", "controller"]].itertuples(index=False, name=None))
        assert sorted(pairs) == sorted(runs)
    assert np.all(np.isfinite(contact.iloc[:, 2:].to_numpy()))
    assert (contact.slip_sideways_rms_mm_s > 0).all() and (contact.slip_max_mm_s < 400).all()
    merged = contact.merge(summary, on=["scenario", "controller"], suffixes=("", "_analytic"))
    np.testing.assert_array_equal(merged.ae_x_mm, merged.ae_x_mm_analytic)
    assert "With contact physics" in report
    assert contact_paragraphs(study.findings.contact)[0] in report


@pytest.mark.slow
def test_reproduce_writes_both_folders(reproduced):
    # `delaytrack reproduce --duration 1`, run once for this module and test_report_rendering.py
    # (tests/conftest.py), with the robustness study at a tiny size (its own tests check it);
    # its verdicts reach the report.
    tmp_path, code, printed = reproduced
    assert code == 0
    assert "report.html" in printed
    verdicts = pd.read_csv(tmp_path / "robustness" / "verdicts.csv")
    assert len(verdicts) == 2 * (4 * 2 * 2 + 2)  # noise x (scenarios x AROLCs x metrics + growth)
    for folder in ("paper", "paper-literal"):
        assert (tmp_path / folder / "summary.csv").exists()
        assert (tmp_path / folder / "report.html").exists()
    literal = (tmp_path / "paper-literal" / "report.html").read_text()
    assert "literal path" in literal and "Measured in this run" in literal
    consistent = (tmp_path / "paper" / "report.html").read_text()
    assert "Measured in the sibling run" in consistent
    assert "The claims over distributions (robustness study)" in consistent
    assert "../robustness/report.html" in consistent


def test_the_printed_summary_says_which_runs_have_no_metrics_and_why_not_nan():
    metrics = dict.fromkeys(paper.SUMMARY_COLUMNS[2:], 1.25)
    summary = pd.DataFrame(
        [
            {"scenario": "S1", "controller": "AROLC", **metrics},
            {"scenario": "S2", "controller": "PCON", **dict.fromkeys(metrics, math.nan)},
        ]
    )
    status = pd.DataFrame(
        {
            "scenario": ["S1", "S2"],
            "controller": ["AROLC", "PCON"],
            "status": ["ok", "left the path"],
            "t_stop": [60.0, 12.5],
        }
    )
    text = paper_report.summary_text(summary, status[status.status != "ok"], "consistent")
    assert "NaN" not in text and "nan" not in text
    lines = text.splitlines()
    from delaytrack.experiments.paper_setup import DIAMETER_MM  # the paper's circle

    assert lines[0].startswith(f"consistent path: AE in mm, %AE of the {DIAMETER_MM:g} mm diameter")
    assert lines[1].split() == [*paper.SUMMARY_COLUMNS[:6], "tv_Nm"]
    assert lines[3].split() == ["S2", "PCON", "—", "—", "—", "—", "—"]
    assert lines[4] == (
        "—: no metrics, the run did not finish: S2 PCON stopped as 'left the path' at t = 12.5 s"
    )
    assert len(lines) == 5
    assert len(paper_report.summary_text(summary.iloc[:1], status.iloc[:0], "x").splitlines()) == 3
    # A run that is not in the table (the tuned AROLC's, in its own file) is named apart.
    tuned = pd.DataFrame(
        [{"scenario": "S2", "controller": "AROLC-tuned", "status": "left the path", "t_stop": 17.0}]
    )
    both = pd.concat([status[status.status != "ok"], tuned], ignore_index=True)
    lines = paper_report.summary_text(summary, both, "consistent").splitlines()
    assert "AROLC-tuned" not in lines[4]
    assert lines[5] == (
        "in summary_tuned_arolc.csv, did not finish: S2 AROLC-tuned stopped as 'left the path' "
        "at t = 17 s"
    )
    written = paper_report.with_status(summary, status)
    assert list(written.columns) == [*paper.SUMMARY_COLUMNS, "status", "t_stop_s"]
    assert written.status.tolist() == ["ok", "left the path"]
    assert written.t_stop_s.tolist() == [60.0, 12.5]


def test_reproduce_refuses_a_duration_off_the_controller_grid(tmp_path, capsys):
    assert main(["reproduce", "--out", str(tmp_path), "--duration", "0.015", "--quiet"]) == 2
    assert "must be a positive integer multiple of 'T_c'" in capsys.readouterr().err


@pytest.mark.parametrize("duration", ["600.01", "1e6"])
def test_reproduce_refuses_a_duration_beyond_ten_papers_before_running(tmp_path, capsys, duration):
    """Not a traceback from the engine (1e6 s), nor a run that outgrows the memory (1e5 s)."""
    assert main(["reproduce", "--out", str(tmp_path), "--duration", duration, "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --duration must be at most 600 s") and "Traceback" not in err
    assert not any(tmp_path.iterdir())


def test_the_paper_job_and_the_shipped_robot_scenario_share_the_left_the_path_rule():
    """One rule: the paper job's bound is that of ``robot_S1``, which ``delaytrack simulate``
    and the studies built on it use."""
    assert tuple(load_builtin("robot_S1").error_bound) == paper.ERROR_BOUND


def test_a_run_that_leaves_the_path_stops_there_with_nan_metrics_and_a_flag(monkeypatch):
    """The engine's rule: with x and y bounded by 20 mm, the runs whose error passes it (the
    paper-gain AROLC and the outer loop, within the first second) stop at that controller tick,
    as ``left the path``, with NaN metrics; the others finish."""
    bound = 0.02
    monkeypatch.setattr(paper, "ERROR_BOUND", (bound, bound, math.inf, math.inf, math.inf))
    study = paper.run_study(duration=1.0, progress=False, check_dt=False, contact=False)
    assert study.contact is None
    stopped = study.status[study.status.status != "ok"]
    assert set(stopped.controller) == {"AROLC", "OuterLoop"}
    assert set(stopped.status) == {"left the path"}
    pd.testing.assert_frame_equal(study.findings.stopped, stopped)
    both = pd.concat([study.summary, study.tuned_summary], ignore_index=True)
    for r in study.status.itertuples():
        metrics = both[(both.scenario == r.scenario) & (both.controller == r.controller)]
        run = study.run(r.scenario, r.controller)
        error = np.abs(run.e1[0, :, :2])
        if r.status == "ok":
            assert r.t_stop == 1.0 and np.all(error <= bound)
            assert metrics.iloc[:, 2:].notna().all(axis=None)
            continue
        tick = int(np.flatnonzero(run.t == r.t_stop)[0])
        assert np.any(error[tick] > bound) and np.all(error[:tick] <= bound)
        assert metrics.iloc[:, 2:].isna().all(axis=None)


def test_contact_findings_are_computed_from_the_table():
    table = pd.DataFrame(
        {
            "contact_time_constant_s": [0.02, 0.02, 0.02, 0.02],
            "scenario": ["S1", "S1", "S2", "S2"],
            "controller": ["AROLC", "PCON", "AROLC", "PCON"],
            "ae_x_mm": [10.0, 5.0, 10.0, 5.0],
            "ae_x_contact_mm": [11.0, 40.0, 30.0, np.nan],
            "ae_y_mm": [10.0, 5.0, 10.0, 5.0],
            "ae_y_contact_mm": [13.0, 5.0, 30.0, np.nan],
            "tv_Nm": [1.0, 2.0, 1.0, 2.0],
            "tv_contact_Nm": [1.5, 2.0, 1.0, np.nan],
            "slip_sideways_rms_mm_s": [0.5, 0.25, 0.75, np.nan],
            "slip_rolling_rms_mm_s": [2.0, 3.0, 4.0, np.nan],
            "slip_max_mm_s": [9.0, 8.0, 12.5, np.nan],
        }
    )
    table["change_ae_pct"] = 100 * (
        (table.ae_x_contact_mm + table.ae_y_contact_mm) / (table.ae_x_mm + table.ae_y_mm) - 1
    )
    table["change_tv_pct"] = 100 * (table.tv_contact_Nm / table.tv_Nm - 1)
    stiff = table.assign(contact_time_constant_s=0.005, ae_x_contact_mm=table.ae_x_mm)
    stiff["change_ae_pct"] = 100 * (
        (stiff.ae_x_contact_mm + stiff.ae_y_contact_mm) / (stiff.ae_x_mm + stiff.ae_y_mm) - 1
    )
    text = " ".join(contact_paragraphs(contact_findings(pd.concat([table, stiff]))))
    assert "In the 3 runs" in text and "+20 % to +350 %" in text and "(median +200 %)" in text
    assert "0 % to +50 %" in text and "0.25–0.75 mm/s" in text and "at most 12.5 mm/s" in text
    assert (
        "in 1 of 2 scenarios (S1: PCON < AROLC on the analytic robot, AROLC < PCON with "
        "contacts; S2: AROLC on both)" in text
    )
    assert "Left the path with contacts only: S2 PCON." in text
    assert "The largest change is PCON's in S1: AE-x 5 → 40 mm" in text
    assert "time constant of 5 ms instead of 20 ms" in text and "0 % to +100 %" in text
    # a run on the path on neither robot is said to be, not "on one of the robots"
    table.loc[3, ["ae_x_mm", "ae_y_mm"]] = np.nan
    findings = contact_findings(table)
    assert findings.lost == {"both": (("S2", "PCON"),)}
    # a small decrease is not written "+0 %"
    from delaytrack.report.contact import _percent

    assert [_percent(v) for v in (-0.316, 0.04, 9.94, 114.6, -12.4)] == [
        "-0.3 %",
        "0 %",
        "+9.9 %",
        "+115 %",
        "-12 %",
    ]


def test_claims_are_computed_from_the_summary():
    rows = []
    for scenario, controller in ROWS:
        ae = {"AROLC": 10.0, "OuterLoop": 30.0}.get(controller, 20.0)
        if scenario == "S4" and controller == "AROLC":
            ae = 12.0
        rows.append(
            dict(scenario=scenario, controller=controller, ae_x_mm=ae, ae_y_mm=ae, tv_Nm=ae)
        )
    checks = paper.claims(pd.DataFrame(rows))
    assert all(checks["ae"].values()) and all(checks["tv"].values())
    assert checks["growth"]["S3->S4"]
    # A run that left the path (NaN metrics) has no accuracy to compare: a claim comparing it
    # is not decided (None), whichever side it was; staying on the path is reported apart.
    rows[4].update(ae_x_mm=np.nan, ae_y_mm=np.nan, tv_Nm=np.nan)  # S2 PCON
    rows[9].update(ae_x_mm=np.nan, ae_y_mm=np.nan, tv_Nm=np.nan)  # S4 AROLC
    checks = paper.claims(pd.DataFrame(rows))
    assert checks["ae"] == {"S1": True, "S2": None, "S3": True, "S4": None}
    assert checks["tv"] == checks["ae"] and checks["growth"]["S3->S4"] is None
    rows[9].update(ae_x_mm=11.0, ae_y_mm=9.0, tv_Nm=30.0)  # S4 AROLC back, above in TV
    checks = paper.claims(pd.DataFrame(rows))
    assert checks["ae"]["S4"] is True and checks["tv"]["S4"] is False
    assert checks["growth"]["S3->S4"] is False  # AE-y fell from 10 to 9


def test_a_claim_comparing_a_run_off_the_path_is_not_decided_and_says_why():
    """Both runs off the path made the AE claim FAIL; one is said to have left the path, the
    other to have stayed, and what the claim compares, with no NaN printed."""
    from types import SimpleNamespace

    from delaytrack.report.paper import _claims_text

    rows = [
        dict(scenario=scenario, controller=controller, ae_x_mm=10.0, ae_y_mm=10.0, tv_Nm=5.0)
        for scenario, controller in ROWS
    ]
    rows[3].update(ae_x_mm=np.nan, ae_y_mm=np.nan, tv_Nm=np.nan)  # S2 AROLC
    summary = pd.DataFrame(rows)
    study = SimpleNamespace(summary=summary, findings=SimpleNamespace(claims=paper.claims(summary)))
    lines = _claims_text(study, None)
    ae = next(line for line in lines if line.startswith("AE, S2"))
    tv = next(line for line in lines if line.startswith("TV, S2"))
    assert "AROLC left the path (x / y) vs PCON 10.00 / 10.00 mm" in ae
    assert "is not decided (AROLC left the path, PCON stayed on it: accuracy is compared" in ae
    assert "TV is compared between runs on the path" in tv
    assert not any("NaN" in line for line in lines)


def test_shipped_gains_file_is_complete():
    gains = tuning.load_gains()
    record = tuning.load_tuning_record()
    assert set(gains) == set(tuning.KINDS)
    # The same drawn conditions for every controller; none is a reported condition.
    conditions = tuning.draw_conditions(record["condition_seed"])
    assert record["conditions"] == [c.text for c in conditions]
    assert record["condition_classes"] == ["varying"] * 3 + ["constant"] * 3
    for c in conditions:
        assert c.seed != paper.PAYLOAD_SEED
    for kind in tuning.KINDS:
        assert set(gains[kind]) == set(tuning.GAIN_SETS)
        for gain_set in tuning.GAIN_SETS:
            table = tuning.grid_table(kind, gain_set)
            assert len(table) >= 125  # the common budget, plus any edge extension
            best = table.loc[table.objective.idxmin()]
            chosen = gains[kind][gain_set]
            assert all(best[name] == chosen[name] for name in tuning.GAIN_NAMES[kind])
            assert chosen["objective"] == best.objective
            if kind == "AROLC":
                g = tuning.arolc_gains(chosen["k"], chosen["zeta"], chosen["alpha"])
                bound = razumikhin_bound(g["K1"], g["K2"], 1.0, beta=1.0, r=1.1, n=5).h_m
                assert chosen["h_m"] == pytest.approx(bound)
                assert (chosen["K1"], chosen["K2"]) == (g["K1"], g["K2"])


def test_conditions_are_drawn_from_the_documented_distribution():
    conditions = tuning.draw_conditions(seed=3, per_class=200)
    varying = [c for c in conditions if c.delay_class == "varying"]
    constant = [c for c in conditions if c.delay_class == "constant"]
    assert len(varying) == len(constant) == 200
    a = np.array([c.delay.offset for c in varying])
    b = np.array([c.delay.amplitude for c in varying])
    assert 0.005 <= a.min() and a.max() <= 0.03 and 0.04 <= b.min() and b.max() <= 0.11
    np.testing.assert_allclose([c.h_bar for c in varying], a + 2 * b / np.pi)
    h = np.array([c.h_bar for c in constant])
    assert 0.02 <= h.min() and h.max() <= 0.14 and h.std() > 0.02
    assert tuning.draw_conditions(seed=3, per_class=200) == conditions
    assert tuning.draw_conditions(seed=4, per_class=200) != conditions


TINY = {"kappa": (4.0, 8.0), "k_b": (1.5,), "c": (0.15, 0.25)}


@pytest.mark.slow
def test_tuning_is_deterministic_and_minimises_the_worst_condition(tmp_path):
    first = tuning.tune("PCONf", grid=TINY, duration=2.0, extensions=0)
    second = tuning.tune("PCONf", grid=TINY, duration=2.0, extensions=0)
    pd.testing.assert_frame_equal(first.table, second.table)
    assert first.best == second.best
    assert len(first.table) == 4
    ae = first.table[[f"ae_mm_{i + 1}" for i in range(6)]]
    # Each set's objective is the worst of its conditions' mean AE, and the winner minimises it.
    for gain_set, columns in (
        ("all", ae),
        ("varying", ae.iloc[:, :3]),
        ("constant", ae.iloc[:, 3:]),
    ):
        worst = columns.max(axis=1)
        assert first.best[gain_set]["objective"] == worst.min()
        best = first.table.loc[worst.idxmin()]
        assert first.best[gain_set]["kappa"] == best.kappa and first.best[gain_set]["c"] == best.c
    assert not np.allclose(ae.max(axis=1), ae.mean(axis=1))
    assert first.interior["all"] == {"kappa": False, "k_b": False, "c": False}
    arolc = tuning.tune(
        "AROLC",
        grid={"k": (1.0, 2.0), "zeta": (0.7,), "alpha": (2.0,)},
        duration=2.0,
        extensions=0,
    )
    assert len(arolc.conditions) == 6 and len(arolc.table) == 2
    assert arolc.table.h_m.iloc[0] > arolc.table.h_m.iloc[1]  # stiffer: smaller bound
    path = tuning.write_gains({"PCONf": first, "AROLC": arolc}, tmp_path / "g.toml")
    loaded = tuning.load_gains(path)
    assert loaded["PCONf"]["all"] == first.best["all"]
    assert loaded["AROLC"]["varying"]["k"] == arolc.best["varying"]["k"]
    pd.testing.assert_series_equal(
        tuning.grid_table("PCONf", "all", path).objective, ae.max(axis=1), check_names=False
    )


@pytest.mark.slow
def test_an_optimum_on_the_grid_edge_extends_the_grid():
    # One value per gain is an edge for every gain: each round extends all three until the
    # rounds run out; the choice of every set lies in the final grid.
    grid = {"kappa": (8.0,), "k_b": (1.5,), "c": (0.2,)}
    result = tuning.tune("PCON", grid=grid, duration=1.0, extensions=1)
    assert sorted(set(result.table.kappa)) == [8.0 / 1.5, 8.0, 12.0]
    assert len(result.table) == 27


def test_worst_case_objective_excludes_any_divergence(monkeypatch):
    """With fake runs: a point that wins on average but diverges once is excluded, and the
    winner minimises the max over conditions (not the mean)."""
    values = {  # grid point -> mean AE per condition (NaN: diverged)
        (1.0, 1.0): (1.0, 9.0, 1.0, 2.0, 2.0, 2.0),  # worst 9 (varying), 2 (constant)
        (1.0, 2.0): (5.0, 5.0, 5.0, 5.0, 5.0, 5.0),  # worst 5  <- winner of "all", "varying"
        (2.0, 1.0): (0.5, np.nan, 0.5, 0.5, 0.5, 0.5),  # best where it runs, diverges once
        (2.0, 2.0): (6.0, 6.0, 6.0, 6.0, 6.0, 6.0),
    }
    calls = itertools.count()

    class Fake:
        def __init__(self, j, n):
            rows = [values[p][j] for p in values]
            self.ae = np.array([[v, v, 0, 0, 0] for v in rows])
            self.status_names = ["diverged" if np.isnan(v) else "ok" for v in rows]
            self.n = n

    def fake_simulate(plant, controllers, delay, x0, **kwargs):
        return Fake(next(calls) % 6, len(controllers))

    monkeypatch.setattr(tuning, "simulate", fake_simulate)
    monkeypatch.setattr(tuning, "mean_absolute_error", lambda r: r.ae / 1e3)
    monkeypatch.setattr(tuning, "total_variation", lambda r: np.zeros(r.n))
    monkeypatch.setattr(tuning, "make_controller", lambda kind, gains, **kw: None)
    grid = {"k": (1.0, 2.0), "zeta": (0.7,), "alpha": (1.0, 2.0)}
    result = tuning.tune("AROLC", grid=grid, duration=1.0, extensions=0)
    assert (result.best["all"]["k"], result.best["all"]["alpha"]) == (1.0, 2.0)
    assert result.best["all"]["objective"] == 5.0
    assert result.best["varying"]["objective"] == 5.0
    # Constant class: (2, 1) diverged only in a varying condition, so it wins there.
    assert (result.best["constant"]["k"], result.best["constant"]["alpha"]) == (2.0, 1.0)
    assert result.table.status.iloc[2].startswith("diverged (condition 2)")


def test_certification_and_dwell_text_are_computed_from_the_profiles():
    largest = {case: paper_findings._delay_range(case, 60.0)[1] for case in paper.SCENARIOS}

    def text(h_m: float, who: str) -> str:
        certified = paper_findings.certified_scenarios(h_m, largest)
        return paper_report._certified_text(largest, certified, who)

    assert text(0.11, "AROLC") == (
        "Largest delays over the run: S1 100 ms, S2 125 ms, S3 60 ms, S4 120 ms. AROLC is "
        "certified for S1, S3 and NOT certified for S2, S4."
    )
    assert text(0.05, "X").endswith("X is certified for none of S1, S2, S3, S4.")
    assert text(0.2, "Y").endswith("Y is certified for S1, S2, S3, S4.")
    # S2 = 5 + 120 |sin 0.1 t| ms is above 112.5 ms where |sin 0.1 t| > 0.8958: around t = 5π k.
    dwells = paper_findings._dwells("S2", 60.0, 0.1125)
    assert len(dwells) == 2
    half = (math.pi / 2 - math.asin(0.1075 / 0.12)) / 0.1
    for (start, end), centre in zip(dwells, (5 * math.pi, 15 * math.pi), strict=True):
        assert start == pytest.approx(centre - half, abs=2e-3)
        assert end == pytest.approx(centre + half, abs=2e-3)


def test_the_report_prose_follows_the_gains(monkeypatch):
    monkeypatch.setitem(paper.AROLC_GAINS, "alpha", 3.5)
    monkeypatch.setitem(paper.AROLC_GAINS, "K1", 4.0)
    study = paper.run_study(duration=1.0, progress=False, check_dt=False, contact=False)
    settings = paper_report._settings(study)
    assert settings["AROLC"].startswith("K1 = 4 I, K2 = 1 I, Q = 1 I, α = 3.5, ε = 0.1")
    text = " ".join(paper_report._explanation(study))
    assert "K1 = 4 I" in text and "natural frequency 2 rad/s and damping 0.25" in text


@pytest.mark.parametrize(
    ("value", "label"),
    [(0.01, "10⁻²"), (1.0, "10⁰"), (10.0, "10¹"), (1e4, "10⁴"), (0.02, ""), (50.0, ""), (0.0, "")],
)
def test_the_error_figures_label_each_decade_as_text(value, label):
    assert paper_report._decade(value, None) == label


def test_without_contact_runs_whether_mujoco_is_installed_is_found_without_importing_it():
    code = (
        "import sys\n"
        "from delaytrack.experiments import paper\n"
        "print(paper._mujoco_installed(False), 'mujoco' in sys.modules)\n"
    )
    found = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    installed = importlib.util.find_spec("mujoco") is not None
    assert found.stdout.split() == [str(installed), "False"]


def test_a_mujoco_that_does_not_import_means_no_contact_runs_by_default(tmp_path, monkeypatch):
    (tmp_path / "mujoco").mkdir()
    (tmp_path / "mujoco" / "__init__.py").write_text("raise ImportError('a broken install')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "mujoco", raising=False)
    assert paper._mujoco_installed(None) is False  # found, but it does not import
    assert paper._mujoco_installed(False) is True  # found: the note says "skipped on request"
    assert isinstance(paper.contact_ahead(60.0), contextlib.nullcontext)
