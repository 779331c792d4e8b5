"""PCON and PCONf (Roy & Kar (filter), (int error); docs/decisions.md D23), checked against the
law and an independent integral of τ.

The oracle for ``e_z(t_k) = ∫_{t_k−h}^{t_k} τ(θ) dθ`` is written out here with exact rational
arithmetic over absolute tick intervals ``[j T_c, (j+1) T_c)`` (``fractions.Fraction`` of the very
floats the controller sees), not with the controller's relative-tick weights. The predictor
property is the identity in docs/decisions.md D23 ("Property"): with ``ϑ = M⁻¹`` and a
constant delay, ``M ϱ̇ = M(q̈_d + κ ė1) + N − τ(t)``, in which the delayed input does not appear.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from arm_closed_form import arm_mass, arm_nonlinear
from delaytrack._counter_noise import hash32, standard_noise
from delaytrack.controllers import PCON, PCONf, PredictorBaseline, controller_from_spec
from delaytrack.controllers.delay_knowledge import told_delays
from delaytrack.controllers.pcon import ring_slots
from delaytrack.delays import AbsSineDelay, ConstantDelay
from delaytrack.plants import CallablePlant, LinearPlant, TwoLinkArm
from delaytrack.references import SinusoidalReference
from delaytrack.sim import simulate

T_C = 0.01
HISTORY = 0.1
# A modest reference for the arm (the two_link_*.toml scenarios' q_d).
ARM_REFERENCE = SinusoidalReference([0.0, 0.0], amplitude=[0.8, 0.5], frequency=[0.5, 0.7])


def exact_window_integral(taus, k, h, T_c, n=2):
    """``Σ_j τ_j |[j T_c, (j+1) T_c) ∩ [k T_c − h, k T_c)|`` over ``j < k``, in exact rationals.

    ``taus[j]`` (n,) is the command of tick ``j``; before tick 0 the input is zero.
    """
    period, delay = Fraction(T_c), Fraction(h)
    low, high = k * period - delay, k * period
    total = [Fraction(0)] * n
    for j in range(k):
        overlap = min((j + 1) * period, high) - max(j * period, low)
        if overlap > 0:
            total = [a + overlap * Fraction(float(x)) for a, x in zip(total, taus[j], strict=True)]
    return np.array([float(a) for a in total])


def random_sample(rng, n=2):
    q, qdot = rng.uniform(-1, 1, n), rng.uniform(-1, 1, n)
    return q, qdot, (rng.uniform(-1, 1, n), rng.uniform(-1, 1, n), rng.uniform(-1, 1, n))


def random_spd(rng, n, shift=0.5):
    A = rng.standard_normal((n, n))
    return A @ A.T + shift * np.eye(n)


@pytest.fixture(scope="module")
def arm():
    return TwoLinkArm()


@pytest.fixture(scope="module")
def arm_gains(arm):
    # The brief's gains: κ = 2, k_b = 10, ϑ = M̂(0)⁻¹ of the (exact) arm model.
    return dict(kappa=2.0, vartheta=np.linalg.inv(arm.mass_matrix(np.zeros(2))[0]), k_b=10.0)


# --------------------------------------------------------------------------------------------
# e_z: exact integral of the held commands
# --------------------------------------------------------------------------------------------


def window_cases():
    rng = np.random.default_rng(3)
    varying = rng.uniform(0.0, HISTORY, 40)
    varying[[5, 11, 17]] = [0.0, 0.03, HISTORY]  # a zero window, a multiple of T_c, the maximum
    return {
        "multiple": ("pconf", 0.05, None),
        "non-multiple": ("pconf", 0.0537, None),
        "zero": ("pconf", 0.0, None),
        "full history": ("pconf", HISTORY, None),
        "varying (PCON)": ("pcon", None, varying),
    }


@pytest.mark.parametrize("case", list(window_cases()))
def test_e_z_is_the_exact_integral_of_the_held_commands(arm, case):
    kind, h_bar, varying = window_cases()[case]
    rng = np.random.default_rng(5)
    gains = dict(kappa=1.5, vartheta=random_spd(rng, 2), k_b=random_spd(rng, 2))
    if kind == "pcon":
        controller = PCON(arm, **gains, history=HISTORY, T_c=T_C)
    else:
        controller = PCONf(arm, **gains, history=HISTORY, T_c=T_C, h_bar=h_bar)
    ticks = 40
    assert ticks > 3 * controller.slots  # the ring wraps around several times
    state = controller.initial_state()
    taus = []
    for k in range(ticks):
        # PCONf must ignore the true delay it is handed; PCON must use it.
        h = float(varying[k]) if varying is not None else float(rng.uniform(0.0, HISTORY))
        window = h if kind == "pcon" else h_bar
        q, qdot, reference = random_sample(rng)
        command, state = controller.step(1000.0 + k * T_C, q, qdot, reference, state, T_c=T_C, h=h)
        e_z = state[:2]
        expected = exact_window_integral(taus, k, window, T_C)
        np.testing.assert_allclose(e_z, expected, rtol=1e-12, atol=1e-15)
        if window == 0.0 or k == 0:
            assert np.all(e_z == 0.0)
        taus.append(command)  # the arm's G = I: the command is τ
    assert np.abs(np.array(taus)).min() > 0.0  # not vacuous: every tick contributes


def test_e_z_in_a_simulation_uses_the_true_delay_of_each_tick(arm, arm_gains):
    # The engine hands PCON h(t_k) of a time-varying profile (S1: 20–100 ms over t in [0, π/2]);
    # the e_z recorded at row k + 1 (the state after tick k) is the integral of the recorded
    # commands over that window.
    T_c = 0.002
    controller = PCON(arm, **arm_gains, history=0.1, T_c=T_c)
    result = simulate(
        arm,
        controller,
        AbsSineDelay.S1(),
        np.zeros(4),
        reference=ARM_REFERENCE,
        t1=1.6,
        dt=0.001,
        T_c=T_c,
    )
    assert result.ok.all()
    commands, h, e_z = result.commands[0], result.h[0], result.controller_state[0, :, :2]
    assert h.min() < 0.021 and h.max() > 0.099
    for k in range(0, commands.shape[0] - 1, 7):
        # Only the last 60 ticks can overlap a window of at most 0.1 s = 50 T_c.
        first = max(0, k - 60)
        expected = exact_window_integral(list(commands[first:k]), k - first, h[k], T_c)
        np.testing.assert_allclose(e_z[k + 1], expected, rtol=1e-12, atol=1e-15)


# --------------------------------------------------------------------------------------------
# The law
# --------------------------------------------------------------------------------------------


def warm_state(controller, rng, ticks=15, h=0.05):
    state = controller.initial_state()
    for k in range(ticks):
        q, qdot, reference = random_sample(rng, controller.n)
        _, state = controller.step(k * T_C, q, qdot, reference, state, T_c=T_C, h=h)
    return state


@pytest.mark.parametrize("model_kind", ["arm", "linear with G"])
def test_command_is_k_b_rho_through_the_command_map(arm, model_kind):
    rng = np.random.default_rng(11)
    if model_kind == "arm":
        model, G = arm, np.eye(2)
    else:
        G = np.array([[2.0, 0.5], [-1.0, 1.0]])
        model = LinearPlant(random_spd(rng, 2), rng.standard_normal((2, 2)), None, G)
    kappa, vartheta, k_b = 1.7, random_spd(rng, 2), random_spd(rng, 2)
    for controller in (
        PCON(model, kappa, vartheta, k_b, HISTORY, T_C),
        PCONf(model, kappa, vartheta, k_b, HISTORY, T_C, h_bar=0.043),
    ):
        for _ in range(10):
            state = warm_state(controller, rng)
            q, qdot, (qd, qd_dot, qd_ddot) = random_sample(rng)
            command, after = controller.step(
                0.5, q, qdot, (qd, qd_dot, qd_ddot), state, T_c=T_C, h=0.071
            )
            e_z = after[:2]
            # Roy & Kar (filter) and D23: ϱ = ė1 + κ e1 − ϑ e_z, τ = k_b ϱ, command = Ĝ⁻¹ τ.
            rho = (qd_dot - qdot) + kappa * (qd - q) - vartheta @ e_z
            np.testing.assert_allclose(after[2:4], rho, rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(
                command, np.linalg.solve(G, k_b @ rho), rtol=1e-10, atol=1e-10
            )
            assert np.linalg.norm(vartheta @ e_z) > 1e-3  # the predictor term is not vacuous
            # The step does not read q̈_d.
            again, _ = controller.step(
                0.5, q, qdot, (qd, qd_dot, qd_ddot + 5.0), state, T_c=T_C, h=0.071
            )
            np.testing.assert_array_equal(again, command)


def test_state_layout_and_names(arm, arm_gains):
    controller = PCON(arm, **arm_gains, history=0.06, T_c=0.002)
    # ceil(0.06 / 0.002) + 2 = 32 ticks of τ (n = 2) after 2n recorded entries and the count.
    assert controller.slots == ring_slots(0.06, 0.002) == 32
    assert controller.state_size == 4 + 1 + 32 * 2
    assert controller.state_names == (
        "e_z_previous_0",
        "e_z_previous_1",
        "rho_previous_0",
        "rho_previous_1",
    )
    np.testing.assert_array_equal(controller.initial_state(), np.zeros(69))
    assert PCON.needs_delay and not PCONf.needs_delay


def test_python_nominal_model_runs_the_same_step(arm, arm_gains):
    # A CallablePlant model runs the step as plain Python: the same numbers.
    user = CallablePlant(2, arm_mass, arm_nonlinear)
    assert not user.compiled
    rng = np.random.default_rng(2)
    python = PCON(user, **arm_gains, history=HISTORY, T_c=T_C)
    compiled = PCON(arm, **arm_gains, history=HISTORY, T_c=T_C)
    state_a, state_b = python.initial_state(), compiled.initial_state()
    for k in range(20):
        q, qdot, reference = random_sample(rng)
        h = float(rng.uniform(0.0, HISTORY))
        command_a, state_a = python.step(k * T_C, q, qdot, reference, state_a, T_c=T_C, h=h)
        command_b, state_b = compiled.step(k * T_C, q, qdot, reference, state_b, T_c=T_C, h=h)
        np.testing.assert_allclose(command_a, command_b, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(state_a, state_b, rtol=1e-12, atol=1e-15)


# --------------------------------------------------------------------------------------------
# Closed loop
# --------------------------------------------------------------------------------------------


def arm_run(arm, controller, delay=0.06, t1=5.0):
    return simulate(
        arm,
        controller,
        ConstantDelay(delay),
        np.zeros(4),
        reference=ARM_REFERENCE,
        t1=t1,
        dt=0.001,
        T_c=0.002,
    )


def test_pconf_tracks_the_arm_under_its_delay_and_pcon_equals_it(arm, arm_gains):
    pconf = arm_run(arm, PCONf(arm, **arm_gains, history=0.1, T_c=0.002, h_bar=0.06))
    assert pconf.ok.all() and np.all(np.isfinite(pconf.x))
    error = pconf.e1[0]
    # Measured at writing: max |e1| = (0.139, 0.077) rad and RMS over the last 2 s (0.057, 0.068)
    # rad, for a reference of amplitude (0.8, 0.5) rad; these soft, untuned gains leave a lag
    # of about 10 % of the amplitude. The bounds allow a factor of about 1.4.
    assert np.all(np.abs(error).max(axis=0) < [0.2, 0.11])
    assert np.all(np.sqrt(np.mean(error[-1000:] ** 2, axis=0)) < [0.08, 0.095])
    # PCON given the true (constant) delay computes the same law.
    pcon = arm_run(arm, PCON(arm, **arm_gains, history=0.1, T_c=0.002))
    for name in ("x", "commands", "applied", "controller_state"):
        np.testing.assert_array_equal(getattr(pcon, name), getattr(pconf, name))


def test_without_its_predictor_the_same_law_diverges(arm, arm_gains):
    # h̄ = 0 makes e_z = 0: the PD law τ = k_b (ė1 + κ e1) with the same gains. Under the 60 ms
    # delay it diverges (measured: status "diverged"), while the predictor (previous test) tracks.
    run = arm_run(arm, PCONf(arm, **arm_gains, history=0.1, T_c=0.002, h_bar=0.0))
    assert run.status_names[0] == "diverged"


@pytest.mark.parametrize("delay", [0.05, 0.047])
def test_predictor_cancels_the_delayed_input(delay):
    # Pure inertia M q̈ = τ(t − h) (D = K = 0, N = 0), exact model, ϑ = M⁻¹, q_d linear in t
    # (q̈_d = 0). Differentiating (filter) with (int error) (docs/decisions.md D23):
    # M ϱ̇ = M(q̈_d + κ ė1) + N − τ(t) + [(1 − ḣ) M ϑ − I] τ(t − h), so
    # over one tick  M (ϱ_{k+1} − ϱ_k − κ (e1_{k+1} − e1_k)) = −T_c τ_k  exactly (RK4 is exact
    # for the piecewise-quadratic q). A wrong ϑ leaves the delayed input in: the residual is
    # then −T_c ((1 − M ϑ) τ_{k−…}) ≠ 0.
    mass = np.array([[2.0, 0.3], [0.3, 0.5]])
    plant = LinearPlant(mass)
    reference = SinusoidalReference([0.2, -0.1], slope=[0.3, 0.1])
    kappa, T_c = 1.0, 0.01

    def residuals(vartheta):
        controller = PCONf(plant, kappa, vartheta, 3.0, 0.1, T_c, h_bar=delay)
        run = simulate(
            plant,
            controller,
            ConstantDelay(delay),
            np.array([0.0, 0.0, 0.5, -0.5]),
            reference=reference,
            t1=3.0,
            dt=0.001,
            T_c=T_c,
        )
        assert run.ok.all()
        rho = run.controller_state[0, 1:, 2:4]  # ϱ_k, recorded at row k + 1
        e1, tau = run.e1[0], run.commands[0, :-1]
        left = (rho[1:] - rho[:-1] - kappa * (e1[1:-1] - e1[:-2])) @ mass.T
        return left + T_c * tau[:-1], T_c * np.abs(tau).max()

    exact, scale = residuals(np.linalg.inv(mass))
    assert np.abs(exact).max() < 1e-12 * scale  # measured: 4e-14 * scale
    wrong, _ = residuals(0.5 * np.linalg.inv(mass))
    assert np.abs(wrong).max() > 1e-2 * scale


# --------------------------------------------------------------------------------------------
# Refusals
# --------------------------------------------------------------------------------------------

GOOD = dict(kappa=2.0, vartheta=1.0, k_b=10.0, history=0.1, T_c=0.002)


@pytest.mark.parametrize(
    "changes, message",
    [
        (dict(kappa=0.0), r"kappa must be > 0; got 0"),
        (dict(kappa=-1.0), r"kappa must be > 0; got -1"),
        (dict(kappa=float("inf")), r"kappa must be finite; got inf"),
        (dict(k_b=0.0), r"k_b must be symmetric positive definite; its eigenvalues are \[0, 0\]"),
        (dict(k_b=-10.0), r"k_b must be symmetric positive definite; its eigenvalues are \[-10"),
        (
            dict(vartheta=[[1.0, 2.0], [2.0, 1.0]]),
            r"vartheta must be symmetric positive definite; its eigenvalues are \[-1, 3\]",
        ),
        (
            dict(vartheta=[[1.0, 0.5], [0.0, 1.0]]),
            r"vartheta must be symmetric positive definite; it is not symmetric",
        ),
        (dict(vartheta=np.eye(3)), r"vartheta must be 2x2; got shape \(3, 3\)"),
        (dict(history=0.0), r"history must be > 0; got 0"),
        (dict(history=-0.1), r"history must be > 0; got -0\.1"),
        (dict(T_c=0.0), r"T_c must be > 0; got 0"),
    ],
)
@pytest.mark.parametrize("kind", [PCON, PCONf])
def test_bad_gains_refused(arm, kind, changes, message):
    extra = {"h_bar": 0.05} if kind is PCONf else {}
    with pytest.raises(ValueError, match=message):
        kind(arm, **{**GOOD, **changes}, **extra)


@pytest.mark.parametrize(
    "h_bar, history, message",
    [
        (-0.01, 0.1, r"h_bar must be >= 0; got -0\.01"),
        (0.12, 0.1, r"h_bar = 0\.12 s exceeds history = 0\.1 s"),
        (float("nan"), 0.1, r"h_bar must be finite; got nan"),
    ],
)
def test_pconf_window_refused(arm, h_bar, history, message):
    with pytest.raises(ValueError, match=message):
        PCONf(arm, **{**GOOD, "history": history}, h_bar=h_bar)


def test_the_shared_law_is_not_a_controller_by_itself(arm):
    with pytest.raises(TypeError, match=r"build a PCON or a PCONf"):
        PredictorBaseline(arm, **GOOD)


def test_step_refuses_what_the_state_cannot_serve(arm):
    controller = PCON(arm, **GOOD)
    call = (0.0, np.zeros(2), np.zeros(2), (np.ones(2), np.zeros(2), np.zeros(2)))
    state = controller.initial_state()
    with pytest.raises(ValueError, match=r"PCON needs the true delay: pass h=\.\.\."):
        controller.step(*call, state, T_c=0.002)
    with pytest.raises(ValueError, match=r"delay 0\.11 s exceeds history = 0\.1 s"):
        controller.step(*call, state, T_c=0.002, h=0.11)
    with pytest.raises(ValueError, match=r"T_c = 0\.004 s differs from the period .* 0\.002 s"):
        controller.step(*call, state, T_c=0.004, h=0.05)
    controller.check_run(0.002, 0.1)
    with pytest.raises(ValueError, match=r"delay 0\.2 s exceeds history"):
        controller.check_run(0.002, 0.2)
    with pytest.raises(
        ValueError,
        match=r"T_c = 0\.004 s differs from the period PCON was built for \(T_c = 0\.002 s\)",
    ):
        controller.check_run(0.004, 0.1)
    # PCONf never reads the true delay: any bound, any h.
    fixed = PCONf(arm, **GOOD, h_bar=0.05)
    fixed.check_run(0.002, 10.0)
    command, _ = fixed.step(*call, fixed.initial_state(), T_c=0.002, h=10.0)
    assert np.all(np.isfinite(command))


@pytest.mark.parametrize(
    "delay, T_c, message",
    [
        (0.12, 0.002, r"delay 0\.12 s exceeds history = 0\.1 s"),
        (
            0.05,
            0.004,
            r"T_c = 0\.004 s differs from the period PCON was built for \(T_c = 0\.002 s\)",
        ),
    ],
    ids=["delay beyond history", "other T_c"],
)
def test_simulate_refuses_a_run_the_law_cannot_do(arm, arm_gains, delay, T_c, message):
    # Refused before the run (Controller.check_run); the compiled step's own guard (a NaN
    # command, reported as "diverged") stays as a second line of defence.
    controller = PCON(arm, **arm_gains, history=0.1, T_c=0.002)
    with pytest.raises(ValueError, match=message):
        simulate(
            arm,
            controller,
            ConstantDelay(delay),
            np.zeros(4),
            reference=ARM_REFERENCE,
            t1=0.2,
            dt=0.001,
            T_c=T_c,
        )


# --------------------------------------------------------------------------------------------
# Registry
# --------------------------------------------------------------------------------------------


def test_controller_from_spec(arm):
    spec = {"type": "pcon", "kappa": 2.0, "vartheta": [0.3, 6.0], "k_b": 10.0, "history": 0.1}
    pcon = controller_from_spec({**spec, "T_c": 0.002}, arm)
    assert isinstance(pcon, PCON) and pcon.needs_delay
    np.testing.assert_array_equal(pcon.vartheta, np.diag([0.3, 6.0]))
    np.testing.assert_array_equal(pcon.k_b, 10.0 * np.eye(2))
    rebuilt = controller_from_spec(pcon.to_spec(), arm)
    assert type(rebuilt) is PCON
    np.testing.assert_array_equal(rebuilt.params, pcon.params)

    pconf = controller_from_spec({**spec, "type": "pconf", "T_c": 0.002, "h_bar": 0.06}, arm)
    assert isinstance(pconf, PCONf) and pconf.h_bar == 0.06 and not pconf.needs_delay
    rebuilt = controller_from_spec(pconf.to_spec(), arm)
    assert type(rebuilt) is PCONf
    np.testing.assert_array_equal(rebuilt.params, pconf.params)

    with pytest.raises(ValueError, match=r"scenario key 'controller\.T_c' is missing"):
        controller_from_spec(spec, arm)
    with pytest.raises(ValueError, match=r"scenario key 'controller\.h_bar' is missing"):
        controller_from_spec({**spec, "type": "pconf", "T_c": 0.002}, arm)
    with pytest.raises(ValueError, match=r"unknown key 'controller\.h_bar' .* type = 'pcon'"):
        controller_from_spec({**spec, "T_c": 0.002, "h_bar": 0.06}, arm)
    with pytest.raises(ValueError, match=r"scenario key 'controller\.kappa' must be > 0; got 0"):
        controller_from_spec({**spec, "T_c": 0.002, "kappa": 0.0}, arm)
    with pytest.raises(
        ValueError, match=r"scenario key 'controller\.vartheta' must be symmetric positive"
    ):
        controller_from_spec({**spec, "T_c": 0.002, "vartheta": [1.0, -1.0]}, arm)
    with pytest.raises(
        ValueError, match=r"scenario key 'controller\.h_bar' = 0\.2 s exceeds history = 0\.1 s"
    ):
        controller_from_spec({**spec, "type": "pconf", "T_c": 0.002, "h_bar": 0.2}, arm)
    with pytest.raises(ValueError, match=r"scenario key 'controller\.history' must be a number"):
        controller_from_spec({**spec, "T_c": 0.002, "history": "0.1"}, arm)


def test_batch_equals_single_runs(arm, arm_gains):
    controllers = [
        PCON(arm, **arm_gains, history=0.1, T_c=0.002),
        PCON(arm, **{**arm_gains, "kappa": 3.0}, history=0.1, T_c=0.002),
    ]
    delays = [ConstantDelay(0.06), AbsSineDelay.S1()]
    settings = dict(reference=ARM_REFERENCE, t1=0.5, dt=0.001, T_c=0.002)
    batch = simulate(arm, controllers, delays, np.zeros(4), **settings)
    for b in range(2):
        single = simulate(arm, controllers[b], delays[b], np.zeros(4), **settings)
        np.testing.assert_array_equal(batch.x[b], single.x[0])
        np.testing.assert_array_equal(batch.controller_state[b], single.controller_state[0])


# --------------------------------------------------------------------------------------------
# What PCON is told of the delay
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize(("scale", "offset"), [(2.0, 0.0), (1.0, -0.01), (0.5, 0.005)])
def test_pcon_told_a_wrong_constant_delay_is_pconf_with_that_window(arm, arm_gains, scale, offset):
    # Under a true constant delay of 30 ms, PCON told s h + b runs the law of PCONf with
    # h_bar = s h + b, bit for bit.
    settings = dict(reference=ARM_REFERENCE, t1=2.0, dt=0.001, T_c=0.002)
    told = PCON(arm, **arm_gains, history=0.1, T_c=0.002, delay_scale=scale, delay_offset=offset)
    fixed = PCONf(arm, **arm_gains, history=0.1, T_c=0.002, h_bar=scale * 0.03 + offset)
    a = simulate(arm, told, ConstantDelay(0.03), np.zeros(4), **settings)
    b = simulate(arm, fixed, ConstantDelay(0.03), np.zeros(4), **settings)
    np.testing.assert_array_equal(a.x, b.x)
    np.testing.assert_array_equal(a.commands, b.commands)
    exact = simulate(
        arm,
        PCON(arm, **arm_gains, history=0.1, T_c=0.002),
        ConstantDelay(0.03),
        np.zeros(4),
        **settings,
    )
    assert not np.array_equal(exact.x, a.x)


def test_the_noisy_estimate_is_seeded_bounded_and_recorded_in_e_z(arm, arm_gains):
    T_c = 0.002
    noisy = PCON(arm, **arm_gains, history=0.2, T_c=T_c, delay_noise=0.01, noise_seed=7)
    settings = dict(reference=ARM_REFERENCE, t1=1.6, dt=0.001, T_c=T_c)
    delay = AbsSineDelay.S1()
    result = simulate(arm, noisy, delay, np.zeros(4), **settings)
    again = simulate(arm, [noisy, noisy], [delay, delay], np.zeros(4), **settings)
    np.testing.assert_array_equal(again.x[1], result.x[0])
    other = simulate(
        arm,
        PCON(arm, **arm_gains, history=0.2, T_c=T_c, delay_noise=0.01, noise_seed=8),
        delay,
        np.zeros(4),
        **settings,
    )
    assert not np.array_equal(other.x, result.x)
    ticks = np.arange(result.commands.shape[1]) * T_c
    told = told_delays(result.h[0], ticks, T_c, noise=0.01, seed=7)
    error = told - result.h[0]
    assert np.all(told >= 0.0) and np.all(np.abs(error[told > 0]) <= 0.06)
    assert 0.006 < np.std(error) < 0.014 and abs(np.mean(error)) < 0.003  # σ = 10 ms
    commands, e_z = result.commands[0], result.controller_state[0, :, :2]
    for k in range(0, commands.shape[0] - 1, 7):
        first = max(0, k - 100)
        expected = exact_window_integral(list(commands[first:k]), k - first, told[k], T_c)
        np.testing.assert_allclose(e_z[k + 1], expected, rtol=1e-12, atol=1e-15)


def test_the_noise_is_near_standard_normal():
    xi = np.array([standard_noise(3, k) for k in range(20000)])
    assert abs(xi.mean()) < 0.03 and abs(xi.std() - 1.0) < 0.03 and np.abs(xi).max() <= 6.0
    assert abs(np.corrcoef(xi[:-1], xi[1:])[0, 1]) < 0.03  # consecutive ticks independent
    assert hash32(2**32 + 5) == hash32(5) and 0 <= hash32(-1) < 2**32


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        (dict(delay_scale=-1.0), "delay_scale"),
        (dict(delay_offset=float("nan")), "delay_offset"),
        (dict(delay_offset="0.01"), "delay_offset must be a real number; got '0.01'"),
        (dict(delay_noise=-0.01), "delay_noise"),
        (dict(noise_seed=-1), "noise_seed must be an integer from 0 to 4294967295"),
        (dict(noise_seed=1.5), "noise_seed"),
    ],
)
def test_bad_delay_knowledge_refused(arm, arm_gains, changes, message):
    with pytest.raises((ValueError, TypeError), match=message):
        PCON(arm, **arm_gains, history=0.1, T_c=T_C, **changes)


def test_a_told_delay_beyond_the_history_is_refused(arm, arm_gains):
    controller = PCON(arm, **arm_gains, history=0.15, T_c=T_C, delay_scale=2.0, delay_noise=0.01)
    with pytest.raises(ValueError, match=r"2 · 0.1 \+ 0 \+ 6 · 0.01 = 0.26 s .* history = 0.15 s"):
        controller.check_run(T_C, 0.1)
    spec = controller.to_spec()
    assert spec["delay_scale"] == 2.0 and spec["delay_noise"] == 0.01 and "noise_seed" not in spec
    rebuilt = controller_from_spec(spec, arm)
    np.testing.assert_array_equal(rebuilt.params, controller.params)


def test_a_batch_of_predictors_with_different_histories_is_refused(arm, arm_gains):
    short, long = (PCON(arm, **arm_gains, history=h, T_c=T_C) for h in (0.1, 0.2))
    with pytest.raises(
        ValueError, match=r"controller\[1\] keeps .* give every one the same history"
    ):
        simulate(
            arm,
            [short, long],
            ConstantDelay(0.05),
            np.zeros(4),
            reference=ARM_REFERENCE,
            t1=0.1,
            dt=0.001,
            T_c=T_C,
        )


# --------------------------------------------------------------------------------------------
# The law in actuator space (for the wheeled robot: wheel space)
# --------------------------------------------------------------------------------------------


def test_actuator_space_law_on_the_robot_integrates_the_wheel_commands():
    # ϱ = S(q)ᵀ(ė1 + κ e1) − ϑ e_z, u = k_b ϱ, with e_z the exact integral of the wheel commands
    # u actually sent (the oracle integrates the returned commands over absolute tick intervals).
    from delaytrack.plants.robot import NominalRobot
    from delaytrack.plants.robot.kinematics import kinematic_map

    robot = NominalRobot()
    rng = np.random.default_rng(21)
    kappa, vartheta, k_b = 1.3, random_spd(rng, 2), random_spd(rng, 2)
    controller = PCON(robot, kappa, vartheta, k_b, HISTORY, T_C, space="actuator")
    assert controller.law_size == 2 and controller.state_size == 4 + 1 + controller.slots * 2
    assert controller.state_names == (
        "e_z_previous_0",
        "e_z_previous_1",
        "rho_previous_0",
        "rho_previous_1",
    )
    state = controller.initial_state()
    commands = []
    for k in range(30):
        h = float(rng.uniform(0.0, HISTORY))
        q, qdot, (qd, qd_dot, qd_ddot) = random_sample(rng, 5)
        command, state = controller.step(
            3.0 + k * T_C, q, qdot, (qd, qd_dot, qd_ddot), state, T_c=T_C, h=h
        )
        e_z = exact_window_integral(commands, k, h, T_C, n=2)
        np.testing.assert_allclose(state[:2], e_z, rtol=1e-12, atol=1e-15)
        S = kinematic_map(q, robot.wheel_radius, robot.half_track, robot.d)
        rho = S.T @ ((qd_dot - qdot) + kappa * (qd - q)) - vartheta @ e_z
        np.testing.assert_allclose(state[2:4], rho, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(command, k_b @ rho, rtol=1e-12, atol=1e-12)
        commands.append(command)
    assert np.linalg.norm(vartheta @ state[:2]) > 1e-3  # the predictor term is not vacuous


def test_both_spaces_coincide_for_scalar_gains_only():
    # With scalar ϑ and k_b the map commutes with them, S(q)ᵀ(k_b(v − ϑ ∫τ)) = k_b(Sᵀv − ϑ ∫Sᵀτ)
    # at a fixed q, so both spaces give the same commands; a matrix ϑ (the estimate of M⁻¹ in
    # five coordinates against one of M_r⁻¹ in two) makes them different laws.
    from delaytrack.plants.robot import NominalRobot

    robot = NominalRobot()
    rng = np.random.default_rng(4)
    q, qdot, reference = random_sample(rng, 5)

    def commands(vartheta, space):
        controller = PCONf(robot, 2.0, vartheta, 3.0, HISTORY, T_C, h_bar=0.05, space=space)
        state, out = controller.initial_state(), []
        for k in range(8):
            command, state = controller.step(k * T_C, q, qdot, reference, state, T_c=T_C)
            out.append(command)
        return np.array(out)

    same = commands(0.5, "actuator")
    np.testing.assert_allclose(commands(0.5, "generalised"), same, rtol=1e-12)
    other = commands(np.diag([0.5, 0.5, 2.0, 0.5, 0.5]), "generalised")
    assert np.abs(other - same).max() > 1e-3 * np.abs(same).max()


def test_actuator_space_in_a_spec_a_batch_and_refusals(arm, arm_gains):
    spec = {"type": "pconf", "kappa": 2.0, "vartheta": 0.3, "k_b": 10.0, "history": 0.1}
    spec |= {"T_c": 0.002, "h_bar": 0.06, "space": "actuator"}
    pconf = controller_from_spec(spec, arm)
    assert pconf.space == "actuator" and pconf.to_spec()["space"] == "actuator"
    np.testing.assert_array_equal(controller_from_spec(pconf.to_spec(), arm).params, pconf.params)
    assert "space" not in PCONf(arm, **arm_gains, history=0.1, T_c=0.002, h_bar=0.06).to_spec()
    # The arm's G = I: in actuator space the law is the generalised one (to rounding) and it
    # tracks; a batch of both spaces equals the runs alone.
    controllers = [
        PCONf(arm, **arm_gains, history=0.1, T_c=0.002, h_bar=0.06),
        PCONf(arm, **arm_gains, history=0.1, T_c=0.002, h_bar=0.06, space="actuator"),
    ]
    settings = dict(reference=ARM_REFERENCE, t1=2.0, dt=0.001, T_c=0.002)
    batch = simulate(arm, controllers, ConstantDelay(0.06), np.zeros(4), **settings)
    assert batch.ok.all()
    np.testing.assert_allclose(batch.x[1], batch.x[0], rtol=0, atol=1e-10)
    alone = simulate(arm, controllers[1], ConstantDelay(0.06), np.zeros(4), **settings)
    np.testing.assert_array_equal(batch.x[1], alone.x[0])
    with pytest.raises(ValueError, match=r"space must be one of \('generalised', 'actuator'\)"):
        PCON(arm, **arm_gains, history=0.1, T_c=0.002, space="wheel")
    with pytest.raises(ValueError, match=r"scenario key 'controller\.space' must be a string"):
        controller_from_spec({**spec, "space": 1}, arm)
