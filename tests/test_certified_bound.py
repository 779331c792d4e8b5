"""``simulate`` beside AROLC's certified delay bound h_m (Theorem 1): the warning when a run's
largest delay exceeds it, at the user's line unless the caller states h_m itself, and h_m per
run."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from delaytrack.analysis import razumikhin_bound
from delaytrack.controllers import AROLC, OuterLoop
from delaytrack.delays import ConstantDelay
from delaytrack.plants import TwoLinkArm
from delaytrack.references import SinusoidalReference
from delaytrack.scenario import load_builtin
from delaytrack.sim import simulate
from delaytrack.sim.certified_bound import (
    BeyondCertifiedBoundWarning,
    _h_m,
    beyond_certified_bound,
    certified_bounds,
    stated_by_the_caller,
)
from delaytrack.sim.no_command import NoCommandArrivesWarning

REFERENCE = SinusoidalReference([0.0, 0.0], amplitude=[0.8, 0.5], frequency=[0.5, 0.7])
FAST = AROLC(TwoLinkArm(), K1=4.0, K2=4.0, Q=1.0, alpha=2.0, epsilon=0.1, gamma=0.001)
H_M = razumikhin_bound(4.0, 4.0).h_m


def run(controller, delays, **options):
    return simulate(
        TwoLinkArm(),
        controller,
        delays,
        np.zeros(4),
        reference=REFERENCE,
        t1=0.2,
        dt=1e-3,
        T_c=2e-3,
        **options,
    )


def test_h_m_is_theorem_1s_with_the_runs_gains_and_the_papers_weights():
    paper = AROLC(TwoLinkArm(), K1=1.0, K2=1.0, Q=1.0, alpha=2.0, epsilon=0.1, gamma=0.001)
    outer = OuterLoop(TwoLinkArm(), K1=1.0, K2=1.0)
    bounds = certified_bounds([FAST, paper, outer])
    # 0.12487 s: Theorem 1 at K1 = K2 = Q = 1, beta = 1, r = 1.1, the package root's example.
    assert bounds[0] == H_M and abs(bounds[1] - 0.12487) < 1e-5
    # The delays of the tests below stand on either side of this h_m (Theorem 1 at K1 = K2 = 4,
    # computed above): 5 and 10 ms under it, 40 ms beyond it.
    assert 0.01 < H_M < 0.04
    assert np.isnan(bounds[2])  # no certificate without AROLC


def test_a_delay_beyond_h_m_warns_at_the_users_line_and_says_it_is_not_instability():
    with pytest.warns(BeyondCertifiedBoundWarning) as caught:
        result = run(FAST, [ConstantDelay(0.005), ConstantDelay(0.04)])
    assert len(caught) == 1 and caught[0].filename == __file__
    warning = caught[0].message
    assert warning.h_m == H_M and warning.largest_delay == pytest.approx(0.04)
    assert "in 1 of 2 runs" in str(warning) and "does not by itself mean instability" in str(
        warning
    )
    assert list(result.status_names) == ["ok", "ok"]  # a warning, not a refusal


@pytest.mark.parametrize("trajectories", [True, False])
def test_a_batch_quotes_its_largest_delay_beyond_h_m_and_names_the_run(trajectories):
    """Not the first run beyond h_m (40 ms here), whose delay is not the batch's largest."""
    delays = [ConstantDelay(0.005), ConstantDelay(0.04), ConstantDelay(0.09), ConstantDelay(0.05)]
    with pytest.warns(BeyondCertifiedBoundWarning) as caught:
        run(FAST, delays, trajectories=trajectories)
    warning = caught[0].message
    assert warning.largest_delay == pytest.approx(0.09) and warning.h_m == H_M
    assert "in 3 of 4 runs" in str(warning) and "run 2: 90 ms" in str(warning)


@pytest.mark.parametrize("trajectories", [True, False])
def test_below_h_m_or_without_arolc_nothing_is_said(trajectories):
    with warnings.catch_warnings():
        warnings.simplefilter("error", BeyondCertifiedBoundWarning)
        run(FAST, ConstantDelay(0.01), trajectories=trajectories)
        run(OuterLoop(TwoLinkArm(), K1=4.0, K2=4.0), ConstantDelay(0.04))


def test_without_trajectories_the_profiles_largest_delay_counts():
    result = run(FAST, ConstantDelay(0.04), trajectories=False)
    warning = beyond_certified_bound([FAST], [ConstantDelay(0.04)], result)
    assert warning is not None and warning.largest_delay == 0.04


def test_a_delay_that_outlasts_a_run_warns_that_no_command_arrives_and_names_how_many():
    with pytest.warns(NoCommandArrivesWarning) as caught:
        result = run(
            OuterLoop(TwoLinkArm(), K1=4.0, K2=4.0), [ConstantDelay(0.2), ConstantDelay(0.01)]
        )
    assert len(caught) == 1 and caught[0].filename == __file__
    assert "never shorter than 0.2 s, and the run lasts 0.2 s in 1 of 2 runs" in str(
        caught[0].message
    )
    np.testing.assert_array_equal(result.applied[0, :-1], 0.0)  # u_init, as the warning says
    with warnings.catch_warnings():
        warnings.simplefilter("error", NoCommandArrivesWarning)
        run(OuterLoop(TwoLinkArm(), K1=4.0, K2=4.0), ConstantDelay(0.19))  # one arrives
        with stated_by_the_caller():  # the toolkit's jobs state their delays themselves
            run(OuterLoop(TwoLinkArm(), K1=4.0, K2=4.0), ConstantDelay(0.2))


def test_the_toolkits_own_jobs_do_not_warn():
    """A scenario run calls simulate from inside the package: its jobs go beyond h_m on
    purpose and say so in their reports (the command line prints its own line)."""
    scenario = load_builtin("two_link_S1").replace(duration=0.2)
    controller = {**scenario.to_dict()["controller"], "K1": 4.0, "K2": 4.0}
    with warnings.catch_warnings():
        warnings.simplefilter("error", BeyondCertifiedBoundWarning)
        scenario.replace(controller=controller).run()


def test_a_caller_that_states_h_m_itself_silences_the_warning_only_within():
    with warnings.catch_warnings():
        warnings.simplefilter("error", BeyondCertifiedBoundWarning)
        with stated_by_the_caller():
            run(FAST, ConstantDelay(0.04))
    with pytest.warns(BeyondCertifiedBoundWarning):
        run(FAST, ConstantDelay(0.04))


def test_h_m_is_computed_once_per_gains_and_follows_every_gain():
    """h_m is remembered per gains (a simulate call pays for it once, not at every call), so
    two controllers with other gains of the same shape get their own h_m."""
    slower = AROLC(TwoLinkArm(), K1=2.0, K2=4.0, Q=1.0, alpha=2.0, epsilon=0.1, gamma=0.001)
    damped = AROLC(TwoLinkArm(), K1=4.0, K2=6.0, Q=1.0, alpha=2.0, epsilon=0.1, gamma=0.001)
    bounds = certified_bounds([FAST, slower, damped, OuterLoop(TwoLinkArm(), K1=4.0, K2=4.0)])
    hits = _h_m.cache_info().hits
    expected = [razumikhin_bound(k1, k2).h_m for k1, k2 in ((4.0, 4.0), (2.0, 4.0), (4.0, 6.0))]
    assert bounds[:3].tolist() == expected and len(set(expected)) == 3
    assert np.isnan(bounds[3])
    again = AROLC(TwoLinkArm(), K1=2.0, K2=4.0, Q=1.0, alpha=2.0, epsilon=0.1, gamma=0.001)
    assert certified_bounds([again]).tolist() == [expected[1]]  # other object, same gains
    assert _h_m.cache_info().hits == hits + 1


def test_the_warning_says_when_the_run_it_names_did_not_finish():
    with pytest.warns(BeyondCertifiedBoundWarning) as caught:
        result = run(FAST, ConstantDelay(0.04), error_bound=1e-9)
    assert list(result.status_names) == ["left the path"]
    assert str(caught[0].message).endswith("; that run did not finish (left the path)")
