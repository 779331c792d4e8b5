"""Gain design for Theorem 1: the diagonal K1, K2, Q and β that maximise the certified delay h_m.

Theorem 1 of Roy & Kar certifies every input delay below h_m = λ_min(Q) / ‖E‖₂
(:func:`delaytrack.analysis.razumikhin_bound`). The paper fixes K1 = K2 = Q = I, β = 1, r = 1.1
and gets h_m = 0.12487 s; here K1, K2, Q and β are searched instead, under a bound on the gains.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from delaytrack._validation import (
    ArgumentError,
    finite_scalar,
    is_integer_at_least,
    positive_scalar,
)
from delaytrack.analysis.exact_margin import ExactDelayMargin, exact_delay_margin
from delaytrack.analysis.razumikhin import RazumikhinBound, _dimension, razumikhin_bound

__all__ = ["GainDesign", "design_gains"]

#: Each searched quantity spans this factor: gains from gain_bound / _SPAN to gain_bound, the
#: ratio q_v / q_p and γ = β / √r from 1 / _SPAN to _SPAN.
_SPAN = 1e4

#: Largest seed: numpy's legacy seeding, which differential_evolution uses, takes 32 bits.
_LARGEST_SEED = 2**32 - 1

#: Where gain_bound gives a trustworthy design, for messages (measured, r = 1.1): below, Theorem
#: 1's bound cannot be computed near the optimum (it fails at 1e-8); above, the optimum k2
#: (0.91 without min_bandwidth, at least 0.84 min_bandwidth with one above 1 rad/s) lies more
#: than four decades below gain_bound, outside the search. The upper limit is for
#: min_bandwidth <= 1 and scales with a larger one.
_GAIN_BOUND_RANGE = (1e-7, 8e3)

#: Largest min_bandwidth (rad/s) that gives a trustworthy design (measured: 3000 does, with
#: k1 = 9e6; 1e4 does not, its bound cannot be computed near k1 = 1e8).
_LARGEST_BANDWIDTH = 3e3

#: Largest r for which the paper's h_m (2.76e-301 s at r = 1e300, falling as 1 / r) is a
#: normal double.
_LARGEST_R = 1.2e307

#: A best point within this distance (in log space, a relative 1e-6) of a box edge is on it;
#: also the step to the neighbours that must be computable.
_EDGE = 1e-6


@dataclass(frozen=True, eq=False)
class GainDesign:
    """Result of :func:`design_gains`. Arrays are read-only; equality is identity.

    Attributes
    ----------
    K1, K2 : ndarray, shape (n, n)
        The designed diagonal gains (every axis the same, see :func:`design_gains`).
    Q : ndarray, shape (2n, 2n)
        The diagonal Lyapunov weight ``diag(1, ..., 1, q_v, ..., q_v)``.
    beta : float
        The weight β of (ineq 1).
    r : float
        The Razumikhin factor, as given (not searched).
    h_m : float
        Theorem 1's certified delay bound of the design, in seconds.
    bound : RazumikhinBound
        The full Theorem 1 result for the design (E, P, ...).
    exact : ExactDelayMargin
        The exact constant-delay margin of the designed K1, K2 (:func:`exact_delay_margin`;
        the joints are identical, so it is that of one axis).
    reference_h_m : float
        h_m of the paper's K1 = K2 = Q = I, β = 1 at the same r, for comparison.
    gain_bound : float
        The bound imposed on every diagonal entry of K1 and K2.
    min_bandwidth : float or None
        The imposed least natural frequency sqrt(K1[i, i]) in rad/s, if any.
    bound_active : bool
        Whether the largest designed gain sits on ``gain_bound`` (to a relative 1e-6).
    bandwidth_active : bool
        Whether sqrt(k1) sits on ``min_bandwidth`` (to a relative 1e-6); False without one.
    seed : int
        Seed of the differential evolution; the same seed gives the same design.
    evaluations : int
        Number of Theorem 1 evaluations the search used.
    seconds : float
        Wall time of the search.
    """

    K1: np.ndarray
    K2: np.ndarray
    Q: np.ndarray
    beta: float
    r: float
    h_m: float
    bound: RazumikhinBound
    exact: ExactDelayMargin
    reference_h_m: float
    gain_bound: float
    min_bandwidth: float | None
    bound_active: bool
    bandwidth_active: bool
    seed: int
    evaluations: int
    seconds: float

    @property
    def n(self) -> int:
        """Number of joints."""
        return int(self.K1.shape[0])

    def to_dict(self) -> dict[str, Any]:
        """Plain floats, ints, bools and nested lists, ready for ``json.dumps``."""
        return {
            "n": self.n,
            "k1": float(self.K1[0, 0]),
            "k2": float(self.K2[0, 0]),
            "q": [float(self.Q[0, 0]), float(self.Q[-1, -1])],
            "beta": self.beta,
            "r": self.r,
            "h_m": self.h_m,
            "h_exact": self.exact.h,
            "omega_exact": self.exact.omega,
            "reference_h_m": self.reference_h_m,
            "gain_bound": self.gain_bound,
            "min_bandwidth": self.min_bandwidth,
            "bound_active": self.bound_active,
            "bandwidth_active": self.bandwidth_active,
            "seed": self.seed,
            "evaluations": self.evaluations,
            "seconds": self.seconds,
        }


def _certified_axis_h_m(log_parameters: np.ndarray, r: float) -> float:
    """razumikhin_bound's h_m of one axis at (k1, k2, q_v, γ) = exp(log_parameters), else 0.

    The axis has gains k1, k2, Q = diag(1, q_v) and β = √r γ.
    """
    k1, k2, q_v, gamma = np.exp(log_parameters)
    try:
        return razumikhin_bound(k1, k2, [1.0, q_v], math.sqrt(r) * gamma, r).h_m
    except ValueError:  # out of the range where the bound can be computed
        return 0.0


def _closed_form_h_m(log_parameters: np.ndarray, r: float) -> float:
    """Theorem 1's h_m of one axis at (k1, k2, q_v, γ) = exp(log_parameters), in closed form.

    The search's objective: :func:`razumikhin_bound` of the same axis (gains k1, k2,
    Q = diag(1, q_v), β = √r γ) to its own accuracy, a thousand times faster. For
    A = [[0, 1], [−k1, −k2]] the Lyapunov equation AᵀP + PA = −Q has the solution::

        P = [[a, b], [b, c]],  b = 1 / (2 k1),  c = (q_v + 1/k1) / (2 k2),
        a = k2 / (2 k1) + (k1 q_v + 1) / (2 k2),
        det P = q_v / (4 k1) + (k1 q_v + 1)² / (4 k1 k2²).

    With A1 = e₁e₂ᵀ and B1 = e₂wᵀ, w = (−k1, −k2), (delay cal) reduces to
    E = β s p pᵀ + (2r/β) P, where p = (b, c) is P's second column and
    s = (1 + k2²) wᵀP⁻¹w + k1² (P⁻¹)₂₂. Every term is written as a sum of positive terms,
    for instance wᵀP⁻¹w det P = ((k2² − k1/2)² + ¾ k1²) / (2 k1 k2) + k1 k2 q_v / 2 +
    k1² q_v / (2 k2), so nothing cancels; ‖E‖₂ is the larger eigenvalue of the 2x2 E.
    Returns 0 where a term overflows or underflows to 0.
    """
    try:
        k1, k2, q_v, gamma = (math.exp(v) for v in log_parameters)
        beta = math.sqrt(r) * gamma
        a = k2 / (2.0 * k1) + (k1 * q_v + 1.0) / (2.0 * k2)
        b = 1.0 / (2.0 * k1)
        c = (q_v + 1.0 / k1) / (2.0 * k2)
        determinant = q_v / (4.0 * k1) + (k1 * q_v + 1.0) * (k1 * q_v + 1.0) / (4.0 * k1 * k2 * k2)
        w_P_inv_w = (
            ((k2 * k2 - 0.5 * k1) * (k2 * k2 - 0.5 * k1) + 0.75 * k1 * k1) / (2.0 * k1 * k2)
            + 0.5 * k1 * k2 * q_v
            + k1 * k1 * q_v / (2.0 * k2)
        ) / determinant
        s = (1.0 + k2 * k2) * w_P_inv_w + k1 * k1 * a / determinant
        weight = 2.0 * r / beta
        E11 = beta * s * b * b + weight * a
        E12 = beta * s * b * c + weight * b
        E22 = beta * s * c * c + weight * c
        norm = 0.5 * (E11 + E22) + math.hypot(0.5 * (E11 - E22), E12)
        h_m = min(1.0, q_v) / norm
    except (ZeroDivisionError, OverflowError):  # a gain or det P underflowed to 0
        return 0.0
    return h_m if math.isfinite(h_m) and h_m > 0.0 else 0.0


def _seed(seed: object) -> int:
    if not (is_integer_at_least(seed, 0) and seed <= _LARGEST_SEED):
        raise ArgumentError(
            "seed",
            f"must be a non-negative integer; got {seed!r} (seeds run from 0 to "
            f"2**32 - 1 = {_LARGEST_SEED})",
        )
    return int(seed)


def _paper_bound(r: float) -> RazumikhinBound:
    """Theorem 1 for the paper's K1 = K2 = Q = I, β = 1 at this r (checks r)."""
    try:
        return razumikhin_bound(1.0, 1.0, 1.0, 1.0, r)
    except ValueError as error:
        if str(error).startswith("r must"):  # not a number > 1
            raise
        raise ArgumentError(
            "r",
            f"is too large for the design: the paper's K1 = K2 = Q = I, beta = 1, which the "
            f"design is compared with, cannot be evaluated at r = {float(r):g} (E overflows or "
            f"h_m underflows in double precision); r up to about {_LARGEST_R:g} works",
        ) from None


def _check_optimum(
    x: np.ndarray,
    lows: list[float],
    highs: list[float],
    r: float,
    gain_bound: float,
    min_bandwidth: float | None,
) -> None:
    """Raise unless the search's best point ``x`` is the optimum of the constrained problem.

    The search box is (k1, k2, q_v, γ) in log space. Its upper gain limits and a lower k1
    limit set by min_bandwidth are the constraints; its other edges (gains four decades below
    gain_bound, q_v and γ = β / √r at 1e-4 or 1e4) only bound the search, and a best point on
    one of them, or beside points where Theorem 1's bound cannot be computed, is not the
    optimum: the optimum lies where the search cannot go.
    """
    bandwidth_binds = min_bandwidth is not None and lows[0] > math.log(gain_bound) - math.log(_SPAN)
    edges = [
        not bandwidth_binds and x[0] <= lows[0] + _EDGE,
        x[1] <= lows[1] + _EDGE,
        x[2] <= lows[2] + _EDGE or x[2] >= highs[2] - _EDGE,
        x[3] <= lows[3] + _EDGE or x[3] >= highs[3] - _EDGE,
    ]
    neighbours = [
        np.clip(x + step * np.eye(4)[i], lows, highs) for i in range(4) for step in (-_EDGE, _EDGE)
    ]
    computable = all(_certified_axis_h_m(point, r) > 0.0 for point in [x, *neighbours])
    if computable and not any(edges):
        return
    k1, k2, q_v, gamma = np.exp(x)
    found = f"k1 = {k1:.3g}, k2 = {k2:.3g}, q_v = {q_v:.3g}, beta = {math.sqrt(r) * gamma:.3g}"
    where = (
        "lies on an edge of the searched range (gains from $gain_bound / 1e4, q_v and "
        "beta / sqrt(r) from 1e-4 to 1e4)"
        if computable
        else "lies next to gains for which Theorem 1's bound cannot be computed in double precision"
    )
    small = x[1] < 0.0  # gains below 1: the search ran into the small side
    beyond = min_bandwidth is not None and min_bandwidth > _LARGEST_BANDWIDTH
    if beyond or (bandwidth_binds and not small and not (computable and any(edges[:2]))):
        raise ArgumentError(
            "min_bandwidth",
            f"is too large for the design: the best design found ({found}) {where}, so it is "
            f"not the optimum (got $min_bandwidth = {min_bandwidth:g} rad/s); $min_bandwidth "
            f"up to about {_LARGEST_BANDWIDTH:g} rad/s works, with $gain_bound from "
            f"$min_bandwidth^2 to about {_GAIN_BOUND_RANGE[1]:g} $min_bandwidth",
            mentions=("min_bandwidth", "gain_bound"),
        )
    most = _GAIN_BOUND_RANGE[1] * max(1.0, min_bandwidth or 1.0)
    raise ArgumentError(
        "gain_bound",
        f"is too {'small' if small else 'large'} for the design: the best design found "
        f"({found}) {where}, so it is not the optimum (got $gain_bound = {gain_bound:g}); "
        f"$gain_bound from about {_GAIN_BOUND_RANGE[0]:g} to {most:g} works here, and without "
        f"$min_bandwidth any value above 1.03 gives the unconstrained optimum k1 ≈ 1.03, "
        f"k2 ≈ 0.91",
        mentions=("gain_bound", "min_bandwidth"),
    )


def _bandwidth(min_bandwidth: float | None, gain_bound: float) -> float | None:
    """``min_bandwidth`` checked: a number > 0 whose square is at most ``gain_bound``."""
    if min_bandwidth is None:
        return None
    bandwidth = finite_scalar("min_bandwidth", min_bandwidth)
    if bandwidth <= 0.0:
        raise ArgumentError(
            "min_bandwidth",
            f"must be > 0 rad/s (the least natural frequency sqrt(k1)); got {bandwidth:g}",
        )
    least_k1 = bandwidth * bandwidth
    if least_k1 > gain_bound:
        square = f"{least_k1:g}" if math.isfinite(least_k1) else f"{bandwidth:g}^2"
        raise ArgumentError(
            "min_bandwidth",
            f"= {bandwidth:g} rad/s needs K1 entries >= {square}, above $gain_bound = "
            f"{gain_bound:g}; raise $gain_bound or lower $min_bandwidth",
            mentions=("gain_bound", "min_bandwidth"),
        )
    return bandwidth


def _search_box(gain_bound: float, bandwidth: float | None) -> tuple[list[float], list[float]]:
    """``(lows, highs)`` of the search over the logarithms of (k1, k2, q_v, γ)
    (:func:`design_gains`)."""
    top, span = math.log(gain_bound), math.log(_SPAN)
    least_log_k1 = top - span
    if bandwidth is not None:
        least_log_k1 = min(max(least_log_k1, 2.0 * math.log(bandwidth)), top)
    return [least_log_k1, top - span, -span, -span], [top, top, span, span]


def _differential_evolution(
    lows: list[float], highs: list[float], r: float, seed: int
) -> tuple[Any, float]:
    """The seeded search of the largest closed-form h_m in the box, and its wall time (s)."""
    import scipy.optimize  # here, not at import: a controller's import need not load it

    start = time.perf_counter()
    search = scipy.optimize.differential_evolution(
        lambda x: -_closed_form_h_m(x, r),
        bounds=list(zip(lows, highs, strict=True)),
        seed=seed,
        tol=1e-10,
    )
    return search, time.perf_counter() - start


def design_gains(
    *,
    n: int = 1,
    gain_bound: float = 1.0,
    min_bandwidth: float | None = None,
    r: float = 1.1,
    seed: int = 0,
) -> GainDesign:
    """Search diagonal K1, K2, Q and β > 0 for the largest delay certified by Theorem 1.

    Maximises the paper's (delay value) over the design::

        h_m(K1, K2, Q, β) = λ_min(Q) / ‖E‖₂,
        E = β P B1 (A1 P⁻¹ A1ᵀ + B1 P⁻¹ B1ᵀ + P⁻¹) B1ᵀ P + 2 (r/β) P,   AᵀP + PA = −Q,

    subject to ``0 < K1[i, i] <= gain_bound`` and ``0 < K2[i, i] <= gain_bound`` for every
    joint i (the paper's K1 = K2 = I has every entry equal to 1) and, with ``min_bandwidth``,
    ``sqrt(K1[i, i]) >= min_bandwidth``: the delay-free loop ë1 + K2 ė1 + K1 e1 = 0 then has
    natural frequency at least ``min_bandwidth`` rad/s in every joint.

    The upper bound alone is inactive beyond about 1.03 (below); a least bandwidth is the
    constraint that binds, and h_m falls as it rises (docs/margins.md has the numbers).

    **Reductions** (each exact, so nothing is lost):

    - *Q's scale.* Q → cQ gives P → cP, P⁻¹ → P⁻¹/c, hence E → cE and λ_min(Q) → cλ_min(Q):
      h_m does not depend on the scale of Q. Per axis Q = diag(q_p, q_v) is fixed to q_p = 1.
    - *r is not searched.* E = E₀ + (2r/β) P with P ≻ 0, so ‖E‖₂ grows strictly with r and
      h_m falls: the supremum is at r → 1⁺, which is no design. r is the caller's choice
      (default 1.1, the paper's), the same r as the comparison ``reference_h_m``. Writing
      E = β X + (2r/β) P and β = √r γ gives E = √r (γ X + 2P/γ): with β optimised,
      h_m(r) = h_m(1) / √r, and the optimal K1, K2, Q do not depend on r.
    - *One axis.* With diagonal K1, K2, Q the error dynamics split into n 2x2 blocks (e1_i,
      ė1_i); P and E are block diagonal with the same β, so ‖E‖ = max_i ‖E_i‖ and
      λ_min(Q) = min_i λ_min(Q_i). Hence h_m <= λ_min(Q_i) / ‖E_i‖ for every axis i, i.e.
      never more than the best single axis, and n copies of the best axis attain it. The
      search is over one axis: (k1, k2, q_v, β), and every joint gets the same gains.

    **Search.** :func:`scipy.optimize.differential_evolution` over the logarithms of
    k1 in [max(gain_bound / 1e4, min_bandwidth²), gain_bound], k2 in [gain_bound / 1e4,
    gain_bound], q_v and γ = β / √r in [1e-4, 1e4] (the optimal γ does not depend on r, so any
    r is searched alike), seeded, then polished with L-BFGS-B (scipy's default). Each point is
    evaluated by a closed form of Theorem 1 for one axis (2x2 P and E written out, equal to
    :func:`razumikhin_bound` to its accuracy and about a thousand times faster; a point where
    it overflows counts as h_m = 0). The returned h_m is recomputed by
    :func:`razumikhin_bound` for the returned n-joint matrices, so it is exactly what
    Theorem 1 certifies for them.

    **Trust.** The best point found is refused, with a ValueError naming gain_bound or
    min_bandwidth, when it lies on an edge of the box that is not a constraint (gains at
    gain_bound / 1e4, q_v or γ at 1e-4 or 1e4) or where, or next to where,
    :func:`razumikhin_bound` refuses to compute the bound: the optimum then lies outside what
    can be certified. Measured at r = 1.1, that leaves
    gain_bound from about 1e-7 to 8000 (8000 min_bandwidth with one above 1 rad/s) and
    min_bandwidth up to about 3000 rad/s.

    Measured (r = 1.1, seed 0): gain_bound = 1 gives h_m ≈ 0.1268 s (k1 = 1, k2 ≈ 0.897,
    Q = I, β ≈ 0.974) against the paper's 0.12487 s; the unconstrained optimum, k1 ≈ 1.029,
    k2 ≈ 0.908, gives h_m ≈ 0.1268 s too, so any bound above about 1.03 is inactive
    (docs/margins.md).

    Parameters
    ----------
    n : int, optional
        Number of joints (default 1).
    gain_bound : float, optional
        Largest allowed diagonal entry of K1 and of K2, > 0 (default 1, the paper's gains).
    min_bandwidth : float, optional
        Least natural frequency sqrt(K1[i, i]) in rad/s, > 0, with min_bandwidth² <= gain_bound
        (default: none).
    r : float, optional
        Razumikhin factor r > 1 of (razu) (default 1.1, the paper's).
    seed : int, optional
        Seed of the differential evolution, 0 to 2**32 - 1 (default 0); the same seed gives the
        same design.

    Returns
    -------
    GainDesign
        The gains, Q, β, r, the certified h_m with Theorem 1's full result, the exact margin of
        the designed gains, and the paper's h_m at the same r for comparison.

    Raises
    ------
    ValueError
        If n is not a positive integer, gain_bound or min_bandwidth is not a finite number > 0,
        min_bandwidth² exceeds gain_bound, r <= 1 or too large for the paper's comparison value
        to be computed (above about 1e307), seed is not an integer from 0 to 2**32 - 1, or the
        search cannot be trusted (see Trust; the message names gain_bound or min_bandwidth and
        the range that works).
    TypeError
        If gain_bound, min_bandwidth or r is not a real number.
    """
    joints = _dimension(None, n)
    bound_value = positive_scalar("gain_bound", gain_bound)
    seed_value = _seed(seed)
    reference = _paper_bound(r)
    r_value = reference.r
    bandwidth = _bandwidth(min_bandwidth, bound_value)
    lows, highs = _search_box(bound_value, bandwidth)
    search, seconds = _differential_evolution(lows, highs, r_value, seed_value)
    _check_optimum(search.x, lows, highs, r_value, bound_value, bandwidth)
    k1, k2, q_v, gamma = (float(v) for v in np.exp(search.x))
    beta = math.sqrt(r_value) * gamma
    # exp(log(b)) may miss b by an ulp: put the gains back inside their bounds.
    k1, k2 = min(max(k1, math.exp(lows[0])), bound_value), min(k2, bound_value)
    ones = np.ones(joints)
    certified = razumikhin_bound(k1 * ones, k2 * ones, np.hstack([ones, q_v * ones]), beta, r_value)
    return GainDesign(
        K1=certified.K1,
        K2=certified.K2,
        Q=certified.Q,
        beta=beta,
        r=r_value,
        h_m=certified.h_m,
        bound=certified,
        exact=exact_delay_margin(k1, k2),  # every joint is this axis
        reference_h_m=reference.h_m,
        gain_bound=bound_value,
        min_bandwidth=bandwidth,
        bound_active=max(k1, k2) >= bound_value * (1.0 - 1e-6),
        bandwidth_active=bandwidth is not None and k1 <= bandwidth * bandwidth * (1.0 + 1e-6),
        seed=seed_value,
        evaluations=int(search.nfev),
        seconds=seconds,
    )
