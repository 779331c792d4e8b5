"""python-control views of the nominal error loop: margins, Padé closed loops, exact-delay FRD,
the sampled loop with a delayed zero-order hold, and bad input."""

from __future__ import annotations

import math

import control
import matplotlib
import numpy as np
import pytest
import scipy.optimize

from delaytrack.analysis import (
    error_loop,
    error_loop_frequency_response,
    error_loop_sampled,
    exact_delay_margin,
)

# K1 = K2 = I: omega_c^2 = (1 + sqrt 5) / 2 and h = atan(omega_c) / omega_c.
IDENTITY_MARGIN = 0.711118648715793

SCALAR_GAINS = [(1.0, 1.0), (4.0, 0.5), (0.2, 3.0), (100.0, 20.0), (2.5, 0.01), (1e-3, 1e-2)]

DENSE_K1 = np.array([[2.0, 0.6], [0.6, 1.0]])
DENSE_K2 = np.array([[1.5, -0.4], [-0.4, 0.8]])


def delay_margin_from_control(system) -> tuple[float, float]:
    """(PM / omega_c, omega_c) of a SISO loop by control.margin, PM in radians."""
    _, phase_margin_deg, _, crossover = control.margin(system)
    return math.radians(float(phase_margin_deg)) / float(crossover), float(crossover)


def largest_real_part(loop, n: int) -> float:
    return float(np.max(control.feedback(loop, np.eye(n)).poles().real))


def largest_modulus(loop, n: int) -> float:
    return float(np.max(np.abs(control.feedback(loop, np.eye(n)).poles())))


# --- the delay-free loop and control.margin ---------------------------------------------------


def test_identity_gains_reference_values():
    loop = error_loop(1.0, 1.0)
    assert loop.isctime() and (loop.ninputs, loop.noutputs, loop.nstates) == (1, 1, 2)
    h, omega = delay_margin_from_control(loop)
    assert h == pytest.approx(IDENTITY_MARGIN, rel=1e-12)
    assert omega == pytest.approx(math.sqrt((1.0 + math.sqrt(5.0)) / 2.0), rel=1e-12)
    assert exact_delay_margin(np.eye(1), np.eye(1)).h == pytest.approx(h, rel=1e-12)


@pytest.mark.parametrize(("k1", "k2"), SCALAR_GAINS)
def test_margin_of_scalar_loop_is_the_exact_delay_margin(k1, k2):
    h, omega = delay_margin_from_control(error_loop(k1, k2))
    exact = exact_delay_margin(k1, k2)
    assert h == pytest.approx(exact.h, rel=1e-6)
    assert omega == pytest.approx(exact.omega, rel=1e-6)


@pytest.mark.parametrize("k", [0.5, 7.0])
def test_loop_transfer_function_is_k2_s_plus_k1_over_s_squared(k):
    tf = control.ss2tf(error_loop(k, 2.0 * k))
    numerator, denominator = np.squeeze(tf.num[0][0]), np.squeeze(tf.den[0][0])
    scale = denominator[0]
    np.testing.assert_allclose(denominator / scale, [1.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(np.trim_zeros(numerator / scale, "f"), [2.0 * k, k], rtol=1e-12)


def test_diagonal_gains_smallest_channel_margin_is_the_exact_margin():
    k1, k2 = np.array([1.0, 4.0, 0.3]), np.array([1.0, 0.5, 2.0])
    loop = error_loop(k1, k2)
    assert (loop.ninputs, loop.noutputs, loop.nstates) == (3, 3, 6)
    response = loop(2.0j)
    np.testing.assert_allclose(response - np.diag(np.diag(response)), 0.0, atol=1e-15)
    # An indexed channel keeps the other channels' (uncontrollable) states: reduce it first.
    channels = [delay_margin_from_control(control.ss2tf(loop[i, i]).minreal())[0] for i in range(3)]
    expected = [exact_delay_margin(a, b).h for a, b in zip(k1, k2, strict=True)]
    np.testing.assert_allclose(channels, expected, rtol=1e-6)
    assert min(channels) == pytest.approx(exact_delay_margin(np.diag(k1), np.diag(k2)).h, rel=1e-6)
    assert int(np.argmin(channels)) == 1
    exact = exact_delay_margin(np.diag(k1), np.diag(k2))
    omega = np.geomspace(exact.omega / 100.0, exact.omega * 100.0, 4001)
    response = error_loop_frequency_response(k1, k2, omega)
    from_frd = [delay_margin_from_control(response[i, i])[0] for i in range(3)]
    np.testing.assert_allclose(from_frd, expected, rtol=1e-6)


def test_scalar_gain_with_n_is_k_times_identity():
    loop = error_loop(2.0, 3.0, n=2)
    np.testing.assert_allclose(loop.C, [[2.0, 0.0, 3.0, 0.0], [0.0, 2.0, 0.0, 3.0]])


# --- the Padé closed loop ---------------------------------------------------------------------


@pytest.mark.parametrize("pade_order", [3, 4, 5])
@pytest.mark.parametrize(
    ("K1", "K2"),
    [(1.0, 1.0), (4.0, 0.5), (0.2, 3.0), (DENSE_K1, DENSE_K2)],
    ids=["identity", "fast", "slow", "dense-2x2"],
)
def test_pade_closed_loop_is_stable_below_the_margin_and_unstable_above(K1, K2, pade_order):
    n = np.shape(K1)[0] if np.ndim(K1) else 1
    h = exact_delay_margin(K1, K2).h
    below = error_loop(K1, K2, delay=0.97 * h, pade_order=pade_order)
    above = error_loop(K1, K2, delay=1.03 * h, pade_order=pade_order)
    assert below.nstates == above.nstates == n * (2 + pade_order)
    assert largest_real_part(below, n) < 0.0
    assert largest_real_part(above, n) > 0.0


@pytest.mark.parametrize(("pade_order", "rtol"), [(3, 2e-4), (4, 2e-6), (5, 2e-8)])
@pytest.mark.parametrize(("k1", "k2"), [(1.0, 1.0), (4.0, 0.5), (0.2, 3.0)])
def test_pade_stability_boundary_converges_to_the_exact_margin(k1, k2, pade_order, rtol):
    exact = exact_delay_margin(k1, k2).h
    boundary = scipy.optimize.brentq(
        lambda h: largest_real_part(error_loop(k1, k2, delay=h, pade_order=pade_order), 1),
        0.5 * exact,
        1.5 * exact,
        xtol=1e-14,
    )
    assert boundary == pytest.approx(exact, rel=rtol)


def test_pade_with_zero_delay_is_the_delay_free_loop():
    loop = error_loop(DENSE_K1, DENSE_K2, delay=0.0, pade_order=3)
    reference = error_loop(DENSE_K1, DENSE_K2)
    for s in (0.3j, 1.0 + 2.0j):
        np.testing.assert_allclose(loop(s), reference(s), rtol=1e-12)


def test_pade_loop_approximates_the_delayed_frequency_response():
    h, omega = 0.2, np.array([0.5, 1.0, 2.0])
    loop = error_loop(DENSE_K1, DENSE_K2, delay=h, pade_order=5)
    exact = error_loop_frequency_response(DENSE_K1, DENSE_K2, omega, delay=h)
    for k, w in enumerate(omega):
        np.testing.assert_allclose(loop(1j * w), exact.frdata[:, :, k], rtol=1e-7)


# --- the frequency response with the exact delay ----------------------------------------------


@pytest.mark.parametrize(("k1", "k2", "h"), [(1.0, 1.0, 0.0), (4.0, 0.5, 0.1), (0.2, 3.0, 2.0)])
def test_frd_magnitude_and_phase_follow_the_formula(k1, k2, h):
    omega = np.array([0.1, 0.7, 1.0, 3.0, 40.0])
    response = error_loop_frequency_response(k1, k2, omega, delay=h)
    assert isinstance(response, control.FrequencyResponseData)
    np.testing.assert_array_equal(response.omega, omega)
    values = response.frdata[0, 0]
    np.testing.assert_allclose(np.abs(values), np.hypot(k1, omega * k2) / omega**2, rtol=1e-13)
    # arg L = atan2(omega k2, k1) - pi - omega h, modulo 2 pi
    expected_phase = np.arctan2(omega * k2, k1) - np.pi - omega * h
    np.testing.assert_allclose(np.exp(1j * (np.angle(values) - expected_phase)), 1.0, atol=1e-12)


def test_frd_of_matrix_gains_is_the_state_space_loop_times_the_delay():
    h, omega = 0.3, np.geomspace(0.05, 50.0, 7)
    response = error_loop_frequency_response(DENSE_K1, DENSE_K2, omega, delay=h)
    assert response.frdata.shape == (2, 2, 7)
    loop = error_loop(DENSE_K1, DENSE_K2)
    for k, w in enumerate(omega):
        np.testing.assert_allclose(
            response.frdata[:, :, k], loop(1j * w) * np.exp(-1j * w * h), rtol=1e-12
        )


def test_frd_at_the_exact_margin_puts_a_closed_loop_root_on_the_axis():
    margin = exact_delay_margin(DENSE_K1, DENSE_K2)
    at = error_loop_frequency_response(DENSE_K1, DENSE_K2, [margin.omega], delay=margin.h)
    assert abs(np.linalg.det(np.eye(2) + at.frdata[:, :, 0])) < 1e-9
    off = error_loop_frequency_response(DENSE_K1, DENSE_K2, [margin.omega], delay=0.9 * margin.h)
    assert abs(np.linalg.det(np.eye(2) + off.frdata[:, :, 0])) > 1e-3


@pytest.mark.parametrize(("k1", "k2"), [(1.0, 1.0), (4.0, 0.5), (0.2, 3.0)])
@pytest.mark.parametrize("fraction", [0.0, 0.4, 0.9])
def test_frd_margin_is_the_delay_still_tolerated(k1, k2, fraction):
    exact = exact_delay_margin(k1, k2)
    omega = np.geomspace(exact.omega / 100.0, exact.omega * 100.0, 4001)
    response = error_loop_frequency_response(k1, k2, omega, delay=fraction * exact.h)
    remaining, crossover = delay_margin_from_control(response)
    assert crossover == pytest.approx(exact.omega, rel=1e-6)
    assert remaining == pytest.approx((1.0 - fraction) * exact.h, rel=1e-6, abs=1e-9)


def test_frd_works_with_bode_and_nyquist_plots():
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    omega = np.geomspace(0.1, 10.0, 200)
    try:
        for gains in ((1.0, 1.0), (DENSE_K1, DENSE_K2)):
            response = error_loop_frequency_response(*gains, omega, delay=0.2)
            control.bode_plot(response)
            if response.ninputs == 1:
                control.nyquist_plot(response)
    finally:
        plt.close("all")


# --- the sampled loop -------------------------------------------------------------------------


def test_sampled_loop_without_delay_is_control_sample_system():
    period = 0.01
    sampled = error_loop_sampled(DENSE_K1, DENSE_K2, period)
    reference = control.sample_system(error_loop(DENSE_K1, DENSE_K2), period, "zoh")
    assert sampled.dt == period and sampled.nstates == 4
    for matrix in ("A", "B", "C", "D"):
        np.testing.assert_allclose(getattr(sampled, matrix), getattr(reference, matrix), atol=1e-14)


@pytest.mark.parametrize("ticks", [1, 3, 10])
def test_sampled_loop_with_whole_ticks_is_a_pure_shift(ticks):
    period = 0.02
    sampled = error_loop_sampled(DENSE_K1, DENSE_K2, period, delay=ticks * period)
    assert sampled.nstates == 2 * (2 + ticks)
    reference = control.sample_system(error_loop(DENSE_K1, DENSE_K2), period, "zoh")
    for w in (0.3, 2.0, 30.0):
        z = np.exp(1j * w * period)
        np.testing.assert_allclose(sampled(z), reference(z) * z**-ticks, rtol=1e-10)


def exact_held_response(
    K1: np.ndarray, K2: np.ndarray, commands: np.ndarray, period: float, delay: float
) -> np.ndarray:
    """y_k = K1 e(t_k) + K2 e'(t_k) for e'' = v, v(t) = command of the latest tick <= t - delay.

    Integrates the double integrator exactly between the instants j T + delay at which the
    applied command switches (before the first, v = 0).
    """
    steps, n = commands.shape
    e, edot = np.zeros(n), np.zeros(n)
    outputs = np.empty((steps, n))
    t = 0.0
    for k in range(steps):
        t_k = k * period
        switches = [j * period + delay for j in range(steps) if t < j * period + delay < t_k]
        for t_next in [*switches, t_k]:
            latest = math.floor((t - delay) / period + 1e-9)  # constant on [t, t_next)
            v = commands[latest] if latest >= 0 else np.zeros(n)
            tau = t_next - t
            e, edot = e + tau * edot + 0.5 * tau * tau * v, edot + tau * v
            t = t_next
        outputs[k] = K1 @ e + K2 @ edot
    return outputs


@pytest.mark.parametrize("delay", [0.0, 0.013, 0.02, 0.047, 0.1999])
def test_sampled_loop_matches_the_delayed_zero_order_hold(delay):
    period, steps = 0.02, 40
    commands = np.random.default_rng(7).standard_normal((steps, 2))
    sampled = error_loop_sampled(DENSE_K1, DENSE_K2, period, delay=delay)
    simulated = control.forced_response(sampled, U=commands.T).outputs.T
    expected = exact_held_response(DENSE_K1, DENSE_K2, commands, period, delay)
    assert np.max(np.abs(expected)) > 1e-3
    np.testing.assert_allclose(simulated, expected, rtol=1e-10, atol=1e-13)


@pytest.mark.parametrize("period", [0.01, 0.005])
@pytest.mark.parametrize(("k1", "k2"), [(1.0, 1.0), (4.0, 0.5)])
def test_sampled_margin_is_the_exact_margin_less_half_a_period(k1, k2, period):
    exact = exact_delay_margin(k1, k2).h
    boundary = scipy.optimize.brentq(
        lambda h: largest_modulus(error_loop_sampled(k1, k2, period, delay=h), 1) - 1.0,
        0.8 * exact,
        1.1 * exact,
        xtol=1e-12,
    )
    assert boundary == pytest.approx(exact - 0.5 * period, abs=0.01 * period)


def test_sampled_delay_near_a_whole_tick_is_that_tick():
    near = error_loop_sampled(1.0, 1.0, 0.01, delay=0.03 * (1.0 + 1e-12))
    assert near.nstates == 2 + 3


# --- bad input ---------------------------------------------------------------------------------

NOT_SPD = np.array([[1.0, 2.0], [2.0, 1.0]])


@pytest.mark.parametrize(
    ("call", "pattern"),
    [
        (lambda: error_loop(1.0, 1.0, delay=-0.1, pade_order=3), r"^delay must be >= 0"),
        (lambda: error_loop(NOT_SPD, np.eye(2)), r"^K1 must be symmetric positive definite"),
        (lambda: error_loop(np.eye(2), -np.eye(2)), r"^K2 must be symmetric positive definite"),
        (lambda: error_loop(np.eye(2), np.eye(3)), r"^K2 must be n x n = 2x2"),
        (lambda: error_loop(np.ones((2, 3)), np.eye(2)), r"^K1 must be"),
        (lambda: error_loop(1.0, 1.0, delay=0.1, pade_order=0), r"^pade_order must be an integer"),
        (lambda: error_loop(1.0, 1.0, delay=0.1, pade_order=2.5), r"^pade_order must be"),
        (lambda: error_loop(1.0, 1.0, delay=0.1, pade_order=True), r"^pade_order must be"),
        (
            lambda: error_loop(1.0, 1.0, delay=0.1),
            r"^delay = 0\.1 s needs pade_order.*error_loop_frequency_response",
        ),
        (lambda: error_loop(1.0, 1.0, pade_order=3), r"^pade_order = 3 is given without delay"),
        (
            lambda: error_loop_frequency_response(1.0, 1.0, [1.0], delay=-1.0),
            r"^delay must be >= 0",
        ),
        (
            lambda: error_loop_frequency_response(1.0, 1.0, [1.0], delay=math.inf),
            r"^delay must be finite",
        ),
        (lambda: error_loop_frequency_response(NOT_SPD, np.eye(2), [1.0]), r"^K1 must be"),
        (lambda: error_loop_frequency_response(1.0, 1.0, [0.0, 1.0]), r"^omega must be > 0"),
        (lambda: error_loop_frequency_response(1.0, 1.0, [2.0, 1.0]), r"^omega must be strictly"),
        (lambda: error_loop_frequency_response(1.0, 1.0, [[1.0, 2.0]]), r"^omega must be a non"),
        (lambda: error_loop_frequency_response(1.0, 1.0, []), r"^omega must be a non-empty"),
        (lambda: error_loop_frequency_response(1.0, 1.0, [1.0, np.nan]), r"^omega must be finite"),
        (lambda: error_loop_sampled(1.0, 1.0, 0.0), r"^period must be > 0"),
        (lambda: error_loop_sampled(1.0, 1.0, 0.01, delay=-0.01), r"^delay must be >= 0"),
        (lambda: error_loop_sampled(-1.0, 1.0, 0.01), r"^K1 must be symmetric positive definite"),
        (lambda: error_loop_sampled(1.0, 1.0, 1e-6, delay=1.0), r"^delay / period = 1e\+06"),
    ],
)
def test_bad_input_is_refused_naming_the_argument(call, pattern):
    with pytest.raises(ValueError, match=pattern):
        call()


@pytest.mark.parametrize(
    "call",
    [
        lambda: error_loop(1.0, 1.0, delay="0.1", pade_order=3),
        lambda: error_loop_frequency_response(1.0, 1.0, ["a"]),
        lambda: error_loop_sampled(1.0, 1.0, "0.01"),
    ],
)
def test_non_numbers_are_type_errors(call):
    with pytest.raises(TypeError):
        call()
