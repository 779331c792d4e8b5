"""The dt-halving check: each run's largest relative change, the verdict the study holds
against the tolerance, and its report section, which states that verdict."""

from __future__ import annotations

import math

import pandas as pd
import pytest

from delaytrack.experiments.convergence import (
    DT_TOLERANCE,
    dt_check_table,
    dt_check_verdict,
)
from delaytrack.report.dt_check import dt_check_line, write_dt_check
from delaytrack.report.html import HtmlReport

COARSE = pd.DataFrame(
    {"scenario": ["S1", "S3"], "controller": ["AROLC", "PCONf"], "ae": [1.0, 2.0], "tv": [4.0, 5.0]}
)


def _fine(ae_s3: float) -> pd.DataFrame:
    return COARSE.assign(ae=[1.001, ae_s3], tv=[4.0, 5.0])


def test_the_verdict_is_the_largest_change_against_the_tolerance():
    within = dt_check_verdict(dt_check_table(COARSE, _fine(2.0), ["ae", "tv"]))
    assert within is not None and within.within_tolerance and within.above.empty
    assert within.largest == pytest.approx(1e-3, rel=1e-6)
    beyond = dt_check_verdict(dt_check_table(COARSE, _fine(2.5), ["ae", "tv"]))
    assert beyond is not None and not beyond.within_tolerance
    assert beyond.largest == pytest.approx(0.25) and beyond.largest >= DT_TOLERANCE
    assert beyond.above.controller.tolist() == ["PCONf"]
    assert dt_check_verdict(None) is None


def test_the_section_states_the_studys_verdict(tmp_path):
    verdict = dt_check_verdict(dt_check_table(COARSE, _fine(2.5), ["ae", "tv"]))
    report = HtmlReport("check")
    write_dt_check(report, verdict, 5e-4)
    text = report.write(tmp_path / "report.html").read_text()
    assert "25 %, NOT below the 1 % criterion" in text and "S3 PCONf (25 %)" in text
    with pytest.warns(DeprecationWarning, match="DtCheck"):  # a table: the verdict made here
        write_dt_check(HtmlReport("old"), verdict.table, 5e-4)
    assert math.isnan(dt_check_verdict(COARSE.assign(max_relative_change=math.nan)).largest)


def test_the_terminals_line_states_the_verdict_and_the_runs_above_it():
    beyond = dt_check_verdict(dt_check_table(COARSE, _fine(2.5), ["ae", "tv"]))
    assert dt_check_line(beyond) == (
        "halving dt: the largest relative change of a summary metric is 25 %, NOT below the "
        "1 % criterion; runs above it: S3 PCONf (25 %)"
    )
    within = dt_check_verdict(dt_check_table(COARSE, _fine(2.0), ["ae", "tv"]))
    assert dt_check_line(within) == (
        "halving dt: the largest relative change of a summary metric is 0.1 %, below the 1 % "
        "criterion"  # a fraction of the criterion's own unit, not "0.001 ... 1%"
    )
