"""The two-link job: its study holds the judgements its report states (which joints AROLC tracks
better, whether the delay effect is small, whether each delay is below the certified bound), and
the report words them as the study holds them, whatever the numbers beside them."""

from __future__ import annotations

import dataclasses
import html
import re

import numpy as np
import pandas as pd
import pytest

from delaytrack.experiments import two_link
from delaytrack.experiments.two_link import SMALL_DELAY_EFFECT_PCT, run_study
from delaytrack.report.two_link import write_study


@pytest.fixture(scope="module")
def study():
    return run_study(duration=0.1, check_dt=False)


def _text(folder) -> str:
    page = (folder / "report.html").read_text(encoding="utf-8")
    return html.unescape(re.sub(r"<[^>]+>", "", page))


def test_the_judgements_of_the_delay_are_strict_at_their_thresholds(study):
    at = dataclasses.replace(
        study,
        largest_delay_effect=SMALL_DELAY_EFFECT_PCT,
        h_max={"S1": study.bound.h_m, "S3": np.nextafter(study.bound.h_m, 0.0)},
    )
    assert not at.delay_effect_small  # "below" the threshold: at it is not small
    assert at.below_bound == {"S1": False, "S3": True} and not at.all_below_bound
    below = dataclasses.replace(at, largest_delay_effect=np.nextafter(SMALL_DELAY_EFFECT_PCT, 0))
    assert below.delay_effect_small


def test_which_joints_are_better_counts_only_finite_decreases():
    changes = pd.DataFrame(
        {
            "scenario": ["S1", "S3", "S4"],
            "ae_q1": [-1.0, 2.0, np.nan],
            "ae_q2": [-0.5, -3.0, 0.0],
        }
    )
    assert two_link._arolc_better(changes) == {"S1": ("q1", "q2"), "S3": ("q2",), "S4": ()}


def test_the_report_words_the_studys_judgements(study, tmp_path):
    write_study(study, tmp_path / "as-run")
    text = _text(tmp_path / "as-run")
    for case in study.cases:
        head = {
            study.coordinates: "mean error is lower than the outer loop's on both joints",
            (): "mean error is not lower than the outer loop's",
        }.get(
            study.arolc_better[case],
            f"mean error is lower than the outer loop's on {study.arolc_better[case][0]}",
        )
        assert f"{case}: in this one run, AROLC's {head}" in text
    small = "comes mostly from the model mismatch, not from the delay"
    assert (small in text) == study.delay_effect_small
    # The report follows the study's judgements, not the numbers beside them.
    judged = dataclasses.replace(
        study,
        arolc_better={"S1": ("q2",), "S3": ()},
        largest_delay_effect=0.0 if not study.delay_effect_small else 2 * SMALL_DELAY_EFFECT_PCT,
        h_max={"S1": 2.0 * study.bound.h_m, "S3": 0.5 * study.bound.h_m},
    )
    write_study(judged, tmp_path / "judged")
    text = _text(tmp_path / "judged")
    assert (
        "S1: in this one run, AROLC's mean error is lower than the outer loop's on q2 only. "
        "AROLC vs outer loop: " in text
    )
    assert (
        "S3: in this one run, AROLC's mean error is not lower than the outer loop's. "
        "AROLC vs outer loop: " in text
    )
    assert (small in text) != study.delay_effect_small
    # A change that is not finite (a run that did not finish): not "not lower".
    stopped = dataclasses.replace(
        judged, changes=judged.changes.assign(ae_q1=[np.nan] * len(judged.changes))
    )
    write_study(stopped, tmp_path / "stopped")
    text_stopped = _text(tmp_path / "stopped")
    assert "S1: in this one run, the mean errors cannot be compared (a run did not finish)" in (
        text_stopped
    )
    assert "AE of q1: not comparable" in text_stopped
    assert ("so the delay is a large part of the tracking error" in text) == (
        study.delay_effect_small
    )
    assert f"The largest delay of S1 is {judged.h_max['S1']:.3g} s, NOT below h_m." in text
    assert f"The largest delay of S3 is {judged.h_max['S3']:.3g} s, below h_m." in text
    assert "Not every case is inside the delay range the theorem certifies" in text
