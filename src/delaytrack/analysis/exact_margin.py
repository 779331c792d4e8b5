"""The exact delay margin of the nominal AROLC error dynamics under a constant input delay.

With the input delayed by a constant h and no uncertainty, the outer loop of AROLC gives
(paper, (new err dyn 1) with Δu = σ = 0)

    ë1(t) = −K2 ė1(t − h) − K1 e1(t − h),

a retarded delay differential equation whose characteristic equation is

    det(s² I + (K2 s + K1) e^{−s h}) = 0.

For symmetric positive definite K1, K2 it is stable at h = 0, and as h grows it stays stable
until a root first reaches the imaginary axis. That delay is the exact delay margin, against
which Theorem 1's certified h_m (:func:`delaytrack.analysis.razumikhin_bound`) can be judged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from delaytrack.analysis.razumikhin import _gains

__all__ = ["MAX_SCANNED_JOINTS", "ExactDelayMargin", "exact_delay_margin"]

#: Number of frequencies sampled across the bracket that holds every crossing frequency.
_SCAN_POINTS = 2048

#: Most coupled joints the scan takes: its cost grows as n³ (0.7 s at n = 30, so about 3 s at
#: n = 50 and minutes beyond 100, in eigenvalue routines that Ctrl-C does not stop).
MAX_SCANNED_JOINTS = 50
_SCAN_SECONDS_AT_30 = 0.7

#: Relative widening of the bracket, so that a crossing on its edge (all gains equal, where the
#: bracket is a single point) is a sign change inside it.
_BRACKET_MARGIN = 1e-3

#: A local extremum of |μ| / ω² − 1 within this distance of 0 is a tangential touch.
_TOUCH_TOLERANCE = 1e-9

#: Smallest positive normal double; a smaller margin has lost precision.
_TINY = float(np.finfo(float).tiny)

#: Largest crossing frequency handled: ω² and |μ| must stay finite with room to spare; its
#: inverse is the smallest, below which ω K2 and ω² underflow.
_LARGEST_FREQUENCY = 1e100

#: Crossings whose frequencies and delays agree to this (relative) are one crossing (repeated
#: eigenvalues); an eigenvalue μ with |log(|μ| / ω²)| below it lies on the unit circle.
_SAME_RTOL = 1e-9


@dataclass(frozen=True)
class ExactDelayMargin:
    """Result of :func:`exact_delay_margin`.

    Attributes
    ----------
    h : float
        The delay margin in seconds: the smallest constant delay h > 0 at which a root of
        det(s² I + (K2 s + K1) e^{−sh}) = 0 lies on the imaginary axis.
    omega : float
        The frequency in rad/s of that root, s = ±jω.
    crossing_omegas : tuple of float
        Every crossing frequency ω > 0 (a frequency at which some delay puts a root at s = jω),
        in the order of ``crossing_delays``.
    crossing_delays : tuple of float
        For each crossing frequency, the smallest delay that puts the root there, ascending.
        The larger delays h + 2πk/ω (k = 1, 2, ...) put it there again.
    """

    h: float
    omega: float
    crossing_omegas: tuple[float, ...]
    crossing_delays: tuple[float, ...]

    def to_dict(self) -> dict[str, Any]:
        """Plain floats and lists, ready for ``json.dumps``."""
        return {
            "h": self.h,
            "omega": self.omega,
            "crossing_omegas": list(self.crossing_omegas),
            "crossing_delays": list(self.crossing_delays),
        }


def _crossover_frequency(k1: float, k2: float) -> float:
    """The frequency ω > 0 with ω⁴ = k1² + ω² k2², i.e. ω² = (k2² + sqrt(k2⁴ + 4 k1²)) / 2.

    For scalar gains it is where the loop (k2 s + k1) / s² has unit gain.
    """
    square = float(k2) * float(k2)
    return math.sqrt(0.5 * (square + math.hypot(square, 2.0 * float(k1))))


def _moduli_excess(K1: np.ndarray, K2: np.ndarray, omegas: np.ndarray) -> np.ndarray:
    """log(ω² / |μ_k(ω)|) for the eigenvalues μ_k of K1 + jωK2, sorted, shape (len(omegas), n).

    A root of the characteristic equation lies at s = jω exactly where a column is zero.
    Each column is continuous in ω (sorted moduli of continuous eigenvalues).
    """
    pencils = K1[None, :, :] + 1j * omegas[:, None, None] * K2[None, :, :]
    moduli = np.sort(np.abs(np.linalg.eigvals(pencils)), axis=1)
    return 2.0 * np.log(omegas)[:, None] - np.log(moduli)


def _excess(K1: np.ndarray, K2: np.ndarray, k: int):
    """The k-th column of :func:`_moduli_excess` as a scalar function of ω."""
    return lambda omega: float(_moduli_excess(K1, K2, np.array([omega]))[0, k])


def _crossings_of_column(excess, omegas: np.ndarray, values: np.ndarray) -> list[float]:
    """Frequencies where one sorted column of excesses is zero: sign changes and touches.

    A sign change between neighbouring samples is refined with Brent's method. At a local
    minimum of |excess| among the samples without a sign change, the excess is pushed towards
    zero over the two neighbouring intervals: if it comes within ``_TOUCH_TOLERANCE`` of zero,
    the frequency is a tangential touch and counts as one crossing; if it changes sign there,
    two crossings hide between samples and both are refined. Brent's method stops within
    1e-14 of the lowest frequency: relative, so as accurate for slow gains as for fast ones.
    """
    import scipy.optimize  # here, not at import: a controller's import need not load it

    xtol = 1e-14 * float(omegas[0])
    found: list[float] = []
    signs = np.sign(values)
    for k in np.flatnonzero(signs[:-1] * signs[1:] <= 0.0):
        found.append(scipy.optimize.brentq(excess, omegas[k], omegas[k + 1], xtol=xtol))
    magnitude = np.abs(values)
    for i in range(1, len(values) - 1):
        same_sign = signs[i - 1] == signs[i] == signs[i + 1] != 0.0
        if not (
            same_sign and magnitude[i] <= magnitude[i - 1] and magnitude[i] <= magnitude[i + 1]
        ):
            continue
        sign = signs[i]
        closest = scipy.optimize.minimize_scalar(
            lambda omega, s=sign: s * excess(omega),
            bounds=(omegas[i - 1], omegas[i + 1]),
            method="bounded",
            options={"xatol": 1e-13 * omegas[i]},
        )
        value = excess(closest.x)
        if abs(value) <= _TOUCH_TOLERANCE:
            found.append(float(closest.x))
        elif np.sign(value) != sign:
            found.append(scipy.optimize.brentq(excess, omegas[i - 1], closest.x, xtol=xtol))
            found.append(scipy.optimize.brentq(excess, closest.x, omegas[i + 1], xtol=xtol))
    return found


def _first_delays(K1: np.ndarray, K2: np.ndarray, omega: float) -> list[float]:
    """Smallest h > 0 with e^{−jωh} = ω² / μ, for each eigenvalue μ of K1 + jωK2 with |μ| = ω².

    λ = ω² / μ gives h = ((−arg λ) mod 2π) / ω = (arg μ mod 2π) / ω. Every eigenvalue within
    ``_SAME_RTOL`` of the unit modulus counts (two axes can cross at one frequency with
    different delays); the closest one always does.
    """
    eigenvalues = np.linalg.eigvals(K1 + 1j * omega * K2)
    distance = np.abs(np.log(np.abs(eigenvalues) / omega**2))
    on_axis = eigenvalues[distance <= max(_SAME_RTOL, float(np.min(distance)))]
    return [float(np.mod(np.angle(mu), 2.0 * np.pi) / omega) for mu in on_axis]


def exact_delay_margin(K1: object, K2: object, *, n: int | None = None) -> ExactDelayMargin:
    """The smallest constant input delay at which the nominal AROLC error dynamics lose stability.

    Implements the characteristic equation of ë1 = −K2 ė1(t − h) − K1 e1(t − h)::

        det(s² I + (K2 s + K1) e^{−s h}) = 0.

    **On the imaginary axis.** s = jω (ω > 0; ω < 0 is the conjugate, and s = 0 is never a root
    because K1 is nonsingular) is a root for delay h exactly when e^{−jωh} is an eigenvalue
    λ = ω² / μ of ω² (K1 + jωK2)⁻¹, μ an eigenvalue of K1 + jωK2. So ω is a crossing frequency
    iff some |μ(ω)| = ω², and then h = (arg μ mod 2π) / ω, plus multiples of 2π / ω.

    **Where crossings can lie.** Let (K1 + jωK2) v = μ v with ‖v‖ = 1. As K1, K2 are
    symmetric, a = vᴴ K1 v and b = vᴴ K2 v are real, with λ_min(K1) <= a <= ‖K1‖ and
    λ_min(K2) <= b <= ‖K2‖, and μ = a + jωb. A crossing needs ω⁴ = |μ|² = a² + ω² b², hence

        λ_min(K1)² + ω² λ_min(K2)² <= ω⁴ <= ‖K1‖² + ω² ‖K2‖²,

    i.e. ω_c(λ_min(K1), λ_min(K2)) <= ω <= ω_c(‖K1‖, ‖K2‖) with
    ω_c(k1, k2)² = (k2² + sqrt(k2⁴ + 4 k1²)) / 2, the crossover of (k2 s + k1) / s². (This is
    tighter than λ_min(K1) <= ω² <= ‖K1‖ + ω‖K2‖, which it implies.) Below the bracket every
    |μ| exceeds ω² and above it every |μ| is below ω², so each of the n sorted curves
    log(ω² / |μ_k(ω)|) changes sign an odd number of times inside it: there are at least n
    crossings (counted with multiplicity). Since a = Re μ > 0 and b = Im μ / ω > 0, μ lies in
    the open first quadrant and h = arg μ / ω with 0 < arg μ < π/2.

    **Method.** The bracket, widened by 0.1 %, is sampled at 2048 log-spaced frequencies; every
    sign change of every sorted curve is refined with :func:`scipy.optimize.brentq`. A local
    minimum of a curve's distance to zero without a sign change is examined too: two roots
    closer than the sampling step are split and refined, and a tangential touch (the curve
    reaches zero within 1e-9 without crossing) counts as a crossing frequency, because a root
    then reaches the imaginary axis, which is what the margin measures. Crossings equal in
    frequency and delay to a relative 1e-9 are merged (repeated gains give repeated
    crossings); distinct delays at one frequency (two axes with one crossover) are all kept.

    Cost: 2 ms for n = 1, 80 ms for a dense n = 10, 0.7 s for a dense n = 30 (one core); dense
    gains of more than :data:`MAX_SCANNED_JOINTS` joints are refused, saying what the scan
    would take.
    Diagonal gains decouple and are not scanned: each axis crosses once, at ω_c = ω_c(k1, k2),
    with h = atan(ω_c k2 / k1) / ω_c (closed form, O(n)); K1 = K2 = I gives h = 0.7111 s.

    **Range.** Crossing frequencies must lie within [1e-100, 1e100] rad/s and the margin must be
    a normal double (>= 2.2e-308 s); gains outside are refused with the range in the message.

    Parameters
    ----------
    K1, K2 : array_like
        Symmetric positive definite gains of (aux), ``(n, n)``; a 1-D array means a diagonal
        matrix and a scalar means ``K * I`` (n = 1 unless ``n`` is given).
    n : int, optional
        Number of joints; needed only to expand a scalar K1 with n > 1.

    Returns
    -------
    ExactDelayMargin
        The margin h (s), its frequency ω (rad/s) and every crossing frequency with its first
        crossing delay.

    Raises
    ------
    ValueError
        If a gain is not symmetric positive definite (the message gives its eigenvalues), is
        not finite, or has the wrong shape (the message names the argument and the shape), or
        the gains are outside the range above (the message says which range).
    TypeError
        If a gain is not numeric.

    Examples
    --------
    >>> round(exact_delay_margin(1.0, 1.0).h, 4)
    0.7111
    """
    K1_matrix, K2_matrix = _gains(K1, K2, n, spd=True)
    (least_k1, largest_k1), (least_k2, largest_k2) = (
        (float(values[0]), float(values[-1]))
        for values in (np.linalg.eigvalsh(K1_matrix), np.linalg.eigvalsh(K2_matrix))
    )
    low, high = (
        _crossover_frequency(least_k1, least_k2),
        _crossover_frequency(largest_k1, largest_k2),
    )
    if not high < _LARGEST_FREQUENCY:
        raise ValueError(
            f"K1 and K2 are too large for the margin to be computed in floating point: crossing "
            f"frequencies may reach {high:.3g} rad/s (||K1|| = {largest_k1:.3g}, ||K2|| = "
            f"{largest_k2:.3g}); they must stay below {_LARGEST_FREQUENCY:g} rad/s, which "
            f"||K1|| below about {0.5 * _LARGEST_FREQUENCY**2:g} and ||K2|| below about "
            f"{0.5 * _LARGEST_FREQUENCY:g} ensure; rescale time"
        )
    if not low > 1.0 / _LARGEST_FREQUENCY:
        raise ValueError(
            f"K1 and K2 are too small for the margin to be computed in floating point: crossing "
            f"frequencies may be as low as {low:.3g} rad/s (smallest eigenvalues of K1 and K2: "
            f"{least_k1:.3g}, {least_k2:.3g}); they must stay above {1.0 / _LARGEST_FREQUENCY:g} "
            f"rad/s, which a smallest eigenvalue of K1 above {1.0 / _LARGEST_FREQUENCY**2:g} "
            "ensures; rescale time"
        )
    crossings: list[tuple[float, float]] = []
    axes = _axis_crossings(K1_matrix, K2_matrix)
    if not axes:
        _check_scan_size(K1_matrix.shape[0])
    for h, omega in axes or _scanned_crossings(K1_matrix, K2_matrix, low, high):
        if not any(_same(omega, w) and _same(h, d) for d, w in crossings):
            crossings.append((h, omega))
    crossings.sort()
    if not crossings[0][0] >= _TINY:
        raise ValueError(
            f"K2 is too small relative to K1 for the margin to be computed in floating point: "
            f"it would be about {crossings[0][0]:.3g} s, below the smallest normal double "
            f"{_TINY:.3g} (smallest eigenvalue of K2 {least_k2:.3g}, largest of K1 "
            f"{largest_k1:.3g}); rescale time"
        )
    return ExactDelayMargin(
        h=crossings[0][0],
        omega=crossings[0][1],
        crossing_omegas=tuple(w for _, w in crossings),
        crossing_delays=tuple(d for d, _ in crossings),
    )


def _check_scan_size(n: int) -> None:
    """Refuse a scan of more than :data:`MAX_SCANNED_JOINTS` coupled joints, saying what it
    would take, before any eigenvalue is computed."""
    if n <= MAX_SCANNED_JOINTS:
        return
    seconds = _SCAN_SECONDS_AT_30 * (n / 30) ** 3
    raise ValueError(
        f"K1 is {n}x{n} and K1, K2 couple the joints: the exact margin scans the eigenvalues "
        f"of K1 + j omega K2 at {_SCAN_POINTS} frequencies (about {seconds:.0f} s of compiled "
        f"code on one core that Ctrl-C cannot stop); it scans at most n = "
        f"{MAX_SCANNED_JOINTS} coupled joints (diagonal gains are solved in closed form for "
        "any n)"
    )


def _axis_crossings(K1: np.ndarray, K2: np.ndarray) -> list[tuple[float, float]]:
    """(h, ω) of every axis of diagonal K1, K2 in closed form; empty for non-diagonal gains.

    Diagonal gains decouple into scalar loops (k2 s + k1) / s², each of which crosses once, at
    ω_c(k1, k2) with h = atan(ω_c k2 / k1) / ω_c: exact, and O(n) where the scan is O(n³) per
    frequency.
    """
    if np.count_nonzero(K1 - np.diag(np.diag(K1))) or np.count_nonzero(K2 - np.diag(np.diag(K2))):
        return []
    crossings = []
    for k1, k2 in zip(np.diag(K1).tolist(), np.diag(K2).tolist(), strict=True):
        omega = _crossover_frequency(k1, k2)
        crossings.append((math.atan2(k2, k1 / omega) / omega, omega))  # ω k2 may underflow
    return crossings


def _scanned_crossings(
    K1: np.ndarray, K2: np.ndarray, low: float, high: float
) -> list[tuple[float, float]]:
    """(h, ω) of every crossing found by scanning the bracket [low, high] (see the method)."""
    omegas = np.geomspace(
        low * (1.0 - _BRACKET_MARGIN), high * (1.0 + _BRACKET_MARGIN), _SCAN_POINTS
    )
    excesses = _moduli_excess(K1, K2, omegas)
    frequencies: list[float] = []
    for k in range(K1.shape[0]):
        frequencies += _crossings_of_column(_excess(K1, K2, k), omegas, excesses[:, k])
    return [(h, float(omega)) for omega in frequencies for h in _first_delays(K1, K2, omega)]


def _same(a: float, b: float) -> bool:
    return abs(a - b) <= _SAME_RTOL * max(abs(a), abs(b))
