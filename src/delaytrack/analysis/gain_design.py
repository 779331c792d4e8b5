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
import scipy.optimize

from delaytrack._validation import is_integer_at_least, positive_scalar
from delaytrack.analysis.exact_margin import ExactDelayMargin, exact_delay_margin
from delaytrack.analysis.razumikhin import RazumikhinBound, _dimension, razumikhin_bound

__all__ = ["GainDesign", "design_gains"]

#: Each searched quantity spans this factor: gains from gain_bound / _SPAN to gain_bound, the
#: ratio q_v / q_p and β from 1 / _SPAN to _SPAN.
_SPAN = 1e4


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


def _axis_h_m(log_parameters: np.ndarray, r: float) -> float:
    """h_m of one axis with k1, k2, Q = diag(1, q_v), β = exp(log_parameters); 0 if unsolvable."""
    k1, k2, q_v, beta = np.exp(log_parameters)
    try:
        return razumikhin_bound(k1, k2, [1.0, q_v], beta, r).h_m
    except ValueError:  # Lyapunov equation too ill-conditioned at the edge of the search box
        return 0.0


def _seed(seed: object) -> int:
    if not is_integer_at_least(seed, 0):
        raise ValueError(f"seed must be a non-negative integer; got {seed!r}")
    return int(seed)


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
    gain_bound] and q_v, β in [1e-4, 1e4], seeded, then polished
    with L-BFGS-B (scipy's default). A point whose Lyapunov equation cannot be solved accurately
    counts as h_m = 0. The returned h_m is recomputed by :func:`razumikhin_bound` for the
    returned n-joint matrices, so it is exactly what Theorem 1 certifies for them.

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
        Seed of the differential evolution (default 0); the same seed gives the same design.

    Returns
    -------
    GainDesign
        The gains, Q, β, r, the certified h_m with Theorem 1's full result, the exact margin of
        the designed gains, and the paper's h_m at the same r for comparison.

    Raises
    ------
    ValueError
        If n is not a positive integer, gain_bound or min_bandwidth is not a finite number > 0,
        min_bandwidth² exceeds gain_bound, r <= 1, or seed is not a non-negative integer.
    TypeError
        If gain_bound, min_bandwidth or r is not a real number.
    """
    joints = _dimension(None, n)
    bound_value = positive_scalar("gain_bound", gain_bound)
    seed_value = _seed(seed)
    reference = razumikhin_bound(1.0, 1.0, 1.0, 1.0, r)  # also checks r
    r_value = reference.r

    least_k1 = bound_value / _SPAN
    bandwidth = None if min_bandwidth is None else positive_scalar("min_bandwidth", min_bandwidth)
    if bandwidth is not None:
        if bandwidth * bandwidth > bound_value:
            raise ValueError(
                f"min_bandwidth = {bandwidth:g} rad/s needs K1 entries >= {bandwidth**2:g}, above "
                f"gain_bound = {bound_value:g}; raise gain_bound or lower min_bandwidth"
            )
        least_k1 = max(least_k1, bandwidth * bandwidth)
    top, span = math.log(bound_value), math.log(_SPAN)
    start = time.perf_counter()
    search = scipy.optimize.differential_evolution(
        lambda x: -_axis_h_m(x, r_value),
        bounds=[(math.log(least_k1), top), (top - span, top), (-span, span), (-span, span)],
        seed=seed_value,
        tol=1e-10,
    )
    seconds = time.perf_counter() - start
    k1, k2, q_v, beta = (float(v) for v in np.exp(search.x))
    # exp(log(b)) may miss b by an ulp: put the gains back inside their bounds.
    k1, k2 = min(max(k1, least_k1), bound_value), min(k2, bound_value)
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
        bandwidth_active=bandwidth is not None and k1 <= bandwidth**2 * (1.0 + 1e-6),
        seed=seed_value,
        evaluations=int(search.nfev),
        seconds=seconds,
    )
