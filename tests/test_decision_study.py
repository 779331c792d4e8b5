"""The decision study (``delaytrack reproduce --job decision``): a tiny version runs end to end,
writes its files and resumes; the paper report renders its section from a hand-built result,
every number from that result; bad sizes are refused in one line before anything runs."""

from __future__ import annotations

import dataclasses
import html
import math
import re

import pandas as pd
import pytest

from delaytrack._validation import ArgumentError
from delaytrack.cli import main
from delaytrack.experiments import paper
from delaytrack.experiments.decision import Envelope, decide
from delaytrack.experiments.decision_study import (
    DecisionSize,
    DecisionStudy,
    envelope_table,
    paper_envelopes,
)
from delaytrack.experiments.intervals import wilson_interval
from delaytrack.experiments.tradeoff import TradeoffStudy
from delaytrack.jobs import decision_study as decision_job
from delaytrack.jobs import paper as paper_job
from delaytrack.jobs.decision_study import reproduce
from delaytrack.report import paper as paper_report
from delaytrack.report.decision import refusal_text
from delaytrack.report.decision_study import decision_sentence, display_envelopes
from delaytrack.scenario import load_builtin

#: Two gain points, two robots per trade-off point, three per candidate and condition.
TINY = DecisionSize(points=2, tradeoff_draws=2, decision_draws=3)


def test_the_envelopes_are_the_papers():
    envelopes = paper_envelopes()
    assert list(envelopes) == [
        *(f"S{i}-{k}" for i in range(1, 5) for k in ("exact", "within")),
        "unknown",
    ]
    largest = {"S1": 0.1, "S2": 0.125, "S3": 0.06, "S4": 0.12}
    for name, (case, envelope) in envelopes.items():
        if case == "any":
            assert envelope == Envelope(0.3, "unknown")
        else:
            assert envelope.h_max == pytest.approx(largest[case])
            known = ("exact", 0.0) if name.endswith("exact") else ("within", 0.25)
            assert (envelope.knowledge, envelope.within) == known


def test_a_tiny_study_runs_end_to_end_writes_its_files_and_resumes(tmp_path):
    study, files = reproduce(tmp_path, size=TINY, progress=False)
    folder = tmp_path / "decision"
    for name in ("decision.csv", "candidates.csv", "report.html", "tradeoff/report.html"):
        assert folder / name in files and (folder / name).stat().st_size > 0
    assert study.tradeoff.omegas == pytest.approx((0.25, 4.0))
    assert study.tradeoff.draws == 2
    table = pd.read_csv(folder / "decision.csv", keep_default_na=False)
    assert list(table.envelope) == list(paper_envelopes())
    assert {"winner", "omega_n_rad_per_s", "k1_per_s2", "k2_per_s", "worst_ae_m"} <= set(
        table.columns
    )
    assert {"worst_share_low", "runner_up", "ae_difference_m", "ae_ratio", "reason"} <= set(
        table.columns
    )
    # Three draws cannot reach the Wilson lower bound 0.95: every envelope says so.
    assert (table.winner == "").all()
    assert table.reason.str.startswith("no candidate qualifies at this size: with 3 draws").all()
    candidates = pd.read_csv(folder / "candidates.csv")
    assert set(candidates.envelope) == set(paper_envelopes())
    assert (candidates.runs == 3).all()
    # Per envelope: AROLC and the outer loop once per true delay, PCONf once per told delay.
    unknown = candidates[candidates.envelope == "unknown"]
    assert len(unknown) == 2 * 2 * 3 and set(unknown.delay_s) == {0.0, 0.3}
    report = (folder / "report.html").read_text()
    assert "Which controller for which delay envelope" in report
    assert report.count("no recommendation") == len(paper_envelopes())

    again, _ = reproduce(tmp_path, size=TINY, progress=False)
    assert again.computed == 0 and again.resumed == study.computed + study.resumed
    pd.testing.assert_frame_equal(again.table, study.table)


def _decision(envelope: Envelope, runs: int, arolc_ae: float) -> pd.DataFrame:
    """AROLC (worst-case AE ``arolc_ae``) and the outer loop (twice that) at 2 rad/s, every
    robot on the path."""
    rows = []
    for controller, ae in (("arolc", arolc_ae), ("outer-loop", 2 * arolc_ae)):
        for h in envelope.delays:
            rows.append(
                {
                    "controller": controller,
                    "omega_n": 2.0,
                    "k1": 4.0,
                    "k2": 4.0,
                    "delay": h,
                    "told": math.nan,
                    "runs": runs,
                    "on_path": runs,
                    "ae_median": ae,
                }
            )
    return decide(pd.DataFrame(rows), envelope, ae_unit="m")


def _hand_built(arolc_ae: float) -> DecisionStudy:
    """A decision study of two envelopes built by hand: one with a winner, one refused."""
    exact, unknown = Envelope(0.1, "exact"), Envelope(0.3, "unknown")
    decisions = {
        "S1-exact": _decision(exact, 120, arolc_ae),
        "unknown": _decision(unknown, 20, arolc_ae),
    }
    cases = {"S1-exact": "S1", "unknown": "any"}
    tradeoff = TradeoffStudy(
        table=pd.DataFrame(),
        runs=pd.DataFrame(),
        evaluated=pd.DataFrame(),
        scenario=load_builtin("robot_S1"),
        zeta=1.0,
        omegas=(0.5, 2.0),
        families=("arolc", "outer-loop"),
        left_out={},
        threshold={"x": 1.0, "y": 1.0},
        ae_unit="m",
        tv_unit="N·m",
        random={},
        draws=40,
        seed=1,
        upper=1.0,
        resolution=0.005,
        beta=1.0,
        r=1.1,
        seconds=0.0,
    )
    return DecisionStudy(
        tradeoff=tradeoff,
        decisions=decisions,
        cases=cases,
        table=envelope_table(decisions, cases),
        size=DecisionSize(2, 40, 120),
        seconds=0.0,
    )


@pytest.fixture(scope="module")
def paper_study():
    return paper.run_study(duration=1.0, progress=False, check_dt=False, contact=False)


@pytest.mark.parametrize("arolc_ae", [0.0123, 0.0456])
def test_the_paper_report_renders_the_section_from_the_result(paper_study, tmp_path, arolc_ae):
    decision = _hand_built(arolc_ae)
    paper_report.write_study(paper_study, tmp_path, decision=decision)
    report = (tmp_path / "report.html").read_text()
    assert report.count("Which controller for which delay envelope") == 2  # contents, heading
    low = wilson_interval(120, 120)[0]
    winner = decision.decisions["S1-exact"]
    sentence = decision_sentence("S1", winner)
    assert sentence == (
        "S1, h_max = 0.1 s, delay known exactly: use AROLC at ω_n = 2 rad/s (K1 = 4 I, K2 = 4 I) "
        "(the largest ω_n of the sweep: larger gains were not tried and may be more accurate "
        f"still); its worst-case AE is {1e3 * arolc_ae:.3g} mm and at least {100 * low:.1f} % "
        "of drawn robots stay on the path in every condition (Wilson 95 % lower bound, 120 "
        "draws per condition); the runner-up, "
        "the outer loop (AROLC without Δu) at ω_n = 2 rad/s (K1 = 4 I, K2 = 4 I), has a "
        f"worst-case AE of {2e3 * arolc_ae:.3g} mm: {1e3 * arolc_ae:.3g} mm more than the "
        "winner's (2 times)."
    )
    text = html.unescape(re.sub(r"<[^>]+>", "", report))
    assert sentence in text
    refused = decision_sentence("any", decision.decisions["unknown"])
    assert refused.startswith("Any delay, h_max = 0.3 s, delay unknown")
    assert "no recommendation, no candidate qualifies at this size: with 20 draws" in refused
    assert refused in text
    assert f"{arolc_ae:.4g}" in report  # the table's worst-case AE


def test_the_study_holds_the_facts_and_the_page_words_them():
    """The study's table holds no sentence: ``decision.csv``'s ``reason`` (last column) is the
    report's wording of each decision's refusal; whether the winner sits at the sweep's largest
    ω_n is the decision's, and the sentence follows it."""
    study = _hand_built(0.0123)
    assert "reason" not in study.table
    shown = display_envelopes(study)
    assert list(shown.columns)[-1] == "reason"
    refused = study.decisions["unknown"]
    assert refused.refused.too_few_draws and refused.refused.draws == 20
    assert list(shown.reason) == ["", refusal_text(refused)]
    assert refusal_text(refused).startswith("no candidate qualifies at this size: with 20 draws")
    winner = study.decisions["S1-exact"]
    assert winner.winner.at_largest_omega_n
    assert "(the largest ω_n of the sweep" in decision_sentence("S1", winner)
    inside = dataclasses.replace(
        winner, winner=dataclasses.replace(winner.winner, at_largest_omega_n=False)
    )
    assert "largest ω_n" not in decision_sentence("S1", inside)
    assert decision_sentence("S1", inside) == decision_sentence("S1", winner).replace(
        " (the largest ω_n of the sweep: larger gains were not tried and may be more accurate "
        "still)",
        "",
    )


def test_the_paper_report_has_no_decision_section_without_the_study(paper_study, tmp_path):
    paper_report.write_study(paper_study, tmp_path)
    assert "Which controller for which delay envelope" not in (tmp_path / "report.html").read_text()


@pytest.mark.parametrize("size", ["huge", "Default", 3, None], ids=str)
def test_the_api_refuses_a_bad_size_before_anything_runs(tmp_path, size):
    with pytest.raises(ArgumentError, match="^size must be one of default, full") as error:
        reproduce(tmp_path / "new", size=size, progress=False)
    assert "\n" not in str(error.value)
    assert not (tmp_path / "new").exists()


@pytest.mark.parametrize("fields", [(0, 2, 2), (2, 0, 2), (2, 2, -1), (2.5, 2, 2)])
def test_a_size_of_ones_own_must_be_counts(fields):
    with pytest.raises(ArgumentError, match=r"^size \w+ must be an integer >= 1; got "):
        DecisionSize(*fields)


@pytest.mark.parametrize(
    ("flags", "message"),
    [
        (["--size", "tiny"], "error: argument --size: invalid choice: 'tiny'"),
        (["--duration", "10"], "error: --duration does not apply to --job decision"),
    ],
)
def test_the_job_refuses_bad_sizes_in_one_line(tmp_path, capsys, flags, message):
    out = tmp_path / "results"
    try:
        code = main(["reproduce", "--job", "decision", "--out", str(out), *flags, "--quiet"])
    except SystemExit as stop:  # argparse's refusal
        code = stop.code
    assert code == 2
    error = capsys.readouterr().err
    assert error.startswith(message) and error.count("\n") == 1
    assert not (out / "decision").exists()


def test_the_paper_job_with_decision_runs_it_after_its_checks(tmp_path, monkeypatch, capsys):
    """``reproduce --decision`` hands the paper job the decision study's size (``--size``); the
    paper job checks its arguments and folders first (a ``--duration`` off the controller grid
    runs nothing, not even the decision study), then runs the study into ``<out>/decision/`` and
    renders it (the section is checked above from a hand-built study, a tiny study end to end
    below). ``--decision`` with another job is refused in one line."""
    calls = {}
    real_paper = paper_job.reproduce

    def run_paper(out, **options):
        calls["paper"] = (out, options["decision"])
        raise SystemExit(0)  # the paper job's own run is tested in test_paper.py

    def run_decision(out, **options):
        calls["decision"] = (out, options["size"])
        raise AssertionError("the decision study ran before the paper job's checks")

    monkeypatch.setattr(paper_job, "reproduce", run_paper)
    common = ["reproduce", "--out", str(tmp_path), "--quiet"]
    with pytest.raises(SystemExit):
        main([*common, "--decision", "--size", "full"])
    assert calls == {"paper": (str(tmp_path), "full")}
    monkeypatch.setattr(decision_job, "reproduce", run_decision)
    with pytest.raises(ArgumentError, match="multiple of 'T_c'"):
        real_paper(tmp_path / "out", duration=0.015, decision="default")
    assert "decision" not in calls
    assert main([*common, "--job", "margins", "--decision"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--decision does not apply to --job margins" in err
