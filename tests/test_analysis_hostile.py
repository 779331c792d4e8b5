"""Hostile numbers for Theorem 1's bound, the exact margin and the gain design.

Extreme gains, weights, beta, r, seeds and bounds must end in a one-line ``error: ...`` naming
the flag and the value (CLI) or a ValueError starting with the argument's name (library): never
a traceback, a numpy warning, a wrong diagnosis ("A must be Hurwitz" for positive gains) or a
NaN, infinite or inaccurate result. Accepted results are checked against Theorem 1 in exact
rational arithmetic.
"""

from __future__ import annotations

import json
import math
from decimal import Decimal, localcontext
from fractions import Fraction

import numpy as np
import pytest

from delaytrack.analysis import (
    design_gains,
    exact_delay_margin,
    lyapunov_matrix,
    razumikhin_bound,
)
from delaytrack.cli import main

PAPER_H_M = 0.12487  # K1 = K2 = Q = I, beta = 1, r = 1.1 (the paper's 125 ms)


def exact_h_m(k1: float, k2: float, q1: float, q2: float, beta: float, r: float) -> float:
    """Theorem 1's h_m for one joint, in exact rational arithmetic (a square root at the end).

    A = [[0, 1], [-k1, -k2]] and Q = diag(q1, q2) give P = [[k1 p22 + k2 p12, p12], [p12, p22]]
    with p12 = q1 / (2 k1) and p22 = (q2 + q1 / k1) / (2 k2).
    """
    k1, k2, q1, q2, beta, r = map(Fraction, (k1, k2, q1, q2, beta, r))
    p12 = q1 / (2 * k1)
    p22 = (q2 + q1 / k1) / (2 * k2)
    P = [[k1 * p22 + k2 * p12, p12], [p12, p22]]
    det = P[0][0] * P[1][1] - p12 * p12
    P_inv = [[P[1][1] / det, -p12 / det], [-p12 / det, P[0][0] / det]]

    def mul(a, b):
        return [[sum(a[i][k] * b[k][j] for k in range(2)) for j in range(2)] for i in range(2)]

    def add(*ms):
        return [[sum(m[i][j] for m in ms) for j in range(2)] for i in range(2)]

    def t(a):
        return [[a[j][i] for j in range(2)] for i in range(2)]

    def scaled(c, a):
        return [[c * a[i][j] for j in range(2)] for i in range(2)]

    A1 = [[Fraction(0), Fraction(1)], [Fraction(0), Fraction(0)]]
    B1 = [[Fraction(0), Fraction(0)], [-k1, -k2]]
    inner = add(mul(mul(A1, P_inv), t(A1)), mul(mul(B1, P_inv), t(B1)), P_inv)
    E = add(scaled(beta, mul(mul(mul(mul(P, B1), inner), t(B1)), P)), scaled(2 * r / beta, P))
    a, b, d = E[0][0], E[0][1], E[1][1]
    with localcontext() as context:
        context.prec = 60
        half = Decimal((a + d).numerator) / Decimal((a + d).denominator) / 2
        gap = ((a - d) / 2) ** 2 + b * b
        root = (Decimal(gap.numerator) / Decimal(gap.denominator)).sqrt()
        q = min(q1, q2)
        return float(Decimal(q.numerator) / Decimal(q.denominator) / (half + root))


def cli_error(capsys, *args: str) -> str:
    """Run the CLI, expect exit code 2 and one ``error: `` line; return that line."""
    assert main(list(args)) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("error: ")
    assert "Traceback" not in captured.err and "RuntimeWarning" not in captured.err
    return lines[0]


# --- the paper's value is untouched ----------------------------------------------------------


def test_paper_value_library_and_cli(capsys):
    assert razumikhin_bound(1.0, 1.0, 1.0, 1.0, 1.1).h_m == pytest.approx(PAPER_H_M, abs=5e-6)
    assert razumikhin_bound(1.0, 1.0, 1.0, 1.0, 1.1, n=3).h_m == pytest.approx(PAPER_H_M, abs=5e-6)
    assert main(["bound", "--k1", "1", "--k2", "1", "--q", "1", "--beta", "1", "--r", "1.1"]) == 0
    assert "h_m           = 0.12487 s" in capsys.readouterr().out


# --- CLI: one line, the flag, the value -------------------------------------------------------


@pytest.mark.parametrize(
    ("args", "flag", "value"),
    [
        (["--k1", "1e300", "--k2", "1"], "--k1", "1e300"),
        (["--k1", "1e-300", "--k2", "1"], "--k1", "1e-300"),
        (["--k1", "1", "--k2", "1e300"], "--k2", "1e300"),
        (["--k1", "1", "--k2", "1e-300"], "--k2", "1e-300"),
        (["--k1", "1e308", "--k2", "1"], "--k1", "1e308"),
        (["--k1", "1,1e300", "--k2", "1"], "--k1", "1,1e300"),
        (["--k1", "1e-400", "--k2", "1"], "--k1", "1e-400"),
        (["--k1", "1e400", "--k2", "1"], "--k1", "1e400"),
        (["--k1", "1", "--k2", "1", "--q", "1e308"], "--q", "1e308"),
        (["--k1", "1", "--k2", "1", "--q", "1e-320"], "--q", "1e-320"),
        (["--k1", "1", "--k2", "1", "--q", "1,1e-310"], "--q", "1,1e-310"),
        (["--k1", "1", "--k2", "1", "--beta", "1e308"], "--beta", "1e308"),
        (["--k1", "1", "--k2", "1", "--beta", "1e-308"], "--beta", "1e-308"),
        (["--k1", "1", "--k2", "1", "--r", "1e308"], "--r", "1e308"),
    ],
)
@pytest.mark.parametrize("command", ["bound", "margin"])
def test_cli_extreme_values_name_the_flag_and_value(capsys, command, args, flag, value):
    if "--q" not in args:
        args = [*args, "--q", "1"]
    line = cli_error(capsys, command, *args)
    assert line.startswith(f"error: {flag} ")
    assert value in line
    assert "Hurwitz" not in line  # A = [[0, I], [-K1, -K2]] is Hurwitz for positive gains


def test_cli_gain_messages_say_which_range_works(capsys):
    line = cli_error(capsys, "bound", "--k1", "1e300", "--k2", "1", "--q", "1")
    assert "--k1 is too large" in line and "(got --k1 1e300)" in line
    assert "every k1 within [1e-06, 1e+06]" in line
    line = cli_error(capsys, "bound", "--k1", "1", "--k2", "1", "--q", "1", "--beta", "1e308")
    assert "--beta is too large" in line and "beta must lie within about [" in line


@pytest.mark.parametrize(
    ("args", "flag", "value"),
    [
        (["--seed", "4294967296"], "--seed", "4294967296"),
        (["--seed", "99999999999999999999999"], "--seed", "99999999999999999999999"),
        (["--gain-bound", "1e300"], "--gain-bound", "1e+300"),
        (["--gain-bound", "1e-300"], "--gain-bound", "1e-300"),
        (["--gain-bound", "1e-400"], "--gain-bound", "1e-400"),
        (["--gain-bound", "1e5"], "--gain-bound", "100000"),
        (["--gain-bound", "1e300", "--min-bandwidth", "1e100"], "--min-bandwidth", "1e+100"),
        (["--gain-bound", "1e200", "--min-bandwidth", "1e200"], "--min-bandwidth", "1e+200"),
        (["--r", "1e308"], "--r", "1e308"),
    ],
)
def test_cli_design_extreme_values_name_the_flag_and_value(capsys, args, flag, value):
    line = cli_error(capsys, "design", *args)
    assert line.startswith(f"error: {flag} ")
    assert value in line


def test_cli_seed_message_gives_the_range(capsys):
    line = cli_error(capsys, "design", "--seed", "4294967296")
    assert "seeds run from 0 to 2**32 - 1 = 4294967295" in line


def test_cli_extreme_values_that_are_representable_still_work(capsys):
    # Q's scale does not change h_m; beta and r this large give a tiny but exact h_m.
    for args in (["--q", "1e300"], ["--q", "1e-300"], ["--beta", "1e300"], ["--r", "1e300"]):
        assert main(["margin", "--k1", "1", "--k2", "1", "--json", *args]) == 0
        data = json.loads(capsys.readouterr().out)
        assert math.isfinite(data["h_m"]) and data["h_m"] > 0.0
        weight = [] if "--q" in args else ["--q", "1"]
        assert main(["bound", "--k1", "1", "--k2", "1", *weight, "--json", *args]) == 0
        data = json.loads(capsys.readouterr().out)
        assert math.isfinite(data["h_m"]) and data["h_m"] > 0.0
        assert math.isfinite(data["E_norm"]) and np.all(np.isfinite(data["P"]))
    assert main(["bound", "--k1", "1", "--k2", "1", "--q", "1e300"]) == 0
    assert "h_m           = 0.12487 s" in capsys.readouterr().out


# --- library: the argument's name first, the value, the range ---------------------------------


@pytest.mark.parametrize(
    ("arguments", "start"),
    [
        ({"K1": 1e300}, "K1 is too large"),
        ({"K1": 1e-300}, "K1 is too small"),
        ({"K1": 1e-320}, "K1 is too small"),
        ({"K2": 1e300}, "K2 is too large relative to K1"),
        ({"K2": 1e-300}, "K2 is too small relative to K1"),
        ({"K1": 1e308}, "K1 has an entry of magnitude 1e+308"),
        ({"Q": 1e308}, "Q has an entry of magnitude 1e+308"),
        ({"Q": 1e-320}, "Q is too small for P and E"),
        ({"Q": [1.0, 1e-310]}, "Q is too ill-conditioned"),
        ({"beta": 1e308}, "beta is too large"),
        ({"beta": 1e-308}, "beta is too small"),
        ({"r": 1e308}, "r is too large"),
    ],
)
def test_library_errors_start_with_the_argument(arguments, start):
    values = {"K1": 1.0, "K2": 1.0, "Q": 1.0, "beta": 1.0, "r": 1.1, **arguments}
    with pytest.raises(ValueError) as raised:
        razumikhin_bound(values["K1"], values["K2"], values["Q"], values["beta"], values["r"])
    message = str(raised.value)
    assert message.startswith(start), message
    assert "Hurwitz" not in message


@pytest.mark.parametrize("k1", [1e-300, 1e-100, 1e100, 1e300])
@pytest.mark.parametrize("k2", [1e-300, 1.0, 1e300])
def test_positive_gains_are_never_called_not_hurwitz(k1, k2):
    for solve in (
        lambda: razumikhin_bound(k1, k2, 1.0, 1.0, 1.1),
        lambda: lyapunov_matrix(k1, k2, 1.0),
    ):
        with pytest.raises(ValueError) as raised:
            solve()
        assert "Hurwitz" not in str(raised.value)
        assert str(raised.value).startswith(("K1 ", "K2 "))


def test_non_hurwitz_gains_are_still_refused_as_such():
    with pytest.raises(ValueError, match="must be Hurwitz"):
        lyapunov_matrix(-1.0, 1.0, 1.0)


def test_every_accepted_result_is_accurate_and_every_refusal_names_an_argument():
    rng = np.random.default_rng(2024)
    accepted = 0
    for _ in range(300):
        k1, k2 = 10.0 ** rng.uniform(-12, 14, 2)
        q1, q2 = 10.0 ** rng.uniform(-12, 12, 2)
        beta = 10.0 ** rng.uniform(-300, 300) if rng.random() < 0.3 else 10.0 ** rng.uniform(-4, 4)
        r = 1.0 + 10.0 ** rng.uniform(-6, 6)
        try:
            bound = razumikhin_bound(k1, k2, [q1, q2], beta, r)
        except ValueError as error:
            assert str(error).startswith(("K1 ", "K2 ", "Q ", "beta ", "r ")), str(error)
            continue
        accepted += 1
        assert math.isfinite(bound.E_norm) and np.all(np.isfinite(bound.E))
        assert bound.h_m == pytest.approx(exact_h_m(k1, k2, q1, q2, beta, r), rel=1e-5)
    assert accepted > 30


def test_gains_in_the_quoted_range_are_always_accepted():
    rng = np.random.default_rng(7)
    for trial in range(200):
        n = int(rng.integers(1, 4))
        if trial % 3 == 0:  # the corners of the range
            log_k1 = rng.choice([-6.0, 6.0], n)
            log_damping = rng.choice([-3.0, 3.0], n)
        else:
            log_k1, log_damping = rng.uniform(-6, 6, n), rng.uniform(-3, 3, n)
        k1 = 10.0**log_k1
        k2 = 2.0 * 10.0**log_damping * np.sqrt(k1)
        q = 10.0 ** rng.uniform(-2, 2, 2 * n)  # eigenvalues within a factor 1e4
        bound = razumikhin_bound(k1, k2, q, 10.0 ** rng.uniform(-2, 2), 1.0 + rng.uniform(0, 10))
        assert math.isfinite(bound.h_m) and bound.h_m > 0.0


@pytest.mark.parametrize("scale", [1e-300, 1e-150, 1.0, 37.0, 1e150, 1e300])
def test_the_scale_of_Q_does_not_change_h_m_at_any_magnitude(scale):
    reference = razumikhin_bound([1.0, 4.0], [2.0, 0.5], [1.0, 2.0, 1.0, 3.0], 0.7, 1.1)
    scaled = razumikhin_bound(
        [1.0, 4.0], [2.0, 0.5], scale * np.array([1.0, 2.0, 1.0, 3.0]), 0.7, 1.1
    )
    assert scaled.h_m == pytest.approx(reference.h_m, rel=1e-12)
    assert np.all(np.isfinite(scaled.P)) and np.all(np.isfinite(scaled.E))


def test_joints_of_very_different_speeds_are_each_as_accurate_as_alone():
    k1 = np.array([1e-6, 1e6, 1e6])
    k2 = 2.0 * 1e3 * np.sqrt(k1)  # damping ratio 1e3 on every joint
    together = razumikhin_bound(k1, k2, 1.0, 1.0, 1.1)
    alone = min(razumikhin_bound(a, b, 1.0, 1.0, 1.1).h_m for a, b in zip(k1, k2, strict=True))
    assert together.h_m == pytest.approx(alone, rel=1e-12)


# --- exact margin -----------------------------------------------------------------------------


def test_margin_of_many_distinct_diagonal_axes_is_the_closed_form():
    k1 = 1.0 + np.arange(400) / 10.0
    margin = exact_delay_margin(k1, np.ones(400))
    omega = np.sqrt((1.0 + np.sqrt(1.0 + 4.0 * k1**2)) / 2.0)
    assert margin.h == pytest.approx(float(np.min(np.arctan(omega / k1) / omega)), rel=1e-12)
    assert len(margin.crossing_delays) == 400


def test_diagonal_closed_form_agrees_with_the_scan_of_the_same_gains_rotated():
    rng = np.random.default_rng(3)
    V = np.linalg.qr(rng.standard_normal((3, 3)))[0]
    for scale in (1e-40, 1.0, 1e40):
        k1, k2 = scale * np.array([1.0, 2.0, 5.0]), np.sqrt(scale) * np.array([1.5, 0.5, 1.0])
        rotated = exact_delay_margin(V @ np.diag(k1) @ V.T, V @ np.diag(k2) @ V.T)
        diagonal = exact_delay_margin(k1, k2)
        assert rotated.h == pytest.approx(diagonal.h, rel=1e-9)
        assert rotated.omega == pytest.approx(diagonal.omega, rel=1e-9)


def test_margin_below_the_smallest_double_is_refused():
    with pytest.raises(ValueError, match=r"^K2 is too small relative to K1 .* 1e-320 s"):
        exact_delay_margin(1e190, 1e-130)


# --- design -----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("options", "start"),
    [
        ({"seed": 2**32}, "seed must be a non-negative integer; got 4294967296"),
        ({"gain_bound": 1e300}, "gain_bound is too large for the design"),
        ({"gain_bound": 1e-300}, "gain_bound is too small for the design"),
        ({"gain_bound": 1e5}, "gain_bound is too large for the design"),
        ({"gain_bound": 1e8, "min_bandwidth": 1e4}, "min_bandwidth is too large for the design"),
        # k2 on the search's lower edge (gain_bound / 1e4 = 100 > the optimal 94): gain_bound.
        ({"gain_bound": 1e6, "min_bandwidth": 100.0}, "gain_bound is too large for the design"),
        ({"gain_bound": 1e200, "min_bandwidth": 1e200}, "min_bandwidth = 1e+200 rad/s needs"),
        ({"r": 1e308}, "r is too large for the design"),
    ],
)
def test_design_refuses_what_it_cannot_trust(options, start):
    with pytest.raises(ValueError) as raised:
        design_gains(**options)
    assert str(raised.value).startswith(start), str(raised.value)


def test_design_at_a_huge_r_is_the_rescaled_design():
    # beta = sqrt(r) gamma: the optimal gains and Q do not depend on r, h_m scales as 1 / sqrt(r).
    design = design_gains(r=1e300)
    paper_bound = design_gains()
    assert design.K2[0, 0] == pytest.approx(paper_bound.K2[0, 0], rel=1e-4)
    assert design.h_m * math.sqrt(1e300 / 1.1) == pytest.approx(paper_bound.h_m, rel=1e-6)
