"""Metrics (AE, %AE and TV as in Roy & Kar, Section III; RMS and max) against values computed
by hand on a tiny constructed result.

The result below has two runs of a 2-coordinate, 2-input system over four records
t = 0, 1, 2, 3. The reference is q_d = (1, 0) throughout, so e1 = q_d - q is easy to read off:

    run 0:  q1 = [1, 0, 2, 1]   -> e1_1 = [0, 1, -1, 0]
            q2 = [0, 3, 0, -1]  -> e1_2 = [0, -3, 0, 1]
            command_1 = [0, 1, 3, 2], command_2 = [5, 5, 4, 4]
    run 1:  diverged at t = 1.5 (records after it are NaN, as the simulator leaves them)
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from delaytrack.metrics import (
    max_abs_error,
    mean_absolute_error,
    metrics_table,
    percent_of,
    rms_error,
    total_variation,
)
from delaytrack.sim import SimResult


def constructed(status_1: int = 1) -> SimResult:
    t = np.array([0.0, 1.0, 2.0, 3.0])
    reference = np.zeros((4, 3, 2))
    reference[:, 0, 0] = 1.0
    x = np.zeros((2, 4, 4))
    x[0, :, 0] = [1.0, 0.0, 2.0, 1.0]
    x[0, :, 1] = [0.0, 3.0, 0.0, -1.0]
    x[1, :, 0] = [1.0, 0.5, np.nan, np.nan]
    x[1, :, 1] = [0.0, 0.5, np.nan, np.nan]
    commands = np.zeros((2, 4, 2))
    commands[0, :, 0] = [0.0, 1.0, 3.0, 2.0]
    commands[0, :, 1] = [5.0, 5.0, 4.0, 4.0]
    commands[1] = [[0.0, 0.0], [1.0, 1.0], [np.nan, np.nan], [np.nan, np.nan]]
    return SimResult(
        t=t,
        x=x,
        reference=reference,
        commands=commands,
        applied=commands.copy(),
        h=np.full((2, 4), 0.01),
        controller_state=np.zeros((2, 4, 0)),
        controller_state_names=(),
        status=np.array([0, status_1]),
        t_stop=np.array([3.0, 1.5 if status_1 else 3.0]),
        settings={},
    )


def test_mean_absolute_error_by_hand():
    ae = mean_absolute_error(constructed())
    assert ae.shape == (2, 2)
    np.testing.assert_allclose(ae[0], [0.5, 1.0], rtol=0, atol=1e-15)


def test_rms_error_by_hand():
    rms = rms_error(constructed())
    np.testing.assert_allclose(rms[0], [math.sqrt(2 / 4), math.sqrt(10 / 4)], rtol=1e-15)


def test_max_abs_error_by_hand():
    np.testing.assert_allclose(max_abs_error(constructed())[0], [1.0, 3.0])


def test_total_variation_by_hand():
    # |1-0| + |3-1| + |2-3| = 4 on input 1, |0| + |-1| + |0| = 1 on input 2.
    tv = total_variation(constructed())
    assert tv.shape == (2,)
    assert tv[0] == pytest.approx(5.0, abs=0)


def test_t_from_skips_the_records_before_it():
    result = constructed()
    # Records t = 2, 3: e1_1 = [-1, 0], e1_2 = [0, 1]; commands [3, 2] and [4, 4].
    np.testing.assert_allclose(mean_absolute_error(result, t_from=2.0)[0], [0.5, 0.5])
    np.testing.assert_allclose(rms_error(result, t_from=2.0)[0], [math.sqrt(0.5), math.sqrt(0.5)])
    np.testing.assert_allclose(max_abs_error(result, t_from=2.0)[0], [1.0, 1.0])
    assert total_variation(result, t_from=2.0)[0] == pytest.approx(1.0)


def test_t_from_after_the_last_record_is_refused():
    with pytest.raises(
        ValueError, match=r"t_from = 5 s leaves no records; the result ends at t = 3 s"
    ):
        mean_absolute_error(constructed(), t_from=5.0)


@pytest.mark.parametrize("metric", [mean_absolute_error, rms_error, max_abs_error])
def test_a_diverged_run_gives_nan_and_leaves_the_others_alone(metric):
    values = metric(constructed(status_1=1))
    assert np.all(np.isnan(values[1]))
    assert np.all(np.isfinite(values[0]))


def test_a_diverged_run_gives_nan_even_before_it_stopped():
    # Records before the stop are finite, but a partial average is not comparable: NaN anyway.
    result = constructed(status_1=1)
    assert np.isnan(mean_absolute_error(result, t_from=0.0)[1]).all()
    assert np.isnan(total_variation(result)[1])


def test_delay_beyond_history_status_also_gives_nan():
    assert np.isnan(total_variation(constructed(status_1=2))[1])


def test_single_run_equals_row_of_batch():
    result = constructed()
    single = result[0]
    np.testing.assert_array_equal(mean_absolute_error(single)[0], mean_absolute_error(result)[0])
    np.testing.assert_array_equal(total_variation(single), total_variation(result)[:1])


@pytest.mark.parametrize("function", [mean_absolute_error, total_variation, metrics_table])
def test_something_other_than_a_result_is_refused_by_name(function):
    with pytest.raises(TypeError, match=r"result must be a SimResult .*; got str 'x'"):
        function("x")


def test_percent_of():
    assert percent_of(12.5, 2500.0) == pytest.approx(0.5)
    np.testing.assert_allclose(percent_of(np.array([25.0, np.nan]), 2500.0), [1.0, np.nan])
    with pytest.raises(ValueError, match="scale must be a finite number > 0; got 0"):
        percent_of(1.0, 0)


def test_metrics_table_rows_and_columns():
    table = metrics_table(constructed(), coordinate_names=["x", "y"], label="case")
    assert list(table.columns) == [
        "label",
        "run",
        "status",
        "t_stop",
        "ae_x",
        "ae_y",
        "rms_x",
        "rms_y",
        "max_x",
        "max_y",
        "tv",
    ]
    assert list(table["status"]) == ["ok", "diverged"]
    assert table.loc[0, "ae_y"] == pytest.approx(1.0)
    assert table.loc[0, "tv"] == pytest.approx(5.0)
    assert table.loc[1, "t_stop"] == pytest.approx(1.5)
    assert pd.isna(table.loc[1, "ae_x"])


def test_metrics_table_default_names_and_checks():
    table = metrics_table(constructed())
    assert "ae_q1" in table.columns and "max_q2" in table.columns and "label" not in table.columns
    with pytest.raises(
        ValueError, match=r"coordinate_names must have n = 2 different entries; got 1"
    ):
        metrics_table(constructed(), coordinate_names=["x"])
