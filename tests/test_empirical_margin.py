"""Empirical delay margin: agreement with the exact margin, the search, the result, refusals."""

from __future__ import annotations

import numpy as np
import pytest

from delaytrack.analysis import exact_delay_margin
from delaytrack.experiments import EmpiricalMargin, empirical_margin
from delaytrack.scenario import Scenario

#: A plant the nominal model describes exactly: q'' = u (unit masses), with the outer loop and a
#: constant reference, so e1'' = -K2 e1'(t-h) - K1 e1(t-h) holds exactly and the empirical
#: constant-delay margin is the exact one up to sampling (T_c = 2 ms of zero-order hold act like
#: about 1 ms of extra delay), the finite horizon and the resolution.
T_C = 0.002


def double_integrator(k1, k2, *, duration=100.0, x0=(1.0, 0.0)) -> Scenario:
    n = len(x0) // 2
    return Scenario.from_dict(
        {
            "name": "double_integrator",
            "duration": duration,
            "dt": T_C,
            "T_c": T_C,
            "x0": list(x0),
            "plant": {"type": "linear", "mass": [1.0] * n},
            "model": {"type": "linear", "mass": [1.0] * n},
            "controller": {"type": "outer-loop", "K1": k1, "K2": k2},
            "delay": {"type": "constant", "h": 0.0},
            "reference": {"offset": [0.0] * n},
        }
    )


#: |empirical - exact| <= resolution + TOLERANCE: the sampling (about T_c / 2 of extra delay)
#: and the finite horizon (100 s, a growth rate of 1/100 s^-1 shows) account for less than this.
TOLERANCE = 2 * T_C


@pytest.mark.parametrize(
    ("k1", "k2"),
    [(1.0, 1.0), ([1.0, 4.0], [1.0, 2.0])],
    ids=["identity", "diagonal-two-axes"],
)
def test_constant_delay_margin_agrees_with_the_exact_margin(k1, k2):
    n = np.size(k1)
    scenario = double_integrator(k1, k2, x0=[1.0] * n + [0.0] * n)
    result = empirical_margin(
        scenario, threshold=1.0, metric="max", resolution=0.002, upper=1.6, grid=16
    )
    exact = exact_delay_margin(np.diag(np.broadcast_to(k1, n)), np.diag(np.broadcast_to(k2, n)))
    assert result.failure_found
    assert result.first_failure - result.margin <= result.resolution
    assert abs(result.margin - exact.h) <= result.resolution + TOLERANCE, (result, exact.h)


def test_search_is_reproducible_and_records_every_run():
    scenario = double_integrator(1.0, 1.0, duration=40.0)
    kwargs = {"threshold": 0.5, "resolution": 0.01, "upper": 1.2, "grid": 6, "points": 3}
    first, second = (empirical_margin(scenario, **kwargs) for _ in range(2))
    assert first.to_dict() == second.to_dict()
    assert first.simulations == len(first.values) == len(set(first.values))
    assert np.all(np.diff(first.values) > 0)
    # The margin passes, the first failure fails, nothing between them was evaluated.
    frame = first.to_frame()
    assert set(frame.status) <= {"ok", "diverged"} and "ok" in set(frame.status)
    assert frame.loc[frame.value == first.margin, "passes"].item()
    assert not frame.loc[frame.value == first.first_failure, "passes"].item()
    assert frame.loc[frame.value < first.margin, "passes"].all()
    assert not ((frame.value > first.margin) & (frame.value < first.first_failure)).any()
    # The coarse grid is one batch, each multi-section round one more.
    assert first.rounds == 1 + int(np.ceil(np.log(0.2 / 0.01) / np.log(4)))


def test_lockstep_search_equals_separate_searches():
    scenario = double_integrator(1.0, 1.0, duration=30.0)
    controllers = [
        double_integrator(k, 1.0).build().controller for k in (0.5, 2.0)
    ]  # different margins, so the two searches take different rounds
    kwargs = {"threshold": 0.5, "resolution": 0.01, "upper": 1.2, "grid": 6, "profile": "abs-sine"}
    together = empirical_margin(scenario, controllers, **kwargs)
    alone = [empirical_margin(scenario, c, **kwargs) for c in controllers]
    assert [r.to_dict() for r in together] == [r.to_dict() for r in alone]


def test_a_threshold_never_missed_is_not_reported_as_a_margin():
    result = empirical_margin(
        double_integrator(1.0, 1.0, duration=20.0), threshold=10.0, upper=0.4, grid=4
    )
    assert not result.failure_found
    assert result.first_failure is None
    assert result.margin == result.upper == 0.4
    assert result.passes.all()
    assert "no failure up to upper = 0.4 s" in result.describe()
    assert "at least 0.4 s" in result.describe()


def test_result_states_its_settings():
    result = empirical_margin(
        double_integrator(1.0, 1.0, duration=20.0),
        threshold=0.3,
        metric="rms",
        settle=5.0,
        profile="abs-sine-offset",
        frequency=2.0,
        upper=0.5,
        grid=4,
        resolution=0.05,
    )
    assert isinstance(result, EmpiricalMargin)
    data = result.to_dict()
    for key, value in {
        "threshold": 0.3,
        "metric": "rms",
        "settle": 5.0,
        "profile": "abs-sine-offset",
        "frequency": 2.0,
        "upper": 0.5,
        "resolution": 0.05,
        "controller": "outer-loop",
        "scenario": "double_integrator",
    }.items():
        assert data[key] == value
    assert len(data["evaluated"]) == result.simulations
    assert "rms <= 0.3 (in each coordinate's unit) after t = 5 s" in result.describe()


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"threshold": 0.0}, "threshold must be > 0; got 0"),
        ({"threshold": "1"}, "threshold must be a real number"),
        ({"profile": "sine"}, "profile must be one of ['constant', 'abs-sine', 'abs-sine-offset']"),
        ({"metric": "mean"}, "metric must be one of ['ae', 'rms', 'max']; got 'mean'"),
        ({"resolution": 1.0, "upper": 0.5}, "resolution must be smaller than upper"),
        ({"upper": -1.0}, "upper must be > 0; got -1"),
        ({"settle": 20.0}, "settle must be below the scenario's duration 20 s"),
        ({"grid": 1}, "grid must be an integer >= 2; got 1"),
        ({"points": 0}, "points must be an integer >= 1; got 0"),
        ({"frequency": 0.0}, "frequency must be > 0"),
    ],
)
def test_bad_arguments_are_refused_by_name(kwargs, message):
    options = {"threshold": 0.5, **kwargs}
    with pytest.raises((ValueError, TypeError)) as error:
        empirical_margin(double_integrator(1.0, 1.0, duration=20.0), **options)
    assert message in str(error.value)


def test_a_threshold_missed_without_delay_is_refused():
    with pytest.raises(
        ValueError, match=r"threshold = 0.01 is missed already without delay: max of q1 = "
    ) as refused:
        empirical_margin(
            double_integrator(1.0, 1.0, duration=4.0), threshold=0.01, metric="max", settle=0.0
        )
    assert str(refused.value).endswith("give a larger threshold or a later settle time")


def test_bad_scenario_and_controllers_are_refused():
    with pytest.raises(TypeError, match="scenario must be a Scenario; got dict"):
        empirical_margin({}, threshold=1.0)
    with pytest.raises(TypeError, match="controller must be a Controller, a non-empty list"):
        empirical_margin(double_integrator(1.0, 1.0), [], threshold=1.0)
    with pytest.raises(TypeError, match=r"controller\[0\] must be a Controller; got str"):
        empirical_margin(double_integrator(1.0, 1.0), ["arolc"], threshold=1.0)


def test_a_threshold_per_coordinate_bounds_each_in_its_own_scale():
    # Two identical axes, the second started ten times farther: its error is ten times the
    # first's at every instant, so (0.5, 5) is the one-axis search at 0.5, and 0.5 for both is
    # stricter.
    options = {"metric": "max", "settle": 10.0, "resolution": 0.01, "upper": 1.2, "grid": 6}
    alone = empirical_margin(double_integrator(1.0, 1.0, duration=20.0), threshold=0.5, **options)
    scaled = double_integrator([1.0, 1.0], [1.0, 1.0], duration=20.0, x0=[1.0, 10.0, 0.0, 0.0])
    each = empirical_margin(scaled, threshold=[0.5, 5.0], **options)
    both = empirical_margin(scaled, threshold=0.5, **options)
    assert alone.failure_found and each.failure_found
    assert each.margin == alone.margin and each.first_failure == alone.first_failure
    assert both.margin < each.margin
    assert each.threshold == (0.5, 5.0) and each.coordinate_names == ("q1", "q2")
    np.testing.assert_allclose(
        each.coordinate_metrics[:, 1], 10.0 * each.coordinate_metrics[:, 0], rtol=1e-9
    )
    np.testing.assert_array_equal(
        each.passes, (each.statuses == 0) & np.all(each.coordinate_metrics <= [0.5, 5.0], axis=1)
    )
    assert "max <= (q1 0.5, q2 5) (each in its coordinate's unit)" in each.describe()
    data = each.to_dict()
    assert data["threshold"] == [0.5, 5.0] and data["coordinate_names"] == ["q1", "q2"]
    assert len(data["coordinate_metrics"]) == each.simulations
    assert {"metric_q1", "metric_q2"} <= set(each.to_frame().columns)


@pytest.mark.parametrize(
    ("threshold", "message"),
    [
        ([0.5, 5.0, 1.0], r"threshold must be a number > 0, or a list of one number > 0 per "),
        ([0.5, -1.0], r"per coordinate \(2: q1, q2\); got \[0.5, -1\]"),
        ([0.5, np.nan], r"threshold must be finite"),
        ([[0.5, 1.0]], r"threshold must be 1-dimensional"),
    ],
)
def test_a_threshold_per_coordinate_needs_one_positive_number_each(threshold, message):
    scenario = double_integrator([1.0, 1.0], [1.0, 1.0], duration=4.0, x0=[1.0, 1.0, 0.0, 0.0])
    with pytest.raises(ValueError, match=message):
        empirical_margin(scenario, threshold=threshold, upper=0.4)


def test_an_upper_beyond_a_predictors_history_is_refused_as_upper():
    """PCON keeps 0.25 s of its commands: a search up to 1 s (the default upper) ran its first
    batch and failed with "delay 1 s exceeds history", naming neither upper nor the fix."""
    from delaytrack._validation import ArgumentError
    from delaytrack.experiments import tuning
    from delaytrack.scenario import load_builtin

    gains = tuning.load_gains()["PCON"]["varying"]
    pcon = tuning.make_controller("PCON", gains, history=0.25)
    scenario = load_builtin("robot_S1").replace(duration=2.0)
    searched = "upper = 1 s searches delays up to 1 s, under which PCON cannot run"
    with pytest.raises(ArgumentError, match=searched) as refusal:
        empirical_margin(scenario, pcon, threshold=1.0, upper=1.0)
    assert refusal.value.argument == "upper" and "exceeds history = 0.25 s" in str(refusal.value)
    empirical_margin(scenario, pcon, threshold=1.0, upper=0.2, resolution=0.05, grid=2)


def _found(margin, first_failure, resolution, threshold, names, units):
    """A search result that found a failure, as :func:`empirical_margin` returns it."""
    return EmpiricalMargin(
        margin=margin,
        failure_found=True,
        first_failure=first_failure,
        profile="constant",
        frequency=1.0,
        metric="ae",
        threshold=threshold,
        settle=30.0,
        resolution=resolution,
        upper=1.0,
        values=np.array([margin, first_failure]),
        statuses=np.array([0, 1]),
        coordinate_metrics=np.array([[0.01] * len(names), [np.nan] * len(names)]),
        coordinate_names=names,
        scenario="robot",
        controller="arolc",
        simulations=2,
        rounds=1,
        coordinate_units=units,
    )


@pytest.mark.parametrize(
    ("margin", "first_failure", "resolution", "shown"),
    [
        (0.6333333333333333, 0.6375, 0.005, "0.633 s (first failure 0.638 s;"),
        (0.7, 0.7025, 0.005, "0.700 s (first failure 0.703 s;"),  # 0.7 is not floored to 0.699
        (0.123456789, 0.123456790, 1e-9, "0.123456789 s (first failure 0.123456790 s;"),
        (3.25, 4.0, 1.0, "3 s (first failure 4 s;"),
        (0.5, 2.0, 2.0, "0 s (first failure 2 s;"),  # a resolution above 1 s: whole seconds
        (0.0, 0.005, 0.005, "0.000 s (first failure 0.005 s;"),  # fails with almost no delay
        # grid values with binary noise are rounded as the values they stand for
        (0.5999999999999999, 0.6000000000000001, 0.005, "0.600 s (first failure 0.600 s;"),
    ],
)
def test_the_margin_is_shown_to_the_resolution_as_a_bracket_that_holds_the_found_one(
    margin, first_failure, resolution, shown
):
    """No digit beyond the search's resolution; the margin rounded down and the first failure
    up, so the bracket shown holds the bracket found."""
    result = _found(margin, first_failure, resolution, 0.2, ("q1",), (None,))
    text = result.describe()
    assert text.startswith(shown)
    # the bracket shown holds the one found, up to the binary noise of a grid value
    low, high = float(text.split(" s ")[0]), float(text.split("first failure ")[1].split()[0])
    assert low <= margin + 1e-12 and first_failure <= high + 1e-12


def test_a_large_first_failure_is_not_shown_below_the_value_found():
    result = _found(1234.567890120, 1234.56789012345, 1e-9, 0.2, ("q1",), (None,))
    assert result.describe().startswith("1234.567890120 s (first failure 1234.567890124 s;")


def test_the_threshold_is_shown_in_the_coordinates_units_where_the_plant_declares_them():
    names, units = ("x", "y", "phi"), ("m", "m", "rad")
    text = _found(0.3, 0.305, 0.005, (0.05, 0.05, 0.5), names, units).describe()
    assert "ae <= (x 0.05 m, y 0.05 m, phi 0.5 rad) after t = 30 s" in text
    assert "coordinate's unit" not in text
    mixed = _found(0.3, 0.305, 0.005, 0.2, names, units).describe()
    assert "ae <= 0.2 in each coordinate (x in m, y in m, phi in rad) after" in mixed
    same = _found(0.3, 0.305, 0.005, 0.2, ("q1", "q2"), ("rad", "rad")).describe()
    assert "ae <= 0.2 rad after" in same
    partly = _found(0.3, 0.305, 0.005, (0.1, 0.2), ("q1", "q2"), ("rad", None)).describe()
    assert "(q1 0.1 rad, q2 0.2) (each in its coordinate's unit)" in partly
