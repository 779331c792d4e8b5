"""SinusoidalReference: q_d(t) = offset + slope t + Σ_k A_ik sin(ω_ik t + φ_ik) and derivatives.

The reference formulas are differentiated by hand here; finite differences of q_d check q̇_d and
q̈_d independently of both.
"""

from __future__ import annotations

import numpy as np
import pytest

from delaytrack.references import SinusoidalReference

# Two coordinates, two harmonics each (arbitrary numbers; the second harmonic of row 1 is a
# constant: frequency 0).
OFFSET = np.array([0.1, -1.35])
SLOPE = np.array([0.25, 0.0])
AMPLITUDE = np.array([[1.25, 0.3], [-0.7, 0.2]])
FREQUENCY = np.array([[0.35, 2.0], [1.1, 0.0]])
PHASE = np.array([[0.0, 0.4], [np.pi / 2, -1.0]])


def analytic(t: np.ndarray):
    """q_d, q̇_d, q̈_d at times t (k,), shape (k, n), by hand."""
    t = np.asarray(t, dtype=float)[:, None, None]
    angle = FREQUENCY * t + PHASE  # (k, n, K)
    qd = OFFSET + SLOPE * t[:, :, 0] + np.sum(AMPLITUDE * np.sin(angle), axis=-1)
    qd_dot = SLOPE + np.sum(AMPLITUDE * FREQUENCY * np.cos(angle), axis=-1)
    qd_ddot = -np.sum(AMPLITUDE * FREQUENCY**2 * np.sin(angle), axis=-1)
    return qd, qd_dot, qd_ddot


@pytest.fixture(scope="module")
def reference():
    return SinusoidalReference(OFFSET, SLOPE, AMPLITUDE, FREQUENCY, PHASE)


def test_evaluate_matches_analytic_formula(reference):
    t = np.linspace(-5.0, 30.0, 701)
    for got, want in zip(reference.evaluate(t), analytic(t), strict=True):
        np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-13)


def test_derivatives_match_finite_differences(reference):
    t = np.linspace(0.0, 20.0, 41)
    step = 1e-4
    qd_plus, dot_plus, _ = reference.evaluate(t + step)
    qd_minus, dot_minus, _ = reference.evaluate(t - step)
    qd, qd_dot, qd_ddot = reference.evaluate(t)
    # Central differences: truncation step² max|q'''| / 6 with max|q'''| <= Σ|A ω³| ≈ 3.4, so
    # ~6e-9; the second difference also loses ~4 eps |q_d| / step² ≈ 3e-7 to rounding.
    np.testing.assert_allclose((qd_plus - qd_minus) / (2 * step), qd_dot, atol=1e-7)
    np.testing.assert_allclose((dot_plus - dot_minus) / (2 * step), qd_ddot, atol=1e-7)
    np.testing.assert_allclose((qd_plus - 2 * qd + qd_minus) / step**2, qd_ddot, atol=1e-5)


def test_paper_circle_x_y():
    # Roy & Kar, Section III: x_d = 1.25 sin(0.35 t) + 0.1,
    # y_d = 1.25 cos(0.35 t) + 1.35 = 1.25 sin(0.35 t + π/2).
    circle = SinusoidalReference(
        [0.1, 1.35], amplitude=[1.25, 1.25], frequency=[0.35, 0.35], phase=[0.0, np.pi / 2]
    )
    t = np.linspace(0.0, 40.0, 81)
    qd, qd_dot, qd_ddot = circle.evaluate(t)
    np.testing.assert_allclose(qd[:, 0], 1.25 * np.sin(0.35 * t) + 0.1, rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(qd[:, 1], 1.25 * np.cos(0.35 * t) + 1.35, rtol=1e-14, atol=1e-14)
    # Speed on the circle: 1.25 * 0.35 = 0.4375 m/s (docs/robot.md, "Reference path").
    np.testing.assert_allclose(np.linalg.norm(qd_dot, axis=1), 0.4375, rtol=1e-14)
    np.testing.assert_allclose(np.linalg.norm(qd_ddot, axis=1), 1.25 * 0.35**2, rtol=1e-14)


def test_set_point_and_ramp():
    ramp = SinusoidalReference([1.0, 2.0], slope=[0.5, -1.0])
    qd, qd_dot, qd_ddot = ramp.evaluate(np.array([0.0, 2.0]))
    np.testing.assert_array_equal(qd, [[1.0, 2.0], [2.0, 0.0]])
    np.testing.assert_array_equal(qd_dot, [[0.5, -1.0], [0.5, -1.0]])
    np.testing.assert_array_equal(qd_ddot, 0.0)
    constant = SinusoidalReference([3.0])
    assert constant.n == 1
    np.testing.assert_array_equal(constant.evaluate(7.0)[0], [3.0])


def test_shapes(reference):
    assert reference.n == 2
    assert reference.amplitude.shape == (2, 2)
    for array in reference.evaluate(1.5):
        assert array.shape == (2,)
    for array in reference.evaluate(np.zeros(5)):
        assert array.shape == (5, 2)
    for array in reference.evaluate(np.zeros((3, 4))):
        assert array.shape == (3, 4, 2)
    t = np.arange(12.0).reshape(3, 4)
    qd = reference.evaluate(t)[0]
    np.testing.assert_allclose(qd.reshape(12, 2), analytic(t.ravel())[0], rtol=1e-13, atol=1e-13)


def test_one_dimensional_harmonics_mean_one_per_coordinate():
    one = SinusoidalReference([0.0, 0.0], amplitude=[1.0, 2.0], frequency=[3.0, 4.0])
    assert one.amplitude.shape == (2, 1)
    np.testing.assert_array_equal(one.phase, np.zeros((2, 1)))  # omitted phase is zero
    t = 0.3
    np.testing.assert_allclose(one.evaluate(t)[0], [np.sin(0.9), 2 * np.sin(1.2)], rtol=1e-15)


def test_spec_round_trip(reference):
    rebuilt = SinusoidalReference.from_spec(reference.to_spec())
    np.testing.assert_array_equal(rebuilt.params, reference.params)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(offset=[0.0, 1.0], slope=[1.0]), r"slope must have length n = 2; got 1"),
        (
            dict(offset=[0.0, 1.0], amplitude=[1.0, 2.0, 3.0], frequency=[1.0, 1.0]),
            r"amplitude must have shape \(n,\) or \(n, K\) with n = 2; got \(3,\)",
        ),
        (
            dict(offset=[0.0, 1.0], amplitude=np.ones((2, 2)), frequency=np.ones((3, 2))),
            r"frequency must have shape \(n,\) or \(n, K\) with n = 2; got \(3, 2\)",
        ),
        (
            dict(offset=[0.0, 1.0], amplitude=np.ones((2, 2)), frequency=np.ones((2, 3))),
            r"amplitude, frequency and phase must have the same shape; "
            r"got \{'amplitude': 2, 'frequency': 3\}",
        ),
        (dict(offset=[[0.0, 1.0]]), r"offset must be 1-dimensional; got shape \(1, 2\)"),
        (dict(offset=[0.0, np.nan]), r"offset must be finite"),
        (
            dict(offset=[0.0], amplitude=[1.0], frequency=[1.0], phase=[np.inf]),
            r"phase must be finite",
        ),
    ],
)
def test_refused_shapes(kwargs, message):
    with pytest.raises(ValueError, match=message):
        SinusoidalReference(**kwargs)


def test_from_spec_refuses_unknown_and_missing_keys():
    with pytest.raises(
        ValueError, match=r"unknown key\(s\) \['amplitudes'\] in reference; valid keys are"
    ):
        SinusoidalReference.from_spec({"offset": [0.0], "amplitudes": [1.0]})
    with pytest.raises(ValueError, match=r"reference needs 'offset'"):
        SinusoidalReference.from_spec({"slope": [1.0]})


def test_a_few_points_evaluated_as_python_are_the_compiled_numbers(reference, monkeypatch):
    from delaytrack._compile import functions
    from delaytrack.references import SplineReference

    knots = np.linspace(0.0, 10.0, 11)
    spline = SplineReference(knots, np.column_stack([np.sin(knots), np.cos(knots)]))
    held = SplineReference(knots, np.column_stack([np.sin(knots), np.cos(knots)]), beyond="hold")
    drawn = np.random.default_rng(3).uniform(-2.0, 40.0, 7)
    # drawn times, a knot, far beyond the knots; then times Python cannot take as they are (the
    # sine of an overflowed angle, an infinite time), computed compiled
    times = np.concatenate([drawn, [4.0, 1e12, 1e308, np.inf, np.nan]])

    def evaluated(as_python: bool) -> list:
        monkeypatch.setattr(functions, "few_points_as_python", lambda function, points: as_python)
        return [
            r.evaluate(t)
            for r in (reference, spline, held)
            for t in (times, 4.0, times[:5], times[7:10])
        ]

    for python, compiled in zip(evaluated(True), evaluated(False), strict=True):
        for got, want in zip(python, compiled, strict=True):
            np.testing.assert_array_equal(got, want)


def test_few_points_run_as_python_only_until_the_code_is_compiled():
    import numba

    from delaytrack._compile.functions import FEW_POINTS, few_points_as_python

    @numba.njit
    def double(x):
        return 2.0 * x

    @numba.njit
    def yours(x):
        return 2.0 * x

    double.py_func.__module__ = "delaytrack.a_module_of_the_package"
    assert few_points_as_python(double, 1) and few_points_as_python(double, FEW_POINTS)
    assert not few_points_as_python(double, FEW_POINTS + 1)  # many points: compile
    assert not few_points_as_python(double.py_func, 1)  # a plain function is Python anyway
    assert not few_points_as_python(yours, 1)  # a function of the user's: always compiled
    double(1.0)
    assert not few_points_as_python(double, 1)  # compiled in this process: use it


def test_a_reference_evaluated_at_one_point_compiles_nothing():
    import subprocess
    import sys

    code = """
from delaytrack.references.sinusoidal import sinusoidal_reference, sinusoidal_reference_values
from delaytrack.plants.robot.reference import paper_reference
paper_reference("consistent").evaluate(0.0)
print(len(sinusoidal_reference.signatures), len(sinusoidal_reference_values.signatures))
"""
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=True
    )
    assert done.stdout.split() == ["0", "0"]


@pytest.mark.parametrize(
    "values",
    [[0.0, 1e308, -1e308, 1.0], [0.0, 1.7e308, 1.7e308, 0.0]],
    ids=["slopes", "coefficients"],
)
def test_samples_whose_spline_overflows_are_refused_by_name_without_a_warning(values):
    """SciPy refused the first with its own words (`dydx` must contain only finite values)
    after numpy's overflow warning; the second gave infinite coefficients."""
    import warnings

    from delaytrack.references import SplineReference

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError, match=r"^values must change slowly enough .* overflows"):
            SplineReference([0.0, 1.0, 2.0, 3.0], values)


@pytest.mark.parametrize(
    ("amplitude", "frequency", "message"),
    [
        ([1.0], [1e200], r"^frequency gives coordinate 1 a bound on its acceleration"),
        ([1e308, 1e308], [1.0, 1.0], r"^amplitude gives coordinate 1 a bound on its position"),
    ],
)
def test_harmonics_beyond_the_doubles_are_refused_by_name(amplitude, frequency, message):
    """A frequency of 1e200 rad/s made q̈_d infinite: every run on the reference diverged, and
    nothing said why."""
    with pytest.raises(ValueError, match=message):
        SinusoidalReference([0.0], amplitude=[amplitude], frequency=[frequency])


def test_a_harmonic_of_zero_amplitude_may_have_any_frequency():
    reference = SinusoidalReference([0.0], amplitude=[[0.0, 0.5]], frequency=[[1e300, 1e150]])
    values = reference.evaluate(np.array([0.0, 0.5]))
    assert all(np.all(np.isfinite(v)) for v in values)
