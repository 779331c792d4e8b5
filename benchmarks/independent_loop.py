"""A second ceiling for ``make bench``: the paper's robot run written from its equations alone.

:mod:`hand_loop` calls the package's own kernels; this loop calls none of them. It is written
from the equations of the paper and of the robot model (docs/robot.md), for five coordinates
and two wheels and nothing general, every buffer allocated before the loop, as one would write
the experiment by hand for speed and nothing else. Only the
*numbers* come from the package's objects (the robot's and the payload schedule's parameters,
the gains and ``P`` of AROLC, the reference's harmonics, the delay's ``params``), so that both
run the same experiment:

* the robot in its reduced wheel-space form, ``q = (x_c, y_c, φ, θ_r, θ_l)``, wheel rates
  ``η = (θ̇_r, θ̇_l)``, ``v = R (θ̇_r + θ̇_l)/2``, ``ω = R (θ̇_r - θ̇_l)/(2L)``::

      q̇ = S(q) η:  ẋ_c = v cos φ - d ω sin φ,  ẏ_c = v sin φ + d ω cos φ,  φ̇ = ω
      M_r η̇ = τ - f(η) - n_r(η)                 (solved as a 2×2 system by Cramer's rule)
      M_r = I_w I + Jᵀ [[M_b, -s_y], [-s_y, I_A]] J,  J = [[R/2, R/2], [R/(2L), -R/(2L)]]
      n_r = Jᵀ [-s_x ω², s_x v ω],  f_i = b_v θ̇_i + f_c tanh(θ̇_i / v_s)

  with the rigid-body aggregates ``M_b, s, I_A`` changed by the payload in force (a point mass
  ``m_p`` at ``p``: ``M_b + m_p``, ``s + m_p p``, ``I_A + m_p |p|²``);
* AROLC (paper eqs. (aux), (control input), (delta u), (input) and the adaptive law) on the
  nominal model ``M̂(q) q̈ + N̂(q, q̇) = G τ``, its wheel torques ``S(q)ᵀ τ``::

      e1 = q_d - q,  s = BᵀP [e1; ė1],  u = q̈_d + K2 ė1 + K1 e1 + α ĉ s / max(‖s‖, ε)
      ĉ' = γ if ĉ <= γ;  ‖s‖ if sᵀ(s - s_prev) > 0;  -‖s‖ otherwise;  ĉ ← ĉ + T_c ĉ'
           (not below γ when decreasing)

* classical RK4 with step ``dt`` on ``(q, η)``, the delayed command looked up at each stage
  time (the command of tick ``k = ⌊(t - h(t)) / T_c⌋``, zero before the first arrives; ``h`` at
  the step's three distinct stage times, its end kept for the next step's start) without
  splitting a step where it switches (first order across a switch, as :mod:`hand_loop`), and
  ``q̇ = S(q) η`` set after each step, which the next step's first stage reads;
* or, with ``split=True``, RK4 kept at fourth order across the switches, as the engine keeps it:
  each step ``[j dt, (j + 1) dt]`` cut at the kinks of ``h`` and where ``g(t) = t - h(t)``
  crosses a tick time ``(k m) dt`` (Newton's steps kept in a bracket), one RK4 sub-step of
  constant command per part, a part shorter than ``1e-9 dt`` merged into its neighbour; ``h``
  evaluated once a step (at its end, the next step's start) and at the kinks; times written as
  the engine writes them (a tick at ``(k m) dt``, a step from ``j dt``), so that a step starts
  where the one before ended, to the last bit;
* the running metrics at each tick: ``Σ|e1_j|`` and the total variation of the command.

Unsplit, the same scheme as :mod:`hand_loop`, written a second time: on the paper's run their
metrics agree to rounding (``make bench`` prints the difference), and both differ from the
engine's by up to about 1 % (the unsplit switches move AROLC's adaptive law). Split, it is a
second derivation of what the engine computes: after the paper's 60 s run its final state
differs from the engine's by about 1e-15 of the state's largest entry, 1.5e-14 of each entry
at most (rounding: the two write the equations in other orders; ``make bench`` prints the
first).

A batch runs one run per thread at a time (``numba.prange``), each with its own payload
placements and |sin| delay profile.
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["independent_batch", "independent_run"]

#: Coordinates of the robot, q = (x_c, y_c, φ, θ_r, θ_l).
N = 5


@numba.njit(cache=True, error_model="numpy", inline="always")
def _aggregates(t, body, schedule, points):
    """``(M_b, s_x, s_y, I_A)`` with the payload in force at ``t``."""
    mass, s_x, s_y, inertia = body[3], body[4], body[5], body[6]
    first_on, time_on, period, count = (
        schedule[1],
        schedule[2],
        schedule[2] + schedule[3],
        schedule[4],
    )
    if t >= first_on:
        k = math.floor((t - first_on) / period)
        if k < count and t - first_on - k * period < time_on:
            m_p = schedule[0]
            p_x = points[int(k), 0]
            p_y = points[int(k), 1]
            mass += m_p
            s_x += m_p * p_x
            s_y += m_p * p_y
            inertia += m_p * (p_x * p_x + p_y * p_y)
    return mass, s_x, s_y, inertia


@numba.njit(cache=True, error_model="numpy", inline="always")
def _wheel_accelerations(t, wr, wl, tau_r, tau_l, body, schedule, points):
    """``η̇`` of the reduced form at ``(t, η)`` under wheel torques ``τ``."""
    mass, s_x, s_y, inertia = _aggregates(t, body, schedule, points)
    a = 0.5 * body[0]
    b = body[0] / (2.0 * body[1])
    wheel_inertia, b_v, f_c, v_s = body[7], body[8], body[9], body[10]
    v = a * (wr + wl)
    w = b * (wr - wl)
    m00 = wheel_inertia + a * a * mass - 2.0 * a * b * s_y + b * b * inertia
    m01 = a * a * mass - b * b * inertia
    m11 = wheel_inertia + a * a * mass + 2.0 * a * b * s_y + b * b * inertia
    r0 = tau_r - b_v * wr - f_c * math.tanh(wr / v_s) - s_x * w * (b * v - a * w)
    r1 = tau_l - b_v * wl - f_c * math.tanh(wl / v_s) + s_x * w * (b * v + a * w)
    det = m00 * m11 - m01 * m01
    return (m11 * r0 - m01 * r1) / det, (m00 * r1 - m01 * r0) / det


@numba.njit(cache=True, error_model="numpy", inline="always")
def _velocity_map(q, qdot, a, b, d):
    """``q̇_{x, y, φ} = S(q) η`` from the wheel rates ``η = q̇_{θ_r, θ_l}``."""
    v = a * (qdot[3] + qdot[4])
    w = b * (qdot[3] - qdot[4])
    c = math.cos(q[2])
    s = math.sin(q[2])
    qdot[0] = v * c - d * w * s
    qdot[1] = v * s + d * w * c
    qdot[2] = w


@numba.njit(cache=True, error_model="numpy", inline="always")
def _command_index(time, delay, T_c):
    """The tick whose command is applied at ``time``: ``⌊(t - h(t)) / T_c⌋`` (< 0: none yet)."""
    h = delay[0] + delay[1] * abs(math.sin(delay[2] * time + delay[3]))
    return math.floor((time - h) / T_c)


#: numba's parallel pipeline with none of its conversions (nothing runs in parallel): for this
#: function numba compiles code about 1.5 times as fast as with its default pipeline, with the
#: same numbers (as it does when the function is called inside a ``prange``); the cause was not
#: found. The engine's kernels compiled so run no faster (decisions D74).
NO_CONVERSIONS = dict.fromkeys(
    (
        "comprehension",
        "reduction",
        "inplace_binop",
        "setitem",
        "numpy",
        "stencil",
        "fusion",
        "prange",
    ),
    False,
)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _tick(k, t_k, q, qdot, body, control, reference, c_hat, buffers, history, sums, T_c):
    """Tick ``k`` at ``t_k``: the reference, AROLC's wheel torques into ``history[k]`` (the
    nominal model's ``τ`` mapped by the robot's ``S(q)ᵀ``), the adaptive law and the running
    metrics; returns the next ``ĉ``."""
    nominal, K1, K2, BtP, law = control
    ref_offset, ref_slope, ref_amplitude, ref_frequency, ref_phase = reference
    alpha, epsilon, gamma = law[0], law[1], law[2]
    qd, qd_dot, qd_ddot, error, s, s_previous, u = buffers
    R, L, d = body[0], body[1], body[2]
    a = 0.5 * R
    b = R / (2.0 * L)
    harmonics = ref_amplitude.shape[1]
    # the reference at t_k
    for i in range(N):
        qd[i] = ref_offset[i] + ref_slope[i] * t_k
        qd_dot[i] = ref_slope[i]
        qd_ddot[i] = 0.0
        for j in range(harmonics):
            angle = ref_frequency[i, j] * t_k + ref_phase[i, j]
            sine = math.sin(angle)
            qd[i] += ref_amplitude[i, j] * sine
            qd_dot[i] += ref_amplitude[i, j] * ref_frequency[i, j] * math.cos(angle)
            qd_ddot[i] -= ref_amplitude[i, j] * ref_frequency[i, j] ** 2 * sine
    # AROLC
    for i in range(N):
        error[i] = qd[i] - q[i]
        error[N + i] = qd_dot[i] - qdot[i]
    norm2 = 0.0
    for i in range(N):
        total = 0.0
        for j in range(2 * N):
            total += BtP[i, j] * error[j]
        s[i] = total
        norm2 += total * total
    norm_s = math.sqrt(norm2)
    switching = alpha * c_hat / max(norm_s, epsilon)
    for i in range(N):
        total = qd_ddot[i] + switching * s[i]
        for j in range(N):
            total += K2[i, j] * error[N + j] + K1[i, j] * error[j]
        u[i] = total
    c = math.cos(q[2])
    sn = math.sin(q[2])
    mass_n, s_x, s_y, inertia_a, wheel_inertia = (
        nominal[3],
        nominal[4],
        nominal[5],
        nominal[6],
        nominal[7],
    )
    first_moment = mass_n * nominal[2] - s_x
    inertia_p = inertia_a - 2.0 * nominal[2] * s_x + mass_n * nominal[2] ** 2
    m02 = first_moment * sn - s_y * c
    m12 = -first_moment * c - s_y * sn
    phidot2 = qdot[2] * qdot[2]
    tau0 = mass_n * u[0] + m02 * u[2] + (first_moment * c + s_y * sn) * phidot2
    tau1 = mass_n * u[1] + m12 * u[2] + (first_moment * sn - s_y * c) * phidot2
    tau2 = m02 * u[0] + m12 * u[1] + inertia_p * u[2]
    # wheel torques S(q)ᵀ τ
    command_r = (a * c - d * b * sn) * tau0 + (a * sn + d * b * c) * tau1 + b * tau2
    command_r += wheel_inertia * u[3]
    command_l = (a * c + d * b * sn) * tau0 + (a * sn - d * b * c) * tau1 - b * tau2
    command_l += wheel_inertia * u[4]
    history[k, 0] = command_r
    history[k, 1] = command_l
    # the adaptive law
    if c_hat <= gamma:
        rate = gamma
    else:
        increasing = 0.0
        for i in range(N):
            increasing += s[i] * (s[i] - s_previous[i])
        rate = norm_s if k > 0 and increasing > 0.0 else -norm_s
    c_next = c_hat + T_c * rate
    for i in range(N):
        s_previous[i] = s[i]
    # metrics at the tick
    for i in range(N):
        sums[i] += abs(error[i])
    if k > 0:
        sums[N] += abs(command_r - history[k - 1, 0]) + abs(command_l - history[k - 1, 1])
    return gamma if rate < 0.0 and c_next < gamma else c_next


@numba.njit(cache=True, error_model="numpy", inline="always")
def _rk4_step(q, qdot, t, length, torques, slope, y, body, schedule, points):
    """One classical RK4 step of ``length`` from ``t`` on ``(q, η)``, the wheel torques at its
    four stages in ``torques (4, 2)``; then ``q̇ = S(q) η``, which the next step's first stage
    reads."""
    R, L, d = body[0], body[1], body[2]
    a = 0.5 * R
    b = R / (2.0 * L)
    for stage in range(4):
        offset = 0.0 if stage == 0 else (0.5 * length if stage < 3 else length)
        for i in range(N):
            y[i] = q[i] if stage == 0 else q[i] + offset * slope[stage - 1, i]
        for i in range(2):
            eta = qdot[3 + i]
            y[N + i] = eta if stage == 0 else eta + offset * slope[stage - 1, N + i]
        wr = y[N]
        wl = y[N + 1]
        if stage == 0:  # q̇ = S(q) η was set at the end of the step before
            for i in range(3):
                slope[0, i] = qdot[i]
        else:
            v = a * (wr + wl)
            w = b * (wr - wl)
            c = math.cos(y[2])
            sn = math.sin(y[2])
            slope[stage, 0] = v * c - d * w * sn
            slope[stage, 1] = v * sn + d * w * c
            slope[stage, 2] = w
        slope[stage, 3] = wr
        slope[stage, 4] = wl
        slope[stage, N], slope[stage, N + 1] = _wheel_accelerations(
            t + offset, wr, wl, torques[stage, 0], torques[stage, 1], body, schedule, points
        )
    for i in range(N + 2):
        increment = slope[0, i] + 2.0 * slope[1, i] + 2.0 * slope[2, i] + slope[3, i]
        if i < N:
            q[i] += length / 6.0 * increment
        else:
            qdot[3 + i - N] += length / 6.0 * increment
    _velocity_map(q, qdot, a, b, d)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _torques_at(torques, stage, history, index):
    """Row ``stage`` of ``torques``: the command of tick ``index`` (zero before the first)."""
    torques[stage, 0] = history[index, 0] if index >= 0 else 0.0
    torques[stage, 1] = history[index, 1] if index >= 0 else 0.0


@numba.njit(cache=True, error_model="numpy", inline="always")
def _delay_value(time, delay):
    """``h(t) = offset + amplitude |sin(ω t + φ)|``."""
    return delay[0] + delay[1] * abs(math.sin(delay[2] * time + delay[3]))


@numba.njit(cache=True, error_model="numpy", inline="always")
def _tick_at_or_before(g, hint, period):
    """Largest ``k`` with ``k T_c <= g`` (tick times as the engine writes them, ``(k m) dt``,
    ``period = (m, dt)``), walking from ``hint``; -1 before the first tick."""
    steps_per_tick, dt = period
    if g < 0.0:
        return -1
    k = max(hint, 0)
    while ((k + 1) * steps_per_tick) * dt <= g:
        k += 1
    while k >= 0 and (k * steps_per_tick) * dt > g:
        k -= 1
    return k


@numba.njit(cache=True, error_model="numpy", inline="always")
def _crossing(target, start, end, g_start, g_end, delay):
    """The time in ``[start, end]`` where ``g(t) = t - h(t)`` reaches ``target`` (``g`` monotone
    there, between ``g_start`` and ``g_end``): Newton's steps kept in the bracket, bisection
    when one leaves it."""
    low, high = start, end
    rising = g_end > g_start
    guess = start + (target - g_start) / (g_end - g_start) * (end - start)
    for _ in range(60):
        theta = delay[2] * guess + delay[3]
        sine = math.sin(theta)
        value = guess - delay[0] - delay[1] * abs(sine) - target
        if value == 0.0:
            return guess
        if (value < 0.0) == rising:
            low = guess
        else:
            high = guess
        derivative = 1.0 - delay[1] * delay[2] * math.cos(theta) * (1.0 if sine >= 0.0 else -1.0)
        following = guess - value / derivative
        if not low < following < high:
            following = 0.5 * (low + high)
        if following == guess or high - low <= 4e-16 * (1.0 + abs(guess)):
            return following
        guess = following
    return guess


@numba.njit(cache=True, error_model="numpy", inline="always")
def _next_kink(time, delay):
    """The first kink of ``|sin(ω t + φ)|`` after ``time`` (``inf`` for a constant profile)."""
    if delay[1] == 0.0 or delay[2] == 0.0:
        return np.inf
    theta = delay[2] * time + delay[3]
    j = math.floor(theta / math.pi)
    for step in range(3):
        kink = ((j + step) * math.pi - delay[3]) / delay[2]
        if kink > time:
            return kink
    return np.inf


@numba.njit(cache=True, error_model="numpy", inline="always")
def _split_step(
    q, qdot, step, dt, delay, history, period, torques, slope, y, body, schedule, points, last
):
    """Step number ``step``, ``[step dt, (step + 1) dt]`` (so that a step starts where the one
    before ended, to the last bit), cut at the kinks of ``h`` and where the delayed command
    switches (``g(t) = t - h(t)`` crossing a tick time), one RK4 sub-step of constant command
    per part; parts closer than ``1e-9 dt`` to a cut are merged into their neighbour, as the
    engine does. ``last = [t, g(t)]`` where ``g`` was last evaluated: ``h`` is evaluated once a
    step (at its end) and at the kinks."""
    steps_per_tick, _ = period
    tolerance = 1e-9 * dt
    a = step * dt
    end = (step + 1) * dt
    while a < end:
        b = min(_next_kink(a, delay), end)
        g_a = last[1] if a == last[0] else a - _delay_value(a, delay)
        g_b = b - _delay_value(b, delay)
        last[0] = b
        last[1] = g_b
        k_a = _tick_at_or_before(g_a, int(math.floor(g_a / (steps_per_tick * dt))), period)
        k_b = _tick_at_or_before(g_b, k_a, period)
        start = a
        for i in range(k_b - k_a + 1):
            stop = b
            if i < k_b - k_a:
                target = ((k_a + 1 + i) * steps_per_tick) * dt
                stop = _crossing(target, a, b, g_a, g_b, delay)
                if stop - start <= tolerance:
                    continue  # a sliver: integrated with the command after this crossing
                if b - stop <= tolerance:
                    stop = b
            for stage in range(4):
                _torques_at(torques, stage, history, k_a + i)
            _rk4_step(q, qdot, start, stop - start, torques, slope, y, body, schedule, points)
            start = stop
            if stop == b:
                break
        a = b


@numba.njit(cache=True, error_model="numpy", parallel=NO_CONVERSIONS)
def _one_run(
    body, schedule, points, delay, control, reference, x0, duration, dt, steps_per_tick, split
):
    """One run; returns ``(final [q, q̇], [Σ|e1_j| / ticks ..., TV])``.

    ``body = [R, L, d, M_b, s_x, s_y, I_A, I_w, b_v, f_c, v_s]``, ``schedule = [m_p, first_on,
    time_on, time_off, count]``, ``points (count, 2)``; ``delay = (offset, amplitude, ω, φ)`` of
    ``h = offset + amplitude |sin(ω t + φ)|``; ``control = (nominal body [R, L, d, M_b, s_x, s_y,
    I_A, I_w], K1 (5, 5), K2 (5, 5), BᵀP (5, 10), [α, ε, γ, ĉ_0])``; ``reference = (offset,
    slope, amplitude (5, K), frequency (5, K), phase (5, K))``; ``split``: whether steps are cut
    where the command switches (else looked up at each stage).
    """
    c_hat = control[4][3]
    R, L, d = body[0], body[1], body[2]
    T_c = steps_per_tick * dt
    period = (steps_per_tick, dt)
    ticks = int(round(duration / T_c))
    # every buffer allocated once, before the loop
    history = np.zeros((ticks + 1, 2))
    q = x0[:N].copy()
    qdot = x0[N:].copy()
    buffers = (
        np.empty(N),  # q_d
        np.empty(N),  # q̇_d
        np.empty(N),  # q̈_d
        np.empty(2 * N),  # e = [e1; ė1]
        np.empty(N),  # s
        np.zeros(N),  # s at the tick before
        np.empty(N),  # û
    )
    sums = np.zeros(N + 1)
    y = np.empty(N + 2)  # (q, η) of a stage
    slope = np.empty((4, N + 2))
    torques = np.empty((4, 2))
    last = np.array([np.nan, np.nan])  # [t, g(t)] where g was last evaluated (split steps)
    index_end = 0  # the command's tick at the end of the step before (unsplit steps)
    for k in range(ticks):
        # the tick's time as the engine writes it when split (the unsplit loops keep k T_c)
        t_k = (k * steps_per_tick) * dt if split else k * T_c
        c_hat = _tick(k, t_k, q, qdot, body, control, reference, c_hat, buffers, history, sums, T_c)
        if k == 0:  # the start onto the constraints
            _velocity_map(q, qdot, 0.5 * R, R / (2.0 * L), d)
            if not split:
                index_end = _command_index(0.0, delay, T_c)
        # the plant's steps to the next tick: RK4 on (q, η)
        for step in range(steps_per_tick):
            if split:
                _split_step(
                    q,
                    qdot,
                    k * steps_per_tick + step,
                    dt,
                    delay,
                    history,
                    period,
                    torques,
                    slope,
                    y,
                    body,
                    schedule,
                    points,
                    last,
                )
                continue
            # h at the three times of a step (its end is the next step's start)
            t = t_k + step * dt
            middle = _command_index(t + 0.5 * dt, delay, T_c)
            _torques_at(torques, 0, history, index_end)
            _torques_at(torques, 1, history, middle)
            _torques_at(torques, 2, history, middle)
            index_end = _command_index(t + dt, delay, T_c)
            _torques_at(torques, 3, history, index_end)
            _rk4_step(q, qdot, t, dt, torques, slope, y, body, schedule, points)
    for i in range(N):
        sums[i] /= ticks
    final = np.empty(2 * N)
    final[:N] = q
    final[N:] = qdot
    return final, sums


@numba.njit(cache=True, error_model="numpy", parallel=True)
def _batch(
    bodies, schedules, points, delays, control, reference, x0, duration, dt, steps_per_tick, split
):
    runs = bodies.shape[0]
    sums = np.empty((runs, N + 1))
    for r in numba.prange(runs):
        sums[r] = _one_run(
            bodies[r],
            schedules[r],
            points[r],
            delays[r],
            control,
            reference,
            x0,
            duration,
            dt,
            steps_per_tick,
            split,
        )[1]
    return sums


# --- the numbers, read from the package's objects (no kernel of the package is called) --------


def _plant_numbers(plant) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``body``, ``schedule`` and ``points`` of a :class:`~delaytrack.plants.robot.PayloadRobot`
    (its parameter vector: the 12 truth parameters ``[R, L, d, M_b, s_x, s_y, I_A, I_w, b_v,
    f_c, v_s, k_b]``, then ``[m_p, first_on, time_on, time_off, count, p_0x, p_0y, ...]``)."""
    params = np.asarray(plant.params, dtype=float)
    count = int(params[16])
    return params[:11].copy(), params[12:17].copy(), params[17 : 17 + 2 * count].reshape(count, 2)


def _control_numbers(controller) -> tuple:
    """The nominal body, ``K1``, ``K2``, ``BᵀP`` and ``[α, ε, γ, ĉ_0]`` of an AROLC."""
    n = controller.n
    c_hat0 = controller.gamma if controller.c_hat0 is None else controller.c_hat0
    return (
        np.asarray(controller.model.params, dtype=float)[:8].copy(),
        np.ascontiguousarray(controller.K1, dtype=float),
        np.ascontiguousarray(controller.K2, dtype=float),
        np.ascontiguousarray(controller.P[n:, :], dtype=float),
        np.array([controller.alpha, controller.epsilon, controller.gamma, c_hat0], dtype=float),
    )


def _reference_numbers(reference) -> tuple:
    """``(offset, slope, amplitude, frequency, phase)`` of a sinusoidal reference, as (5,) and
    (5, K) arrays."""
    offset = np.asarray(reference.offset, dtype=float)
    n = offset.size

    def column(values) -> np.ndarray:
        return np.ascontiguousarray(np.asarray(values, dtype=float).reshape(n, -1))

    slope = np.zeros(n) if reference.slope is None else np.asarray(reference.slope, dtype=float)
    return (
        offset,
        slope,
        column(reference.amplitude),
        column(reference.frequency),
        column(reference.phase),
    )


def _shared(controller, reference, x0, duration, dt, T_c) -> tuple:
    """The arguments of :func:`_one_run` after the run's own (plant and delay), which every run
    of a batch shares."""
    return (
        _control_numbers(controller),
        _reference_numbers(reference),
        np.asarray(x0, dtype=float),
        float(duration),
        float(dt),
        round(T_c / dt),
    )


def _delay_numbers(delay, split: bool) -> np.ndarray:
    """``(offset, amplitude, ω, φ)`` of an :class:`~delaytrack.delays.AbsSineDelay`; split
    steps need ``g = t - h(t)`` rising on every piece (``|A ω| < 1``)."""
    params = np.asarray(delay.params, dtype=float)
    if split and not abs(params[1] * params[2]) < 1.0:
        raise ValueError(f"split steps need |A ω| < 1; got A = {params[1]}, ω = {params[2]}")
    return params


def independent_run(
    plant, controller, delay, reference, x0, duration, dt, T_c, *, split=False
) -> tuple:
    """One run: ``(final [q, q̇], [AE_j..., TV])``; ``split``: the exact scheme (steps cut where
    the delayed command switches) instead of the command looked up at each stage."""
    body, schedule, points = _plant_numbers(plant)
    shared = _shared(controller, reference, x0, duration, dt, T_c)
    return _one_run(body, schedule, points, _delay_numbers(delay, split), *shared, split)


def independent_batch(
    plants, controller, delays, reference, x0, duration, dt, T_c, *, split=False
) -> np.ndarray:
    """A batch on all cores (``prange``); ``[AE_j..., TV]`` per run. ``delays`` are
    :class:`~delaytrack.delays.AbsSineDelay` profiles."""
    numbers = [_plant_numbers(plant) for plant in plants]
    most = max(points.shape[0] for _, _, points in numbers)
    points = np.zeros((len(plants), most, 2))
    for r, (_, _, own) in enumerate(numbers):
        points[r, : own.shape[0]] = own
    return _batch(
        np.array([body for body, _, _ in numbers]),
        np.array([schedule for _, schedule, _ in numbers]),
        points,
        np.array([_delay_numbers(delay, split) for delay in delays]),
        *_shared(controller, reference, x0, duration, dt, T_c),
        split,
    )
