"""The decision rule: on hand-built candidate tables it picks the known winner, runner-up and
margin, refuses when the Wilson lower bound cannot reach 0.95; end to end on a small linear
plant, which draws nothing, it says no candidate can qualify; bad flags exit 2."""

from __future__ import annotations

import dataclasses
import html
import math
import re

import pandas as pd
import pytest

from delaytrack._validation import ArgumentError
from delaytrack.cli import main
from delaytrack.experiments.decision import Envelope, Refusal, Shortfall, decide, draws_needed
from delaytrack.experiments.intervals import Z95, wilson_interval
from delaytrack.report.decision import candidates_table, decision_table, refusal_text
from delaytrack.scenario import Scenario
from test_tradeoff import PLANT, ZETA

#: Within ±25 % of 0.1 s: the predictor is told 0.075 s and 0.125 s at a true 0.1 s.
ENVELOPE = Envelope(0.1, "within", 0.25)


def _table(runs: int, pconf_on_path: int, on_path: int | None = None) -> pd.DataFrame:
    """Four candidates over the envelope's conditions; ``runs`` robots each, all on the path
    (``on_path`` when given) except PCONf's ``pconf_on_path``."""
    kept = runs if on_path is None else on_path
    rows = []
    for controller, omega, ae in (
        ("arolc", 1.0, (0.020, 0.020)),
        ("arolc", 2.0, (0.010, 0.012)),  # the winner: worst-case AE 0.012
        ("outer-loop", 2.0, (0.015, 0.015)),  # the runner-up: 0.015
        ("pconf", 2.0, (0.001, 0.002)),  # most accurate, but leaves the path too often
    ):
        told = ENVELOPE.told if controller == "pconf" else (math.nan, math.nan)
        for t, a in zip(told, ae, strict=True):
            rows.append(
                {
                    "controller": controller,
                    "omega_n": omega,
                    "k1": omega**2,
                    "k2": 2 * omega,
                    "delay": 0.1,
                    "told": t,
                    "runs": runs,
                    "on_path": pconf_on_path if controller == "pconf" else kept,
                    "ae_median": a,
                }
            )
    return pd.DataFrame(rows)


def test_the_rule_picks_the_winner_runner_up_and_margin():
    decision = decide(_table(80, 78), ENVELOPE, ae_unit="m")
    assert refusal_text(decision) is None
    assert (decision.winner.controller, decision.winner.omega_n) == ("arolc", 2.0)
    assert decision.winner.worst_ae == 0.012
    assert (decision.runner_up.controller, decision.runner_up.omega_n) == ("outer-loop", 2.0)
    assert decision.ae_difference == pytest.approx(0.003)
    assert decision.ae_ratio == pytest.approx(1.25)
    status = dict(
        zip(
            decision.candidates.controller + decision.candidates.omega_n.astype(str),
            decision.candidates.status,
            strict=True,
        )
    )
    assert status == {
        "arolc2.0": "winner",
        "outer-loop2.0": "runner-up",
        "arolc1.0": "qualifies",
        "pconf2.0": "excluded",
    }
    candidates = candidates_table(decision)
    pconf = candidates[candidates.controller == "pconf"].iloc[0]
    low = wilson_interval(78, 80)[0]
    assert pconf.worst_share_low == low < 0.95
    assert f"Wilson lower bound {low:.3f} < 0.95" in pconf.why and "78 of 80" in pconf.why
    assert len(decision.table) == 8 and decision.table.share_low.notna().all()


def test_the_decision_holds_the_facts_and_the_report_words_them():
    """Why each candidate was not chosen is held as facts (the worst condition, whether the
    draws were too few; the winner at the sweep's largest ω_n); the report words them into the
    ``why`` column and the refusal, with the columns the tables always had."""
    decision = decide(_table(80, 78), ENVELOPE, ae_unit="m")
    assert decision.winner.at_largest_omega_n and decision.runner_up.at_largest_omega_n
    assert "why" not in decision.candidates and "why" not in decision.table
    assert list(decision.shortfalls) == [("pconf", 2.0)]
    low = wilson_interval(78, 80)[0]
    assert decision.shortfalls["pconf", 2.0] == Shortfall(
        "pconf", 2.0, low, 0.1, ENVELOPE.told[0], 78, 80, too_few_draws=False
    )
    candidates = candidates_table(decision)
    assert list(candidates.columns) == [
        *("controller", "omega_n", "k1", "k2", "worst_share_low", "worst_ae"),
        *("qualifies", "status", "why"),
    ]
    keys = candidates.controller + candidates.omega_n.astype(str)
    why = dict(zip(keys, candidates.why, strict=True))
    assert why == {
        "arolc2.0": "",
        "outer-loop2.0": "",
        "arolc1.0": "worst-case AE 0.02 m against the winner's 0.012 m",  # as the table
        "pconf2.0": f"Wilson lower bound {low:.3f} < 0.95 at delay 0.1 s, told 0.075 s "
        "(78 of 80 on the path)",
    }
    table = decision_table(decision)
    assert list(table.columns) == [*decision.table.columns, "why"]
    assert list(table.why) == list((table.controller + table.omega_n.astype(str)).map(why))
    assert decision.refused is None and refusal_text(decision) is None

    t = _table(80, 78)
    t.loc[t.omega_n == 1.0, "ae_median"] = 0.005  # AROLC at 1 rad/s wins, inside the sweep
    inside = decide(t, ENVELOPE)
    assert (inside.winner.omega_n, inside.winner.at_largest_omega_n) == (1.0, False)
    assert inside.runner_up.at_largest_omega_n


def test_a_refusal_holds_its_facts_and_the_report_words_them():
    few = decide(_table(40, 40), ENVELOPE)
    ceiling = 40 / (40 + Z95**2)
    assert few.refused == Refusal(too_few_draws=True, draws=40, ceiling=ceiling)
    assert few.shortfalls["arolc", 1.0].too_few_draws
    assert refusal_text(few) == (
        "no candidate qualifies at this size: with 40 draws per condition the Wilson lower "
        f"bound cannot exceed n/(n + z²) = {ceiling:.3f} < 0.95 even with every robot on the "
        "path; at least 73 draws are needed"
    )
    assert candidates_table(few).why.str.endswith("; 40 draws cannot reach it (at least 73)").all()

    none = decide(_table(80, 70, on_path=76), ENVELOPE)
    closest = none.refused.closest
    assert not none.refused.too_few_draws and none.refused.draws == 80
    # Every candidate but PCONf has 76 of 80 on the path: one of them is the closest.
    assert (closest.controller, closest.omega_n, closest.on_path) == ("arolc", 2.0, 76)
    assert closest == none.shortfalls["arolc", 2.0] and not closest.too_few_draws
    assert refusal_text(none) == (
        "no candidate qualifies: none stays on the path in at least 95 % of the drawn robots "
        "by the Wilson lower bound in every condition (closest: arolc at omega_n = 2 rad/s, "
        f"Wilson lower bound {closest.share_low:.3f} < 0.95 at delay 0.1 s (76 of 80 on "
        "the path))"
    )


def test_a_scenario_that_draws_nothing_is_not_told_to_draw_more():
    """One run per condition, as :func:`run_decision` gives a scenario with nothing to draw:
    the refusal says so, and does not ask for 73 draws that would all be the same run."""
    one = dataclasses.replace(decide(_table(1, 1), ENVELOPE), drawn=False)
    assert refusal_text(one) == (
        "no candidate qualifies: the scenario draws nothing, so each condition is one run, whose "
        f"Wilson lower bound cannot exceed {1 / (1 + Z95**2):.3f} < 0.95 even on the path; more "
        "draws cannot help, only a scenario with something to draw (the payload robot's payload "
        "and friction)"
    )


def test_the_rule_refuses_when_the_lower_bound_cannot_reach_095():
    assert draws_needed() == 73
    assert wilson_interval(73, 73)[0] >= 0.95 > wilson_interval(72, 72)[0]
    decision = decide(_table(40, 40), ENVELOPE)
    assert decision.winner is None and decision.runner_up is None
    assert math.isnan(decision.ae_difference)
    refusal = refusal_text(decision)
    assert refusal.startswith("no candidate qualifies at this size: with 40 draws")
    assert "at least 73 draws are needed" in refusal
    assert not decision.candidates.qualifies.any()


def test_the_rule_refuses_when_none_stays_on_the_path_often_enough():
    decision = decide(_table(80, 70, on_path=76), ENVELOPE)
    assert decision.winner is None
    assert refusal_text(decision).startswith("no candidate qualifies: none stays on the path")


def test_the_envelope_sets_the_conditions():
    assert Envelope.from_text(0.3, "exact").told == (0.3,)
    within = Envelope.from_text(0.2, "±25%")
    assert within == Envelope.from_text(0.2, "25 %") == Envelope.from_text(0.2, "+-25%")
    assert within.delays == (0.2,) and within.told == pytest.approx((0.15, 0.25))
    unknown = Envelope.from_text(0.3, "unknown")
    assert unknown.delays == (0.3, 0.0) and unknown.told == (0.15,)
    for bad in ("sometimes", "0%", "150%"):
        with pytest.raises(ArgumentError, match="must be exact, ±X% .0 < X <= 100. or unknown"):
            Envelope.from_text(0.3, bad)


def _tradeoff_with_a_decision(folder, envelope: str, knowledge: str):
    """``delaytrack tradeoff`` of the light mass at two gain points with a decision for
    ``--envelope envelope --knowledge knowledge``; returns its output folder."""
    scenario = folder / "light_mass.toml"
    Scenario.from_dict(PLANT).to_toml(scenario)
    out = folder / "out"
    args = ["tradeoff", str(scenario), "--omega", "0.7", "1.4", "2", "--upper", "2"]
    args += ["--zeta", str(ZETA), "--envelope", envelope, "--knowledge", knowledge]
    assert main([*args, "--out", str(out), "--quiet"]) == 0
    return out


def test_an_envelope_as_long_as_the_runs_is_refused(tmp_path):
    from types import SimpleNamespace

    from delaytrack.experiments.decision import run_decision

    study = SimpleNamespace(scenario=SimpleNamespace(duration=8.0))
    refused = r"^h_max must be less than the scenario's duration 8 s"
    with pytest.raises(ArgumentError, match=refused):
        run_decision(study, Envelope(8.0, "exact"), tmp_path)


def test_a_scenario_that_draws_nothing_says_no_candidate_can_qualify(tmp_path, capsys):
    """The linear plant draws nothing: one run per condition, and the page does not ask for
    more draws (they would all be the same run)."""
    out = _tradeoff_with_a_decision(tmp_path, "0.1", "±25%")
    printed = capsys.readouterr().out
    assert "no candidate qualifies: the scenario draws nothing, so each condition is one" in printed
    assert "draws are needed" not in printed
    table = pd.read_csv(out / "decision.csv")
    # AROLC and the outer loop at the true delay, PCONf told 0.075 s and 0.125 s; PCON is PCONf
    assert len(table) == 2 * (1 + 1 + 2)
    assert set(table.controller) == {"arolc", "outer-loop", "pconf"}
    assert sorted(table.told_s.dropna().unique()) == pytest.approx([0.075, 0.125])
    assert (table.delay_s == 0.1).all() and (table.status == "excluded").all()
    assert "Decision for a delay envelope" in (out / "report.html").read_text()


def test_an_envelope_beyond_a_predictors_history_leaves_it_out_and_says_why(
    tmp_path, capsys, monkeypatch
):
    """PCONf cannot keep 5 s of commands when its history holds at most 2000 ticks of 2 ms (a
    limit lowered from 1e7 ticks, which only a run of hours reaches): the decision goes on
    without it (it ended in a KeyError)."""
    from delaytrack.controllers import pcon

    monkeypatch.setattr(pcon, "MAX_HISTORY_TICKS", 2000)
    out = _tradeoff_with_a_decision(tmp_path, "5", "exact")
    assert set(pd.read_csv(out / "decision.csv").controller) == {"arolc", "outer-loop"}
    report = html.unescape((out / "report.html").read_text())
    assert "pconf: under the envelope's largest delay, the scenario's nominal model" in report
    assert "'controller.history' must be at most 2e+03 controller periods" in report
    capsys.readouterr()


def test_the_old_refusal_attribute_warns_and_reads_the_reports_words():
    decision = decide(_table(40, 40), ENVELOPE)
    with pytest.warns(DeprecationWarning, match=r"report\.decision\.refusal_text"):
        assert decision.refusal == refusal_text(decision)
    with pytest.warns(DeprecationWarning):
        assert decide(_table(80, 78), ENVELOPE).refusal is None


def test_a_condition_with_no_run_on_the_path_leaves_the_worst_case_ae_undefined():
    """A candidate none of whose robots stayed on the path at one delay has no AE there: its
    worst-case AE is NaN, not the largest of the other conditions', and it ranks last."""
    table = _table(80, 80)
    lost = (table.controller == "arolc") & (table.omega_n == 1.0)
    table.loc[lost.idxmax(), ["on_path", "ae_median"]] = (0, math.nan)
    decision = decide(table, ENVELOPE)
    arolc = decision.candidates[
        (decision.candidates.controller == "arolc") & (decision.candidates.omega_n == 1.0)
    ].iloc[0]
    assert math.isnan(arolc.worst_ae) and arolc.status == "excluded"
    assert decision.candidates.iloc[-1].omega_n == 1.0  # best first: it is last


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda t: t.iloc[:0], "has no rows"),
        (lambda t: t.assign(runs=0), "runs must be whole numbers >= 1"),
        (lambda t: t.assign(runs=math.nan), "runs must be whole numbers >= 1"),
        (lambda t: t.assign(on_path=t.runs + 1), "on_path must be whole numbers from 0 to runs"),
        (lambda t: t.assign(on_path=-1), "on_path must be whole numbers from 0 to runs"),
        (lambda t: t.assign(ae_median=math.nan), "ae_median must be a number >= 0 where"),
        (lambda t: t.assign(k1=range(len(t))), "one k1 and one k2"),
        (lambda t: t.drop(columns="told"), "lacks the columns ['told']"),
    ],
)
def test_a_table_the_rule_cannot_read_is_refused_naming_what_is_wrong(edit, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        decide(edit(_table(80, 80)), ENVELOPE)


@pytest.mark.parametrize("share", [0.0, 1.0, 1.5, math.nan, -0.1])
def test_a_required_share_outside_zero_to_one_is_refused(share):
    with pytest.raises(ValueError, match="required_share must be a share strictly between 0"):
        decide(_table(80, 80), ENVELOPE, required_share=share)


def test_a_chosen_predictor_is_given_with_its_own_gains():
    """PCON and PCONf have κ and k_b, not K1 and K2: the text gives κ = K1/K2 and
    k_b = K2 M̂(q0), the same delay-free nominal loop."""
    from delaytrack.experiments.decision import Choice
    from delaytrack.report.decision import gains_text

    pconf = Choice("pconf", 4.0, 16.0, 8.0, 0.01, 0.96, at_largest_omega_n=False)
    assert gains_text(pconf) == (
        "κ = 2, k_b = 8 M̂(q0), M̂(q0) the nominal mass matrix at the initial pose"
    )
    arolc = Choice("arolc", 4.0, 16.0, 8.0, 0.01, 0.96, at_largest_omega_n=False)
    assert gains_text(arolc) == "K1 = 16 I, K2 = 8 I"


def test_a_winner_that_tracked_without_error_has_no_ratio_to_the_runner_up():
    """Worst-case AE 0 (to the digits kept): the difference is given, no "inf times"."""
    from delaytrack.report.tradeoff import decision_lines

    table = _table(80, 0)
    table.loc[table.controller == "pconf", "ae_median"] = math.nan  # none on the path
    table.loc[(table.controller == "arolc") & (table.omega_n == 2.0), "ae_median"] = 0.0
    decision = decide(table, ENVELOPE, ae_unit="m")
    assert decision.winner.worst_ae == 0.0 and math.isnan(decision.ae_ratio)
    assert decision.ae_difference == pytest.approx(0.015)
    text = "\n".join(decision_lines(decision))
    assert "wins by 15 mm of worst-case AE" in text and "times" not in text
