"""Delay profiles h(t) and the compiled kernel behind them (docs/decisions.md D11, D12, D21).

Every reference value is an independent numpy formula written here, never a call back into the
code under test: the rectified sines of the paper's S1/S2 (Section III), a right-continuous step
function for the piecewise-constant profile, ``np.interp`` for traces, and closed-form kink and
extremum instants of ``t - h(t)`` for the breakpoint search the simulator relies on (it splits
each RK4 step at those instants: docs/decisions.md D12).
"""

from __future__ import annotations

import math
import types

import numpy as np
import pytest
import scipy.optimize

from delaytrack.delays import (
    DELAY_SPECS,
    AbsSineDelay,
    ConstantDelay,
    PiecewiseConstantDelay,
    RandomDelay,
    TraceDelay,
    delay_from_spec,
    random_delay,
)
from delaytrack.delays._kernel import (
    ABS_SINE,
    CONSTANT,
    PIECEWISE_CONSTANT,
    PIECEWISE_LINEAR,
    crossing_time,
    delay_value,
    next_breakpoint,
    piece_end_values,
    slope_bound,
)
from delaytrack.delays.random_delay import reflected_walk

TIMES = np.linspace(-3.0, 40.0, 4001)  # dense grid including negative times


def unpack_knots(params: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Split ``[m, t_0 .. t_{m-1}, h_0 .. h_{m-1}]`` (the layout in the _kernel docstring)."""
    m = int(params[0])
    return params[1 : 1 + m], params[1 + m : 1 + 2 * m]


def step_function(times: np.ndarray, values: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Right-continuous step function, ``values[0]`` before ``times[0]`` (class docstring)."""
    index = np.searchsorted(times, t, side="right") - 1
    return values[np.clip(index, 0, None)]


# --------------------------------------------------------------------------------------------
# h(t) against independent formulas
# --------------------------------------------------------------------------------------------


def test_s1_matches_paper_formula():
    # Roy & Kar, Section III: S1 h = 20 + 80 |sin t| ms.
    profile = AbsSineDelay.S1()
    expected = 0.020 + 0.080 * np.abs(np.sin(TIMES))
    np.testing.assert_allclose(profile.h(TIMES), expected, rtol=1e-15, atol=1e-17)
    assert profile.h_max == pytest.approx(0.100, abs=1e-15)


def test_s2_matches_paper_formula():
    # Roy & Kar, Section III: S2 h = 5 + 120 |sin 0.1 t| ms.
    profile = AbsSineDelay.S2()
    expected = 0.005 + 0.120 * np.abs(np.sin(0.1 * TIMES))
    np.testing.assert_allclose(profile.h(TIMES), expected, rtol=1e-15, atol=1e-17)
    assert profile.h_max == pytest.approx(0.125, abs=1e-15)


def test_abs_sine_with_phase_matches_formula():
    profile = AbsSineDelay(offset=0.01, amplitude=0.3, frequency=2.5, phase=0.7)
    expected = 0.01 + 0.3 * np.abs(np.sin(2.5 * TIMES + 0.7))
    np.testing.assert_allclose(profile.h(TIMES), expected, rtol=1e-14, atol=1e-17)


@pytest.mark.parametrize("name, value", [("S3", 0.060), ("S4", 0.120)])
def test_paper_constant_delays(name, value):
    # Roy & Kar, Section III: S3 60 ms, S4 120 ms.
    profile = DELAY_SPECS[name].build()
    assert isinstance(profile, ConstantDelay)
    np.testing.assert_array_equal(profile.h(TIMES), np.full(TIMES.shape, value))
    assert profile.h_max == value


def test_constant_delay_value_and_zero_allowed():
    np.testing.assert_array_equal(ConstantDelay(0.037).h(TIMES), 0.037)
    np.testing.assert_array_equal(ConstantDelay(0.0).h(TIMES), 0.0)


def test_piecewise_constant_right_continuous_and_held_before_first_knot():
    times = np.array([1.0, 2.0, 3.5, 7.0])
    values = np.array([0.05, 0.02, 0.11, 0.0])
    profile = PiecewiseConstantDelay(times, values)
    np.testing.assert_array_equal(profile.h(TIMES), step_function(times, values, TIMES))
    # Right-continuity at every knot and the value just before it (hand-written table).
    at_knots = profile.h(times)
    np.testing.assert_array_equal(at_knots, values)
    before = profile.h(times - 1e-12)
    np.testing.assert_array_equal(before, [0.05, 0.05, 0.02, 0.11])
    assert profile.h(-100.0) == 0.05  # values[0] before the first knot
    assert profile.h(1e6) == 0.0  # last value held


def test_trace_is_np_interp():
    rng = np.random.default_rng(3)
    times = np.cumsum(rng.uniform(0.05, 1.0, 30)) - 2.0
    values = rng.uniform(0.0, 0.2, 30)
    profile = TraceDelay(times, values)
    # np.interp holds the end values outside the knots, like the trace (class docstring).
    np.testing.assert_allclose(
        profile.h(TIMES), np.interp(TIMES, times, values), rtol=1e-13, atol=1e-16
    )
    np.testing.assert_array_equal(profile.h(times), values)


def test_h_keeps_the_shape_of_t():
    profile = AbsSineDelay.S1()
    t = np.arange(12.0).reshape(3, 4)
    assert profile.h(t).shape == (3, 4)
    assert np.shape(profile.h(0.5)) == ()
    np.testing.assert_allclose(profile.h([0.5, 1.0]), 0.02 + 0.08 * np.abs(np.sin([0.5, 1.0])))


def test_random_delay_stays_within_bounds_and_interpolates_its_knots():
    profile = RandomDelay(h_low=0.02, h_high=0.09, max_rate=0.5, duration=5.0, seed=11)
    knot_times, knot_values = unpack_knots(profile.params)
    assert knot_times[0] == 0.0 and knot_times[-1] >= 5.0
    np.testing.assert_allclose(np.diff(knot_times), 0.01, rtol=1e-9)  # default knot_spacing
    t = np.linspace(-1.0, 7.0, 20001)
    h = profile.h(t)
    assert np.all(h >= 0.02) and np.all(h <= 0.09)
    np.testing.assert_allclose(h, np.interp(t, knot_times, knot_values), rtol=1e-13, atol=1e-16)
    # Held after the duration.
    assert profile.h(100.0) == knot_values[-1]


# --------------------------------------------------------------------------------------------
# h_max
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "profile, attained_at",
    [
        # |sin(w t + phase)| = 1 at w t + phase = pi / 2.
        (AbsSineDelay.S1(), math.pi / 2),
        (AbsSineDelay.S2(), math.pi / 2 / 0.1),
        (AbsSineDelay(0.01, 0.3, 2.5, 0.7), (math.pi / 2 - 0.7) / 2.5),
        (ConstantDelay(0.06), 0.0),
        (PiecewiseConstantDelay([0.0, 1.0, 2.0], [0.02, 0.13, 0.05]), 1.5),
    ],
    ids=["S1", "S2", "abs-sine-phase", "constant", "piecewise"],
)
def test_h_max_bounds_and_is_attained(profile, attained_at):
    assert np.all(profile.h(TIMES) <= profile.h_max)
    assert profile.h(attained_at) == pytest.approx(profile.h_max, rel=1e-14)


@pytest.mark.parametrize(
    "profile",
    [
        TraceDelay([0.0, 1.0, 2.0, 4.0], [0.01, 0.2, 0.05, 0.1]),
        RandomDelay(0.0, 0.15, 2.0, 10.0, seed=5),
    ],
    ids=["trace", "random"],
)
def test_h_max_bounds_sampled_h(profile):
    assert np.all(profile.h(TIMES) <= profile.h_max)
    assert np.all(profile.h(TIMES) >= 0.0)


@pytest.mark.parametrize(
    ("profile", "h_min"),
    [
        (AbsSineDelay.S1(), 0.02),  # attained where sin = 0
        (ConstantDelay(0.06), 0.06),
        (PiecewiseConstantDelay([0.0, 1.0, 2.0], [0.02, 0.13, 0.05]), 0.02),
        (TraceDelay([0.0, 1.0, 2.0, 4.0], [0.01, 0.2, 0.05, 0.1]), 0.01),
        (RandomDelay(0.03, 0.15, 2.0, 10.0, seed=5), 0.03),
    ],
    ids=["S1", "constant", "piecewise", "trace", "random"],
)
def test_h_min_bounds_h_from_below(profile, h_min):
    """What a run no longer than ``h_min`` is told: no command reaches its plant."""
    assert profile.h_min == h_min
    assert np.all(profile.h(TIMES) >= h_min)


# --------------------------------------------------------------------------------------------
# RandomDelay
# --------------------------------------------------------------------------------------------


def test_random_delay_same_seed_identical_different_seed_differs():
    a = RandomDelay(0.01, 0.1, 0.8, 3.0, seed=42)
    b = RandomDelay(0.01, 0.1, 0.8, 3.0, seed=42)
    c = RandomDelay(0.01, 0.1, 0.8, 3.0, seed=43)
    np.testing.assert_array_equal(a.params, b.params)
    np.testing.assert_array_equal(a.h(TIMES), b.h(TIMES))
    assert not np.array_equal(a.params, c.params)
    assert np.any(a.h(TIMES) != c.h(TIMES))
    # numpy integer seeds are accepted and mean the same seed.
    np.testing.assert_array_equal(
        RandomDelay(0.01, 0.1, 0.8, 3.0, seed=np.int64(42)).params, a.params
    )


def test_a_random_walk_shows_its_knots_as_a_trace_does():
    walk = RandomDelay(0.01, 0.1, 0.8, 3.0, seed=42, knot_spacing=0.05)
    np.testing.assert_allclose(walk.times, np.arange(61) * 0.05)
    np.testing.assert_array_equal(walk.h(walk.times), walk.values)
    with pytest.raises(ValueError, match="read-only"):
        walk.values[0] = 1.0
    trace = TraceDelay(walk.times, walk.values)
    np.testing.assert_array_equal(trace.h(TIMES[TIMES <= 3.0]), walk.h(TIMES[TIMES <= 3.0]))


@pytest.mark.parametrize("max_rate", [0.3, 1.0, 3.0, 8.0])  # max_rate * spacing < h_high - h_low
def test_random_delay_rate_bound(max_rate):
    spacing = 0.02
    profile = RandomDelay(0.0, 0.2, max_rate, 4.0, seed=7, knot_spacing=spacing)
    knot_times, knot_values = unpack_knots(profile.params)
    slopes = np.diff(knot_values) / np.diff(knot_times)
    assert np.max(np.abs(slopes)) <= max_rate * (1 + 1e-9)
    assert np.all(knot_values >= 0.0) and np.all(knot_values <= 0.2)
    # The rate bound is used in both directions, not silently clamped to 1 (docs/decisions.md
    # D11 allows dh/dt < -1): with ~200 uniform slope draws some come within a factor 2 of
    # +-max_rate.
    assert np.max(slopes) > 0.5 * max_rate
    assert np.min(slopes) < -0.5 * max_rate


def test_random_delay_slopes_uniform_in_rate_bound():
    # Class docstring: each slope is uniform in [-max_rate, max_rate]. With a step of at most
    # 3 * 0.002 = 0.006 s against a 0.2 s band, reflections are rare, so about 1/3 of the 2000
    # slopes exceed +1 and about 1/3 are below -1 (P(U(-3, 3) > 1) = 1/3). Fixed seed: no flakes.
    profile = RandomDelay(0.0, 0.2, 3.0, 4.0, seed=3, knot_spacing=0.002)
    knot_times, knot_values = unpack_knots(profile.params)
    slopes = np.diff(knot_values) / np.diff(knot_times)
    assert slopes.size == 2000
    assert 0.28 < np.mean(slopes > 1.0) < 0.39
    assert 0.28 < np.mean(slopes < -1.0) < 0.39


def test_random_delay_zero_width_and_zero_rate():
    flat = RandomDelay(0.05, 0.05, 2.0, 1.0, seed=0)
    np.testing.assert_array_equal(flat.h(TIMES), 0.05)
    still = RandomDelay(0.0, 0.1, 0.0, 1.0, seed=0)
    assert np.ptp(still.h(TIMES)) == 0.0


# --------------------------------------------------------------------------------------------
# Kernel: breakpoints and crossings
# --------------------------------------------------------------------------------------------


def walk_breakpoints(profile, t0: float, t1: float) -> np.ndarray:
    """All breakpoints in (t0, t1] by repeated next_breakpoint calls."""
    points = []
    t = t0
    while True:
        t_next = next_breakpoint(profile.kind, profile.params, t)
        assert t_next > t  # strictly after t
        if t_next > t1:
            return np.array(points)
        points.append(t_next)
        t = t_next


def abs_sine_breakpoints(offset, amplitude, omega, phase, t0, t1):
    """Independent: zeros of sin(omega t + phase), and where dh/dt = 1 if amplitude*omega > 1.

    On theta in [k pi, (k+1) pi), h = offset + amplitude sin(theta - k pi), so
    dh/dt = amplitude omega cos(theta - k pi) = 1 at theta = k pi + arccos(1/(amplitude omega)).
    """
    k = np.arange(
        math.floor((omega * t0 + phase) / math.pi) - 1, (omega * t1 + phase) / math.pi + 2
    )
    theta = list(k * math.pi)
    if amplitude * omega > 1:
        theta += list(k * math.pi + math.acos(1 / (amplitude * omega)))
    t = (np.array(theta) - phase) / omega
    return np.sort(t[(t > t0) & (t <= t1)])


ABS_SINE_CASES = [
    (0.020, 0.080, 1.0, 0.0),  # S1: amplitude*omega = 0.08
    (0.005, 0.120, 0.1, 0.0),  # S2
    (0.05, 0.3, 5.0, 0.7),  # amplitude*omega = 1.5 > 1
    (0.0, 1.0, 3.0, -2.0),  # amplitude*omega = 3
]


@pytest.mark.parametrize("case", ABS_SINE_CASES)
def test_next_breakpoint_abs_sine_matches_closed_form(case):
    profile = AbsSineDelay(*case)
    t0, t1 = -1.3, 12.0 if case[2] >= 1 else 80.0
    got = walk_breakpoints(profile, t0, t1)
    expected = abs_sine_breakpoints(*case, t0, t1)
    assert got.shape == expected.shape
    np.testing.assert_allclose(got, expected, rtol=1e-13, atol=1e-13)
    if case[1] * case[2] > 1:
        # Half the breakpoints are where dh/dt = 1 (central difference, h smooth there).
        extrema = expected[np.abs(np.sin(case[2] * expected + case[3])) > 1e-6]
        assert extrema.size > 0
        step = 1e-7
        rate = (profile.h(extrema + step) - profile.h(extrema - step)) / (2 * step)
        np.testing.assert_allclose(rate, 1.0, atol=1e-6)


def test_next_breakpoint_is_strictly_after_t_at_a_breakpoint():
    profile = AbsSineDelay(0.05, 0.3, 5.0, 0.7)
    zero = (2 * math.pi - 0.7) / 5.0  # a kink: sin(5 t + 0.7) = 0
    assert next_breakpoint(profile.kind, profile.params, zero) > zero
    assert next_breakpoint(profile.kind, profile.params, zero) == pytest.approx(
        (2 * math.pi + math.acos(1 / 1.5) - 0.7) / 5.0, rel=1e-14
    )


def test_next_breakpoint_knots_and_constant():
    assert next_breakpoint(CONSTANT, np.array([0.1]), 3.0) == math.inf
    times = [1.0, 2.0, 3.5]
    for cls in (PiecewiseConstantDelay, TraceDelay):
        profile = cls(times, [0.1, 0.2, 0.0])
        assert profile.kind == (
            PIECEWISE_CONSTANT if cls is PiecewiseConstantDelay else PIECEWISE_LINEAR
        )
        assert next_breakpoint(profile.kind, profile.params, -5.0) == 1.0  # before the first knot
        assert next_breakpoint(profile.kind, profile.params, 1.0) == 2.0  # strictly after a knot
        assert next_breakpoint(profile.kind, profile.params, 1.7) == 2.0
        assert next_breakpoint(profile.kind, profile.params, 2.0) == 3.5
        assert next_breakpoint(profile.kind, profile.params, 3.5) == math.inf
        assert next_breakpoint(profile.kind, profile.params, 9.0) == math.inf


MONOTONE_CASES = [
    (AbsSineDelay.S1(), -1.0, 10.0),
    (AbsSineDelay.S2(), 0.0, 70.0),
    (AbsSineDelay(0.05, 0.3, 5.0, 0.7), -0.5, 6.0),
    (AbsSineDelay(0.0, 1.0, 3.0, -2.0), 0.0, 6.0),
    (TraceDelay([0.0, 0.5, 0.6, 1.0, 1.2], [0.0, 0.1, 0.4, 0.05, 0.5]), -0.5, 2.0),
    (RandomDelay(0.0, 0.2, 3.0, 1.0, seed=1, knot_spacing=0.02), -0.1, 1.5),
    (PiecewiseConstantDelay([0.1, 0.4, 0.45], [0.3, 0.0, 0.2]), -0.5, 1.0),
]


@pytest.mark.parametrize("profile, t0, t1", MONOTONE_CASES)
def test_t_minus_h_is_monotone_between_breakpoints(profile, t0, t1):
    edges = np.concatenate(([t0], walk_breakpoints(profile, t0, t1), [t1]))
    directions = set()
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        t = np.linspace(a, b, 402)[1:-1]  # open piece
        dg = np.diff(t - profile.h(t))
        tol = 1e-13
        increasing, decreasing = np.all(dg >= -tol), np.all(dg <= tol)
        assert increasing or decreasing, f"t - h(t) not monotone on ({a}, {b})"
        directions.add("up" if increasing else "down")
    # Profiles that can shrink faster than time passes must show a decreasing piece, else the
    # test would not exercise the dh/dt = 1 breakpoints.
    # (The trace and random cases here have segments with slope > 1.)
    fast_sine = isinstance(profile, AbsSineDelay) and profile.amplitude * profile.frequency > 1
    if fast_sine or isinstance(profile, TraceDelay | RandomDelay):
        assert directions == {"up", "down"}


def pieces(profile, t0, t1):
    edges = np.concatenate(([t0], walk_breakpoints(profile, t0, t1), [t1]))
    return list(zip(edges[:-1], edges[1:], strict=True))


@pytest.mark.parametrize(
    "profile, t0, t1",
    [
        (AbsSineDelay(0.05, 0.3, 5.0, 0.7), 0.0, 4.0),  # amplitude*omega = 1.5: g up and down
        (AbsSineDelay(0.0, 1.0, 3.0, -2.0), 0.0, 4.0),
        (AbsSineDelay.S1(), 0.0, 7.0),
    ],
)
def test_crossing_time_abs_sine(profile, t0, t1):
    directions = set()
    for a, b in pieces(profile, t0, t1):
        h_a, h_b = piece_end_values(profile.kind, profile.params, a, b)
        g_a, g_b = a - h_a, b - h_b
        directions.add(g_b > g_a)

        def g(t):
            return t - (
                profile.offset
                + profile.amplitude * abs(math.sin(profile.frequency * t + profile.phase))
            )

        for fraction in (1e-6, 0.1, 0.5, 0.9, 1 - 1e-6):
            target = g_a + fraction * (g_b - g_a)
            root = crossing_time(profile.kind, profile.params, a, b, g_a, g_b, target)
            assert a <= root <= b
            # The crossing instant is solved (docs/decisions.md D12), to ~1e-14 in g.
            assert abs(g(root) - target) <= 1e-14 * max(1.0, abs(target))
            # Independent bracketing oracle.
            reference = scipy.optimize.brentq(
                lambda t, c=target: g(t) - c, a, b, xtol=1e-16, rtol=8.9e-16
            )
            assert root == pytest.approx(reference, abs=1e-12)
    if profile.amplitude * profile.frequency > 1:
        assert directions == {True, False}  # increasing and decreasing g both solved


@pytest.mark.parametrize(
    "profile",
    [
        TraceDelay([0.0, 0.5, 0.6, 1.0, 1.2], [0.0, 0.1, 0.4, 0.05, 0.5]),
        RandomDelay(0.0, 0.2, 3.0, 1.0, seed=1, knot_spacing=0.02),
        PiecewiseConstantDelay([0.1, 0.4, 0.45], [0.3, 0.0, 0.2]),
    ],
    ids=["trace", "random", "piecewise-constant"],
)
def test_crossing_time_linear_pieces(profile):
    knot_times, knot_values = unpack_knots(profile.params)
    directions = set()
    for a, b in pieces(profile, knot_times[0], knot_times[-1]):
        # Independent end values: the linear interpolant, or the constant value on [a, b).
        if profile.kind == PIECEWISE_LINEAR:
            h_a, h_b = np.interp([a, b], knot_times, knot_values)
        else:
            h_a = h_b = step_function(knot_times, knot_values, np.array([a]))[0]
        g_a, g_b = a - h_a, b - h_b
        if g_a == g_b:
            continue
        directions.add(g_b > g_a)
        for fraction in (0.0, 0.25, 0.5, 1.0):
            target = g_a + fraction * (g_b - g_a)
            root = crossing_time(profile.kind, profile.params, a, b, g_a, g_b, target)
            assert a <= root <= b
            # g is linear on the piece: g(t) = g_a + (g_b - g_a) (t - a) / (b - a).
            g_root = g_a + (g_b - g_a) * (root - a) / (b - a)
            assert abs(g_root - target) <= 1e-14 * max(1.0, abs(target))
            if 0.0 < fraction < 1.0:  # and it is the profile's own g inside the piece
                assert abs(root - float(profile.h(root)) - target) <= 1e-14
    expected = {True} if profile.kind == PIECEWISE_CONSTANT else {True, False}
    assert directions == expected


def test_crossing_time_of_a_zero_amplitude_is_the_constant_delays_own():
    """|sin| with amplitude 0 is a constant delay: its crossings are the constant delay's, bit for
    bit, also where a crossing lies at an end of the step (where a constant delay that is a
    multiple of the step puts every crossing, and bracketed Newton steps had halved the bracket
    to the last bit, the run then three times as slow)."""
    flat, constant = AbsSineDelay(0.05, 0.0, 1.0), ConstantDelay(0.05)
    a, b = 0.073, 0.074  # one step of 1 ms
    g_a, g_b = a - 0.05, b - 0.05
    for target in (g_a, np.nextafter(g_a, 1.0), g_a + 0.3e-3, np.nextafter(g_b, 0.0), g_b):
        root = crossing_time(flat.kind, flat.params, a, b, g_a, g_b, target)
        assert root == crossing_time(constant.kind, constant.params, a, b, g_a, g_b, target)
        # g(root) = target to the rounding of t near 0.073 (its last bit is 1.4e-17: half of
        # it, and the subtraction's rounding)
        assert abs(root - 0.05 - target) <= 1e-17


def test_crossing_time_flat_piece_returns_start():
    # h(t) = t on [0, 1] makes g = t - h identically 0: any point solves it; the start is returned.
    profile = TraceDelay([0.0, 1.0], [0.0, 1.0])
    assert crossing_time(profile.kind, profile.params, 0.0, 1.0, 0.0, 0.0, 0.0) == 0.0


def test_delay_value_scalar_kernel_matches_profiles():
    profile = AbsSineDelay(0.05, 0.3, 5.0, 0.7)
    assert delay_value(ABS_SINE, profile.params, 1.23) == 0.05 + 0.3 * abs(
        math.sin(5.0 * 1.23 + 0.7)
    )


# --------------------------------------------------------------------------------------------
# Validation messages
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "build, message",
    [
        (lambda: ConstantDelay(-0.01), r"value must be >= 0; got -0\.01"),
        (lambda: ConstantDelay(float("nan")), r"value must be finite; got nan"),
        (lambda: ConstantDelay(float("inf")), r"value must be finite"),
        (lambda: AbsSineDelay(-0.02, 0.08, 1.0), r"offset must be >= 0; got -0\.02"),
        (lambda: AbsSineDelay(0.02, -0.08, 1.0), r"amplitude must be >= 0; got -0\.08"),
        (lambda: AbsSineDelay(0.02, 0.08, 0.0), r"frequency must be > 0; got 0"),
        (lambda: AbsSineDelay(0.02, 0.08, -1.0), r"frequency must be > 0; got -1"),
        (lambda: AbsSineDelay(0.02, 0.08, 1.0, float("nan")), r"phase must be finite"),
        (
            lambda: AbsSineDelay(1e308, 1e308, 1.0),
            r"amplitude \+ offset must be a finite delay; got 1e\+308 \+ 1e\+308 s",
        ),
        (
            lambda: TraceDelay([0.0, 1.0, 0.5, 2.0], [0.1] * 4),
            r"strictly increasing; times\[1\] = 1 is followed by times\[2\] = 0\.5",
        ),
        (
            lambda: TraceDelay([0.0, 1.0, 1.0], [0.1] * 3),
            r"strictly increasing; times\[1\] = 1 is followed by times\[2\] = 1",
        ),
        (
            lambda: PiecewiseConstantDelay([0.0, 1.0, 1.0], [0.1] * 3),
            r"times\[1\] = 1 is followed by times\[2\] = 1",
        ),
        (lambda: TraceDelay([0.0, 1.0, 2.0], [0.1, 0.0, -0.01]), r"values\[2\] = -0\.01 at t = 2"),
        (lambda: PiecewiseConstantDelay([0.0, 1.0], [-0.5, 0.1]), r"values\[0\] = -0\.5 at t = 0"),
        (
            lambda: TraceDelay([0.0, 1.0, 2.0], [0.1, 0.2]),
            r"one entry per time; got 2 values for 3 times",
        ),
        (lambda: TraceDelay([], []), r"at least one knot"),
        (
            lambda: TraceDelay([0.0, float("nan")], [0.1, 0.1]),
            r"times must be finite; times\[1\] is nan",
        ),
        (lambda: TraceDelay([[0.0, 1.0]], [[0.1, 0.1]]), r"times must be 1-dimensional"),
        (lambda: RandomDelay(0.1, 0.05, 1.0, 1.0, seed=0), r"h_low = 0\.1, h_high = 0\.05"),
        (lambda: RandomDelay(-0.1, 0.05, 1.0, 1.0, seed=0), r"h_low must be >= 0; got -0\.1"),
        (lambda: RandomDelay(0.0, 0.05, -1.0, 1.0, seed=0), r"max_rate must be >= 0; got -1"),
        (lambda: RandomDelay(0.0, 0.05, 1.0, 0.0, seed=0), r"duration must be > 0; got 0"),
        (
            lambda: RandomDelay(0.0, 0.05, 1.0, 1.0, seed=0, knot_spacing=0.0),
            r"knot_spacing must be > 0",
        ),
        (
            lambda: RandomDelay(0.0, 0.05, 1.0, 1.0, seed=-1),
            r"seed must be a non-negative integer; got -1",
        ),
        (lambda: RandomDelay(0.0, 0.05, 1.0, 1.0, seed=1.5), r"non-negative integer; got 1\.5"),
        (lambda: RandomDelay(0.0, 0.05, 1.0, 1.0, seed="7"), r"non-negative integer; got '7'"),
    ],
)
def test_refused_profiles(build, message):
    with pytest.raises(ValueError, match=message):
        build()


def test_non_numeric_delay_is_a_type_error():
    with pytest.raises(TypeError, match=r"phase must be a real number; got '0.1'"):
        AbsSineDelay(0.02, 0.08, 1.0, "0.1")  # was read as 0.1, unlike every other argument
    with pytest.raises(TypeError, match=r"value must be a real number; got 'abc'"):
        ConstantDelay("abc")


# --------------------------------------------------------------------------------------------
# delay_from_spec
# --------------------------------------------------------------------------------------------

VALID_TYPES = [
    "S1",
    "S2",
    "S3",
    "S4",
    "abs-sine",
    "constant",
    "piecewise-constant",
    "random",
    "trace",
]


def test_delay_from_spec_unknown_type_lists_valid_types():
    with pytest.raises(ValueError, match=r"'delay\.type' must be one of .*; got 'sine'") as info:
        delay_from_spec({"type": "sine"})
    assert str(VALID_TYPES) in str(info.value)
    with pytest.raises(ValueError, match=r"'delay\.type' is missing; \[delay\] needs a type"):
        delay_from_spec({"h": 0.1})


def test_delay_from_spec_unknown_key_names_it():
    with pytest.raises(ValueError, match=r"unknown key 'delay\.amp'") as info:
        delay_from_spec({"type": "abs-sine", "offset": 0.0, "amp": 0.1, "frequency": 1.0})
    assert "are ['type', 'amplitude', 'frequency', 'offset', 'phase']" in str(info.value)
    with pytest.raises(ValueError, match=r"unknown key 'delay\.value' .* type = 'constant'"):
        delay_from_spec({"type": "constant", "value": 0.1})


@pytest.mark.parametrize(
    "name, expected",
    [
        ("S1", lambda t: 0.020 + 0.080 * np.abs(np.sin(t))),
        ("S2", lambda t: 0.005 + 0.120 * np.abs(np.sin(0.1 * t))),
        ("S3", lambda t: np.full_like(t, 0.060)),
        ("S4", lambda t: np.full_like(t, 0.120)),
    ],
)
def test_delay_from_spec_paper_names(name, expected):
    profile = delay_from_spec({"type": name})
    np.testing.assert_allclose(profile.h(TIMES), expected(TIMES), rtol=1e-15, atol=1e-17)


@pytest.mark.parametrize("name", ["S1", "S3"])
def test_delay_from_spec_paper_name_with_parameters_refused(name):
    with pytest.raises(
        ValueError, match=rf"unknown key 'delay\.phase' .* type = '{name}' are \['type'\]"
    ):
        delay_from_spec({"type": name, "phase": 0.3})


@pytest.mark.parametrize(
    "profile",
    [
        ConstantDelay(0.07),
        AbsSineDelay(0.01, 0.2, 3.0, 0.4),
        PiecewiseConstantDelay([0.0, 1.0], [0.1, 0.2]),
        TraceDelay([0.0, 1.0, 3.0], [0.1, 0.2, 0.0]),
        RandomDelay(0.01, 0.1, 2.0, 2.0, seed=9, knot_spacing=0.05),
    ],
    ids=lambda p: type(p).__name__,
)
def test_spec_round_trip(profile):
    rebuilt = delay_from_spec(profile.to_spec())
    assert type(rebuilt) is type(profile)
    np.testing.assert_array_equal(rebuilt.params, profile.params)
    assert rebuilt.to_spec()["type"] in DELAY_SPECS


def test_delay_from_spec_trace_needs_path_or_knots_not_both(tmp_path):
    path = tmp_path / "h.csv"
    path.write_text("0,0.1\n1,0.2\n")
    with pytest.raises(ValueError, match=r"either 'path' or 'times' and 'values', not both"):
        delay_from_spec({"type": "trace", "path": str(path), "times": [0.0], "values": [0.1]})
    profile = delay_from_spec({"type": "trace", "path": str(path)})
    np.testing.assert_allclose(profile.h([0.5]), [0.15], rtol=1e-15)


# --------------------------------------------------------------------------------------------
# TraceDelay.from_csv
# --------------------------------------------------------------------------------------------


def test_from_csv_with_and_without_header(tmp_path):
    rows = "0.0,0.10\n0.5,0.02\n2.0,0.30\n"
    plain = tmp_path / "plain.csv"
    plain.write_text(rows)
    headed = tmp_path / "headed.csv"
    headed.write_text("t,h\n" + rows + "\n")  # a trailing empty line is ignored
    times, values = np.array([0.0, 0.5, 2.0]), np.array([0.10, 0.02, 0.30])
    for path in (plain, headed):
        profile = TraceDelay.from_csv(path)
        np.testing.assert_array_equal(profile.times, times)
        np.testing.assert_array_equal(profile.values, values)
        np.testing.assert_allclose(profile.h(TIMES), np.interp(TIMES, times, values), rtol=1e-13)
        assert profile.source == str(path)
        assert profile.to_spec() == {"type": "trace", "path": str(path)}


def test_from_csv_missing_file(tmp_path):
    path = tmp_path / "nope.csv"
    with pytest.raises(FileNotFoundError, match="nope.csv"):
        TraceDelay.from_csv(path)


def test_from_csv_non_numeric_row(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("t,h\n0,0.1\n1,abc\n")
    with pytest.raises(ValueError, match=r"bad\.csv: line 3, column 'h' must be a number"):
        TraceDelay.from_csv(path)


def test_from_csv_wrong_column_count(tmp_path):
    path = tmp_path / "cols.csv"
    path.write_text("0,0.1,7\n1,0.2\n")
    with pytest.raises(ValueError, match=r"cols\.csv: line 1 must have 2 columns \(t, h\)"):
        TraceDelay.from_csv(path)


def test_from_csv_non_monotone_times_names_the_file(tmp_path):
    path = tmp_path / "order.csv"
    path.write_text("0,0.1\n2,0.1\n1,0.1\n")
    with pytest.raises(ValueError, match=r"order\.csv: times must be strictly increasing") as info:
        TraceDelay.from_csv(path)
    assert str(path) in str(info.value)
    assert "times[1] = 2 is followed by times[2] = 1" in str(info.value)


def test_delay_from_spec_missing_key_names_the_scenario_key():
    # A scenario file says [delay] type = "constant", h = ...; forgetting h should say so.
    with pytest.raises(ValueError, match=r"'h'"):
        delay_from_spec({"type": "constant"})


def test_random_delay_in_a_very_narrow_band_reflects_in_closed_form():
    # A band of 1e-9 s with slope steps of up to 0.01 s needs ~1e7 reflections per knot if done
    # one at a time; the closed-form fold keeps construction instant and the walk in the band.
    profile = RandomDelay(0.05, 0.05 + 1e-9, 1.0, 1.0, seed=1)
    values = profile.h(np.linspace(0.0, 1.0, 1001))
    assert np.all((values >= 0.05) & (values <= 0.05 + 1e-9))


@pytest.mark.parametrize(
    "low, high, rate, spacing",
    [
        (0.01, 0.12, 0.2, 0.01),  # the example sweep's walk
        (0.05, 0.05 + 1e-9, 1.0, 1e-3),  # folded at almost every knot
        (0.0, 5e-324, 3.0, 0.1),  # the narrowest band there is
        (0.02, 0.02, 1.0, 0.01),  # no band: every value is h_low
        (1e-300, 1e300, 1e300, 7.0),  # steps of 1e301
    ],
)
def test_a_walk_drawn_compiled_has_the_knots_plain_python_draws(low, high, rate, spacing):
    # Walks of more than PYTHON_KNOTS knots are drawn compiled: the same doubles as the plain
    # Python loop, fold for fold.
    rng = np.random.default_rng(7)
    steps = rng.uniform(-rate, rate, size=20_000) * spacing
    compiled, python = (np.empty(steps.size + 1) for _ in range(2))
    compiled[0] = python[0] = rng.uniform(low, high)
    reflected_walk(compiled, steps, low, high)
    reflected_walk.py_func(python, steps, low, high)
    np.testing.assert_array_equal(compiled, python)
    assert np.all((compiled >= low) & (compiled <= high))


def test_a_walk_of_more_knots_than_python_draws_is_the_same_walk(monkeypatch):
    def walk() -> np.ndarray:
        return RandomDelay(0.01, 0.12, 0.5, 30.0, seed=9, knot_spacing=1e-3).params

    # Drawn in plain Python: a stand-in for the kernel that cannot be called compiled.
    python_only = types.SimpleNamespace(signatures=[], py_func=reflected_walk.py_func)
    with monkeypatch.context() as patch:
        patch.setattr(random_delay, "reflected_walk", python_only)
        drawn_in_python = walk()
    # More knots than PYTHON_KNOTS: drawn compiled.
    monkeypatch.setattr(random_delay, "PYTHON_KNOTS", 100)
    np.testing.assert_array_equal(walk(), drawn_in_python)
    assert reflected_walk.signatures


def test_a_number_given_as_text_or_bool_is_refused():
    # float("0.06") and float(True) would succeed: a string or a bool for a delay is a mistake.
    with pytest.raises(TypeError, match=r"value must be a real number; got '0\.06'"):
        ConstantDelay("0.06")
    with pytest.raises(TypeError, match=r"frequency must be a real number; got True"):
        AbsSineDelay(0.01, 0.02, True)


@pytest.mark.parametrize(
    "profile",
    [
        ConstantDelay(0.04),
        AbsSineDelay.S1(),
        AbsSineDelay(0.05, 0.3, 5.0, 0.7),  # A ω = 1.5
        PiecewiseConstantDelay([0.0, 0.5, 0.9], [0.03, 0.011, 0.07]),
        RandomDelay(0.01, 0.12, 2.0, 5.0, seed=4),
    ],
    ids=["constant", "S1", "fast-sine", "piecewise-constant", "random-walk"],
)
def test_slope_bound_bounds_the_slope_of_h_on_every_piece(profile) -> None:
    # The simulator skips evaluating h over steps where g = t - h cannot reach a tick; that is
    # exact only if |h(s) - h(t)| <= L |s - t| for s, t in one piece.
    t = -0.5
    checked = 0
    while t < 5.0:
        end = min(next_breakpoint(profile.kind, profile.params, t), 5.0)
        bound = slope_bound(profile.kind, profile.params, t)
        inside = np.linspace(t, end, 202)[1:-1]  # h jumps at a piecewise-constant breakpoint
        values = np.array([delay_value(profile.kind, profile.params, s) for s in inside])
        slopes = np.abs(np.diff(values)) / np.diff(inside)
        assert np.all(slopes <= bound * (1 + 1e-9) + 1e-12), (t, end, slopes.max(), bound)
        checked += 1
        t = end
    assert checked >= (1 if isinstance(profile, ConstantDelay) else 2)
    if isinstance(profile, RandomDelay):  # the bound is the piece's own slope, not a global one
        assert slope_bound(profile.kind, profile.params, 1.0) > 0.0
