"""Compiled evaluation of delay profiles, shared by the Python classes and the simulation engine.

A profile is a ``kind`` code and a flat ``params`` vector:

========================  ===========================================================
kind                      params
========================  ===========================================================
``CONSTANT``              ``[h]``
``ABS_SINE``              ``[offset, amplitude, omega, phase]``:
                          ``h(t) = offset + amplitude |sin(omega t + phase)|``
``PIECEWISE_CONSTANT``    ``[m, t_0 .. t_{m-1}, h_0 .. h_{m-1}]``, ``h = h_i`` on ``[t_i, t_{i+1})``
``PIECEWISE_LINEAR``      ``[m, t_0 .. t_{m-1}, h_0 .. h_{m-1}]``, linear between knots
``KERNEL``                a kernel of your own: ``h(t) = kernel(t, params)``
                          (:class:`~delaytrack.delays.CompiledDelay`)
========================  ===========================================================

Both piecewise kinds hold their first value before ``t_0`` and their last after ``t_{m-1}``.
The engine evaluates ``h`` and solves the crossings of every kind through
:func:`profile_value` and :func:`profile_crossing_time`, which take the batch's delay
:class:`~delaytrack.components.Kernel` (:func:`no_kernel` when no run has one). A kernel has no
breakpoints that the engine knows (``t - h(t)`` is taken as monotone between step ends):
:func:`next_breakpoint` gives none.

The simulator integrates across the instants where ``g(t) = t - h(t)`` crosses a controller tick.
To find them it needs pieces on which ``g`` is continuous and monotone: :func:`next_breakpoint`
returns the next end of such a piece (a kink or jump of ``h``, or an extremum of ``g`` where
``dh/dt = 1``), and :func:`crossing_time` solves ``g(t) = target`` inside one piece.
:func:`slope_bound` bounds ``|dh/dt|`` on a piece, so that the simulator can tell, without
evaluating ``h``, that ``g`` cannot reach the next tick within a step.
"""

from __future__ import annotations

import math

import numpy as np
from numba.extending import overload

from delaytrack._compile.jit import inline_kernel, kernel, shared_kernel, tick_kernel
from delaytrack._compile.native_call import NativeFunctionType, call_native
from delaytrack._sorted_search import count_at_or_before
from delaytrack.components import Kernel, call_delay

CONSTANT = 0
ABS_SINE = 1
PIECEWISE_CONSTANT = 2
PIECEWISE_LINEAR = 3
KERNEL = 4

_NEWTON_ITERATIONS = 60
#: The spacing of doubles at 1 (a constant in compiled code; numba's ``np.finfo`` would be
#: compiled in each kernel that asks for it).
_EPSILON = float(np.finfo(np.float64).eps)


@inline_kernel
def _knot_index(params, t):
    """Index ``i`` with ``t_i <= t < t_{i+1}``; -1 before the first knot."""
    m = int(params[0])
    return count_at_or_before(params[1 : 1 + m], t) - 1


@inline_kernel
def delay_value(kind, params, t):
    """Return ``h(t)`` for one profile (see the module table for ``params``)."""
    if kind == CONSTANT:
        return params[0]
    if kind == ABS_SINE:
        return params[0] + params[1] * abs(math.sin(params[2] * t + params[3]))
    m = int(params[0])
    i = _knot_index(params, t)
    if i < 0:
        return params[1 + m]
    if kind == PIECEWISE_CONSTANT or i >= m - 1:
        return params[1 + m + i]
    t_a = params[1 + i]
    t_b = params[2 + i]
    h_a = params[1 + m + i]
    h_b = params[2 + m + i]
    return h_a + (h_b - h_a) * (t - t_a) / (t_b - t_a)


@shared_kernel
def piece_end_values(kind, params, a, b):
    """``(h(a+), h(b-))`` on a piece ``[a, b]`` that contains no breakpoint inside."""
    if kind == PIECEWISE_CONSTANT:
        value = delay_value(kind, params, 0.5 * (a + b))
        return value, value
    return delay_value(kind, params, a), delay_value(kind, params, b)


@shared_kernel
def next_breakpoint(kind, params, t):
    """Smallest ``t_b > t`` at which ``h`` has a kink or jump or ``t - h(t)`` has an extremum.

    Returns ``inf`` when there is none. Between two consecutive breakpoints ``t - h(t)`` is
    continuous and monotone.
    """
    if kind == CONSTANT or kind == KERNEL:
        return np.inf
    if kind == ABS_SINE:
        amplitude = params[1]
        omega = params[2]
        if omega == 0.0 or amplitude == 0.0:
            return np.inf
        # In each half period theta in [j pi, (j+1) pi) the profile is offset + A sin(theta - j pi);
        # it has a kink at j pi and, when A omega > 1, dh/dt = 1 at j pi + arccos(1 / (A omega)).
        extremum = math.acos(1.0 / (amplitude * omega)) if amplitude * omega > 1.0 else -1.0
        theta = omega * t + params[3]
        j = math.floor(theta / math.pi)
        for step in range(3):
            base = (j + step) * math.pi
            for offset in (0.0, extremum):
                if offset < 0.0:
                    continue
                t_b = (base + offset - params[3]) / omega
                if t_b > t:
                    return t_b
        return np.inf
    m = int(params[0])
    i = _knot_index(params, t)
    if i + 1 < m:
        return params[2 + i]
    return np.inf


@shared_kernel
def slope_bound(kind, params, t):
    """A bound on ``|dh/dt|`` over the piece that starts at ``t`` (up to :func:`next_breakpoint`).

    ``|A ω|`` for ``ABS_SINE``, the knot interval's slope for ``PIECEWISE_LINEAR``, 0 for the
    constant kinds (within a piece) and ``inf`` for a kernel of the user's, whose slope is not
    known. On such a piece ``g = t - h`` moves at a speed between ``1 - L`` and ``1 + L``.
    """
    if kind == CONSTANT or kind == PIECEWISE_CONSTANT:
        return 0.0
    if kind == ABS_SINE:
        return abs(params[1] * params[2])
    if kind == KERNEL:
        return np.inf
    m = int(params[0])
    i = _knot_index(params, t)
    if i < 0 or i >= m - 1:
        return 0.0
    return abs((params[2 + m + i] - params[1 + m + i]) / (params[2 + i] - params[1 + i]))


@inline_kernel
def crossing_time(kind, params, a, b, g_a, g_b, target):
    """Solve ``t - h(t) = target`` for ``t`` in a piece ``[a, b]`` where ``g = t - h`` is monotone.

    ``g_a`` and ``g_b`` are ``g(a+)`` and ``g(b-)``; ``target`` must lie between them. ``g`` is
    linear on a piece for every kind but ``ABS_SINE``, which is solved by bracketed Newton steps
    (unless its slope ``A ω`` is zero, as for a zero amplitude: ``g`` is then linear too, and
    Newton steps from a root at an end of the piece, where a constant delay puts every crossing,
    would halve the bracket to the last bit, 60 evaluations of ``sin`` a step).
    """
    if g_b == g_a:
        return a
    amplitude = params[1] if kind == ABS_SINE else 0.0
    omega = params[2] if kind == ABS_SINE else 0.0
    root = a + (target - g_a) * (b - a) / (g_b - g_a)
    if amplitude * omega == 0.0:  # g is linear
        return min(max(root, a), b)
    phase = params[3]
    increasing = g_b > g_a
    lo = a
    hi = b
    for _ in range(_NEWTON_ITERATIONS):
        if not lo < root < hi:
            root = 0.5 * (lo + hi)
        theta = omega * root + phase
        sine = math.sin(theta)
        residual = root - params[0] - amplitude * abs(sine) - target
        if residual == 0.0:
            return root
        if (residual < 0.0) == increasing:
            lo = root
        else:
            hi = root
        if hi - lo <= 4.0 * _EPSILON * max(1.0, abs(root)):
            return 0.5 * (lo + hi)
        slope = 1.0 - amplitude * omega * math.cos(theta) * (1.0 if sine >= 0.0 else -1.0)
        root = root - residual / slope if slope != 0.0 else 0.5 * (lo + hi)
    return root


def switch_bound(kind: int, params: np.ndarray, t0: float, t1: float, T_c: float) -> float:
    """How many times, at most, the applied command can switch in ``[t0, t1]`` (within a
    factor of two; what matters is the order of magnitude).

    The command switches where ``g(t) = t - h(t)`` crosses a controller tick (ticks lie in
    ``[t0, t1]``), and the simulator also splits steps at the ends of the pieces of ``g``
    (:func:`next_breakpoint`). On each piece ``g`` is monotone, so it crosses at most
    ``|Δ clip(g)| / T_c + 1`` ticks, with ``g`` clipped to the ticks' range. A profile whose
    bound is astronomically large (a rectified sine of frequency 1e300) would keep the step
    splitting busy without end.
    """
    duration = t1 - t0
    if kind == CONSTANT:
        return duration / T_c + 1.0
    if kind == ABS_SINE:
        amplitude, omega = abs(float(params[1])), abs(float(params[2]))  # inf, not a warning
        pieces = 2.0 * omega * duration / math.pi + 2.0
        travel = min(duration * (1.0 + amplitude * omega), pieces * duration)
        return travel / T_c + pieces
    m = int(params[0])
    times = params[1 : 1 + m]
    values = params[1 + m : 1 + 2 * m]
    inside = (np.append(times[1:], np.inf) >= t0) & (times <= t1)
    g = np.clip(times - values, t0, t1)
    # Jumps (piecewise constant) and slopes (piecewise linear) between knots inside the run,
    # plus the unit slope of g before, between and after them.
    steps = np.abs(np.diff(g))[inside[:-1]] if m > 1 else np.zeros(0)
    return (duration + float(np.sum(steps))) / T_c + float(np.count_nonzero(inside)) + 2.0


# ---- every kind, a kernel of the user's included (the engine's calls) ------------------------


@kernel
def no_kernel(t, params):
    """The delay kernel of a batch without a :data:`KERNEL` profile (never called)."""
    return math.nan


#: The :class:`~delaytrack.components.Kernel` of :func:`no_kernel`.
NO_KERNEL = Kernel.of(no_kernel)


@shared_kernel
def profile_value(delay, kind, params, t):
    """``h(t)`` of a profile of any kind; ``delay`` is the batch's delay kernel."""
    if kind == KERNEL:
        return call_delay(delay, t, params)
    return delay_value(kind, params, t)


@tick_kernel
def evaluate_profile(delay, kind, params, t):
    """:func:`profile_value`, compiled on its own for each delay kernel: the compiled engine calls
    it through its address (:mod:`delaytrack._compile.native_parts`)."""
    return profile_value(delay, kind, params, t)


def delay_at(delay, kind, params, t):
    """``h(t)`` of a profile of any kind, in the engine's tick loop: ``delay`` is the batch's
    delay kernel (plain-Python engine) or, compiled, :func:`evaluate_profile` compiled for it
    and called through its address with the kernel bound."""
    return profile_value(delay, kind, params, t)


@overload(delay_at, inline="always")
def _delay_at_compiled(delay, kind, params, t):
    if isinstance(delay, NativeFunctionType):

        def native(delay, kind, params, t):
            return call_native(delay, (kind, params, t))

        return native
    return None


@shared_kernel
def profile_crossing_time(delay, kind, params, a, b, g_a, g_b, target):
    """:func:`crossing_time` of a profile of any kind.

    A kernel of the user's is solved by regula falsi with the Illinois modification (the kept
    end's value halved when the same end is kept twice), inside the bracket ``[a, b]`` whose
    ends straddle ``target``, until the bracket is a few units of round-off wide.
    """
    if kind != KERNEL:
        return crossing_time(kind, params, a, b, g_a, g_b, target)
    lo = a
    hi = b
    f_lo = g_a - target
    f_hi = g_b - target
    if f_lo == 0.0:
        return a
    if f_hi == 0.0:
        return b
    kept = 0
    for _ in range(2 * _NEWTON_ITERATIONS):
        if hi - lo <= 4.0 * _EPSILON * max(1.0, abs(lo)):
            break
        root = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
        if not lo < root < hi:
            root = 0.5 * (lo + hi)
        residual = root - call_delay(delay, root, params) - target
        if residual == 0.0:
            return root
        if (residual < 0.0) == (f_lo < 0.0):
            lo, f_lo = root, residual
            if kept == -1:
                f_hi *= 0.5
            kept = -1
        else:
            hi, f_hi = root, residual
            if kept == 1:
                f_lo *= 0.5
            kept = 1
    return 0.5 * (lo + hi)


@kernel
def profile_values(delay, kind, params, times):
    """:func:`profile_value` at each of ``times`` (1-D), through :func:`evaluate_profile`: the
    compiled code the engine calls (numba would compile the profile's code again for this
    caller, compiled with its runtime, if it called :func:`profile_value` itself: most of its
    first call's time)."""
    out = np.empty(times.shape[0])
    for i in range(times.shape[0]):
        out[i] = evaluate_profile(delay, kind, params, times[i])
    return out


@kernel
def first_invalid_step_end(delay, params, t0, dt, steps, h_max):
    """Index ``j`` of the first step end ``t0 + j dt`` (``j = 0 .. steps``) where a delay kernel
    of the user's gives an ``h`` that is not a number in ``[0, h_max]``, and that ``h``;
    ``(-1, 0.0)`` when there is none."""
    for j in range(steps + 1):
        h = call_delay(delay, t0 + j * dt, params)
        if not (0.0 <= h <= h_max):
            return j, h
    return -1, 0.0
