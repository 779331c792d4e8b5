"""Names that moved work from their old place, with a DeprecationWarning naming the new one."""

from __future__ import annotations

import importlib

import pytest

MOVED = [
    ("delaytrack.components", "code_fingerprint", "delaytrack._compile.fingerprint"),
    ("delaytrack.components", "refuse_random_draws", "delaytrack._compile.guards"),
    ("delaytrack.components", "evaluate_step", "delaytrack._compile.native_entries"),
    ("delaytrack.experiments.scenario", "Scenario", "delaytrack.scenario"),
    ("delaytrack.experiments.scenario", "run_to_folder", "delaytrack.jobs.scenario_run"),
    ("delaytrack.experiments", "run_to_folder", "delaytrack.jobs.scenario_run"),
    ("delaytrack.experiments.scenario_run", "RunOutput", "delaytrack.jobs.scenario_run"),
    ("delaytrack.experiments.paper", "run_paper", "delaytrack.jobs.paper"),
    ("delaytrack.experiments.paper", "reproduce", "delaytrack.jobs.paper"),
    ("delaytrack.experiments.paper", "write_study", "delaytrack.report.paper"),
    ("delaytrack.experiments.robustness", "run_robustness", "delaytrack.jobs.robustness"),
    ("delaytrack.experiments.margins", "reproduce", "delaytrack.jobs.margins"),
    ("delaytrack.experiments.margins", "write_study", "delaytrack.report.margins"),
    ("delaytrack.sweeps", "write_sweep_outputs", "delaytrack.report.sweep"),
    ("delaytrack.experiments.two_link", "reproduce", "delaytrack.jobs.two_link"),
    ("delaytrack.experiments.decision_study", "reproduce", "delaytrack.jobs.decision_study"),
    ("delaytrack.sweeps.report", "findings", "delaytrack.report.sweep"),
    ("delaytrack.sweeps.report", "metric_units", "delaytrack.sweeps.summary"),
    ("delaytrack.experiments.robustness", "findings", "delaytrack.report.robustness"),
    ("delaytrack.experiments.robustness", "median_interval", "delaytrack.experiments.intervals"),
    ("delaytrack.experiments.convergence", "write_dt_check", "delaytrack.report.dt_check"),
    ("delaytrack.report", "relative_change", "delaytrack.experiments.relative_change"),
    ("delaytrack.report.tables", "relative_difference", "delaytrack.experiments.relative_change"),
    ("delaytrack.report.tables", "metric_columns", "delaytrack.experiments.relative_change"),
]


@pytest.mark.parametrize(("old", "name", "new"), MOVED)
def test_a_moved_name_warns_and_is_the_same_object(old: str, name: str, new: str) -> None:
    with pytest.warns(DeprecationWarning, match=rf"{old}\.{name} moved to {new}\.{name}"):
        found = getattr(importlib.import_module(old), name)
    assert found is getattr(importlib.import_module(new), name)


def test_a_name_that_never_lived_there_is_an_attribute_error() -> None:
    module = importlib.import_module("delaytrack.components")
    with pytest.raises(AttributeError, match="has no attribute 'no_such_name'"):
        module.no_such_name  # noqa: B018


def test_arolc_gains_text_gives_the_outer_loop_from_k_and_zeta() -> None:
    from delaytrack.experiments.tuning import gains_text

    text = gains_text("AROLC", {"k": 6.0, "zeta": 0.7, "alpha": 54.0})
    assert text == "k = 6 rad/s, ζ = 0.7 (K1 = 36 I, K2 = 8.4 I), α = 54"


def test_with_tuned_arolc_warns_and_gives_the_tuned_summary() -> None:
    from types import SimpleNamespace

    import pandas as pd

    from delaytrack.experiments import paper
    from delaytrack.experiments.paper_findings import tuned_as_arolc

    summary = pd.DataFrame({"controller": ["AROLC", "PCON"], "ae_mm": [1.0, 2.0]})
    tuned = pd.DataFrame({"controller": ["AROLC (tuned)"], "ae_mm": [0.5]})
    study = SimpleNamespace(summary=summary, tuned_summary=tuned)
    with pytest.warns(DeprecationWarning, match="paper_findings.tuned_as_arolc"):
        found = paper.with_tuned_arolc(study)
    pd.testing.assert_frame_equal(found, tuned_as_arolc(summary, tuned))
