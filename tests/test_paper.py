"""The paper's robot experiment (``delaytrack.experiments.paper``) and the baseline tuning."""

from __future__ import annotations

import base64
import re

import numpy as np
import pandas as pd
import pytest

from delaytrack.cli import main
from delaytrack.experiments import paper, tuning

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
    "scenario,controller,ae_x_mm,ae_y_mm,pct_ae_x,pct_ae_y,tv,rms_x_mm,rms_y_mm,max_x_mm,max_y_mm"
)


@pytest.mark.slow
def test_short_run_writes_every_promised_file(tmp_path):
    study = paper.run_paper(tmp_path, duration=2.0, progress=False, check_dt=False)
    summary_text = (tmp_path / "summary.csv").read_text().splitlines()
    assert summary_text[0] == COLUMNS
    summary = pd.read_csv(tmp_path / "summary.csv")
    assert list(summary[["scenario", "controller"]].itertuples(index=False, name=None)) == ROWS
    assert (study.status.status == "ok").all()
    assert np.all(np.isfinite(summary.iloc[:, 2:].to_numpy()))
    np.testing.assert_allclose(summary.pct_ae_x, summary.ae_x_mm / 2500 * 100)
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
    for text in ("Claims check", "payload", "seed 2024", "T_c", "Literal path", "PCONf"):
        assert text in report
    assert "Not run (check_dt = False)" in report


@pytest.mark.slow
def test_reproduce_writes_both_folders(tmp_path, capsys):
    args = ["reproduce", "--out", str(tmp_path), "--duration", "1", "--no-dt-check", "--quiet"]
    assert main(args) == 0
    assert "report.html" in capsys.readouterr().out
    for folder in ("paper", "paper-literal"):
        assert (tmp_path / folder / "summary.csv").exists()
        assert (tmp_path / folder / "report.html").exists()
    literal = (tmp_path / "paper-literal" / "report.html").read_text()
    assert "literal path" in literal and "Measured in this run" in literal
    consistent = (tmp_path / "paper" / "report.html").read_text()
    assert "Measured in the sibling run" in consistent


def test_reproduce_refuses_a_duration_off_the_controller_grid(tmp_path, capsys):
    assert main(["reproduce", "--out", str(tmp_path), "--duration", "0.015", "--quiet"]) == 2
    assert "must be a positive integer multiple of 'T_c'" in capsys.readouterr().err


def test_diverged_runs_get_nan_metrics_and_a_flag():
    study = paper.run_study(duration=1.0, progress=False, check_dt=False)
    result = study.results["baseline"]
    # Push one run off the path: the same summary code must flag it.
    broken = result.x.copy()
    broken[1, -1, 0] += 2 * paper.LEFT_PATH_M
    from dataclasses import replace

    summary, status = paper._summary({**study.results, "baseline": replace(result, x=broken)})
    row = (summary.scenario == "S2") & (summary.controller == "PCON")
    assert summary[row].iloc[:, 2:].isna().all(axis=None)
    assert status[row].status.iloc[0] == "diverged (left the path)"
    assert paper.claims(summary)["ae"]["S2"]  # a diverged baseline loses


def test_claims_are_computed_from_the_summary():
    rows = []
    for scenario, controller in ROWS:
        ae = {"AROLC": 10.0, "OuterLoop": 30.0}.get(controller, 20.0)
        if scenario == "S4" and controller == "AROLC":
            ae = 12.0
        rows.append(dict(scenario=scenario, controller=controller, ae_x_mm=ae, ae_y_mm=ae, tv=ae))
    checks = paper.claims(pd.DataFrame(rows))
    assert all(checks["ae"].values()) and all(checks["tv"].values())
    assert checks["growth"]["S3->S4"]


def test_shipped_gains_file_is_complete():
    gains = tuning.load_gains()
    record = tuning.load_tuning_record()
    assert set(gains) == {"PCON", "PCONf"}
    assert record["payload_seed"] != paper.PAYLOAD_SEED
    for kind in gains:
        table = pd.DataFrame(record[kind]["rows"], columns=record[kind]["columns"])
        assert len(table) == np.prod([len(record[f"grid_{g}"]) for g in ("kappa", "k_b", "c")])
        best = table.loc[table.objective.idxmin()]
        assert (best.kappa, best.k_b, best.c) == (
            gains[kind]["kappa"],
            gains[kind]["k_b"],
            gains[kind]["c"],
        )
        assert record[kind]["interior"]
        # Not tuned on any reported condition.
        assert "60 ms" not in record[kind]["condition"]
        assert "120 ms" not in record[kind]["condition"]


TINY = {"kappa": (4.0, 8.0), "k_b": (1.5,), "c": (0.15, 0.25)}


@pytest.mark.slow
def test_tuning_is_deterministic_and_picks_the_smallest_objective(tmp_path):
    first = tuning.tune("PCONf", grid=TINY, duration=2.0)
    second = tuning.tune("PCONf", grid=TINY, duration=2.0)
    pd.testing.assert_frame_equal(first.table, second.table)
    assert first.best == second.best
    assert len(first.table) == 4
    best = first.table.loc[first.table.objective.idxmin()]
    assert (first.best["kappa"], first.best["k_b"], first.best["c"]) == (
        best.kappa,
        best.k_b,
        best.c,
    )
    assert first.best["h_bar"] == 0.13
    assert first.interior == {"kappa": False, "k_b": False, "c": False}
    path = tuning.write_gains({"PCON": first, "PCONf": first}, tmp_path / "g.toml", grid=TINY)
    assert tuning.load_gains(path)["PCONf"] == {k: first.best[k] for k in ("kappa", "k_b", "c")}
    other_seed = tuning.tune("PCONf", grid=TINY, duration=6.0, seed=11)
    assert not np.allclose(other_seed.table.objective, first.table.objective)
