"""Theorem 2 of Roy & Kar: the ultimate bounds ϖ1…ϖ6 on the tracking error ‖e‖ under AROLC.

The proof of Theorem 2 starts from (delay cal) with Ψ = Q − h E ≻ 0 (Theorem 1) and splits the
state space into six cases by ĉ ≶ γ (ATRC), ‖s‖ ≶ ε (delta u) and the sign of sᵀṡ. In each case
V̇ < 0 outside a ball ‖e‖ > ϖ_i. The quantities entering the bounds are

- Psi_min = λ_min(Ψ), Ψ = Q − h E (see :func:`psi_min`);
- Gamma (Γ), the bound (cond4) on the integrated delay and uncertainty terms;
- Theta_norm = ‖Θ‖, Θ = Δu(t) − Δu(t − h) (delay cal);
- BtP_norm = ‖Bᵀ P‖₂, so that ‖s‖ ≤ ‖Bᵀ P‖ ‖e‖;
- c, the bound ‖σ‖ ≤ c on the lumped uncertainty (Assumption on σ);
- c_hat (ĉ), alpha (α), epsilon (ε), gamma (γ) of (delta u) and (ATRC).

None of Γ, ‖Θ‖ or c is known to the controller; these functions evaluate the bounds for values
the user supplies.
"""

from __future__ import annotations

import math
from dataclasses import astuple, dataclass

import numpy as np

from delaytrack._validation import positive_scalar
from delaytrack.analysis.razumikhin import RazumikhinBound

__all__ = ["UltimateBounds", "psi_min", "ultimate_bounds"]


@dataclass(frozen=True)
class UltimateBounds:
    """The six ultimate bounds of Theorem 2 on ‖e‖, ‖e‖ = ‖[e1; ė1]‖, one per case.

    Attributes
    ----------
    varpi_1 : float
        Case (i): ĉ > γ, ‖s‖ >= ε, sᵀṡ > 0.
    varpi_2 : float
        Case (ii): ĉ > γ, ‖s‖ >= ε, sᵀṡ <= 0.
    varpi_3 : float
        Case (iii): ĉ <= γ, ‖s‖ >= ε.
    varpi_4 : float
        Case (iv): ĉ > γ, ‖s‖ < ε, sᵀṡ > 0.
    varpi_5 : float
        Case (v): ĉ > γ, ‖s‖ < ε, sᵀṡ <= 0.
    varpi_6 : float
        Case (vi): ĉ <= γ, ‖s‖ < ε.
    """

    varpi_1: float
    varpi_2: float
    varpi_3: float
    varpi_4: float
    varpi_5: float
    varpi_6: float

    def as_tuple(self) -> tuple[float, float, float, float, float, float]:
        """``(varpi_1, ..., varpi_6)``."""
        return astuple(self)


def psi_min(bound: RazumikhinBound, h: float) -> float:
    """Smallest eigenvalue of Ψ = Q − h E, the decay rate used by Theorem 2.

    Implements λ_min(Ψ) with Ψ = Q − h E from (delay cal); Theorem 1 (delay value) guarantees
    Ψ ≻ 0 for 0 <= h < h_m, since λ_min(Q − h E) >= λ_min(Q) − h ‖E‖₂ > 0. It decreases as h
    grows (E is positive definite), so every ϖ_i grows with the delay.

    Parameters
    ----------
    bound : RazumikhinBound
        Result of :func:`~delaytrack.analysis.razumikhin_bound` for the gains in use.
    h : float
        Delay in seconds, 0 <= h < bound.h_m.

    Returns
    -------
    float
        λ_min(Q − h E) > 0.

    Raises
    ------
    ValueError
        If h < 0, h is not finite, or h >= h_m (Ψ is then not certified positive definite).
    """
    h_value = positive_scalar("h", h, strictly=False)
    if h_value >= bound.h_m:
        raise ValueError(
            f"h must be < h_m = {bound.h_m:.6g} s (Theorem 1), the range where Psi = Q - h E is "
            f"certified positive definite; got h = {h_value:.6g} s"
        )
    return float(np.linalg.eigvalsh(bound.Q - h_value * bound.E)[0])


def _quadratic_root(mu: float, constant: float, lmin: float) -> float:
    """Positive root of lmin x² − 2 lmin mu x − 2 constant = 0: mu + sqrt(2 constant/lmin + mu²)."""
    return mu + math.sqrt(2.0 * constant / lmin + mu * mu)


def ultimate_bounds(
    *,
    Psi_min: float,
    Gamma: float,
    Theta_norm: float,
    BtP_norm: float,
    c: float,
    c_hat: float,
    alpha: float,
    epsilon: float,
    gamma: float,
) -> UltimateBounds:
    """Theorem 2: the ultimate bounds ϖ1…ϖ6 on ‖e‖ in its six cases.

    With lmin = λ_min(Ψ), b = ‖Bᵀ P‖ and Θ = ‖Θ‖, the proof of Theorem 2 gives::

        mu1 = (max(1 - alpha, 0) c_hat + Θ) b / lmin
        varpi1 = mu1 + sqrt(2 Gamma / lmin + mu1^2)                          (error bound 1)
        mu2 = max(2c - (alpha + 1) c_hat + Θ, 0) b / lmin
        varpi2 = mu2 + sqrt(2 Gamma / lmin + mu2^2)
        mu3 = max(c - alpha c_hat + Θ, 0) b / lmin
        varpi3 = mu3 + sqrt(2 (Gamma + gamma^2) / lmin + mu3^2)
        varpi4 = sqrt((4 alpha Gamma c_hat + epsilon (c_hat + Θ)^2) / (2 alpha c_hat lmin))
        varpi5 = sqrt((4 alpha Gamma c_hat + epsilon (2c - c_hat + Θ)^2) / (2 alpha c_hat lmin))
        varpi6 = sqrt((4 alpha c_hat (Gamma + gamma^2) + epsilon (c + Θ)^2)
                      / (2 alpha c_hat lmin))

    In cases (i)-(iii) the proof reaches V̇ <= -½ lmin ‖e‖² + k ‖s‖ + const and bounds
    k ‖s‖ <= k b ‖e‖; ϖ is then the positive root of lmin x² − 2 k b x − 2 const = 0. In cases
    (iv)-(vi) the quadratic in ‖s‖ is maximised over ‖s‖. ĉ is a single value used for all
    six cases; cases (iii) and (vi) assume ĉ <= γ, the others ĉ > γ.

    Deviations from the printed paper, each following the paper's own inequalities:

    - mu3 carries the factor ‖Bᵀ P‖. The paper prints mu3 = (c − α ĉ + ‖Θ‖)/λ_min(Ψ); the line
      above it, V̇ <= −½ λ_min(Ψ)‖e‖² + (c − α ĉ + ‖Θ‖)‖s‖ + Γ + γ², together with
      ‖s‖ <= ‖Bᵀ P‖ ‖e‖ needs the factor, as in mu1 and mu2.
    - A negative coefficient k is replaced by 0 in mu2 and mu3. The step k ‖s‖ <= k b ‖e‖
      holds only for k >= 0: s = Bᵀ P e vanishes on an n-dimensional subspace, so for k < 0 the
      only valid bound is k ‖s‖ <= 0. The paper's formula with a negative mu gives a smaller
      number that the proof does not certify.
    - Case (i) drops the term −(α − 1) ĉ ‖s‖, which the paper allows "for a choice of α > 1".
      For α < 1 that term is positive and is kept, through max(1 − α, 0) ĉ in mu1; for α >= 1
      mu1 is the paper's ‖Θ‖ ‖Bᵀ P‖ / λ_min(Ψ).

    In case (v), 2c − ĉ + ‖Θ‖ may be negative; the paper's maximum ε (2c − ĉ + ‖Θ‖)²/(4 α ĉ)
    then over-estimates the true maximum 0, so ϖ5 stays valid, only conservative.

    Parameters
    ----------
    Psi_min : float
        λ_min(Q − h E) > 0; see :func:`psi_min`.
    Gamma : float
        Γ >= 0 of (cond4).
    Theta_norm : float
        ‖Δu(t) − Δu(t − h)‖ >= 0.
    BtP_norm : float
        Spectral norm ‖Bᵀ P‖ >= 0.
    c : float
        Uncertainty bound ‖σ‖ <= c, c >= 0.
    c_hat : float
        Switching gain ĉ > 0.
    alpha : float
        Adaptive gain α > 0 of (delta u).
    epsilon : float
        Boundary-layer width ε > 0 of (delta u).
    gamma : float
        Floor γ > 0 of (ATRC).

    Returns
    -------
    UltimateBounds
        ϖ1…ϖ6, in the units of ‖e‖.

    Raises
    ------
    ValueError
        If an argument is out of its range or not finite; the message names it and its value.
    """
    lmin = positive_scalar("Psi_min", Psi_min)
    Gamma = positive_scalar("Gamma", Gamma, strictly=False)
    Theta = positive_scalar("Theta_norm", Theta_norm, strictly=False)
    b = positive_scalar("BtP_norm", BtP_norm, strictly=False)
    c = positive_scalar("c", c, strictly=False)
    c_hat = positive_scalar("c_hat", c_hat)
    alpha = positive_scalar("alpha", alpha)
    epsilon = positive_scalar("epsilon", epsilon)
    gamma = positive_scalar("gamma", gamma)

    mu1 = (max(1.0 - alpha, 0.0) * c_hat + Theta) * b / lmin
    mu2 = max(2.0 * c - (alpha + 1.0) * c_hat + Theta, 0.0) * b / lmin
    mu3 = max(c - alpha * c_hat + Theta, 0.0) * b / lmin
    layer = 2.0 * alpha * c_hat * lmin
    return UltimateBounds(
        varpi_1=_quadratic_root(mu1, Gamma, lmin),
        varpi_2=_quadratic_root(mu2, Gamma, lmin),
        varpi_3=_quadratic_root(mu3, Gamma + gamma**2, lmin),
        varpi_4=math.sqrt((4.0 * alpha * Gamma * c_hat + epsilon * (c_hat + Theta) ** 2) / layer),
        varpi_5=math.sqrt(
            (4.0 * alpha * Gamma * c_hat + epsilon * (2.0 * c - c_hat + Theta) ** 2) / layer
        ),
        varpi_6=math.sqrt(
            (4.0 * alpha * c_hat * (Gamma + gamma**2) + epsilon * (c + Theta) ** 2) / layer
        ),
    )
