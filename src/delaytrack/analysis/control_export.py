"""The nominal AROLC error loop as python-control systems, for Bode, Nyquist and margin analysis.

With the input delayed by a constant h and no uncertainty, the outer loop of Roy & Kar's AROLC,
u = q̈_d + K2 ė + K1 e, gives the error dynamics (paper, (new err dyn 1) with Δu = σ = 0)

    ë(t) = −K2 ė(t − h) − K1 e(t − h),

which is the unity negative feedback u = −y(t − h) around the open loop

    ẋ = [[0, I], [0, 0]] x + [[0], [I]] u,   y = [K1, K2] x,   x = [e; ė],

i.e. the n x n transfer matrix L(s) = (K2 s + K1) / s² followed (or preceded: the delay is
the same on every channel) by e^{−sh} I. Its characteristic equation
det(s² I + (K2 s + K1) e^{−sh}) = 0 is the one :func:`~delaytrack.analysis.exact_delay_margin`
solves; for scalar gains the delay margin is the phase margin over the crossover frequency,
PM / ω_c.

Three views of the loop:

* :func:`error_loop`: the rational part as a ``control.StateSpace``, optionally with the delay
  replaced by a Padé approximant (``control.pade``) on each channel;
* :func:`error_loop_frequency_response`: L(jω) e^{−jωh} with the exact delay, as a
  ``control.FrequencyResponseData`` for ``control.bode_plot``, ``control.nyquist_plot`` and
  ``control.margin``;
* :func:`error_loop_sampled`: the loop as the simulation engine runs it, a controller sampled
  at period T_c whose command is applied through a delayed zero-order hold (the command of the
  latest tick <= t − h): the exact discretisation, any h >= 0, as a discrete-time
  ``control.StateSpace``. It is exact for the engine's nominal error loop when q̈_d is constant
  between ticks; otherwise the held feedforward q̈_d(t_k) differs from q̈_d(t), a disturbance
  outside the loop. ``control.sample_system`` would discretise only the delay-free plant (and
  a delay that is a whole number of ticks); the fractional part of h is built in here.

python-control is imported when a function is called, so :mod:`delaytrack.analysis` works
without it.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from delaytrack._validation import finite_array, is_integer_at_least, positive_scalar
from delaytrack.analysis.razumikhin import _gains

if TYPE_CHECKING:
    import control

__all__ = ["error_loop", "error_loop_frequency_response", "error_loop_sampled"]

#: A delay within this (relative, in ticks) of a whole number of ticks is that number of ticks.
_TICK_RTOL = 1e-9

#: Largest number of states of :func:`error_loop_sampled` (its matrices are dense).
_MAX_SAMPLED_STATES = 4096


def _control():
    """Import python-control, or say how to get it."""
    try:
        import control
    except ImportError:  # pragma: no cover - control is installed with the test extra
        raise ImportError(
            "python-control is needed for delaytrack.analysis.control_export; "
            "install it with `pip install control` (or delaytrack's `tutorial` extra, from a "
            "clone of delaytrack: `pip install -e '.[tutorial]'`)"
        ) from None
    return control


def _signal_names(n: int) -> dict[str, list[str]]:
    return {
        "inputs": [f"u[{i}]" for i in range(n)],
        "outputs": [f"y[{i}]" for i in range(n)],
    }


def _plant_matrices(
    K1: np.ndarray, K2: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(A, B, C, D) of ẋ = [[0, I], [0, 0]] x + [[0], [I]] u, y = [K1, K2] x."""
    n = K1.shape[0]
    eye, zero = np.eye(n), np.zeros((n, n))
    A = np.block([[zero, eye], [zero, zero]])
    B = np.vstack([zero, eye])
    C = np.hstack([K1, K2])
    return A, B, C, np.zeros((n, n))


def _pade_order(pade_order: object) -> int:
    if not is_integer_at_least(pade_order, 1):
        raise ValueError(
            "pade_order must be an integer >= 1 (the degree of the Padé approximant of "
            f"e^(-s delay)); got {pade_order!r}"
        )
    return int(pade_order)


def error_loop(
    K1: object,
    K2: object,
    *,
    delay: float | None = None,
    pade_order: int | None = None,
    n: int | None = None,
) -> control.StateSpace:
    """The open error loop L(s) = (K2 s + K1) / s² of AROLC as a python-control state space.

    Implements, with x = [e; ė] (2n states), input u (n) and output y (n)::

        ẋ = [[0, I], [0, 0]] x + [[0], [I]] u,    y = K1 e + K2 ė,

    so that L(s) = (K2 s + K1) / s² and the unity negative feedback u = −y(t − h) is the nominal
    error dynamics ë = −K2 ė(t − h) − K1 e(t − h) of Roy & Kar. With ``delay`` and
    ``pade_order`` the input passes first through the Padé approximant
    P(s) ≈ e^{−s·delay} of ``control.pade(delay, pade_order)`` on each channel (``pade_order``
    more states per channel)::

        L_pade(s) = L(s) P(s),

    so ``control.feedback(error_loop(K1, K2, delay=h, pade_order=m), np.eye(n))`` approximates
    the delayed closed loop, and its poles approximate the rightmost characteristic roots of
    det(s² I + (K2 s + K1) e^{−sh}) = 0. The approximation is good while ω h is small at the
    frequencies that matter (the crossover); Padé approximants of high degree (above about 10)
    are numerically poor. For the exact delay use :func:`error_loop_frequency_response`.

    For scalar gains, ``control.margin`` of the delay-free loop gives the phase margin PM and
    crossover ω_c, and PM (rad) / ω_c is the exact delay margin
    (:func:`~delaytrack.analysis.exact_delay_margin`); K1 = K2 = 1 gives
    PM = 51.83°, ω_c = 1.2720 rad/s and 0.7111 s. For diagonal gains each channel is such a
    loop; ``control.ss2tf(loop[i, i]).minreal()`` gives channel i without the other channels'
    states (which ``control.margin`` cannot handle as they stand).

    Parameters
    ----------
    K1, K2 : array_like
        Symmetric positive definite gains of the outer loop u = q̈_d + K2 ė + K1 e, ``(n, n)``;
        a 1-D array means a diagonal matrix and a scalar means ``K * I`` (n = 1 unless ``n`` is
        given).
    delay : float, optional
        Constant input delay h >= 0 in seconds, approximated by a Padé approximant; needs
        ``pade_order``.
    pade_order : int, optional
        Degree (>= 1) of the Padé approximant; needs ``delay``.
    n : int, optional
        Number of joints; needed only to expand a scalar K1 with n > 1.

    Returns
    -------
    control.StateSpace
        Continuous time, n inputs ``u[i]`` and n outputs ``y[i]``; 2n states, plus
        ``n * pade_order`` with a delay. The first 2n states are ``e[i]`` then ``edot[i]``.

    Raises
    ------
    ValueError
        If a gain is not symmetric positive definite, not finite or has the wrong shape (the
        message names it), ``delay`` is negative or not finite, ``pade_order`` is not an integer
        >= 1, or only one of ``delay`` and ``pade_order`` is given.
    TypeError
        If a gain or ``delay`` is not numeric.

    Examples
    --------
    >>> import control
    >>> _, pm, _, wc = control.margin(error_loop(1.0, 1.0))
    >>> round(float(pm) * 3.141592653589793 / 180 / float(wc), 4)
    0.7111
    """
    K1_matrix, K2_matrix = _gains(K1, K2, n, spd=True)
    if delay is not None:
        h = positive_scalar("delay", delay, strictly=False)
        if pade_order is None:
            raise ValueError(
                f"delay = {h:g} s needs pade_order (an integer >= 1, the degree of the Padé "
                "approximant standing in for e^(-s delay) in a rational model); for the exact "
                "delay use error_loop_frequency_response(K1, K2, omega, delay=...)"
            )
        order = _pade_order(pade_order)
    elif pade_order is not None:
        _pade_order(pade_order)
        raise ValueError(
            f"pade_order = {pade_order!r} is given without delay; give the delay in seconds "
            "(delay=...) to approximate, or neither for the delay-free loop"
        )
    control = _control()
    size = K1_matrix.shape[0]
    A, B, C, D = _plant_matrices(K1_matrix, K2_matrix)
    states = [f"e[{i}]" for i in range(size)] + [f"edot[{i}]" for i in range(size)]
    if delay is None:
        return control.ss(A, B, C, D, states=states, name="error_loop", **_signal_names(size))
    numerator, denominator = control.pade(h, order)
    pade = control.tf2ss(numerator, denominator)
    if pade.nstates:
        eye = np.eye(size)
        a, b, c, d = (np.kron(eye, m) for m in (pade.A, pade.B, pade.C, pade.D))
        # The Padé filter w = P(s) u feeds the plant: x' = A x + B w, w = c z + d u.
        A = np.block([[A, B @ c], [np.zeros((a.shape[0], A.shape[1])), a]])
        B = np.vstack([B @ d, b])
        C = np.hstack([C, np.zeros((size, a.shape[0]))])
        states += [f"pade[{i}][{j}]" for i in range(size) for j in range(pade.nstates)]
    return control.ss(A, B, C, D, states=states, name="error_loop_pade", **_signal_names(size))


def error_loop_frequency_response(
    K1: object,
    K2: object,
    omega: object,
    *,
    delay: float = 0.0,
    n: int | None = None,
) -> control.FrequencyResponseData:
    """The frequency response L(jω) e^{−jωh} of the AROLC error loop, with the exact delay.

    Implements, at each frequency ω > 0::

        L(jω) e^{−jωh} = (K1 + jω K2) e^{−jωh} / (jω)² = −(K1 + jω K2) e^{−jωh} / ω²,

    the open loop of :func:`error_loop` with the delay h on every channel; its unity negative
    feedback is the nominal error dynamics ë = −K2 ė(t − h) − K1 e(t − h) of Roy & Kar. The
    result works with ``control.bode_plot``, ``control.nyquist_plot`` and (scalar gains)
    ``control.margin``, which then gives PM(h) = PM(0) − ω_c h: the delay still tolerated is
    PM(h) / ω_c = h_margin − h (``control.margin`` interpolates between the given frequencies,
    so a fine grid around the crossover gives an accurate margin).

    A Nyquist plot of the response shows only the given band: L has a double pole at s = 0,
    which the frequency points cannot show, so read stability from the margin or from
    :func:`~delaytrack.analysis.exact_delay_margin`, not from the encirclement count.

    Parameters
    ----------
    K1, K2 : array_like
        Symmetric positive definite gains, ``(n, n)``; a 1-D array means a diagonal matrix and a
        scalar means ``K * I`` (n = 1 unless ``n`` is given).
    omega : array_like
        Frequencies in rad/s, 1-D (or a scalar), every one finite and > 0 (L is infinite at
        ω = 0), strictly increasing.
    delay : float, optional
        Constant input delay h >= 0 in seconds (default 0).
    n : int, optional
        Number of joints; needed only to expand a scalar K1 with n > 1.

    Returns
    -------
    control.FrequencyResponseData
        n inputs ``u[i]``, n outputs ``y[i]``, response ``(n, n, len(omega))``.

    Raises
    ------
    ValueError
        If a gain is not symmetric positive definite, not finite or has the wrong shape,
        ``omega`` is empty, not 1-D, not finite, not > 0 or not strictly increasing, or ``delay``
        is negative or not finite (each message names the argument).
    TypeError
        If a gain, ``omega`` or ``delay`` is not numeric.

    Examples
    --------
    >>> import numpy as np
    >>> response = error_loop_frequency_response(1.0, 1.0, [1.0, 2.0], delay=0.1)
    >>> response.ninputs, response.omega.tolist()
    (1, [1.0, 2.0])
    """
    K1_matrix, K2_matrix = _gains(K1, K2, n, spd=True)
    frequencies = np.atleast_1d(finite_array("omega", omega))
    if frequencies.ndim != 1 or frequencies.size == 0:
        raise ValueError(
            "omega must be a non-empty 1-D array of frequencies in rad/s; got shape "
            f"{frequencies.shape}"
        )
    if not np.all(frequencies > 0.0):
        raise ValueError(
            "omega must be > 0 rad/s everywhere (L(s) = (K2 s + K1) / s² is infinite at s = 0); "
            f"its smallest entry is {float(np.min(frequencies)):g}"
        )
    if frequencies.size > 1 and not np.all(np.diff(frequencies) > 0.0):
        bad = int(np.flatnonzero(np.diff(frequencies) <= 0.0)[0])
        raise ValueError(
            f"omega must be strictly increasing; entry {bad + 1} ({frequencies[bad + 1]:g}) does "
            f"not exceed entry {bad} ({frequencies[bad]:g})"
        )
    h = positive_scalar("delay", delay, strictly=False)
    control = _control()
    size = K1_matrix.shape[0]
    pencil = K1_matrix[:, :, None] + 1j * frequencies * K2_matrix[:, :, None]
    response = -pencil * (np.exp(-1j * frequencies * h) / frequencies**2)
    return control.frd(
        response, frequencies, name="error_loop_frequency_response", **_signal_names(size)
    )


def error_loop_sampled(
    K1: object,
    K2: object,
    period: float,
    *,
    delay: float = 0.0,
    n: int | None = None,
) -> control.StateSpace:
    """The AROLC error loop with a controller sampled at ``period``, held and delayed.

    The controller reads y_k = K1 e(t_k) + K2 ė(t_k) at the ticks t_k = k T_c and its command
    u_k is applied through a delayed zero-order hold: at time t the plant ë = v receives the
    command of the latest tick <= t − h (as the simulation engine does). With
    h = (w + f) T_c, w a whole number of ticks and 0 <= f < 1, the state x = [e; ė] obeys
    exactly::

        x_{k+1} = Φ x_k + Γ0 u_{k−w} + Γ1 u_{k−w−1},    y_k = [K1, K2] x_k,

        Φ = [[I, T_c I], [0, I]],
        Γ0 = ∫_0^{(1−f) T_c} e^{Aσ} dσ B = [[a² / 2 I], [a I]],   a = (1 − f) T_c,
        Γ1 = ∫_{(1−f) T_c}^{T_c} e^{Aσ} dσ B = [[(T_c² − a²) / 2 I], [(T_c − a) I]],

    (A = [[0, I], [0, 0]], B = [[0], [I]]): on [t_k, t_k + f T_c) the plant still receives
    u_{k−w−1}, then u_{k−w}. The past commands u_{k−1}, ..., u_{k−m} (m = w, or w + 1 when
    f > 0) are states, so the closed loop u_k = −y_k is
    ``control.feedback(error_loop_sampled(...), np.eye(n))`` and is stable iff its poles lie
    inside the unit circle. With h = 0 it equals ``control.sample_system(error_loop(K1, K2),
    T_c, "zoh")``; as T_c → 0 its delay margin tends to that of the continuous loop
    (:func:`~delaytrack.analysis.exact_delay_margin`), less about T_c / 2 from the hold.

    It is exact for the simulation's nominal error loop when the reference acceleration q̈_d is
    constant between ticks; otherwise the held q̈_d(t_k) differs from q̈_d(t), a disturbance
    outside this loop.

    Parameters
    ----------
    K1, K2 : array_like
        Symmetric positive definite gains, ``(n, n)``; a 1-D array means a diagonal matrix and a
        scalar means ``K * I`` (n = 1 unless ``n`` is given).
    period : float
        The control period T_c > 0 in seconds.
    delay : float, optional
        Constant input delay h >= 0 in seconds (default 0); need not be a whole number of
        periods. Within a relative 1e-9 of one, it is taken as that whole number.
    n : int, optional
        Number of joints; needed only to expand a scalar K1 with n > 1.

    Returns
    -------
    control.StateSpace
        Discrete time with ``dt = period``; n inputs ``u[i]``, n outputs ``y[i]``; states
        ``e[i]``, ``edot[i]`` and then ``u_past[j][i]`` = u_{k−j} (j = 1 ... m), n (2 + m) in
        all.

    Raises
    ------
    ValueError
        If a gain is not symmetric positive definite, not finite or has the wrong shape,
        ``period`` is not > 0, ``delay`` is negative, or the model would have more than 4096
        states (``delay / period`` too large; the matrices are dense).
    TypeError
        If a gain, ``period`` or ``delay`` is not numeric.

    Examples
    --------
    >>> system = error_loop_sampled(1.0, 1.0, 0.01, delay=0.025)
    >>> system.dt, system.nstates
    (0.01, 5)
    """
    K1_matrix, K2_matrix = _gains(K1, K2, n, spd=True)
    T = positive_scalar("period", period)
    h = positive_scalar("delay", delay, strictly=False)
    ticks = h / T
    if not math.isfinite(ticks):
        raise ValueError(f"delay / period must be finite; got delay = {h:g}, period = {T:g}")
    whole = round(ticks)
    if abs(ticks - whole) <= _TICK_RTOL * max(1.0, ticks):
        whole, fraction = whole, 0.0
    else:
        whole = math.floor(ticks)
        fraction = ticks - whole
    size = K1_matrix.shape[0]
    past = whole + (1 if fraction > 0.0 else 0)
    n_states = size * (2 + past)
    if n_states > _MAX_SAMPLED_STATES:
        raise ValueError(
            f"delay / period = {ticks:.6g} ticks would need {n_states} states (n (2 + m), "
            f"m = {past} past commands), more than {_MAX_SAMPLED_STATES}; use a longer period "
            "or a shorter delay"
        )
    control = _control()
    eye, zero = np.eye(size), np.zeros((size, size))
    _, _, C_plant, D = _plant_matrices(K1_matrix, K2_matrix)
    Phi = np.block([[eye, T * eye], [zero, eye]])
    a = (1.0 - fraction) * T
    Gamma0 = np.vstack([0.5 * a * a * eye, a * eye])
    Gamma1 = np.vstack([0.5 * (T * T - a * a) * eye, (T - a) * eye])
    A = np.zeros((n_states, n_states))
    B = np.zeros((n_states, size))
    C = np.zeros((size, n_states))
    A[: 2 * size, : 2 * size] = Phi
    C[:, : 2 * size] = C_plant

    def past_block(j: int) -> slice:
        """Columns/rows of u_{k−j} (j >= 1) in the state."""
        start = size * (1 + j)
        return slice(start, start + size)

    if past:
        B[past_block(1)] = eye  # u_{k-1} at the next tick is u_k
        for j in range(2, past + 1):
            A[past_block(j), past_block(j - 1)] = eye
    for lag, Gamma in ((whole, Gamma0), (whole + 1, Gamma1)):
        if lag > past:
            continue  # f = 0: no Γ1 term
        if lag == 0:
            B[: 2 * size] += Gamma
        else:
            A[: 2 * size, past_block(lag)] += Gamma
    states = [f"e[{i}]" for i in range(size)] + [f"edot[{i}]" for i in range(size)]
    states += [f"u_past[{j}][{i}]" for j in range(1, past + 1) for i in range(size)]
    return control.ss(
        A, B, C, D, T, states=states, name="error_loop_sampled", **_signal_names(size)
    )
