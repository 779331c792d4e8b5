"""The simulation engine (docs/decisions.md D10–D17): delayed lookup, step splitting, order,
batching, status."""

from __future__ import annotations

import numba
import numpy as np
import pytest
from scipy.linalg import expm
from scipy.optimize import brentq

from delaytrack._counter_noise import standard_noise, uniform
from delaytrack.controllers import AROLC, OuterLoop
from delaytrack.delays import (
    AbsSineDelay,
    CompiledDelay,
    ConstantDelay,
    DelayProfile,
    PiecewiseConstantDelay,
    RandomDelay,
)
from delaytrack.plants import CallablePlant, CompiledPlant, LinearPlant, TwoLinkArm
from delaytrack.references import SinusoidalReference
from delaytrack.sim import MeasurementNoise, PacketLoss, SimResult, simulate
from delaytrack.sim.history import latest_tick_index, latest_tick_index_from
from delaytrack.sim.integrator import TickArguments, beyond, integrate_reduced_tick, integrate_tick

# A damped point mass q̈ = -c q̇ + u under a sampled PD law u = -K2 q̇ - K1 q (q_d = 0): linear,
# so its exact solution between input switches is a matrix exponential.
DAMPING = 30.0
K1, K2 = 20.0, 6.0
T_C = 0.01

ARM_REFERENCE = SinusoidalReference([0.0, 0.0], amplitude=[[0.8], [0.5]], frequency=[[1.0], [1.7]])


def point_mass_loop() -> tuple[LinearPlant, OuterLoop, SinusoidalReference]:
    plant = LinearPlant(mass=1.0, damping=DAMPING)
    controller = OuterLoop(LinearPlant(mass=1.0), K1=K1, K2=K2)
    return plant, controller, SinusoidalReference([0.0])


def point_mass_run(delay: DelayProfile, **settings) -> SimResult:
    """The point-mass loop from ``q = 1`` at rest, ``dt`` = 1 ms, ``T_c`` = :data:`T_C`, under
    ``delay``, with ``settings`` (``t1`` and other keywords of ``simulate``)."""
    plant, controller, reference = point_mass_loop()
    return simulate(
        plant, controller, delay, [1.0, 0.0], reference=reference, dt=1e-3, T_c=T_C, **settings
    )


def arm_arolc() -> AROLC:
    nominal = TwoLinkArm(p1=3.0, p2=0.17, p3=0.2, fd1=0.0, fd2=0.0)
    return AROLC(nominal, K1=4.0, K2=4.0, Q=1.0, alpha=2.0, epsilon=0.1, gamma=0.001)


def short_arm_run(**options):
    """0.1 s of the arm under AROLC and a 10 ms delay (for checks of what simulate refuses)."""
    return simulate(
        TwoLinkArm(),
        arm_arolc(),
        ConstantDelay(0.01),
        np.zeros(4),
        reference=ARM_REFERENCE,
        t1=0.1,
        dt=1e-3,
        T_c=2e-3,
        **options,
    )


def brute_force_index(t: float, delay: DelayProfile, tick_times: np.ndarray) -> int:
    """Index of the latest command issued at or before ``t - h(t)``, by scanning the whole log."""
    issued = np.flatnonzero(tick_times <= t - float(delay.h(t)))
    return int(issued[-1]) if issued.size else -1


@numba.njit
def own_delay(t, params):
    """A delay kernel of a user's, in two shapes. ``params[0] = 0``: a tanh rise plus a ripple,
    |dh/dt| < 1. ``params[0] = 1``: a jump down (t - h(t) jumps forward) at ``params[3]``. One
    kernel for both, so that each closed loop compiles one engine for them."""
    if params[0] == 0.0:
        rise = np.tanh((t - params[3]) / params[4])
        return params[1] + params[2] * rise + 0.01 * np.sin(7.0 * t)
    return params[1] if t < params[3] else params[2]


def own_delays() -> list[CompiledDelay]:
    return [
        CompiledDelay(own_delay, [0.0, 0.035, 0.02, 0.4, 0.05], h_max=0.07, name="rise"),
        CompiledDelay(own_delay, [1.0, 0.061, 0.0137, 0.5031], h_max=0.07, name="drop"),
    ]


def fast_random_delay() -> RandomDelay:
    # max_rate 3 gives stretches with dh/dt > 1, where t - h(t) runs back and older commands
    # come back.
    return RandomDelay(
        h_low=0.0, h_high=0.08, max_rate=3.0, duration=2.0, seed=11, knot_spacing=0.013
    )


# First in the suite (tests/conftest.py): this compiles the engine with the linear plant's
# integrator and the outer loop's step, which tests/test_cli_empirical.py, usually started by the
# other worker after they are done, then loads from numba's cache instead of compiling them too.
def test_input_before_the_first_command_arrives_is_u_init() -> None:
    result = point_mass_run(ConstantDelay(0.0505), t1=0.2, u_init=[0.75])
    early = result.t < 0.0505
    np.testing.assert_array_equal(result.applied[0, early, 0], 0.75)
    assert result.applied[0, ~early, 0][0] == result.commands[0, 0, 0]


# --- the lookup itself -------------------------------------------------------------------------


def test_latest_tick_index_equals_a_scan_of_all_tick_times() -> None:
    rng = np.random.default_rng(0)
    t0, dt, steps = 0.3, 1e-3, 7
    ticks = t0 + (np.arange(2000) * steps) * dt
    samples = np.concatenate(
        [rng.uniform(t0 - 0.1, ticks[-1], 3000), ticks[:200], ticks[:200] - 1e-15]
    )
    for g in samples:
        issued = np.flatnonzero(ticks <= g)
        expected = int(issued[-1]) if issued.size else -1
        assert latest_tick_index(g, t0, dt, steps) == expected
        hint = int(rng.integers(-1, 2000))
        assert latest_tick_index_from(g, hint, t0, dt, steps) == expected


@pytest.mark.parametrize(
    "delay",
    [
        ConstantDelay(0.0623),
        ConstantDelay(0.06),  # a multiple of T_c: every switch falls on a step boundary
        AbsSineDelay.S1(),
        AbsSineDelay(offset=0.01, amplitude=0.05, frequency=30.0),  # A·ω = 1.5: g non-monotone
        PiecewiseConstantDelay([0.0, 0.5, 0.9, 1.4], [0.03, 0.011, 0.07, 0.0]),
        fast_random_delay(),
        *own_delays(),
    ],
    ids=[
        "constant",
        "constant-aligned",
        "S1",
        "fast-sine",
        "piecewise",
        "random-fast",
        "own-rise",
        "own-drop",
    ],
)
def test_applied_input_is_the_latest_command_issued_before_t_minus_h(delay: DelayProfile) -> None:
    indices = assert_applied_is_the_latest_command(delay, t0=0.0, t1=2.0, dt=5e-4, T_c=2e-3)
    if isinstance(delay, RandomDelay):
        assert np.any(np.diff(indices) < 0), "a fast-growing delay must re-apply older commands"


def assert_applied_is_the_latest_command(delay: DelayProfile, **times: float) -> np.ndarray:
    """Run the arm under ``delay`` and check each recorded applied input against a brute-force
    lookup; return the command indices found."""
    result = simulate(
        TwoLinkArm(), arm_arolc(), delay, np.zeros(4), reference=ARM_REFERENCE, **times
    )
    commands = result.commands[0]
    assert np.all(np.abs(np.diff(commands, axis=0)).sum(axis=1) > 0), (
        "commands must differ per tick"
    )
    # The record at tick j is the input over the first sub-step after t_j; sample just inside it.
    # The last row too: it is the input a step from t1 would start with.
    probe = result.t + 0.5e-9 * times["dt"]
    indices = np.array([brute_force_index(t, delay, result.t) for t in probe])
    expected = np.where(indices[:, None] >= 0, commands[np.maximum(indices, 0)], 0.0)
    np.testing.assert_array_equal(result.applied[0], expected)
    return indices


def test_a_step_starting_a_rounding_step_before_a_knot_is_not_skipped() -> None:
    # From t0 = 0.1 the step of tick 71 starts at 0.1 + 710 dt = 0.8099999999999999, one
    # rounding step before the knot at 0.81; its first piece, that sliver, takes h at its
    # midpoint, which rounds onto the knot. The steps that skip evaluating h (no switch certain)
    # must stop short of such a piece, or its input would be another command.
    dt = 1e-3
    assert 0.1 + 710 * dt < 0.81
    delay = PiecewiseConstantDelay([0.0, 0.81], [0.0033, 0.1])
    assert_applied_is_the_latest_command(delay, t0=0.1, t1=1.0, dt=dt, T_c=1e-2)


@pytest.mark.parametrize("offset", [1e-13, -1e-13])
def test_a_crossing_within_the_sliver_tolerance_of_a_step_end_is_not_split_off(
    offset: float,
) -> None:
    # h = 3 T_c: every switch of the input falls on a step boundary. Moved by 1e-13 s (below the
    # 1e-9 dt tolerance), a switch lies just inside a step, after its start (+) or before its
    # end (-); the sliver is integrated with its neighbour's input, so the run is the same.
    # Integrating the whole step with the wrong command would move the states by ~1e-4.
    settings = dict(reference=ARM_REFERENCE, t1=1.0, dt=1e-3, T_c=T_C)
    on_boundary = simulate(
        TwoLinkArm(), arm_arolc(), ConstantDelay(3 * T_C), np.zeros(4), **settings
    )
    moved = simulate(
        TwoLinkArm(), arm_arolc(), ConstantDelay(3 * T_C + offset), np.zeros(4), **settings
    )
    np.testing.assert_array_equal(moved.applied, on_boundary.applied)
    np.testing.assert_allclose(moved.x, on_boundary.x, rtol=0, atol=1e-12)


# --- exact solution and order ------------------------------------------------------------------


def exact_sampled_solution(
    delay: DelayProfile, x0: np.ndarray, t1: float, t0: float = 0.0
) -> np.ndarray:
    """Exact state at ``t1`` of the sampled, delayed point-mass loop (independent of the engine).

    Events are the ticks (a new command from the exact state) and the instants where
    ``t - h(t)`` crosses a tick (found by bracketing on a fine grid and brentq); between events
    the input is constant and the state moves by the matrix exponential.
    """
    system = np.array([[0.0, 1.0, 0.0], [0.0, -DAMPING, 1.0], [0.0, 0.0, 0.0]])
    ticks = t0 + (np.arange(round((t1 - t0) / T_C) + 1) * T_C)
    grid = np.linspace(t0, t1, 400_001)
    g = grid - delay.h(grid)
    events = set(ticks.tolist())
    for tick in ticks:
        above = g - tick
        for i in np.flatnonzero(np.sign(above[:-1]) != np.sign(above[1:])):
            events.add(
                brentq(
                    lambda t, tick=tick: t - float(delay.h(t)) - tick,
                    grid[i],
                    grid[i + 1],
                    xtol=1e-15,
                )
            )
    times = np.array(sorted(events))
    commands: list[float] = []
    x = np.array(x0, dtype=float)
    for a, b in zip(times[:-1], times[1:], strict=True):
        k = int(round((a - t0) / T_C))
        if abs(a - ticks[min(k, ticks.size - 1)]) < 1e-12 and k == len(commands):
            commands.append(-K2 * x[1] - K1 * x[0])
        index = brute_force_index(0.5 * (a + b), delay, ticks[: len(commands)])
        u = commands[index] if index >= 0 else 0.0
        x = (expm(system * (b - a)) @ np.array([x[0], x[1], u]))[:2]
    return x


@pytest.mark.parametrize(
    ("delay", "t0"),
    [
        (ConstantDelay(0.0437), 0.0),
        (AbsSineDelay(offset=0.02, amplitude=0.05, frequency=2.0), 0.0),
        # A·ω = 1.5: t - h(t) is not monotone, so some ticks are crossed three times.
        (AbsSineDelay(offset=0.01, amplitude=0.05, frequency=30.0, phase=0.3), 0.37),
        (
            PiecewiseConstantDelay([0.1, 0.3031, 0.5, 0.62, 0.8], [0.05, 0.0123, 0.041, 0.0, 0.03]),
            0.0,
        ),
        (fast_random_delay(), 0.0),
        *((delay, 0.0) for delay in own_delays()),
    ],
    ids=[
        "constant",
        "abs-sine",
        "abs-sine-nonmonotone-t0",
        "piecewise-jumps",
        "random-fast",
        "own-rise",
        "own-drop",
    ],
)
def test_engine_converges_to_the_exact_solution_at_fourth_order(
    delay: DelayProfile, t0: float
) -> None:
    plant, controller, reference = point_mass_loop()
    x0 = np.array([1.0, -0.5])
    t1 = t0 + 1.0
    exact = exact_sampled_solution(delay, x0, t1, t0)
    errors = []
    # dt = T_c is left out: there the split sub-steps are pre-asymptotic (ratio ~2.4 measured).
    for dt in (T_C / 2, T_C / 4, T_C / 8, T_C / 16):
        result = simulate(
            plant, controller, delay, x0, reference=reference, t0=t0, t1=t1, dt=dt, T_c=T_C
        )
        errors.append(np.max(np.abs(result.x[0, -1] - exact)))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    # RK4 is fourth order when every sub-step sees a constant input; looking the input up at
    # stage times instead would give order one with a time-varying delay.
    assert errors[-1] < 1e-10, errors
    assert np.all(orders > 3.5), (errors, orders)


# --- batching, seeds, status -------------------------------------------------------------------


def test_batch_equals_single_runs_element_by_element() -> None:
    delays = [
        AbsSineDelay.S1(),
        AbsSineDelay.S2(),
        RandomDelay(0.0, 0.1, 0.5, 3.0, seed=4),
        ConstantDelay(0.06),
    ]
    x0 = np.array(
        [[0.1, -0.2, 0.0, 0.0], [0.0, 0.0, 0.5, 0.0], [0.3, 0.1, 0.0, -0.4], [0.0, 0.0, 0.0, 0.0]]
    )
    settings = dict(reference=ARM_REFERENCE, t1=3.0, dt=1e-3, T_c=2e-3)
    batch = simulate(TwoLinkArm(), arm_arolc(), delays, x0, **settings)
    for b, delay in enumerate(delays):
        single = simulate(TwoLinkArm(), arm_arolc(), delay, x0[b], **settings)
        for name in ("x", "commands", "applied", "h", "controller_state"):
            np.testing.assert_array_equal(
                getattr(batch, name)[b], getattr(single, name)[0], err_msg=name
            )


def test_same_seed_same_result_other_seed_other_result() -> None:
    settings = dict(reference=ARM_REFERENCE, t1=2.0, dt=1e-3, T_c=2e-3)
    runs = [
        simulate(
            TwoLinkArm(),
            arm_arolc(),
            RandomDelay(0.0, 0.1, 1.5, 2.0, seed=seed),
            np.zeros(4),
            **settings,
        )
        for seed in (7, 7, 8)
    ]
    np.testing.assert_array_equal(runs[0].x, runs[1].x)
    assert not np.array_equal(runs[0].x, runs[2].x)


def test_a_diverging_run_stops_with_a_status_and_the_batch_goes_on() -> None:
    plant, _, reference = point_mass_loop()
    stiff = OuterLoop(LinearPlant(mass=1.0), K1=400.0, K2=40.0)
    # K2 = 40 with a 0.2 s delay is far beyond the delay margin: the loop oscillates and grows.
    delays = [ConstantDelay(0.005), ConstantDelay(0.2)]
    result = simulate(
        plant,
        stiff,
        delays,
        [1.0, 0.0],
        reference=reference,
        t1=5.0,
        dt=1e-3,
        T_c=T_C,
        divergence_bound=1e3,
    )
    assert result.status_names == ["ok", "diverged"]
    assert result.t_stop[0] == pytest.approx(5.0)
    assert result.t_stop[1] < 5.0
    assert np.all(np.isnan(result.x[1, result.t > result.t_stop[1]]))
    alone = simulate(
        plant, stiff, delays[0], [1.0, 0.0], reference=reference, t1=5.0, dt=1e-3, T_c=T_C
    )
    np.testing.assert_array_equal(result.x[0], alone.x[0])


def test_a_non_finite_stage_stops_only_that_run() -> None:
    # A 0.6 s delay destabilises the arm; with no practical divergence bound the state overflows
    # inside an RK4 step, where the mass-matrix solve must not end the whole batch.
    delays = [ConstantDelay(0.01), ConstantDelay(0.6)]
    strong = OuterLoop(TwoLinkArm(), K1=400.0, K2=40.0)
    result = simulate(
        TwoLinkArm(),
        strong,
        delays,
        np.zeros(4),
        reference=ARM_REFERENCE,
        t1=20.0,
        dt=1e-3,
        T_c=2e-3,
        divergence_bound=1e300,
    )
    assert result.status_names == ["ok", "diverged"]


def test_the_integrators_named_arguments_are_its_own_in_its_order() -> None:
    """The engine names the integrator's arguments (``TickArguments``); both integrators take
    them in that order after their two kernels."""
    for integrator in (integrate_tick, integrate_reduced_tick):
        code = integrator.py_func.__code__
        names = code.co_varnames[: code.co_argcount]
        assert names[:2] == ("plant_terms", "delay")
        assert names[2:] == TickArguments._fields


def test_beyond_flags_non_finite_entries_and_entries_over_the_bound() -> None:
    for values, bound, expected in [
        ([0.0, -2.0], 2.0, False),
        ([0.0, -2.5], 2.0, True),
        ([np.nan, 0.0], 2.0, True),
        ([0.0, np.inf], 2.0, True),
        ([1e300, -1e300], np.inf, False),
        ([0.0, -np.inf], np.inf, True),
        ([np.nan], np.inf, True),
    ]:
        assert beyond(np.array(values), bound) is expected, (values, bound)


def test_a_non_finite_force_stops_the_run_at_the_end_of_its_step() -> None:
    @numba.njit
    def breaks_at_one_second(t, q, qdot, params, M, N, G):
        M[0, 0] = 1.0
        N[0] = np.inf if t >= 1.0005 else q[0]
        G[0, 0] = 1.0

    plant = CompiledPlant(1, 1, breaks_at_one_second, [0.0])
    controller = OuterLoop(LinearPlant(mass=1.0), K1=1.0, K2=2.0)
    result = simulate(
        plant,
        controller,
        ConstantDelay(0.0),
        [0.1, 0.0],
        reference=SinusoidalReference([0.0]),
        t1=2.0,
        dt=1e-3,
        T_c=0.01,
        divergence_bound=1e300,
    )
    assert result.status_names == ["diverged"]
    # The middle stages of the step [1, 1.001] see t = 1.0005; the run stops at its end, not at
    # the next controller tick.
    assert result.t_stop[0] == pytest.approx(1.001)


def test_a_batch_of_python_plants_runs_each_with_its_own_functions() -> None:
    def pendulum(mass: float) -> CallablePlant:
        return CallablePlant(1, lambda q: np.array([[mass]]), lambda q, qdot: 2.0 * np.sin(q))

    light, heavy = pendulum(0.5), pendulum(3.0)
    _, controller, reference = point_mass_loop()
    settings = dict(reference=reference, t1=0.3, dt=1e-3, T_c=T_C)
    batch = simulate([light, heavy], controller, ConstantDelay(0.02), [1.0, 0.0], **settings)
    for b, plant in enumerate((light, heavy)):
        alone = simulate(plant, controller, ConstantDelay(0.02), [1.0, 0.0], **settings)
        np.testing.assert_array_equal(batch.x[b], alone.x[0])
    assert not np.array_equal(batch.x[0], batch.x[1])


class _UnderstatedBound(ConstantDelay):
    """A profile that claims a smaller h_max than its delay: the engine must notice."""

    @property
    def h_max(self) -> float:
        return 0.01


def test_a_delay_beyond_the_history_is_a_status_never_a_clamp() -> None:
    result = point_mass_run(_UnderstatedBound(0.2), t1=1.0)
    assert result.status_names == ["delay beyond history"]
    assert result.t_stop[0] < 1.0


def test_python_plant_runs_the_same_engine_as_the_compiled_one() -> None:
    plant, controller, reference = point_mass_loop()
    python_plant = CallablePlant(1, lambda q: np.eye(1), lambda q, qdot: DAMPING * qdot)
    settings = dict(reference=reference, t1=0.5, dt=1e-3, T_c=T_C)
    compiled = simulate(plant, controller, AbsSineDelay.S1(), [1.0, 0.0], **settings)
    python = simulate(python_plant, controller, AbsSineDelay.S1(), [1.0, 0.0], **settings)
    assert compiled.settings["compiled"] and not python.settings["compiled"]
    np.testing.assert_allclose(python.x, compiled.x, rtol=0, atol=1e-12)


def test_record_every_decimates_the_full_record() -> None:
    plant, controller, reference = point_mass_loop()
    settings = dict(reference=reference, t1=1.0, dt=1e-3, T_c=T_C)
    full = simulate(plant, controller, AbsSineDelay.S1(), [1.0, 0.0], **settings)
    sparse = simulate(plant, controller, AbsSineDelay.S1(), [1.0, 0.0], record_every=5, **settings)
    np.testing.assert_array_equal(sparse.t, full.t[::5])
    np.testing.assert_array_equal(sparse.x, full.x[:, ::5])


# --- refused input -----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("override", "message"),
    [
        (
            {"T_c": 0.0025, "dt": 0.001},
            r"^T_c must be a positive integer multiple of dt; got T_c = 0\.0025, dt = 0\.001 "
            r"\(T_c/dt = 2\.5\)$",
        ),
        (
            {"t1": 1.005},
            r"^t1 - t0 must be a positive integer multiple of T_c; got t1 = 1\.005, t0 = 0, "
            r"T_c = 0\.01 \(\(t1 - t0\)/T_c = 100\.5\)$",
        ),
        ({"dt": -1e-3}, r"dt must be > 0; got -0\.001"),
        ({"dt": float("nan")}, r"dt must be finite"),
        ({"t1": 0.0}, r"t1 must be later than t0"),
        ({"record_every": 0}, r"record_every must be a positive integer; got 0"),
        ({"x0": [1.0, 0.0, 0.0]}, r"x0 must have shape \(2,\) or \(batch, 2\); got \(3,\)"),
        ({"x0": [np.nan, 0.0]}, r"x0 must be finite"),
        ({"x0": [2e6, 0.0]}, r"x0 must lie within divergence_bound = 1e\+06; max \|x0\| = 2e\+06"),
        (
            {"t1": 1e5, "x0": np.tile([1.0, 0.0], (1000, 1))},
            r"needs .* GiB, more than this machine.s memory; raise record_every",
        ),
        ({"t1": 1e9}, r"t1 - t0 must be at most 1e\+08 plant steps of dt per run"),
        ({"u_init": [0.0, 0.0]}, r"u_init must have shape \(1,\); got \(2,\)"),
        (
            {"delay": [ConstantDelay(0.01)] * 3, "x0": np.zeros((2, 2))},
            r"x0 has 2 rows but the batch has 3",
        ),
        ({"reference": ARM_REFERENCE}, r"reference has n = 2 coordinates; the plant has n = 1"),
    ],
)
def test_bad_simulation_settings_are_refused_with_the_offending_value(
    override: dict, message: str
) -> None:
    plant, controller, reference = point_mass_loop()
    arguments = dict(
        delay=ConstantDelay(0.01), x0=[1.0, 0.0], reference=reference, t1=1.0, dt=1e-3, T_c=T_C
    )
    arguments.update(override)
    with pytest.raises(ValueError, match=message):
        simulate(plant, controller, **arguments)


def test_a_duration_far_from_t0_is_not_refused_for_rounding() -> None:
    # With t0 = 1e5 + 0.1 the difference t1 - t0 carries rounding of order ulp(1e5), far more
    # than 1e-9 of eight ticks (found in review); the check allows for it.
    t0 = 1e5 + 0.1
    result = point_mass_run(ConstantDelay(0.01), t0=t0, t1=t0 + 8 * T_C)
    assert result.t.size == 9 and result.status_names == ["ok"]


def test_plant_and_controller_of_different_sizes_are_refused() -> None:
    _, controller, reference = point_mass_loop()
    with pytest.raises(
        ValueError, match=r"controller\[0\] has n = 1, m = 1; the plant has n = 2, m = 2"
    ):
        simulate(
            TwoLinkArm(),
            controller,
            ConstantDelay(0.01),
            np.zeros(4),
            reference=reference,
            t1=1.0,
            dt=1e-3,
            T_c=T_C,
        )


def test_saturated_actuators_apply_the_clipped_delayed_command() -> None:
    # The actuators apply clip(command, -limit, limit) of the delayed command; the record
    # `commands` keeps what the controller issued, which exceeds the limits here.
    dt, t_c = 5e-4, 2e-3
    delay = AbsSineDelay.S1()
    limits = np.array([4.0, 1.5])
    settings = dict(reference=ARM_REFERENCE, t1=2.0, dt=dt, T_c=t_c, input_limits=limits)
    result = simulate(TwoLinkArm(), arm_arolc(), delay, np.zeros(4), **settings)
    commands = result.commands[0]
    assert np.any(np.abs(commands) > limits, axis=0).all()  # not vacuous: both saturate
    probe = result.t + 0.5e-9 * dt
    indices = np.array([brute_force_index(t, delay, result.t) for t in probe])
    issued = np.where(indices[:, None] >= 0, commands[np.maximum(indices, 0)], 0.0)
    np.testing.assert_array_equal(result.applied[0], np.clip(issued, -limits, limits))
    assert result.settings["input_limits"] == limits.tolist()
    free = simulate(
        TwoLinkArm(), arm_arolc(), delay, np.zeros(4), **{**settings, "input_limits": np.inf}
    )
    assert not np.array_equal(free.x, result.x)
    # Per run: a batch with a limited and an unlimited element equals the two alone.
    unlimited = {key: value for key, value in settings.items() if key != "input_limits"}
    batch_equals_alone(
        (TwoLinkArm(), arm_arolc(), delay),
        unlimited,
        "input_limits",
        [limits, [np.inf, np.inf]],
        [result, free],
    )
    python = simulate(TwoLinkArm(), arm_arolc(), delay, np.zeros(4), engine="python", **settings)
    np.testing.assert_array_equal(python.x, result.x)


def test_limits_per_input_for_a_batch_need_no_other_engine() -> None:
    # Broadcast to (batch, m), a row of limits was laid out in Fortran order: another argument
    # type, so the engine compiled again (silently, once its first compile had been announced).
    from delaytrack.sim.engine import run_batch_compiled

    runs = dict(reference=ARM_REFERENCE, t1=0.1, dt=1e-3, T_c=T_C, x0=np.zeros((2, 4)))
    simulate(TwoLinkArm(), arm_arolc(), AbsSineDelay.S1(), **runs, input_limits=np.inf)
    compiled = len(run_batch_compiled.overloads)
    simulate(TwoLinkArm(), arm_arolc(), AbsSineDelay.S1(), **runs, input_limits=[4.0, 1.5])
    assert len(run_batch_compiled.overloads) == compiled


@pytest.mark.parametrize(
    ("limits", "u_init", "message"),
    [
        (0.0, None, "input_limits must be > 0"),
        (float("nan"), None, "input_limits must be > 0"),
        ([1.0, 2.0, 3.0], None, "input_limits must be a number > 0 or 2 of them"),
        ("high", None, "input_limits must be a number > 0"),
        (1.0, [2.0, 0.0], "u_init = \\[2.0, 0.0\\] lies beyond input_limits"),
    ],
)
def test_bad_input_limits_are_refused(limits, u_init, message) -> None:
    with pytest.raises(ValueError, match=message):
        short_arm_run(input_limits=limits, u_init=u_init)


def batch_equals_alone(components, settings, option, values, alone):
    """A batch of the same closed loop with ``option`` set per run to ``values`` equals the
    runs ``alone`` (one per value), bit for bit."""
    plant, controller, delay = components
    batch = simulate(
        plant, controller, [delay] * len(values), np.zeros(4), **{option: values}, **settings
    )
    for b, run in enumerate(alone):
        np.testing.assert_array_equal(batch.x[b], run.x[0])


def _measured(x, k, noise, n):
    """q~, q~dot of the measurement model at tick k, written out again here with NumPy."""
    q, qdot = x[:n].copy(), x[n:].copy()
    step = np.broadcast_to(np.asarray(noise.quantization, dtype=float), (n,))
    position = np.broadcast_to(np.asarray(noise.position, dtype=float), (n,))
    velocity = np.broadcast_to(np.asarray(noise.velocity, dtype=float), (n,))
    for j in range(n):
        if step[j] > 0:
            q[j] = step[j] * np.floor(q[j] / step[j] + 0.5)
        if position[j] > 0:
            q[j] += position[j] * standard_noise(noise.seed, 2 * n * k + j)
        if velocity[j] > 0:
            qdot[j] += velocity[j] * standard_noise(noise.seed, 2 * n * k + n + j)
    return q, qdot


def test_a_quantization_step_far_below_the_position_rounds_it_compiled_as_in_python() -> None:
    # q / Δ = 9.5e18 is beyond an int64: the rounding is a float's, compiled and in Python.
    from delaytrack.sim.measurement import measure

    noise = np.array([1e-16, 0.0, 0.0, 0.0])
    measured = {}
    for name, function in (("compiled", measure), ("python", measure.py_func)):
        q, qdot = np.empty(1), np.empty(1)
        function(np.array([950.0]), np.array([0.0]), 0, noise, q, qdot)
        measured[name] = q[0]
    assert measured["compiled"] == measured["python"] == 1e-16 * np.floor(950.0 / 1e-16 + 0.5)
    assert measured["compiled"] == pytest.approx(950.0)


@pytest.mark.parametrize(
    "noise",
    [
        MeasurementNoise(quantization=2 * np.pi / 500),
        MeasurementNoise(quantization=[0.01, 0.0], position=0.002, velocity=[0.05, 0.1], seed=9),
    ],
)
def test_the_controller_reads_the_measured_state(noise) -> None:
    # The outer loop has no state: each recorded command must be its law evaluated on the
    # measured state of the recorded true state at that tick.
    controller = OuterLoop(TwoLinkArm(), K1=4.0, K2=4.0)
    settings = dict(reference=ARM_REFERENCE, t1=0.5, dt=1e-3, T_c=2e-3)
    result = simulate(
        TwoLinkArm(),
        controller,
        ConstantDelay(0.01),
        np.zeros(4),
        measurement_noise=noise,
        **settings,
    )
    qd, qd_dot, qd_ddot = ARM_REFERENCE.evaluate(result.t)
    state = controller.initial_state()
    for k in range(0, result.t.size, 17):
        q, qdot = _measured(result.x[0, k], k, noise, 2)
        command, _ = controller.step(
            result.t[k], q, qdot, (qd[k], qd_dot[k], qd_ddot[k]), state, T_c=2e-3, h=0.01
        )
        np.testing.assert_array_equal(result.commands[0, k], command)
    exact = simulate(TwoLinkArm(), controller, ConstantDelay(0.01), np.zeros(4), **settings)
    assert not np.array_equal(exact.commands, result.commands)
    silent = simulate(
        TwoLinkArm(),
        controller,
        ConstantDelay(0.01),
        np.zeros(4),
        measurement_noise=MeasurementNoise(),
        **settings,
    )
    np.testing.assert_array_equal(silent.x, exact.x)  # no noise: the true state, bit for bit
    batch_equals_alone(
        (TwoLinkArm(), controller, ConstantDelay(0.01)),
        settings,
        "measurement_noise",
        [MeasurementNoise(), noise],
        [exact, result],
    )


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (dict(position=-0.1), "measurement_noise.position must be a number >= 0"),
        (dict(velocity=float("nan")), "measurement_noise.velocity must be a number >= 0"),
        (dict(quantization=[[0.1]]), "measurement_noise.quantization must be a number >= 0"),
        (dict(seed=-1), "measurement_noise.seed must be an integer from 0 to 4294967295"),
        (dict(seed=2**32), "measurement_noise.seed"),
    ],
)
def test_bad_measurement_noise_is_refused(arguments, message) -> None:
    with pytest.raises(ValueError, match=message):
        MeasurementNoise(**arguments)


def test_measurement_noise_of_the_wrong_size_is_refused() -> None:
    with pytest.raises(
        ValueError, match=r"measurement_noise.position must have 1 or n = 2 entries"
    ):
        short_arm_run(measurement_noise=MeasurementNoise(position=[0.1, 0.2, 0.3]))
    for wrong in (0.1, [0.1]):
        with pytest.raises(TypeError, match=r"measurement_noise\[0\] must be an instance of"):
            short_arm_run(measurement_noise=wrong)


def test_a_lost_packet_leaves_the_latest_received_command_applied() -> None:
    # Each applied input is the brute-force lookup's command, or, if that packet was lost, the
    # latest received one before it (u_init = 0 before any).
    dt, t_c = 5e-4, 2e-3
    delay = AbsSineDelay.S1()
    loss = PacketLoss(probability=0.3, seed=5)
    settings = dict(reference=ARM_REFERENCE, t1=2.0, dt=dt, T_c=t_c)
    result = simulate(TwoLinkArm(), arm_arolc(), delay, np.zeros(4), packet_loss=loss, **settings)
    commands = result.commands[0]
    lost = np.array([uniform(5, k) < 0.3 for k in range(commands.shape[0])])
    assert 0.25 < lost.mean() < 0.35
    received = np.zeros_like(commands)  # the command the actuators hold after tick k's packet
    held = np.zeros(2)
    for k in range(commands.shape[0]):
        if not lost[k]:
            held = commands[k]
        received[k] = held
    probe = result.t + 0.5e-9 * dt
    indices = np.array([brute_force_index(t, delay, result.t) for t in probe])
    expected = np.where(indices[:, None] >= 0, received[np.maximum(indices, 0)], 0.0)
    np.testing.assert_array_equal(result.applied[0], expected)
    assert result.settings["packet_loss"] == [{"probability": 0.3, "seed": 5}]
    none = simulate(
        TwoLinkArm(), arm_arolc(), delay, np.zeros(4), packet_loss=PacketLoss(), **settings
    )
    exact = simulate(TwoLinkArm(), arm_arolc(), delay, np.zeros(4), **settings)
    np.testing.assert_array_equal(none.x, exact.x)
    batch_equals_alone(
        (TwoLinkArm(), arm_arolc(), delay),
        settings,
        "packet_loss",
        [PacketLoss(), loss],
        [exact, result],
    )


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (dict(probability=1.0), r"packet_loss.probability must be a number in \[0, 1\)"),
        (dict(probability=-0.1), "packet_loss.probability"),
        (dict(probability="half"), "packet_loss.probability"),
        (dict(seed=-3), "packet_loss.seed must be an integer from 0 to 4294967295"),
    ],
)
def test_bad_packet_loss_is_refused(arguments, message) -> None:
    with pytest.raises(ValueError, match=message):
        PacketLoss(**arguments)


def test_one_noise_entry_serves_every_coordinate() -> None:
    for key in ("quantization", "position", "velocity"):
        one = MeasurementNoise(**{key: [0.1]}, seed=3).params(4)
        assert np.array_equal(one, MeasurementNoise(**{key: 0.1}, seed=3).params(4))
    # The documented layout [Δ (n), σ_q (n), σ_v (n), seed]: one value spread, a list as given.
    assert np.array_equal(
        MeasurementNoise(quantization=0.1, position=[0.2, 0.3], seed=5).params(2),
        [0.1, 0.1, 0.2, 0.3, 0.0, 0.0, 5.0],
    )
