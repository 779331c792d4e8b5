"""Theorem 1 of Roy & Kar: the Razumikhin bound on the input delay that AROLC tolerates.

The nominal error dynamics under AROLC with a delayed input are (paper, (new err dyn 1))

    ė = A1 e + B1 e_h + B (−Δu_h + σ),

    A1 = [[0, I], [0, 0]],   B1 = [[0, 0], [−K1, −K2]],   B = [[0], [I]],   A = A1 + B1.

With P ≻ 0 solving Aᵀ P + P A = −Q (paper, (lyapunov)) and the Razumikhin condition
V(e(ξ)) < r V(e(t)) for t − 2h ≤ ξ ≤ t, r > 1 (paper, (razu)), Theorem 1 certifies every delay

    h < h_m = λ_min(Q) / ‖E‖₂,
    E = β P B1 (A1 P⁻¹ A1ᵀ + B1 P⁻¹ B1ᵀ + P⁻¹) B1ᵀ P + 2 (r/β) P

(paper, (delay value) and (delay cal)). For K1 = K2 = Q = I, β = 1, r = 1.1 this gives
h_m = 0.12487 s, the paper's "125 ms", for every n.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg

from delaytrack._validation import (
    as_spd_matrix,
    as_square_matrix,
    is_integer_at_least,
    positive_scalar,
)

__all__ = [
    "RazumikhinBound",
    "error_dynamics_matrices",
    "lyapunov_matrix",
    "razumikhin_bound",
]


#: Largest accepted relative residual ‖AᵀP + PA + Q‖ / ‖Q‖ of the Lyapunov solution.
_LYAPUNOV_RTOL = 1e-8


def _dimension(K1: object, n: int | None) -> int:
    """Return n: the keyword when given, else the size of K1 (a scalar K1 means n = 1)."""
    if n is None:
        shape = np.shape(K1)
        return 1 if len(shape) == 0 else int(shape[0])
    if not is_integer_at_least(n, 1):
        raise ValueError(f"n must be a positive integer (the number of joints); got {n!r}")
    return int(n)


def _matrix_of_size(name: str, value: object, size: int, expected: str, spd: bool) -> np.ndarray:
    """Return ``value`` as a ``(size, size)`` matrix; ``expected`` says why that size in words."""
    matrix = as_square_matrix(name, value, size if np.ndim(value) == 0 else None)
    if matrix.shape != (size, size):
        raise ValueError(f"{name} must be {expected}; got shape {matrix.shape}")
    return as_spd_matrix(name, matrix) if spd else matrix


def _gains(K1: object, K2: object, n: int | None, spd: bool) -> tuple[np.ndarray, np.ndarray]:
    """Validate the gain pair (K1, K2) as n x n matrices, symmetric positive definite if ``spd``."""
    size = _dimension(K1, n)
    K1_matrix = _matrix_of_size("K1", K1, size, f"n x n = {size}x{size} (n = {size} given)", spd)
    K2_matrix = _matrix_of_size("K2", K2, size, f"n x n = {size}x{size}, the size of K1", spd)
    return K1_matrix, K2_matrix


def _weight_matrix(Q: object, n: int) -> np.ndarray:
    """Validate Q as a symmetric positive definite 2n x 2n matrix."""
    size = 2 * n
    expected = f"2n x 2n = {size}x{size} for n = {n} (the size of K1)"
    return _matrix_of_size("Q", Q, size, expected, spd=True)


def _block_matrices(
    K1: np.ndarray, K2: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Build (A, A1, B1, B) from validated n x n gains."""
    n = K1.shape[0]
    eye = np.eye(n)
    zero = np.zeros((n, n))
    A1 = np.block([[zero, eye], [zero, zero]])
    B1 = np.block([[zero, zero], [-K1, -K2]])
    B = np.vstack([zero, eye])
    return A1 + B1, A1, B1, B


def _format_complex(values: np.ndarray) -> str:
    """Render eigenvalues, complex or real, for an error message."""
    parts = [
        f"{z.real:.6g}" if z.imag == 0.0 else f"{z.real:.6g}{z.imag:+.6g}j" for z in values[:8]
    ]
    return f"[{', '.join(parts)}{', ...' if values.size > 8 else ''}]"


def _require_hurwitz(A: np.ndarray) -> None:
    """Raise unless every eigenvalue of A has a strictly negative real part."""
    eigenvalues = np.linalg.eigvals(A)
    largest = float(np.max(eigenvalues.real))
    if largest < 0.0:
        return
    tolerance = 1e-9 * max(1.0, abs(largest))
    worst = eigenvalues[eigenvalues.real >= largest - tolerance]
    raise ValueError(
        "A = [[0, I], [-K1, -K2]] must be Hurwitz (every eigenvalue in the open left half plane) "
        "for A^T P + P A = -Q to have a positive definite solution P; its eigenvalues with the "
        f"largest real part are {_format_complex(worst)}"
    )


def error_dynamics_matrices(
    K1: object, K2: object, *, n: int | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Matrices of the delayed error dynamics ė = A1 e + B1 e_h + B (−Δu_h + σ).

    Implements the paper's (new err dyn 1) and (error dyn delayed)::

        A1 = [[0, I], [0, 0]],   B1 = [[0, 0], [-K1, -K2]],   A = A1 + B1,   B = [[0], [I]]

    with the error state e = [e1; ė1] (2n).

    Parameters
    ----------
    K1, K2 : array_like
        Proportional and derivative gains, ``(n, n)``; a 1-D array means a diagonal matrix and a
        scalar means ``K * I``. Any square gains are accepted here; :func:`razumikhin_bound`
        requires them symmetric positive definite as the paper does.
    n : int, optional
        Number of joints; needed only to expand a scalar K1 to ``K1 * I`` with n > 1.

    Returns
    -------
    A : ndarray, shape (2n, 2n)
        Closed-loop matrix of the delay-free error dynamics, ``A1 + B1``.
    A1 : ndarray, shape (2n, 2n)
        The double-integrator part, acting on the current error.
    B1 : ndarray, shape (2n, 2n)
        The feedback part, acting on the delayed error e_h.
    B : ndarray, shape (2n, n)
        Input matrix of the switching control and uncertainty.

    Raises
    ------
    ValueError
        If a gain is not square, or K2 does not have K1's size.
    """
    K1_matrix, K2_matrix = _gains(K1, K2, n, spd=False)
    return _block_matrices(K1_matrix, K2_matrix)


def lyapunov_matrix(K1: object, K2: object, Q: object, *, n: int | None = None) -> np.ndarray:
    """Solve the Lyapunov equation Aᵀ P + P A = −Q of AROLC for P ≻ 0.

    Implements the paper's (lyapunov): P defines V1(e) = ½ eᵀ P e and the sliding variable
    s = Bᵀ P e, with A = [[0, I], [−K1, −K2]].

    Parameters
    ----------
    K1, K2 : array_like
        Gains, ``(n, n)`` (1-D means diagonal, scalar means ``K * I``). They need not be symmetric,
        but A must be Hurwitz.
    Q : array_like
        Symmetric positive definite ``(2n, 2n)`` weight; 1-D of length 2n means diagonal, a
        scalar means ``Q * I``.
    n : int, optional
        Number of joints; needed only to expand a scalar K1 with n > 1.

    Returns
    -------
    P : ndarray, shape (2n, 2n)
        The symmetric positive definite solution.

    Raises
    ------
    ValueError
        If Q is not symmetric positive definite or not 2n x 2n, or A is not Hurwitz (the message
        gives the eigenvalues of A with the largest real part).
    """
    K1_matrix, K2_matrix = _gains(K1, K2, n, spd=False)
    Q_matrix = _weight_matrix(Q, K1_matrix.shape[0])
    A = _block_matrices(K1_matrix, K2_matrix)[0]
    return _solve_lyapunov(A, Q_matrix)


def _solve_lyapunov(A: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """P with Aᵀ P + P A = −Q for a Hurwitz A, exactly symmetrised."""
    _require_hurwitz(A)
    # scipy solves  M X + X M^H = C;  with M = A^T and C = -Q that is  A^T P + P A = -Q.
    # Its conditioning warning is replaced by the explicit accuracy check below.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", scipy.linalg.LinAlgWarning)
        warnings.simplefilter("ignore", RuntimeWarning)
        try:
            P = scipy.linalg.solve_continuous_lyapunov(A.T, -Q)
        except (np.linalg.LinAlgError, ValueError):
            P = np.full_like(Q, np.nan)
    P = 0.5 * (P + P.T)
    finite = bool(np.all(np.isfinite(P)))
    residual = np.linalg.norm(A.T @ P + P @ A + Q) / np.linalg.norm(Q) if finite else np.inf
    smallest = np.linalg.eigvalsh(P)[0] if np.isfinite(residual) else np.nan
    if not residual <= _LYAPUNOV_RTOL or not smallest > 0.0:
        magnitudes = np.abs(np.linalg.eigvals(A))
        raise ValueError(
            "the Lyapunov equation A^T P + P A = -Q cannot be solved accurately for these gains "
            f"(relative residual {residual:.3g}, smallest eigenvalue of P {smallest:.3g}); "
            f"K1 and K2 are too ill-conditioned: |eigenvalues of A| range from "
            f"{magnitudes.min():.3g} to {magnitudes.max():.3g}"
        )
    return P


def _read_only(array: np.ndarray) -> np.ndarray:
    array = np.array(array, dtype=float)
    array.setflags(write=False)
    return array


@dataclass(frozen=True, eq=False)
class RazumikhinBound:
    """Result of :func:`razumikhin_bound`: Theorem 1's certified delay bound and its ingredients.

    Arrays are read-only. Equality is identity (the fields are arrays).

    Attributes
    ----------
    h_m : float
        Certified maximum input delay in seconds, ``lambda_min(Q) / ||E||_2`` (delay value).
    E : ndarray, shape (2n, 2n)
        The symmetric positive definite matrix of (delay cal).
    E_norm : float
        Spectral norm ``||E||_2`` (its largest eigenvalue).
    P : ndarray, shape (2n, 2n)
        Solution of ``A^T P + P A = -Q``.
    lambda_min_Q : float
        Smallest eigenvalue of Q.
    A : ndarray, shape (2n, 2n)
        ``[[0, I], [-K1, -K2]]``.
    K1, K2 : ndarray, shape (n, n)
        The gains, symmetric positive definite.
    Q : ndarray, shape (2n, 2n)
        The Lyapunov weight, symmetric positive definite.
    beta : float
        Weight of the inequality -2 z1ᵀ z2 <= β z1ᵀ P⁻¹ z1 + (1/β) z2ᵀ P z2 (ineq 1).
    r : float
        Razumikhin factor of (razu), > 1.
    """

    h_m: float
    E: np.ndarray
    E_norm: float
    P: np.ndarray
    lambda_min_Q: float
    A: np.ndarray
    K1: np.ndarray
    K2: np.ndarray
    Q: np.ndarray
    beta: float
    r: float

    @property
    def n(self) -> int:
        """Number of joints (the error state has 2n entries)."""
        return int(self.K1.shape[0])

    def to_dict(self) -> dict[str, Any]:
        """Plain floats, ints and nested lists, ready for ``json.dumps``."""
        return {
            "h_m": float(self.h_m),
            "E_norm": float(self.E_norm),
            "lambda_min_Q": float(self.lambda_min_Q),
            "beta": float(self.beta),
            "r": float(self.r),
            "n": self.n,
            "P": self.P.tolist(),
            "E": self.E.tolist(),
            "A": self.A.tolist(),
            "K1": self.K1.tolist(),
            "K2": self.K2.tolist(),
            "Q": self.Q.tolist(),
        }


def razumikhin_bound(
    K1: object, K2: object, Q: object, beta: float, r: float, *, n: int | None = None
) -> RazumikhinBound:
    """Theorem 1: the largest input delay h_m that AROLC is certified to tolerate.

    Implements the paper's (delay cal) and (delay value)::

        E   = beta P B1 (A1 P^-1 A1^T + B1 P^-1 B1^T + P^-1) B1^T P + 2 (r / beta) P
        h_m = lambda_min(Q) / ||E||_2

    where P solves ``A^T P + P A = -Q`` (lyapunov) and A1, B1, A come from
    :func:`error_dynamics_matrices`. Every delay 0 <= h(t) < h_m keeps
    ``Psi = Q - h E`` positive definite, which Theorem 2 needs.

    Parameters
    ----------
    K1, K2 : array_like
        Symmetric positive definite gains of û = q̈_d + K2 ė1 + K1 e1 (aux), ``(n, n)``; a 1-D
        array means a diagonal matrix and a scalar means ``K * I`` (n = 1 unless ``n`` is given).
    Q : array_like
        Symmetric positive definite ``(2n, 2n)`` Lyapunov weight; 1-D of length 2n means
        diagonal, a scalar means ``Q * I``.
    beta : float
        beta > 0, the free weight of (ineq 1).
    r : float
        r > 1, the Razumikhin factor of (razu): V(e(xi)) < r V(e(t)) for t - 2h <= xi <= t.
    n : int, optional
        Number of joints; needed only to expand a scalar K1 with n > 1.

    Returns
    -------
    RazumikhinBound
        h_m in seconds with E, ||E||_2, P, lambda_min(Q), A and the inputs.

    Raises
    ------
    ValueError
        If r <= 1, beta <= 0 or not finite, a gain or Q is not symmetric positive definite (the
        message gives its eigenvalues) or has the wrong shape (the message names the argument and
        the expected shape).

    Examples
    --------
    >>> round(razumikhin_bound([1.0, 1.0], [1.0, 1.0], 1.0, beta=1.0, r=1.1).h_m, 5)
    0.12487
    """
    beta_value = positive_scalar("beta", beta)
    try:
        r_value = float(r)
    except (TypeError, ValueError):
        raise TypeError(f"r must be a real number; got {r!r}") from None
    if not (math.isfinite(r_value) and r_value > 1.0):
        raise ValueError(
            f"r must be > 1 (Razumikhin condition V(e(xi)) < r V(e(t))); got {r_value:g}"
        )
    K1_matrix, K2_matrix = _gains(K1, K2, n, spd=True)
    Q_matrix = _weight_matrix(Q, K1_matrix.shape[0])

    A, A1, B1, _ = _block_matrices(K1_matrix, K2_matrix)
    P = _solve_lyapunov(A, Q_matrix)
    P_inv = np.linalg.inv(P)
    inner = A1 @ P_inv @ A1.T + B1 @ P_inv @ B1.T + P_inv
    E = beta_value * P @ B1 @ inner @ B1.T @ P + 2.0 * (r_value / beta_value) * P
    E = 0.5 * (E + E.T)
    E_norm = float(np.linalg.norm(E, 2))
    lambda_min_Q = float(np.linalg.eigvalsh(Q_matrix)[0])
    return RazumikhinBound(
        h_m=lambda_min_Q / E_norm,
        E=_read_only(E),
        E_norm=E_norm,
        P=_read_only(P),
        lambda_min_Q=lambda_min_Q,
        A=_read_only(A),
        K1=_read_only(K1_matrix),
        K2=_read_only(K2_matrix),
        Q=_read_only(Q_matrix),
        beta=beta_value,
        r=r_value,
    )
