"""AROLC and the outer loop, checked tick by tick against Roy & Kar's laws, written out here.

Reference computations are independent of the code under test: the two-link arm's M̂, N̂ are
re-typed from the closed form in ``delaytrack.plants.two_link_arm``'s docstring, P comes from a
Kronecker-product solve of AᵀP + PA = −Q (not scipy's Lyapunov solver), and the adaptive law is
the three-case rule of the paper's (ATRC) with the backward-difference sign of sᵀṡ and
forward-Euler ĉ (docs/decisions.md D4 and D2).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from arm_closed_form import arm_mass, arm_nonlinear
from delaytrack._validation import ArgumentError
from delaytrack.controllers import AROLC, PCON, OuterLoop, PCONf, controller_from_spec
from delaytrack.controllers.arolc import adaptive_gain_rate
from delaytrack.plants import CallablePlant, LinearPlant, TwoLinkArm

# The paper's gains (Roy & Kar, Section III): K1 = K2 = Q = I, alpha = 2, epsilon = 0.1,
# gamma = 0.001.
PAPER = dict(K1=1.0, K2=1.0, Q=1.0, alpha=2.0, epsilon=0.1, gamma=0.001)
T_C = 0.01


def lyapunov_by_kronecker(A, Q):
    """P with AᵀP + PA = −Q via column-major vec: (I ⊗ Aᵀ + Aᵀ ⊗ I) vec P = −vec Q."""
    m = A.shape[0]
    operator = np.kron(np.eye(m), A.T) + np.kron(A.T, np.eye(m))
    return np.linalg.solve(operator, -Q.reshape(-1, order="F")).reshape((m, m), order="F")


def closed_loop_matrix(K1, K2):
    n = K1.shape[0]
    return np.block([[np.zeros((n, n)), np.eye(n)], [-K1, -K2]])


def random_spd(rng, n, shift=0.5):
    A = rng.standard_normal((n, n))
    return A @ A.T + shift * np.eye(n)


def reference_sample(rng, n=2, scale=1.0):
    """Random q, q̇ and a reference (q_d, q̇_d, q̈_d)."""
    q, qdot = rng.uniform(-2, 2, n), rng.uniform(-2, 2, n)
    qd = q + scale * rng.standard_normal(n)
    qd_dot = qdot + scale * rng.standard_normal(n)
    return q, qdot, (qd, qd_dot, rng.standard_normal(n))


def sliding_variable(P, q, qdot, qd, qd_dot):
    """s = Bᵀ P e with B = [0; I], e = [q_d − q; q̇_d − q̇] (Roy & Kar, Section II)."""
    n = q.size
    e = np.concatenate([qd - q, qd_dot - qdot])
    return P[n:, :] @ e


def outer_loop_command(K1, K2, q, qdot, reference, extra=0.0):
    """τ = M̂ (q̈_d + K2 ė1 + K1 e1 + Δu) + N̂ for the arm (paper eqs. (input), (aux))."""
    qd, qd_dot, qd_ddot = reference
    u = qd_ddot + K2 @ (qd_dot - qdot) + K1 @ (qd - q) + extra
    return arm_mass(q) @ u + arm_nonlinear(q, qdot)


@pytest.fixture(scope="module")
def rng():
    return np.random.default_rng(7)


@pytest.fixture(scope="module")
def arm():
    return TwoLinkArm()


# --------------------------------------------------------------------------------------------
# Outer loop
# --------------------------------------------------------------------------------------------


def test_outer_loop_command(rng, arm):
    K1, K2 = random_spd(rng, 2), random_spd(rng, 2)
    controller = OuterLoop(model=arm, K1=K1, K2=K2)
    assert controller.initial_state().shape == (0,) and controller.state_names == ()
    for _ in range(20):
        q, qdot, reference = reference_sample(rng)
        command, state = controller.step(
            0.3, q, qdot, reference, controller.initial_state(), T_c=T_C
        )
        np.testing.assert_allclose(
            command, outer_loop_command(K1, K2, q, qdot, reference), rtol=1e-12, atol=1e-12
        )
        assert state.shape == (0,)


def test_outer_loop_solves_a_non_identity_input_map(rng):
    # τ = M̂ u + N̂ is realised through Ĝ: command = Ĝ⁻¹ τ (controllers.base docstring).
    mass, damping, stiffness = (
        random_spd(rng, 2),
        rng.standard_normal((2, 2)),
        rng.standard_normal((2, 2)),
    )
    G = np.array([[2.0, 0.5], [-1.0, 1.0]])
    model = LinearPlant(mass, damping, stiffness, G)
    controller = OuterLoop(model=model, K1=[1.0, 2.0], K2=3.0)
    K1, K2 = np.diag([1.0, 2.0]), 3.0 * np.eye(2)
    q, qdot, (qd, qd_dot, qd_ddot) = reference_sample(rng)
    command, _ = controller.step(0.0, q, qdot, (qd, qd_dot, qd_ddot), np.zeros(0), T_c=T_C)
    tau = mass @ (qd_ddot + K2 @ (qd_dot - qdot) + K1 @ (qd - q)) + damping @ qdot + stiffness @ q
    np.testing.assert_allclose(G @ command, tau, rtol=1e-12, atol=1e-12)


# --------------------------------------------------------------------------------------------
# AROLC: P, Δu
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("n", [1, 2, 3])
def test_arolc_P_solves_lyapunov(rng, n):
    K1, K2, Q = random_spd(rng, n), random_spd(rng, n), random_spd(rng, 2 * n)
    model = LinearPlant(np.eye(n))
    controller = AROLC(model=model, K1=K1, K2=K2, Q=Q, alpha=2.0, epsilon=0.1, gamma=1e-3)
    A = closed_loop_matrix(K1, K2)
    P = controller.P
    np.testing.assert_allclose(A.T @ P + P @ A, -Q, atol=1e-10 * np.abs(Q).max())
    np.testing.assert_allclose(P, lyapunov_by_kronecker(A, Q), rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(P, P.T)
    assert np.linalg.eigvalsh(P)[0] > 0


def test_arolc_paper_gains_P():
    # K1 = K2 = Q = I, n = 1: A = [[0, 1], [-1, -1]]; solving AᵀP + PA = -I by hand gives
    # P = [[1.5, 0.5], [0.5, 1.0]].
    controller = AROLC(model=LinearPlant(1.0), **PAPER)
    np.testing.assert_allclose(controller.P, [[1.5, 0.5], [0.5, 1.0]], rtol=1e-12)


@pytest.mark.parametrize("regime", ["outside", "inside"])
def test_arolc_command_is_outer_loop_plus_switching_term(rng, arm, regime):
    K1, K2, Q = random_spd(rng, 2), random_spd(rng, 2), random_spd(rng, 4)
    epsilon, alpha = 0.1, 2.5
    controller = AROLC(model=arm, K1=K1, K2=K2, Q=Q, alpha=alpha, epsilon=epsilon, gamma=1e-3)
    P = lyapunov_by_kronecker(closed_loop_matrix(K1, K2), Q)
    scale = 1.0 if regime == "outside" else 1e-3
    for _ in range(20):
        q, qdot, reference = reference_sample(rng, scale=scale)
        s = sliding_variable(P, q, qdot, *reference[:2])
        norm_s = np.linalg.norm(s)
        if (norm_s >= epsilon) != (regime == "outside"):
            continue
        c_hat = rng.uniform(0.01, 3.0)
        state = np.array([c_hat, 1.0, *rng.standard_normal(2)])
        command, _ = controller.step(1.0, q, qdot, reference, state, T_c=T_C)
        # Roy & Kar (delta u): Δu = α ĉ s/‖s‖ if ‖s‖ >= ε, α ĉ s/ε otherwise; ĉ is the value
        # at this tick (docs/decisions.md D2).
        delta_u = alpha * c_hat * s / max(norm_s, epsilon)
        expected = outer_loop_command(K1, K2, q, qdot, reference, delta_u)
        np.testing.assert_allclose(command, expected, rtol=1e-10, atol=1e-10)
        # Not vacuous: the switching term changes the command.
        assert np.linalg.norm(expected - outer_loop_command(K1, K2, q, qdot, reference)) > 1e-6


def test_arolc_alpha_to_zero_is_the_outer_loop(rng, arm):
    K1, K2 = random_spd(rng, 2), random_spd(rng, 2)
    arolc = AROLC(
        model=arm, K1=K1, K2=K2, Q=random_spd(rng, 4), alpha=1e-300, epsilon=0.1, gamma=1e-3
    )
    outer = OuterLoop(model=arm, K1=K1, K2=K2)
    for _ in range(20):
        q, qdot, reference = reference_sample(rng)
        state = np.array([rng.uniform(0.0, 100.0), 1.0, *rng.standard_normal(2)])
        got, _ = arolc.step(0.0, q, qdot, reference, state, T_c=T_C)
        want, _ = outer.step(0.0, q, qdot, reference, np.zeros(0), T_c=T_C)
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12 * np.abs(want).max())


# --------------------------------------------------------------------------------------------
# Adaptive law (the paper's (ATRC), with backward-difference sᵀṡ and forward Euler at T_c;
# docs/decisions.md D4, D2)
# --------------------------------------------------------------------------------------------

GAMMA = 0.001


def expected_next_c_hat(c_hat, s, s_previous, has_previous, gamma=GAMMA, T_c=T_C):
    if c_hat <= gamma:
        return c_hat + T_c * gamma  # case (c)
    increasing = has_previous and float(s @ (s - s_previous)) > 0.0
    if increasing:
        return c_hat + T_c * np.linalg.norm(s)  # case (a)
    # Case (b). arolc module docstring: a decreasing Euler step stops at γ, as the continuous
    # law does (ĉ slides along γ), instead of overshooting below γ or below zero.
    return max(c_hat - T_c * np.linalg.norm(s), gamma)


S = np.array([0.6, -0.8])  # ‖S‖ = 1


@pytest.mark.parametrize(
    "c_hat, s_previous, has_previous, rate",
    [
        (0.5, 0.5 * S, True, 1.0),  # (a) sᵀ(s − s_prev) = 0.5 > 0: +‖s‖
        (0.5, 2.0 * S, True, -1.0),  # (b) sᵀ(s − s_prev) = −1 <= 0: −‖s‖
        (0.5, S, True, -1.0),  # (b) boundary sᵀ(s − s_prev) = 0 counts as <= 0
        (0.5, -S, True, 1.0),  # (a) sᵀ(s − s_prev) = 2‖s‖² > 0 (s reversed)
        (0.5, 1.5 * S, True, -1.0),  # (b) shrinking s
        (0.5, 0.5 * S, False, -1.0),  # first tick: no previous s, treated as <= 0
        (GAMMA, 0.5 * S, True, GAMMA),  # (c) ĉ = γ: +γ
        (0.5 * GAMMA, 2.0 * S, True, GAMMA),  # (c) ĉ < γ: +γ whatever s does
    ],
)
def test_adaptive_gain_rate_cases(c_hat, s_previous, has_previous, rate):
    got = adaptive_gain_rate(c_hat, 2.0 * S, 2.0 * s_previous, has_previous, GAMMA)
    # With s = 2S, ‖s‖ = 2 in cases (a) and (b).
    expected = rate * 2.0 if abs(rate) == 1.0 else rate
    assert got == pytest.approx(expected, rel=1e-15)
    # ‖s‖ handed in by a caller that has it (AROLC's step) is the one used: the same rate for
    # the true norm, and the norm given (here 3, not 2) where the rate is ±‖s‖
    given = adaptive_gain_rate(c_hat, 2.0 * S, 2.0 * s_previous, has_previous, GAMMA, 2.0)
    assert given == got
    scaled = adaptive_gain_rate(c_hat, 2.0 * S, 2.0 * s_previous, has_previous, GAMMA, 3.0)
    assert scaled == (rate * 3.0 if abs(rate) == 1.0 else rate)


def arm_state_for_s(P, target_s, rng):
    """q, q̇ and a reference with Bᵀ P e = target_s: e = [0; P22⁻¹ target_s] (n = 2)."""
    n = 2
    edot = np.linalg.solve(P[n:, n:], target_s)
    q, qdot = rng.uniform(-1, 1, n), rng.uniform(-1, 1, n)
    return q, qdot, (q.copy(), qdot + edot, rng.standard_normal(n))


@pytest.mark.parametrize(
    "c_hat, s_previous_factor, has_previous, case",
    [
        (0.5, 0.5, 1.0, "a"),
        (0.5, 2.0, 1.0, "b"),
        (0.5, 1.0, 1.0, "b"),
        (0.5, 0.5, 0.0, "first"),
        (GAMMA, 2.0, 1.0, "c"),
        (0.2 * GAMMA, 0.5, 1.0, "c"),
    ],
)
def test_adaptive_law_through_step(rng, arm, c_hat, s_previous_factor, has_previous, case):
    controller = AROLC(model=arm, **PAPER)
    P = lyapunov_by_kronecker(closed_loop_matrix(np.eye(2), np.eye(2)), np.eye(4))
    target = 0.7 * S  # ‖s‖ = 0.7 >= ε: outside the boundary layer
    q, qdot, reference = arm_state_for_s(P, target, rng)
    np.testing.assert_allclose(sliding_variable(P, q, qdot, *reference[:2]), target, atol=1e-14)
    state = np.array([c_hat, has_previous, *(s_previous_factor * target)])
    before = state.copy()
    _, next_state = controller.step(0.0, q, qdot, reference, state, T_c=T_C)
    np.testing.assert_array_equal(state, before)  # the input state is not modified
    expected = {
        "a": c_hat + T_C * 0.7,
        "b": c_hat - T_C * 0.7,
        "first": c_hat - T_C * 0.7,
        "c": c_hat + T_C * GAMMA,
    }[case]
    # Layout [c_hat, has_previous_s, s_previous...] (AROLC.state_names).
    assert next_state[0] == pytest.approx(expected, rel=1e-13)
    assert next_state[1] == 1.0
    np.testing.assert_allclose(next_state[2:], target, atol=1e-14)


@pytest.mark.parametrize("c_hat", [1.5 * GAMMA, 0.0061, 0.0069])
def test_decreasing_step_stops_at_gamma(rng, arm, c_hat):
    # ĉ > γ, s shrinking, T_c ‖s‖ = 0.007 > ĉ − γ: plain Euler would give ĉ − 0.007 < γ (for
    # 1.5 γ even < 0, flipping Δu's sign); the documented step gives exactly γ.
    controller = AROLC(model=arm, **PAPER)
    P = lyapunov_by_kronecker(closed_loop_matrix(np.eye(2), np.eye(2)), np.eye(4))
    target = 0.7 * S
    q, qdot, reference = arm_state_for_s(P, target, rng)
    state = np.array([c_hat, 1.0, *(2.0 * target)])
    _, next_state = controller.step(0.0, q, qdot, reference, state, T_c=T_C)
    assert next_state[0] == GAMMA
    # Where Euler stays above γ it is not touched: ĉ = 0.0081 -> 0.0011.
    state[0] = 0.0081
    _, next_state = controller.step(0.0, q, qdot, reference, state, T_c=T_C)
    assert next_state[0] == pytest.approx(0.0081 - 0.007, rel=1e-12)


def test_adaptive_law_over_a_sequence_of_ticks(rng, arm):
    # ĉ(0) = 0.02 > γ; decreasing phases push it below γ, exercising all three branches.
    controller = AROLC(model=arm, **{**PAPER, "c_hat0": 0.02})
    assert controller.state_names == ("c_hat", "has_previous_s", "s_previous_0", "s_previous_1")
    state = controller.initial_state()
    np.testing.assert_array_equal(state, [0.02, 0.0, 0.0, 0.0])
    P = lyapunov_by_kronecker(closed_loop_matrix(np.eye(2), np.eye(2)), np.eye(4))
    c_hat, s_previous, has_previous = 0.02, np.zeros(2), False
    branches = set()
    # A slowly rotating s whose norm first grows (case (a) after the first tick), then shrinks
    # (case (b)) until ĉ falls to γ or below (case (c)); the last ticks sit in the boundary layer.
    norms = np.concatenate([np.linspace(0.3, 0.8, 10), np.linspace(0.75, 0.05, 30)])
    for k, norm in enumerate(norms):
        target = norm * np.array([math.cos(0.05 * k), math.sin(0.05 * k)])
        q, qdot, reference = arm_state_for_s(P, target, rng)
        command, state = controller.step(k * T_C, q, qdot, reference, state, T_c=T_C)
        delta_u = PAPER["alpha"] * c_hat * target / max(np.linalg.norm(target), PAPER["epsilon"])
        np.testing.assert_allclose(
            command,
            outer_loop_command(np.eye(2), np.eye(2), q, qdot, reference, delta_u),
            rtol=1e-11,
            atol=1e-11,
        )
        if c_hat <= GAMMA:
            branches.add("c")
        elif has_previous and target @ (target - s_previous) > 0:
            branches.add("a")
        else:
            branches.add("b")
            if c_hat - T_C * np.linalg.norm(target) < GAMMA:
                branches.add("b stopped at gamma")
        c_hat = expected_next_c_hat(c_hat, target, s_previous, has_previous)
        s_previous, has_previous = target, True
        assert state[0] == pytest.approx(c_hat, rel=1e-12, abs=1e-15)
        np.testing.assert_allclose(state[2:], target, atol=1e-13)
    assert branches == {"a", "b", "b stopped at gamma", "c"}


def test_c_hat0_defaults_to_gamma(arm):
    controller = AROLC(model=arm, **PAPER)
    assert controller.c_hat0 == PAPER["gamma"]
    np.testing.assert_array_equal(controller.initial_state(), [0.001, 0.0, 0.0, 0.0])


# --------------------------------------------------------------------------------------------
# Refused inputs
# --------------------------------------------------------------------------------------------


def arolc_with(arm, **changes):
    return AROLC(model=arm, **{**PAPER, **changes})


@pytest.mark.parametrize(
    "changes, message",
    [
        (
            dict(K1=[[1.0, 0.2], [0.0, 1.0]]),
            r"K1 must be symmetric positive definite; it is not symmetric "
            r"\(max \|K1 - K1\^T\| = 0\.2\)",
        ),
        (
            dict(K1=[[1.0, 2.0], [2.0, 1.0]]),
            r"K1 must be symmetric positive definite; its eigenvalues are \[-1, 3\]",
        ),
        (
            dict(K2=[-1.0, 2.0]),
            r"K2 must be symmetric positive definite; its eigenvalues are \[-1, 2\]",
        ),
        (dict(K2=np.eye(3)), r"K2 must be 2x2; got shape \(3, 3\)"),
        (dict(K2=np.ones((2, 3))), r"K2 must be square; got shape \(2, 3\)"),
        (dict(Q=np.eye(2)), r"Q must be 4x4; got shape \(2, 2\)"),
        (
            dict(Q=-1.0),
            r"Q must be symmetric positive definite; its eigenvalues are \[-1, -1, -1, -1\]",
        ),
        (dict(alpha=0.0), r"alpha must be > 0; got 0"),
        (dict(alpha=-2.0), r"alpha must be > 0; got -2"),
        (dict(alpha=float("nan")), r"alpha must be finite; got nan"),
        (dict(epsilon=0.0), r"epsilon must be > 0; got 0"),
        (dict(epsilon=-0.1), r"epsilon must be > 0; got -0\.1"),
        (dict(gamma=0.0), r"gamma must be > 0; got 0"),
        (dict(c_hat0=0.0), r"c_hat0 must be > 0; got 0"),
        (dict(c_hat0=-1.0), r"c_hat0 must be > 0; got -1"),
    ],
)
def test_arolc_refused(arm, changes, message):
    with pytest.raises(ValueError, match=message):
        arolc_with(arm, **changes)


_PREDICTOR = dict(kappa=1.0, vartheta=1.0, k_b=1.0, history=1.0, T_c=0.002)


@pytest.mark.parametrize(
    ("build", "argument", "message"),
    [
        (lambda arm: AROLC(model=arm, **{**PAPER, "alpha": 1e300}), "alpha", "alpha must be <="),
        (lambda arm: AROLC(model=arm, **{**PAPER, "epsilon": 1e-300}), "epsilon", ">= 1e-"),
        (lambda arm: PCON(model=arm, **_PREDICTOR, space="joint"), "space", "space must be one"),
        (lambda arm: PCON(model=arm, **{**_PREDICTOR, "history": 1e6}), "history", "at most"),
        (lambda arm: PCON(model=arm, **_PREDICTOR, noise_seed=-1), "noise_seed", "from 0 to"),
        (lambda arm: PCONf(model=arm, **_PREDICTOR, h_bar=2.0), "h_bar", "h_bar = 2 s exceeds"),
    ],
)
def test_constructor_refusals_carry_their_argument(arm, build, argument, message):
    with pytest.raises(ArgumentError) as refused:  # a ValueError, as before
        build(arm)
    assert isinstance(refused.value, ValueError)
    assert refused.value.argument == argument and message in str(refused.value)
    assert str(refused.value).startswith(f"{argument} ")


def test_outer_loop_refused(arm):
    with pytest.raises(
        ValueError, match=r"K1 must be symmetric positive definite; its eigenvalues are \[0, 1\]"
    ):
        OuterLoop(model=arm, K1=[0.0, 1.0], K2=1.0)
    with pytest.raises(ValueError, match=r"K2 must be 2x2; got shape \(1, 1\)"):
        OuterLoop(model=arm, K1=1.0, K2=[[1.0]])


def test_under_actuated_model_refused():
    model = LinearPlant(np.eye(2), input_map_matrix=[[1.0], [0.0]])
    assert (model.n, model.m) == (2, 1)
    with pytest.raises(
        ValueError,
        match=r"AROLC needs a fully actuated nominal model \(m == n\) or one with its own "
        r"command map; got n = 2, m = 1",
    ):
        AROLC(model=model, **PAPER)
    with pytest.raises(ValueError, match=r"OuterLoop needs a fully actuated .* got n = 2, m = 1"):
        OuterLoop(model=model, K1=1.0, K2=1.0)
    with pytest.raises(TypeError, match=r"model must be an ELPlant .* got str"):
        AROLC(model="arm", **PAPER)


def test_controller_from_spec(arm, rng):
    controller = controller_from_spec({"type": "arolc", **PAPER, "c_hat0": 0.5}, arm)
    assert isinstance(controller, AROLC) and controller.c_hat0 == 0.5
    rebuilt = controller_from_spec(controller.to_spec(), arm)
    np.testing.assert_array_equal(rebuilt.params, controller.params)
    outer = controller_from_spec({"type": "outer-loop", "K1": 2.0, "K2": 3.0}, arm)
    np.testing.assert_array_equal(outer.K1, 2 * np.eye(2))
    with pytest.raises(
        ValueError,
        match=r"'controller\.type' must be one of "
        r"\['arolc', 'outer-loop', 'pcon', 'pconf'\] or a factory of yours, "
        r"'python:<module>:<function>'; got 'pid'",
    ):
        controller_from_spec({"type": "pid"}, arm)
    with pytest.raises(
        ValueError, match=r"unknown key 'controller\.beta' .* type = 'arolc' are \['type', 'K1'"
    ):
        controller_from_spec({"type": "arolc", **PAPER, "beta": 1.0}, arm)
    with pytest.raises(ValueError, match=r"unknown key 'controller\.alpha' .* type = 'outer-loop'"):
        controller_from_spec({"type": "outer-loop", "K1": 1.0, "K2": 1.0, "alpha": 2.0}, arm)


@pytest.mark.parametrize(
    "args, message",
    [
        (dict(q=np.zeros(3)), r"q must have shape \(2,\); got \(3,\)"),
        (dict(qdot=np.zeros((2, 1))), r"qdot must have shape \(2,\); got \(2, 1\)"),
        (
            dict(reference=(np.zeros(2), np.zeros(2), np.zeros(1))),
            r"qd_ddot must have shape \(2,\); got \(1,\)",
        ),
        (dict(state=np.zeros(3)), r"state must have shape \(4,\); got \(3,\)"),
        (dict(state=[0.0, 1.0, "a", 2.0]), r"state must be a vector of 4 numbers; got list \[0\.0"),
        (dict(q=[{}, 1.0]), r"q must be a vector of 2 numbers; got list \[\{\}"),
        (dict(T_c=0.0), r"T_c must be > 0; got 0"),
    ],
)
def test_step_wrong_inputs_refused(arm, args, message):
    controller = AROLC(model=arm, **PAPER)
    call = dict(q=np.zeros(2), qdot=np.zeros(2), reference=(np.ones(2), np.zeros(2), np.zeros(2)))
    call.update(state=controller.initial_state(), T_c=T_C)
    call.update(args)
    with pytest.raises(ValueError, match=message):
        controller.step(
            0.0, call["q"], call["qdot"], call["reference"], call["state"], T_c=call["T_c"]
        )


# --------------------------------------------------------------------------------------------
# A user (Python) nominal model
# --------------------------------------------------------------------------------------------


def test_controllers_with_callable_nominal_model(rng, arm):
    # The nominal model may be any ELPlant (controllers.base: the step runs as Python when the
    # model is not compiled): the same commands and states as with the compiled arm.
    user = CallablePlant(2, arm_mass, arm_nonlinear)
    assert not user.compiled
    pairs = [
        (
            AROLC(model=user, **{**PAPER, "c_hat0": 0.2}),
            AROLC(model=arm, **{**PAPER, "c_hat0": 0.2}),
        ),
        (OuterLoop(model=user, K1=2.0, K2=1.0), OuterLoop(model=arm, K1=2.0, K2=1.0)),
    ]
    for python_controller, compiled_controller in pairs:
        state_a = python_controller.initial_state()
        state_b = compiled_controller.initial_state()
        for k in range(5):
            q, qdot, reference = reference_sample(rng)
            command_a, state_a = python_controller.step(
                k * T_C, q, qdot, reference, state_a, T_c=T_C
            )
            command_b, state_b = compiled_controller.step(
                k * T_C, q, qdot, reference, state_b, T_c=T_C
            )
            np.testing.assert_allclose(command_a, command_b, rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(state_a, state_b, rtol=1e-12, atol=1e-15)


def test_a_singular_nominal_input_map_is_refused():
    # G = [[1, 1], [1, 1]] cannot turn a torque into actuator commands; found in review, where
    # the simulation crashed inside the compiled solve instead.
    singular = LinearPlant(mass=[1.0, 1.0], input_map_matrix=[[1.0, 1.0], [1.0, 1.0]])
    with pytest.raises(ValueError, match=r"invertible nominal input map .* condition number"):
        OuterLoop(singular, K1=1.0, K2=1.0)
