"""The tuning's report (``delaytrack.report.tuning``): the chosen gains as the study holds them."""

from __future__ import annotations

import pandas as pd

from delaytrack.experiments import tuning
from delaytrack.report.tuning import chosen_gains_lines, gains_text


def result(kind, best, inside):
    interior = {
        gain_set: dict.fromkeys(tuning.GAIN_NAMES[kind], flag) for gain_set, flag in inside.items()
    }
    return tuning.TuningResult(kind, pd.DataFrame(), best, interior, (), 1.0, 0.0)


def test_the_lines_quote_the_chosen_gains_their_objective_and_the_edge():
    arolc = dict(k=2.0, zeta=0.5, alpha=4.0, objective=3.25, h_m=0.1, K1=4.0, K2=2.0)
    pcon = dict(kappa=8.0, k_b=3.0, c=0.35, objective=1.5)
    study = tuning.TuningStudy(
        {
            "AROLC": result("AROLC", {"all": arolc}, {"all": True}),
            "PCON-wheel": result("PCON-wheel", {"varying": pcon}, {"varying": False}),
        }
    )
    assert list(study) == ["AROLC", "PCON-wheel"] and study["AROLC"].best["all"] is arolc
    assert chosen_gains_lines(study) == [
        "AROLC (all): k = 2 rad/s, ζ = 0.5 (K1 = 4 I, K2 = 2 I), α = 4 (worst mean AE 3.25 mm)",
        "PCON-wheel (varying): κ = 8, k_b = 3 I, ϑ = 0.35 M̂_r⁻¹ (worst mean AE 1.5 mm, ON THE "
        "GRID'S EDGE)",
    ]
    assert gains_text("PCONf", pcon) == "κ = 8, k_b = 3 I, ϑ = 0.35 M̂⁻¹"


def test_the_shipped_gains_read_as_text_with_the_outer_loop_gains_they_give():
    chosen = tuning.load_gains()["AROLC"]["all"]
    g = tuning.arolc_gains(chosen["k"], chosen["zeta"], chosen["alpha"])
    assert f"(K1 = {g['K1']:g} I, K2 = {g['K2']:g} I)" in gains_text("AROLC", chosen)


def test_a_run_is_off_the_path_when_it_stopped_or_its_mean_error_passed_a_metre():
    """The one rule of the tuning, the robustness study and the paper job's claims."""
    import numpy as np

    from delaytrack.experiments.tuning import DIVERGED_AE_MM, off_path

    ok = np.array([True, True, True, False, True])
    ae = np.array([1.0, DIVERGED_AE_MM, np.nextafter(DIVERGED_AE_MM, np.inf), 1.0, np.nan])
    assert off_path(ok, ae).tolist() == [False, False, True, True, True]
