"""The decision rule: on hand-built candidate tables it picks the known winner, runner-up and
margin, refuses when the Wilson lower bound cannot reach 0.95; end to end on a small linear
plant with few draws it says no candidate qualifies at this size; bad flags exit 2."""

from __future__ import annotations

import math

import pandas as pd
import pytest

from delaytrack._validation import ArgumentError
from delaytrack.cli import main
from delaytrack.experiments.decision import Envelope, decide, draws_needed
from delaytrack.experiments.intervals import wilson_interval
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
    assert decision.refusal is None
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
    pconf = decision.candidates[decision.candidates.controller == "pconf"].iloc[0]
    low = wilson_interval(78, 80)[0]
    assert pconf.worst_share_low == low < 0.95
    assert f"Wilson lower bound {low:.3f} < 0.95" in pconf.why and "78 of 80" in pconf.why
    assert len(decision.table) == 8 and decision.table.share_low.notna().all()


def test_the_rule_refuses_when_the_lower_bound_cannot_reach_095():
    assert draws_needed() == 73
    assert wilson_interval(73, 73)[0] >= 0.95 > wilson_interval(72, 72)[0]
    decision = decide(_table(40, 40), ENVELOPE)
    assert decision.winner is None and decision.runner_up is None
    assert math.isnan(decision.ae_difference)
    assert decision.refusal.startswith("no candidate qualifies at this size: with 40 draws")
    assert "at least 73 draws are needed" in decision.refusal
    assert not decision.candidates.qualifies.any()


def test_the_rule_refuses_when_none_stays_on_the_path_often_enough():
    decision = decide(_table(80, 70, on_path=76), ENVELOPE)
    assert decision.winner is None
    assert decision.refusal.startswith("no candidate qualifies: none stays on the path")


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


def test_a_small_run_says_no_candidate_qualifies_at_this_size(tmp_path, capsys):
    scenario = tmp_path / "light_mass.toml"
    Scenario.from_dict(PLANT).to_toml(scenario)
    out = tmp_path / "out"
    args = ["tradeoff", str(scenario), "--omega", "0.7", "1.4", "2", "--upper", "2"]
    args += ["--zeta", str(ZETA), "--envelope", "0.1", "--knowledge", "±25%"]
    assert main([*args, "--out", str(out), "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "no candidate qualifies at this size: with 1 draws per condition" in printed
    table = pd.read_csv(out / "decision.csv")
    # AROLC and the outer loop at the true delay, PCONf told 0.075 s and 0.125 s; PCON is PCONf
    assert len(table) == 2 * (1 + 1 + 2)
    assert set(table.controller) == {"arolc", "outer-loop", "pconf"}
    assert sorted(table.told_s.dropna().unique()) == pytest.approx([0.075, 0.125])
    assert (table.delay_s == 0.1).all() and (table.status == "excluded").all()
    assert "Decision for a delay envelope" in (out / "report.html").read_text()
