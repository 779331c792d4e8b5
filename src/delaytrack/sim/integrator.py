"""One plant step of the closed loop, split where the delayed input switches.

The applied input ``u(t)`` is the command of the latest tick ``<= t - h(t)``. With a time-varying
delay it switches at instants inside a step, where ``g(t) = t - h(t)`` crosses a tick time.
:func:`integrate_tick` splits the step there, so that every RK4 sub-step sees a constant input
and the scheme keeps its fourth order: the step is first cut at the profile's breakpoints (pieces
on which ``g`` is continuous and monotone), then each piece at the crossings, solved from
``g(t) = t_k``. Between two consecutive crossings ``g`` lies between two consecutive ticks, so
the input of a sub-step is the command of the crossing count, without evaluating ``h`` again.
Crossings closer than ``1e-9 dt`` to either end of a sub-step are not split off (the sliver is
integrated with its neighbour's input).

Most steps contain no switch, and ``h`` need not be evaluated to know it: on a piece where
``|dh/dt| <= L`` (:func:`~delaytrack.delays._kernel.slope_bound`), ``g`` moves at a speed between
``1 - L`` and ``1 + L``, so from the last point where ``g`` was evaluated, with its tick index
``k``, a step whose end keeps ``g`` strictly between ``t_k`` and ``t_{k+1}`` (with a margin far
above rounding) is integrated with command ``k`` directly. A step that may contain a switch is
treated as above, with ``g`` evaluated at its ends; both ways give the same numbers.

A plant stepped by an integrator of its own (a MuJoCo model, :attr:`Kernel.stepper
<delaytrack.components.Kernel>`) takes whole steps instead: the command in force at a step's
start, that of the latest tick ``<= t_start - h(t_start)`` (``+ 1e-9 dt``, so that a tick
that ``t - h(t)`` reaches at the step's start up to rounding counts, as a sliver does in the
split steps), is held over the step, as a zero-order hold sampled at ``dt``. A switch inside a
step then takes effect at the next step.

This is the innermost loop of every simulation: nothing here allocates (the working memory is
:func:`rk4_workspace`, made once per run, or, for the stages, arrays on the stack:
:func:`rk4_memory`), and :func:`integrate_tick` is compiled without
reference counting (:data:`delaytrack._compile.jit.tick_kernel`). It is compiled on its own for
each plant and called by the engine through its address (:func:`integrate`), so that the engine's
tick loop is compiled once for every plant. The horizon of the quiet steps after a piece whose
ends were evaluated (:func:`_quiet_until`) is a :func:`~delaytrack._compile.jit.shared_kernel`,
compiled once, kept on disk and linked into each plant's integrator (where LLVM inlines it);
``g`` at a piece's ends (:func:`_piece`) stays inlined: linked, LLVM called it, at nearly every
step with the controller at every step, which cost 1–5 % of such a run.
"""

from __future__ import annotations

import math
import types
from typing import NamedTuple

import numpy as np
from numba.extending import overload

from delaytrack._compile.jit import hot_inline_kernel, inline_kernel, shared_kernel, tick_kernel
from delaytrack._compile.native_call import NativeFunctionType, call_native
from delaytrack._compile.stack_arrays import stack_matrix, stack_terms, stack_vector
from delaytrack.components import (
    call_reduced_dynamics,
    call_stepper,
    call_velocity_map,
    has_stepper,
    plant_sizes,
    reduced_size,
    sizes_on_stack,
)
from delaytrack.delays._kernel import (
    PIECEWISE_CONSTANT,
    delay_at,
    next_breakpoint,
    piece_end_values,
    profile_crossing_time,
    profile_value,
    slope_bound,
)
from delaytrack.plants.base import el_rhs, rhs_scratch
from delaytrack.sim.history import latest_tick_index, latest_tick_index_from, tick_time

__all__ = [
    "DELAY_BEYOND_HISTORY",
    "DIVERGED",
    "LEFT_PATH",
    "MASS_NOT_POSITIVE_DEFINITE",
    "OK",
    "TickArguments",
    "beyond",
    "delay_at_tick",
    "integrate",
    "integrate_reduced_tick",
    "integrate_tick",
    "plant_integrator",
    "reduced_twin",
    "rk4_memory",
    "rk4_workspace",
]

_SPLIT_TOLERANCE = 1e-9
#: Margin of :func:`_quiet_until`, relative to ``dt`` and to ``1 + |t| + |g|`` (far above the
#: rounding of ``g = t - h(t)``).
_SWITCH_MARGIN = 1e-9

#: Entries of the ``profile`` memory of :func:`rk4_workspace`: the current piece
#: ``[from, breakpoint)``, the last point where ``h`` was evaluated and ``h`` there, the last
#: ``g`` evaluated and its tick index, the piece's slope bound and the quiet horizon.
(
    _FROM,
    _BREAKPOINT,
    _EVALUATED_AT,
    _H_THERE,
    _LAST_G,
    _LAST_TICK,
    _SLOPE,
    _QUIET_UNTIL,
) = range(8)

#: Outcomes of :func:`integrate_tick`, and the status codes of a run.
OK = 0
DIVERGED = 1
DELAY_BEYOND_HISTORY = 2
#: A tracking error exceeded the run's ``error_bound`` (:func:`delaytrack.sim.simulate`).
LEFT_PATH = 3
#: The solve for ``q̈`` met a mass matrix that is not symmetric positive definite (a plant's
#: kernel fault, not a divergence of the loop:
#: :func:`~delaytrack._small_linalg.solve_mass_in_place`).
MASS_NOT_POSITIVE_DEFINITE = 4


@hot_inline_kernel
def beyond(values, bound):
    """Whether any entry is non-finite or larger than ``bound`` in magnitude."""
    for value in values:
        magnitude = abs(value)
        if not (magnitude <= bound and magnitude < math.inf):  # NaN fails both
            return True
    return False


@inline_kernel
def rk4_workspace(x, m):
    """Working memory of :func:`_rk4_substep` for the state ``x = [q, q̇]`` (2n,) and ``m`` inputs.

    ``(slopes (4, 2n), stage (2n,), stage_q, stage_q̇, scratch, profile)``: the views are taken
    once per run, so the inner loop neither allocates nor slices. ``profile`` remembers, from
    one step to the next, the delay profile's current piece ``[from, breakpoint)`` and its slope
    bound ``L``, for a continuous profile the last point ``t`` where ``h`` was evaluated and
    ``h(t)``, the last ``g`` evaluated with its tick index, and until when that index certainly
    holds: ``[from, breakpoint, t, h, g, k, L, quiet_until]``, indexed by :data:`_FROM` ..
    :data:`_QUIET_UNTIL` (see :func:`_piece` and :func:`_quiet_until`). It starts with no piece,
    nothing evaluated and nothing certain. Zeroed, as the plant's ``M, N, G`` on the stack
    (:func:`rk4_memory`): an entry a kernel leaves unwritten is the same in every run.
    """
    n = x.shape[0] // 2
    slopes = np.zeros((4, 2 * n))
    stage = np.zeros(2 * n)
    profile = np.array([np.inf, -np.inf, np.nan, np.nan, np.nan, -1.0, np.inf, -np.inf])
    return slopes, stage, stage[:n], stage[n:], rhs_scratch(n, m), profile


def rk4_memory(plant_terms, work):
    """The working memory of :func:`_rk4_substep` for one call of :func:`integrate_tick`.

    Compiled, for a plant whose sizes ``(n, m)`` are known when compiling, the slopes, the stage
    state and the plant's ``M, N, G`` are arrays on the stack of :func:`integrate_tick`
    (:mod:`delaytrack._compile.stack_arrays`), and only ``profile``, which lasts from one tick to
    the next, is taken from ``work`` (:func:`rk4_workspace`); otherwise ``work`` itself. The stage
    arrays hold nothing between calls, so the two give the same numbers. ``M, N, G`` on the
    stack are zeroed at each call (once a tick), so that an entry a kernel leaves unwritten is
    the same in every run, not what the stack held (a kernel that writes every entry, as the
    start-up check of :class:`~delaytrack.plants.CompiledPlant` asks, sees no difference).
    """
    return work


@overload(rk4_memory, inline="always")
def _rk4_memory_compiled(plant_terms, work):
    # slopes, stage, M, N, G
    sizes = sizes_on_stack(plant_terms, lambda n, m: 5 * (2 * n) + n * n + n + n * m)
    if sizes is None:
        return lambda plant_terms, work: work
    n, m = sizes
    width = 2 * n

    def on_stack(plant_terms, work):
        stage = stack_vector(width)
        scratch = stack_terms(n, m)
        return stack_matrix(4, width), stage, stage[:n], stage[n:], scratch, work[5]

    return on_stack


@hot_inline_kernel
def _rk4_substep(plant_terms, plant_params, t, x, u, length, work, bound):
    """One classical RK4 step of length ``length`` with constant input ``u``; updates ``x``.

    Stage ``s`` evaluates the slope ``k_s = f(t + c_s length, x + c_s length k_{s-1})``,
    ``c = (0, 1/2, 1/2, 1)``, and ``x += length (k_0 + 2 k_1 + 2 k_2 + k_3) / 6``. ``work`` is
    :func:`rk4_workspace` of this ``x``; written as loops so that nothing is allocated, with one
    call of the (inlined) right-hand side. Returns ``(outside, indefinite_at)``: whether an
    entry of the new ``x`` is non-finite or larger than ``bound`` in magnitude (:func:`beyond`,
    checked as it is written: a loop over ``x`` less per step, about 2 % of a robot run), and
    the time of the first stage whose mass matrix was not positive definite (NaN if none).
    """
    slopes, stage, stage_q, stage_qdot, scratch, _ = work
    n, _ = plant_sizes(plant_terms, stage_q, u)
    half = 0.5 * length
    indefinite_at = math.nan
    for s in range(4):
        if s == 0:
            offset = 0.0
            for i in range(2 * n):
                stage[i] = x[i]
        else:
            offset = half if s < 3 else length
            for i in range(2 * n):
                stage[i] = x[i] + offset * slopes[s - 1, i]
        acceleration = slopes[s, n:]
        if not el_rhs(
            plant_terms, t + offset, stage_q, stage_qdot, u, plant_params, acceleration, scratch
        ) and math.isnan(indefinite_at):
            indefinite_at = t + offset
        for i in range(n):
            slopes[s, i] = stage_qdot[i]
    sixth = length / 6.0
    outside = False
    for i in range(2 * n):
        increment = slopes[0, i] + 2.0 * slopes[1, i] + 2.0 * slopes[2, i] + slopes[3, i]
        value = x[i] + sixth * increment
        x[i] = value
        magnitude = abs(value)
        if not (magnitude <= bound and magnitude < math.inf):  # NaN fails both
            outside = True
    return outside, indefinite_at


@hot_inline_kernel
def _reduced_rk4_substep(plant_terms, plant_params, t, x, u, length, work, bound):
    """:func:`_rk4_substep` for a plant with a reduced form
    (:class:`~delaytrack.components.ReducedForm`): classical RK4 on ``(q, η)``, ``η`` the last
    ``r`` entries of ``q̇``, with the slopes ``(S(q) η, η̇)`` of the stage's ``(q, η)``; after the
    step, ``q̇ = S(q) η`` at the new ``(q, η)``. The other ``n - r`` velocities are never
    integrated, so the velocity constraints hold to rounding. ``x`` must hold ``q̇ = S(q) η``
    already (the first stage's slope of ``q``): the map wrote it at the end of the sub-step
    before, or at the start of the run (:func:`integrate_tick`). Returns ``(outside, NaN)``."""
    slopes, stage, stage_q, stage_qdot, _, _ = work
    n, _ = plant_sizes(plant_terms, stage_q, u)
    r = reduced_size(plant_terms)
    first = 2 * n - r  # where η starts in [q, q̇]
    stage_eta = stage[first:]
    half = 0.5 * length
    for s in range(4):
        if s == 0:
            # x's q̇ is S(q) η already: set by the map at the end of the last sub-step, or at
            # the run's start (:func:`integrate_tick`), from this same (q, η).
            offset = 0.0
            for i in range(2 * n):
                stage[i] = x[i]
        else:
            offset = half if s < 3 else length
            for i in range(n):
                stage[i] = x[i] + offset * slopes[s - 1, i]
            for i in range(first, 2 * n):
                stage[i] = x[i] + offset * slopes[s - 1, i]
            call_velocity_map(plant_terms, stage_q, stage_eta, plant_params, stage_qdot)
        for i in range(n):
            slopes[s, i] = stage_qdot[i]
        call_reduced_dynamics(
            plant_terms, t + offset, stage_q, stage_eta, u, plant_params, slopes[s, first:]
        )
    sixth = length / 6.0
    for i in range(n):
        x[i] += sixth * (slopes[0, i] + 2.0 * slopes[1, i] + 2.0 * slopes[2, i] + slopes[3, i])
    for i in range(first, 2 * n):
        x[i] += sixth * (slopes[0, i] + 2.0 * slopes[1, i] + 2.0 * slopes[2, i] + slopes[3, i])
    call_velocity_map(plant_terms, x[:n], x[first:], plant_params, x[n:])
    return beyond(x, bound), math.nan


@hot_inline_kernel
def _history_slot(k, newest, newest_slot, capacity):
    """Ring slot ``k % capacity`` of command ``k`` (-1 for ``u_init`` before the first tick, -2
    when it has left the history of ``capacity`` commands whose newest, ``newest``, is in slot
    ``newest_slot``), counted from the newest slot without an integer division."""
    if k < 0:
        return -1
    if k <= newest - capacity:
        return -2
    slot = newest_slot - (newest - k)
    if slot < 0:
        return slot + capacity
    if slot >= capacity:
        return slot - capacity
    return slot


@hot_inline_kernel
def _piece(delay, delay_kind, delay_params, a, b, profile):
    """``g = t - h(t)`` at the ends of the piece ``[a, b]`` (:func:`_piece_end`):
    ``(g(a+), g(b-))``.

    A piece starts where the last one ended, so for a continuous profile ``h`` at the start is
    taken from the ``profile`` memory of :func:`rk4_workspace`: the same number, computed once.
    """
    if delay_kind == PIECEWISE_CONSTANT:
        h_a, h_b = piece_end_values(delay_kind, delay_params, a, b)
    else:  # continuous: h(a+) = h(a), remembered when a ended the last piece
        h_a = (
            profile[_H_THERE]
            if a == profile[_EVALUATED_AT]
            else profile_value(delay, delay_kind, delay_params, a)
        )
        h_b = profile_value(delay, delay_kind, delay_params, b)
        profile[_EVALUATED_AT] = b
        profile[_H_THERE] = h_b
    return a - h_a, b - h_b


@inline_kernel
def delay_at_tick(delay, delay_kind, delay_params, t_k, work):
    """``h(t_k)`` at the tick ``t_k`` (:func:`~delaytrack.delays._kernel.delay_at`), taken from
    the ``profile`` memory of :func:`rk4_workspace` when the last step, ending at ``t_k``, left
    it there (a continuous profile, evaluated at that step's end): the same number, computed
    once. With the controller at every step this saves an evaluation of ``h`` a step."""
    profile = work[5]
    if delay_kind != PIECEWISE_CONSTANT and profile[_EVALUATED_AT] == t_k:
        return profile[_H_THERE]
    return delay_at(delay, delay_kind, delay_params, t_k)


@hot_inline_kernel
def _piece_end(delay_kind, delay_params, a, t_end, profile):
    """End ``b`` of the piece that starts at ``a`` within a step ending ``t_end``.

    The profile's piece ``[from, breakpoint)`` and its slope bound are remembered in ``profile``
    and found again only when ``a`` has left it (``next_breakpoint(a)`` is the same for every
    ``a`` in a piece).
    """
    if not profile[_FROM] <= a < profile[_BREAKPOINT]:
        profile[_FROM] = a
        profile[_BREAKPOINT] = next_breakpoint(delay_kind, delay_params, a)
        profile[_SLOPE] = slope_bound(delay_kind, delay_params, a)
    return min(profile[_BREAKPOINT], t_end)


@shared_kernel
def _quiet_until(b, g_b, k_b, profile, t0, dt, steps_per_tick):
    """Until when ``g`` certainly keeps the tick index ``k_b`` it has at ``b`` (module docstring).

    On the current piece ``g`` moves at a speed between ``1 - L`` and ``1 + L``, so it stays in
    ``[t_k, t_{k+1})`` until it could first reach ``t_{k+1}`` rising at ``1 + L`` or, when
    ``L > 1``, ``t_k`` falling at ``L - 1``, each less a margin of
    ``1e-9 (dt + (1 + |b| + |g(b)|) (1 + L))``; and at most until the piece ends. Before ``b``
    when ``g(b)`` lies within the margin of ``t_k`` (``g`` may then fall below it by rounding).
    """
    slope = profile[_SLOPE]
    if not slope < np.inf:  # a kernel of the user's: no bound, h is evaluated at every step
        return -np.inf
    margin = _SWITCH_MARGIN * (dt + (1.0 + abs(b) + abs(g_b)) * (1.0 + slope))
    horizon = b + (tick_time(k_b + 1, t0, dt, steps_per_tick) - g_b - margin) / (1.0 + slope)
    if k_b >= 0:
        above = g_b - tick_time(k_b, t0, dt, steps_per_tick) - margin
        if not above >= 0.0:
            return -np.inf
        if slope > 1.0:
            horizon = min(horizon, b + above / (slope - 1.0))
    if not horizon <= profile[_BREAKPOINT]:  # the piece ends first (or NaN: nothing is certain)
        return profile[_BREAKPOINT] if horizon > profile[_BREAKPOINT] else -np.inf
    return horizon


@tick_kernel
def integrate_tick(
    plant_terms,
    delay,
    plant_params,
    delay_kind,
    delay_params,
    x,
    k,
    history,
    u_init,
    t0,
    dt,
    steps_per_tick,
    divergence_bound,
    work,
    probe_only,
):
    """Integrate ``x`` over the ``steps_per_tick`` plant steps after tick ``k``.

    Each step ``[t_start, t_end]`` is split at the profile's breakpoints and then where the
    input switches (module docstring). Command ``k`` is the newest in ``history``. Returns
    ``(outcome, t_stop, first_slot)``: :data:`OK` with ``t_stop`` the next tick's time;
    :data:`DIVERGED` when, at the end ``t_stop`` of a step, an entry of ``x`` is non-finite or
    beyond ``divergence_bound``; :data:`MASS_NOT_POSITIVE_DEFINITE` when an RK4 stage at
    ``t_stop`` met a mass matrix that is not positive definite; or
    :data:`DELAY_BEYOND_HISTORY` when the step starting at
    ``t_stop`` needs a command that has left the history. ``first_slot`` is the ring slot of the
    input of the first sub-step after the tick (-1 for ``u_init``; -3 when even that one could
    not start). With ``probe_only`` nothing is integrated: only ``first_slot`` is found.

    One call per tick, compiled without reference counts: a call per step, with its arguments,
    cost about a tenth of the step. Compiled on its own for each plant (its kernel is a
    compile-time constant, bound when the engine calls it through its address: :func:`integrate`).
    """
    tolerance = _SPLIT_TOLERANCE * dt
    capacity = history.shape[0]
    newest_slot = k % capacity
    profile = work[5]
    r = reduced_size(plant_terms)
    if k == 0 and r > 0 and not probe_only:
        # A plant in its reduced form starts from q̇ = S(q) η (its sub-steps then keep it so).
        n = x.shape[0] // 2
        call_velocity_map(plant_terms, x[:n], x[2 * n - r :], plant_params, x[n:])
    work = rk4_memory(plant_terms, work)
    first_slot = -3
    outside = False  # whether x left the bound at the end of the last sub-step
    for j in range(steps_per_tick):
        t_start = t0 + (k * steps_per_tick + j) * dt
        t_end = t0 + (k * steps_per_tick + j + 1) * dt
        a = t_start
        while a < t_end:
            b = _piece_end(delay_kind, delay_params, a, t_end, profile)
            if has_stepper(plant_terms):
                # The plant's own integrator takes the whole step, with the command in force at
                # its start (a switch within the sliver tolerance after it counts as at it).
                g_a, g_b = _piece(delay, delay_kind, delay_params, a, b, profile)
                b = t_end
                k_a = latest_tick_index(g_a + tolerance, t0, dt, steps_per_tick)
                k_b = k_a
            else:
                # No switch up to b: g keeps the remembered index. Strictly before the horizon,
                # which may be the piece's end: a piece-wise constant profile evaluated on a
                # piece ending there takes h at its midpoint, which may round onto the next piece.
                if b < profile[_QUIET_UNTIL]:
                    k_a = int(profile[_LAST_TICK])
                    k_b = k_a
                    g_a = g_b = 0.0  # not needed: no crossing
                else:
                    g_a, g_b = _piece(delay, delay_kind, delay_params, a, b, profile)
                    # g(a) is mostly g(b) of the last piece, whose tick index is remembered;
                    # the index at b is then found by walking from the one at a.
                    if g_a == profile[_LAST_G]:
                        k_a = int(profile[_LAST_TICK])
                    else:
                        k_a = latest_tick_index(g_a, t0, dt, steps_per_tick)
                    k_b = latest_tick_index_from(g_b, k_a, t0, dt, steps_per_tick)
                    profile[_LAST_G] = g_b
                    profile[_LAST_TICK] = k_b
                    profile[_QUIET_UNTIL] = _quiet_until(
                        b, g_b, k_b, profile, t0, dt, steps_per_tick
                    )
            # Sub-intervals end at each tick crossed by g on this piece, in time order, then b.
            crossings = abs(k_b - k_a)
            direction = 1 if k_b >= k_a else -1
            first_tick = k_a + 1 if direction == 1 else k_a
            start = a
            for i in range(crossings + 1):
                end = b
                if i < crossings:
                    target = tick_time(first_tick + direction * i, t0, dt, steps_per_tick)
                    end = profile_crossing_time(
                        delay, delay_kind, delay_params, a, b, g_a, g_b, target
                    )
                    if end - start <= tolerance:
                        continue  # a sliver: integrated with the input after this crossing
                    if b - end <= tolerance:
                        end = b  # the rest of the piece is a sliver: integrated with this input
                # On sub-interval i, g lies between the ticks crossed at its ends: command k_a ± i.
                slot = _history_slot(k_a + direction * i, k, newest_slot, capacity)
                if slot == -2:
                    return DELAY_BEYOND_HISTORY, t_start, first_slot
                if first_slot == -3:
                    first_slot = slot
                    if probe_only:
                        return OK, t_start, first_slot
                u = u_init if slot == -1 else history[slot]
                if has_stepper(plant_terms):
                    call_stepper(plant_terms, start, x, u, dt, plant_params, k == 0 and j == 0)
                    outside = beyond(x, divergence_bound)
                else:
                    outside, indefinite_at = _rk4_substep(
                        plant_terms, plant_params, start, x, u, end - start, work, divergence_bound
                    )
                    if not math.isnan(indefinite_at):
                        return MASS_NOT_POSITIVE_DEFINITE, indefinite_at, first_slot
                start = end
                if end == b:
                    break
            a = b
        if outside:
            return DIVERGED, t_end, first_slot
    return OK, tick_time(k + 1, t0, dt, steps_per_tick), first_slot


def reduced_twin(function, name):
    """The plain Python ``function``, which calls :func:`_rk4_substep`, made again under
    ``name`` calling :func:`_reduced_rk4_substep` instead, to be compiled for the plants with a
    reduced form (:class:`~delaytrack.components.ReducedForm`).

    numba inlines a sub-step into its caller before typing, and types both sides of a branch
    even when the kernel decides it: with a branch between the two sub-steps, the robot's
    integrator took 11.4–13.2 s to compile instead of 5.4 s, and a pendulum's 5.8–6.0 s instead
    of 4.4 s (measured from an empty cache). Each twin is compiled with its own sub-step only;
    the code is written once. The twin reads the module's globals as they are when it is made
    (the end of the module): nothing it uses may be defined or replaced later.
    """
    namespace = {**function.__globals__, "_rk4_substep": _reduced_rk4_substep}
    twin = types.FunctionType(
        function.__code__, namespace, name, function.__defaults__, function.__closure__
    )
    twin.__qualname__ = name
    twin.__doc__ = function.__doc__
    return twin


#: :func:`integrate_tick` for the plants with a reduced form (:func:`reduced_twin`).
integrate_reduced_tick = tick_kernel(reduced_twin(integrate_tick.py_func, "integrate_reduced_tick"))


def plant_integrator(plant_terms):
    """:func:`integrate_tick`, or :data:`integrate_reduced_tick` for a plant :class:`Kernel
    <delaytrack.components.Kernel>` with a reduced form."""
    return integrate_reduced_tick if plant_terms.reduced is not None else integrate_tick


class TickArguments(NamedTuple):
    """The arguments of :func:`integrate_tick` after its two kernels, by name, as the engine
    hands them to :func:`integrate` (the compiled integrator takes them one by one, in this
    order, which a test checks against its signature)."""

    #: The plant's parameters.
    plant_params: np.ndarray
    #: The delay profile's kind (:mod:`delaytrack.delays._kernel`).
    delay_kind: int
    #: The delay profile's parameters.
    delay_params: np.ndarray
    #: The state ``[q, q̇]`` (2n,), advanced in place.
    x: np.ndarray
    #: The tick after which the plant steps: command ``k`` is the newest in ``history``.
    k: int
    #: The ring of the commands issued (capacity, m).
    history: np.ndarray
    #: The input before the first command arrives (m,).
    u_init: np.ndarray
    #: The run's start, seconds.
    t0: float
    #: The plant's step, seconds.
    dt: float
    #: Plant steps per controller tick.
    steps_per_tick: int
    #: A state beyond it in magnitude ends the run (``DIVERGED``).
    divergence_bound: float
    #: :func:`rk4_workspace` of the run.
    work: tuple
    #: Only find the first sub-step's input, integrating nothing.
    probe_only: bool

    @classmethod
    def sample(cls, n: int, m: int) -> TickArguments:
        """Arguments of the types the engine passes for ``n`` coordinates and ``m`` inputs (for
        the integrator's compiled signature)."""
        vector, state = np.empty(n), np.empty(2 * n)
        return cls(
            vector, 0, vector, state, 0, np.empty((1, m)), np.empty(m), 0.0, 0.0, 1, 0.0,
            rk4_workspace(state, m), False,
        )  # fmt: skip


def integrate(plant_step, delay, arguments):
    """:func:`integrate_tick` for the plant of ``plant_step`` and the delay kernel ``delay``, with
    its other ``arguments`` (:class:`TickArguments`); returns its result.

    In the compiled engine ``plant_step`` is :func:`integrate_tick` compiled for the plant's
    kernel and the batch's delay kernel, called through its address with both kernels bound
    (:class:`~delaytrack._compile.native_call.NativeFunction`,
    :mod:`delaytrack._compile.native_parts`), so that the engine is not compiled again for each
    plant, and ``delay`` is not read; in the plain-Python engine it is the plant's
    :class:`~delaytrack.components.Kernel`, run as Python.
    """
    return plant_integrator(plant_step).py_func(plant_step, delay, *arguments)


@overload(integrate, inline="always")
def _integrate_compiled(plant_step, delay, arguments):
    if isinstance(plant_step, NativeFunctionType):

        def native(plant_step, delay, arguments):
            return call_native(plant_step, arguments)

        return native
    return None
