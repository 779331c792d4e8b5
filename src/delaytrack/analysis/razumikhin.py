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

import functools
import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from delaytrack._validation import (
    ArgumentError,
    as_spd_matrix,
    as_square_matrix,
    format_values,
    is_integer_at_least,
    positive_scalar,
)

__all__ = [
    "MAX_COUPLED_JOINTS",
    "MAX_JOINTS",
    "PAPER_BETA",
    "PAPER_R",
    "RazumikhinBound",
    "error_dynamics_matrices",
    "lyapunov_matrix",
    "razumikhin_bound",
]

#: Theorem 1's free weights ``β`` and ``r`` as the paper chooses them (β = 1, r = 1.1, which give
#: its h_m = 0.12487 s for K1 = K2 = Q = I): the defaults of :func:`razumikhin_bound`.
PAPER_BETA, PAPER_R = 1.0, 1.1


#: Largest accepted relative residual ‖AᵀP + PA + Q‖ / ‖Q‖ of the Lyapunov solution.
_LYAPUNOV_RTOL = 1e-8

#: Largest accepted bound on the relative error of P (:func:`_error_bound`): h_m is then
#: accurate to a few parts in a million, enough for the six digits the CLI prints.
_LYAPUNOV_ERROR = 1e-6

#: Diagonal gains with every k1 in this range and every damping ratio k2 / (2 sqrt(k1)) in
#: ``_DAMPING_RANGE`` pass the accuracy checks of the Lyapunov solution with any Q whose
#: eigenvalues lie within ``_Q_SPREAD`` of each other (tested on grids of one joint and on random
#: mixed diagonal gains and Q with n = 3; beyond, the checks fail somewhere: at k1 = 1e8 for
#: K2 = Q = I, at damping ratios above about 1e4). They are quoted in error messages; the
#: checks on the computed solution decide.
_K1_RANGE = (1e-6, 1e6)
_DAMPING_RANGE = (1e-3, 1e3)
_Q_SPREAD = 1e4

#: What to say about the range that works, per argument.
_RANGE_HINTS = {
    "K1": f"diagonal gains with every k1 within [{_K1_RANGE[0]:g}, {_K1_RANGE[1]:g}] and every "
    f"damping ratio k2 / (2 sqrt(k1)) within [{_DAMPING_RANGE[0]:g}, {_DAMPING_RANGE[1]:g}] can "
    f"always be used, with a Q whose eigenvalues lie within a factor {_Q_SPREAD:g} of each other",
    "Q": "h_m does not depend on the scale of Q, so rescale Q by a power of ten",
}
_RANGE_HINTS["K2"] = _RANGE_HINTS["K1"]

#: The words every range error ends its first clause with.
_UNCOMPUTABLE = "for Theorem 1's bound to be computed in double precision"

#: Largest magnitude of an entry of K1, K2 or Q (M + M^T must stay finite), and of P and E.
_LARGEST_ENTRY = float(np.finfo(float).max) / 2

#: Smallest positive normal double; a smaller h_m or eigenvalue of P has lost precision.
_TINY = float(np.finfo(float).tiny)

#: Most joints the analyses take: their matrices are dense 2n x 2n (32 MB each at n = 1000),
#: and checking a 2n x 2n Q takes about a second there.
MAX_JOINTS = 1000

#: Most joints whose Lyapunov equation is solved as one dense 2n x 2n problem (gains or a Q that
#: couple the joints, and AROLC's P): about a second at n = 400 on one core. Its time grows as
#: n³ in compiled code that Ctrl-C does not stop: n = 2000 took minutes and 2.3 GB.
MAX_COUPLED_JOINTS = 400

#: Cost of one dense Lyapunov solve with its checks, for messages: seconds per (2n)³ on one
#: core and double-precision matrices held at once (measured: 2n = 800 in 1.1 s; 2n = 4000
#: held 2.3 GB, 18 matrices).
_LYAPUNOV_SECONDS_PER_CUBE = 2e-9
_LYAPUNOV_MATRICES = 18


def _dimension(K1: object, n: int | None) -> int:
    """Return n: the keyword when given, else the size of K1 (a scalar K1 means n = 1); at most
    :data:`MAX_JOINTS`, checked before any matrix is built."""
    if n is None:
        shape = np.asarray(K1).shape
        size, name = (1 if len(shape) == 0 else int(shape[0])), "K1"
    elif not is_integer_at_least(n, 1):
        raise ArgumentError("n", f"must be a positive integer (the number of joints); got {n!r}")
    else:
        size, name = int(n), "n"
    if size > MAX_JOINTS:
        raise ArgumentError(
            name,
            f"gives n = {size} joints; the analyses work on dense 2n x 2n matrices "
            f"({2 * size}x{2 * size}, {8 * (2 * size) ** 2 / 2**20:.0f} MB each), for at most "
            f"n = {MAX_JOINTS} joints",
        )
    return size


def _check_coupled(n: int, what: str) -> None:
    """Refuse a Lyapunov equation of more than :data:`MAX_COUPLED_JOINTS` coupled joints, with
    what it would ask, before anything of its size is computed; ``what`` says why it is one
    problem."""
    if n <= MAX_COUPLED_JOINTS:
        return
    size = 2 * n
    seconds = _LYAPUNOV_SECONDS_PER_CUBE * size**3
    memory = _LYAPUNOV_MATRICES * 8 * size**2 / 2**30
    raise ArgumentError(
        "K1",
        f"is {n}x{n}: {what}, the Lyapunov equation A^T P + P A = -Q is one dense "
        f"{size}x{size} problem (about {memory:.2g} GB and {seconds:.0f} s of compiled code "
        f"on one core that Ctrl-C cannot stop); it is solved for at most n = "
        f"{MAX_COUPLED_JOINTS} coupled joints",
    )


def _matrix_of_size(name: str, value: object, size: int, expected: str, spd: bool) -> np.ndarray:
    """Return ``value`` as a ``(size, size)`` matrix; ``expected`` says why that size in words."""
    matrix = as_square_matrix(name, value, size if np.asarray(value).ndim == 0 else None)
    if matrix.shape != (size, size):
        raise ArgumentError(name, f"must be {expected}; got shape {matrix.shape}")
    largest = float(np.max(np.abs(matrix)))
    if largest > _LARGEST_ENTRY:
        raise ArgumentError(
            name,
            f"has an entry of magnitude {largest:.3g}, beyond {_LARGEST_ENTRY:.3g}, the "
            f"largest that double-precision arithmetic on {name} can hold; {_RANGE_HINTS[name]}",
        )
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


def _hurwitz_by_energy(K1: np.ndarray, K2: np.ndarray) -> bool:
    """Whether A = [[0, I], [-K1, -K2]] is Hurwitz by the energy argument, without eigenvalues.

    If K1 is symmetric positive definite and K2 + K2ᵀ positive definite, V = ½ ė1ᵀ ė1 +
    ½ e1ᵀ K1 e1 decreases along ë1 + K2 ė1 + K1 e1 = 0 (V̇ = −ė1ᵀ K2 ė1) and can stay constant
    only at e1 = 0 (LaSalle), so A is Hurwitz at any scale of the gains, where its computed
    eigenvalues would under- or overflow.
    """
    if not np.array_equal(K1, K1.T):
        return False
    return bool(np.linalg.eigvalsh(K1)[0] > 0.0 and np.linalg.eigvalsh(K2 + K2.T)[0] > 0.0)


def _require_hurwitz(A: np.ndarray, K1: np.ndarray, K2: np.ndarray) -> None:
    """Raise unless every eigenvalue of A has a strictly negative real part."""
    if _hurwitz_by_energy(K1, K2):
        return
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
        gives the eigenvalues of A with the largest real part; gains with K1 symmetric positive
        definite and K2 + K2ᵀ positive definite always give a Hurwitz A), or P cannot be
        computed accurately in double precision (the checks of :func:`razumikhin_bound`; the
        message starts with the argument to change and says which range works), or n exceeds
        :data:`MAX_COUPLED_JOINTS` (P is one dense 2n x 2n problem).
    """
    K1_matrix, K2_matrix = _gains(K1, K2, n, spd=False)
    _check_coupled(K1_matrix.shape[0], _WHOLE_P)
    Q_matrix = _weight_matrix(Q, K1_matrix.shape[0])
    size = K1_matrix.shape[0]
    matrices = b"".join(matrix.tobytes() for matrix in (K1_matrix, K2_matrix, Q_matrix))
    solve = _solved_lyapunov if size <= _REMEMBERED_JOINTS else _solved_lyapunov.__wrapped__
    return solve(size, matrices).copy()


#: Why :func:`lyapunov_matrix` (AROLC's P) solves one coupled Lyapunov equation, for
#: :func:`_check_coupled`.
_WHOLE_P = "for AROLC's P (solved whole, whatever the gains)"

#: Solutions of :func:`lyapunov_matrix` kept for gains met again (a sweep's runs), for up to
#: this many joints: at most 256 solutions of under 80 kB each with their inputs.
_REMEMBERED_JOINTS = 32


@functools.lru_cache(maxsize=256)
def _solved_lyapunov(size: int, matrices: bytes) -> np.ndarray:
    """:func:`lyapunov_matrix` of validated K1, K2 (size x size) and Q, given as their bytes,
    read-only: the gains a sweep repeats over its runs are solved once."""
    values = np.frombuffer(matrices, dtype=float)
    square = size * size
    K1_matrix = values[:square].reshape(size, size)
    K2_matrix = values[square : 2 * square].reshape(size, size)
    Q_matrix = values[2 * square :].reshape(2 * size, 2 * size)
    A = _block_matrices(K1_matrix, K2_matrix)[0]
    _require_hurwitz(A, K1_matrix, K2_matrix)
    largest_Q = float(np.linalg.eigvalsh(Q_matrix)[-1])
    scale = _scale_of(largest_Q)
    # One Schur decomposition of the whole A, as the controllers have always used: their P
    # keeps its digits. (razumikhin_bound solves joint by joint where it can.)
    whole = [np.ix_(np.arange(A.shape[0]), np.arange(A.shape[0]))]
    P_unit = _solve_lyapunov(A, Q_matrix, scale, whole, K1_matrix, K2_matrix)
    return _read_only(_rescaled(scale, largest_Q, whole, P_unit)[0])


def _scale_of(largest_Q: float) -> float:
    """The power of two s with λ_max(Q) / s in [1, 2), given ``largest_Q`` = λ_max(Q).

    P and E are linear in Q and h_m does not depend on its scale, so they are computed for
    Q / s (exactly, s being a power of two) and P, E multiplied by s at the end: any scale of Q
    gives the same h_m, and P, E bit for bit the same digits.
    """
    return math.ldexp(1.0, math.frexp(largest_Q)[1] - 1)


def _diagonal(K1: np.ndarray, K2: np.ndarray) -> bool:
    """Whether both gains are diagonal (the joints are then independent, for a Q that does not
    couple them)."""
    return not (
        np.count_nonzero(K1 - np.diag(np.diag(K1))) or np.count_nonzero(K2 - np.diag(np.diag(K2)))
    )


#: Why :func:`razumikhin_bound` solves one coupled Lyapunov equation, for :func:`_check_coupled`.
_COUPLED = (
    "as K1, K2 or Q couple the joints (diagonal gains with a Q that pairs each joint's e1 and "
    "e1_dot only are solved joint by joint, for any n)"
)


def _independent_blocks(K1: np.ndarray, K2: np.ndarray, Q: np.ndarray) -> list[tuple]:
    """Index pairs (for ``M[block]``) of the independent diagonal blocks of A, Q, P and E.

    With diagonal K1, K2 and a Q that pairs the state entries of a joint only with each other
    (e1_i with ė1_i), every joint is an independent 2x2 problem: solving each on its own keeps
    every joint as accurate as a single one (a Schur decomposition of the whole A spreads the
    rounding errors of fast joints over slow ones) and costs O(n). Otherwise one block holds the
    whole state.
    """
    n = K1.shape[0]
    joint = np.arange(2 * n) % n
    if _diagonal(K1, K2) and not np.any(Q[joint[:, None] != joint[None, :]]):
        return [np.ix_([i, n + i], [i, n + i]) for i in range(n)]
    return [np.ix_(np.arange(2 * n), np.arange(2 * n))]


def _solve_lyapunov(
    A: np.ndarray, Q: np.ndarray, scale: float, blocks: list[tuple], K1: np.ndarray, K2: np.ndarray
) -> np.ndarray:
    """P with Aᵀ P + P A = −Q / scale, block by block; raise unless every block is accurate.

    Accurate means: relative residual ‖AᵀP + PA + Q‖ / ‖Q‖ <= ``_LYAPUNOV_RTOL``, P positive
    definite, and :func:`_error_bound` <= ``_LYAPUNOV_ERROR``. ``scale`` is :func:`_scale_of`;
    K1 and K2 only word the error.
    """
    P = np.zeros_like(A)
    for block in blocks:
        weight = Q[block] / scale
        P[block] = _lyapunov(A[block], weight)
        with np.errstate(all="ignore"):
            R = A[block].T @ P[block] + P[block] @ A[block] + weight
            residual = float(np.linalg.norm(R) / np.linalg.norm(weight))
        smallest = float(np.linalg.eigvalsh(P[block])[0]) if math.isfinite(residual) else math.nan
        error = math.nan
        if residual <= _LYAPUNOV_RTOL and smallest > 0.0:
            error = _error_bound(A[block], P[block], weight, R)
        if not error <= _LYAPUNOV_ERROR:
            raise _unsolvable(K1, K2, Q, residual, smallest, error)
    return P


def _lyapunov(A: np.ndarray, C: np.ndarray) -> np.ndarray:
    """X with Aᵀ X + X A = −C, exactly symmetrised; NaN where scipy gives up.

    scipy solves M X + X Mᴴ = F; with M = Aᵀ and F = −C that is Aᵀ X + X A = −C. Its
    conditioning warning and any overflow are left to the caller's accuracy check. SciPy's linear
    algebra is imported here, when a bound is first computed, not when a controller is.
    """
    import scipy.linalg

    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore", scipy.linalg.LinAlgWarning)
        warnings.simplefilter("ignore", RuntimeWarning)  # a near-singular operator, perturbed
        try:
            X = scipy.linalg.solve_continuous_lyapunov(A.T, -C)
        except (np.linalg.LinAlgError, ValueError):
            X = np.full_like(C, np.nan)
        return 0.5 * (X + X.T)


def _error_bound(A: np.ndarray, P: np.ndarray, Q: np.ndarray, R: np.ndarray) -> float:
    """t with −t P ⪯ P_exact − P ⪯ t P: the relative error of P in every direction.

    P_exact − P solves Aᵀ Δ + Δ A = −R_exact for the exact residual R_exact of P, and
    |R_exact| <= N = |R| + γ (|Aᵀ| |P| + |P| |A| + |Q|) entrywise, γ = (2n + 2) eps bounding
    the rounding of the computed R. By Gershgorin −D ⪯ R_exact ⪯ D for D = diag(N 1), and as
    the solution of Aᵀ Δ + Δ A = −C grows with C (Löwner order) for a Hurwitz A, the solution
    Δ_D for D bounds the error: t = λ_max(L⁻¹ Δ_D L⁻ᵀ) with P = L Lᵀ. E and h_m inherit a
    relative error of a few t (E sums positive semidefinite terms in P and P⁻¹).
    """
    import scipy.linalg

    gamma = (A.shape[0] + 2) * np.finfo(float).eps
    with np.errstate(all="ignore"):
        N = np.abs(R) + gamma * (np.abs(A.T) @ np.abs(P) + np.abs(P) @ np.abs(A) + np.abs(Q))
        bound = _lyapunov(A, np.diag(N.sum(axis=1)))
    try:
        factor = np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        return math.inf
    if not np.all(np.isfinite(bound)):
        return math.inf
    whitened = scipy.linalg.solve_triangular(factor, bound, lower=True)
    whitened = scipy.linalg.solve_triangular(factor, whitened.T, lower=True)
    return float(np.linalg.eigvalsh(0.5 * (whitened + whitened.T))[-1])


def _shown(matrix: np.ndarray) -> str:
    """``"2 I"``, ``"diag(1, 2)"`` or ``"a matrix with eigenvalues [...]"``, for a message."""
    diagonal = np.diag(matrix)
    if np.count_nonzero(matrix - np.diag(diagonal)):
        return f"a matrix with eigenvalues {format_values(np.linalg.eigvals(matrix).real, 3)}"
    if np.all(diagonal == diagonal[0]):
        return f"{diagonal[0]:g} I"
    shown = ", ".join(f"{v:g}" for v in diagonal[:8])
    return f"diag({shown}{', ...' if diagonal.size > 8 else ''})"


def _unsolvable(
    K1: np.ndarray, K2: np.ndarray, Q: np.ndarray, residual: float, smallest: float, error: float
) -> ValueError:
    """The error for a Lyapunov equation that cannot be solved accurately.

    It names K1 when an eigenvalue of K1 lies outside ``_K1_RANGE``, else K2 when a damping
    ratio k2 / (2 sqrt(k1)) (bounded by eigenvalue magnitudes for non-diagonal gains) lies
    outside ``_DAMPING_RANGE``, else Q when its eigenvalues spread beyond ``_Q_SPREAD`` (an
    :class:`~delaytrack._validation.ArgumentError` for that argument), else both gains.
    """
    weights = np.linalg.eigvalsh(Q)
    spread = float(weights[-1]) / float(weights[0])
    k1 = np.abs(np.linalg.eigvals(K1))
    k2 = np.abs(np.linalg.eigvals(K2))
    low, high = _K1_RANGE
    least, most = _DAMPING_RANGE
    with np.errstate(all="ignore"):
        damping = (k2.min() / (2.0 * np.sqrt(k1.max())), k2.max() / (2.0 * np.sqrt(k1.min())))
    gains = f"K1 = {_shown(K1)}, K2 = {_shown(K2)}"
    argument: str | None = None  # None: both gains
    if k1.min() < low or k1.max() > high:
        size = "large" if k1.max() > high else "small"
        argument, start = "K1", f"is too {size} {_UNCOMPUTABLE} ({gains})"
    elif damping[0] < least or damping[1] > most:
        size = "large" if damping[1] > most else "small"
        ratios = f"{damping[0]:.3g}" + ("" if damping[0] == damping[1] else f" to {damping[1]:.3g}")
        argument, start = (
            "K2",
            f"is too {size} relative to K1 {_UNCOMPUTABLE} ({gains}: damping ratio "
            f"k2 / (2 sqrt(k1)) {ratios})",
        )
    elif spread > _Q_SPREAD:
        argument, start = (
            "Q",
            f"is too ill-conditioned for these gains {_UNCOMPUTABLE} ({gains}; "
            f"lambda_max(Q) / lambda_min(Q) = {spread:.3g})",
        )
    else:
        start = f"K1 and K2 are out of range {_UNCOMPUTABLE} ({gains})"
    found = f"relative residual {residual:.3g}, smallest eigenvalue of P {smallest:.3g}"
    if math.isfinite(error):
        found += f", relative error of P up to {error:.3g}"
    problem = (
        f"{start}: the Lyapunov equation A^T P + P A = -Q cannot be solved accurately ({found}); "
        f"{_RANGE_HINTS['K1']}"
    )
    return ValueError(problem) if argument is None else ArgumentError(argument, problem)


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
    K1: object,
    K2: object,
    Q: object = 1.0,
    beta: float = PAPER_BETA,
    r: float = PAPER_R,
    *,
    n: int | None = None,
) -> RazumikhinBound:
    """Theorem 1: the largest input delay h_m that AROLC is certified to tolerate.

    Implements the paper's (delay cal) and (delay value)::

        E   = beta P B1 (A1 P^-1 A1^T + B1 P^-1 B1^T + P^-1) B1^T P + 2 (r / beta) P
        h_m = lambda_min(Q) / ||E||_2

    where P solves ``A^T P + P A = -Q`` (lyapunov) and A1, B1, A come from
    :func:`error_dynamics_matrices`. Every delay 0 <= h(t) < h_m keeps
    ``Psi = Q - h E`` positive definite, which Theorem 2 needs.

    **Double precision.** A is Hurwitz for any symmetric positive definite gains, so no
    eigenvalues of A are computed. Q is divided by a power of two near λ_max(Q) (h_m does not
    depend on Q's scale) and P, E multiplied back at the end; diagonal K1, K2 with a Q that does
    not couple joints are solved joint by joint (2x2 each). A result is returned only when it
    can be trusted: the Lyapunov solution has a relative residual <= 1e-8 and a bound on its
    relative error <= 1e-6 (h_m is then accurate to a few parts in a million), E is finite,
    and h_m and the eigenvalues of P are normal doubles. Otherwise a ValueError names the
    argument to change. Diagonal gains with every k1 in [1e-6, 1e6] and every damping ratio
    k2 / (2 sqrt(k1)) in [1e-3, 1e3] always pass, with a Q whose eigenvalues lie within a
    factor 1e4 of each other; other gains pass or fail by the same checks.

    Parameters
    ----------
    K1, K2 : array_like
        Symmetric positive definite gains of û = q̈_d + K2 ė1 + K1 e1 (aux), ``(n, n)``; a 1-D
        array means a diagonal matrix and a scalar means ``K * I`` (n = 1 unless ``n`` is given).
    Q : array_like, optional
        Symmetric positive definite ``(2n, 2n)`` Lyapunov weight; 1-D of length 2n means
        diagonal, a scalar means ``Q * I``. ``I`` by default (the paper's robot experiment).
    beta : float, optional
        beta > 0, the free weight of (ineq 1); 1 by default.
    r : float, optional
        r > 1, the Razumikhin factor of (razu): V(e(xi)) < r V(e(t)) for t - 2h <= xi <= t;
        1.1 by default (the defaults are those of ``delaytrack bound``).
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
        the expected shape), or the result cannot be trusted in double precision (see above; the
        message starts with K1, K2, Q, beta or r, gives the value and the range that works), or
        n exceeds :data:`MAX_JOINTS`, or :data:`MAX_COUPLED_JOINTS` for gains or a Q that couple
        the joints (the message says what the dense problem would ask).

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
        raise ArgumentError(
            "r", f"must be > 1 (Razumikhin condition V(e(xi)) < r V(e(t))); got {r_value:g}"
        )
    K1_matrix, K2_matrix = _gains(K1, K2, n, spd=True)
    if not _diagonal(K1_matrix, K2_matrix):  # refused before Q, a 2n x 2n matrix, is checked
        _check_coupled(K1_matrix.shape[0], _COUPLED)
    Q_matrix = _weight_matrix(Q, K1_matrix.shape[0])

    A, A1, B1, _ = _block_matrices(K1_matrix, K2_matrix)
    # Symmetric positive definite gains make A Hurwitz (_hurwitz_by_energy): no eigenvalues needed.
    lambda_min_Q, largest_Q = (float(v) for v in np.linalg.eigvalsh(Q_matrix)[[0, -1]])
    scale = _scale_of(largest_Q)
    blocks = _independent_blocks(K1_matrix, K2_matrix, Q_matrix)
    if len(blocks) == 1:
        _check_coupled(K1_matrix.shape[0], _COUPLED)
    P_unit = _solve_lyapunov(A, Q_matrix, scale, blocks, K1_matrix, K2_matrix)
    lambda_Q = (lambda_min_Q / scale, largest_Q / scale)
    E_unit = np.zeros_like(A)
    for block in blocks:
        E_unit[block] = _delay_matrix(
            P_unit[block], A1[block], B1[block], beta_value, r_value, lambda_Q
        )
    P, E = _rescaled(scale, largest_Q, blocks, P_unit, E_unit)
    E_norm = max(float(np.linalg.norm(E[block], 2)) for block in blocks)
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


def _delay_matrix(
    P: np.ndarray,
    A1: np.ndarray,
    B1: np.ndarray,
    beta: float,
    r: float,
    lambda_Q: tuple[float, float],
) -> np.ndarray:
    """E of (delay cal) for P; raise unless E is finite and λ_min(Q) / ‖E‖₂ a normal double.

    P and ``lambda_Q`` = (λ_min(Q), λ_max(Q)) belong to Q scaled by :func:`_scale_of`.
    """
    with np.errstate(all="ignore"):
        P_inv = np.linalg.inv(P)
        inner = A1 @ P_inv @ A1.T + B1 @ P_inv @ B1.T + P_inv
        E = beta * P @ B1 @ inner @ B1.T @ P + 2.0 * (r / beta) * P
        E = 0.5 * (E + E.T)
    if np.all(np.isfinite(E)) and lambda_Q[0] / float(np.linalg.norm(E, 2)) >= _TINY:
        return E
    X = P @ B1 @ inner @ B1.T @ P
    x = float(np.linalg.eigvalsh(0.5 * (X + X.T))[-1])
    raise _unrepresentable(x, float(np.linalg.eigvalsh(P)[-1]), beta, r, lambda_Q)


def _budget(lambda_min_Q: float) -> float:
    """Bound on each of beta ‖X‖ and (2 r / beta) ‖P‖ that keeps E finite and h_m normal.

    Their sum bounds ‖E‖₂; E stays finite below max / 4 and h_m = λ_min(Q) / ‖E‖₂ normal while
    ‖E‖₂ <= λ_min(Q) / tiny.
    """
    return 0.5 * min(_LARGEST_ENTRY / 2, lambda_min_Q / _TINY)


def _unrepresentable(
    x: float, p: float, beta: float, r: float, lambda_Q: tuple[float, float]
) -> ArgumentError:
    """The error for beta, r or Q that make E = beta X + (2 r / beta) P overflow or h_m underflow.

    ``x`` = ‖X‖₂ with X = P B1 (A1 P⁻¹ A1ᵀ + B1 P⁻¹ B1ᵀ + P⁻¹) B1ᵀ P, ``p`` = ‖P‖₂ and
    ``lambda_Q`` = (λ_min(Q), λ_max(Q)), all for Q scaled by :func:`_scale_of`. Some beta keeps
    both terms of E within :func:`_budget` exactly when 2 r ‖P‖ ‖X‖ <= budget². If none does,
    Q is named, whose λ_min(Q) / λ_max(Q) sets the budget (with λ_min(Q) = λ_max(Q) the budget
    is about 2e307, which any double r fits unless ‖P‖ ‖X‖ exceeds 1e306, far beyond gains whose
    Lyapunov equation can be solved). Else the argument that makes the larger term too large:
    beta for beta ‖X‖; for (2 r / beta) ‖P‖, r when r >= 1 / beta (and some r > 1 fits), else
    beta.
    """
    total = beta * x + 2.0 * r / beta * p
    consequence = (
        "E overflows"
        if math.isinf(total)
        else f"h_m = lambda_min(Q) / ||E||_2 would be about {lambda_Q[0] / total:.3g} s, below "
        f"the smallest normal double {_TINY:.3g}"
    )
    budget = _budget(lambda_Q[0])
    low = 2.0 * (r / budget) * p if budget > 0.0 else math.inf  # λ_min(Q) / λ_max(Q) underflowed
    high = budget / x
    if low > high:
        least_ratio = 2.0 * _TINY * math.sqrt(2.0 * p * x) * math.sqrt(r) / lambda_Q[1]
        return ArgumentError(
            "Q",
            f"is too ill-conditioned {_UNCOMPUTABLE} (lambda_min(Q) / lambda_max(Q) = "
            f"{lambda_Q[0] / lambda_Q[1]:.3g}: {consequence}); for these K1, K2 and r, no beta "
            f"works unless lambda_min(Q) / lambda_max(Q) is at least about {least_ratio:.3g}",
        )
    largest_r = budget * beta / (2.0 * p)
    if beta * x < 2.0 * (r / beta) * p and r * beta >= 1.0 and largest_r > 1.0:
        return ArgumentError(
            "r",
            f"is too large {_UNCOMPUTABLE} (r = {r:g}, beta = {beta:g}: {consequence}); for "
            f"these K1, K2, Q and beta, r must be at most about {largest_r:.3g} (a larger beta "
            f"allows more)",
        )
    size = "large" if beta * x >= 2.0 * (r / beta) * p else "small"
    return ArgumentError(
        "beta",
        f"is too {size} {_UNCOMPUTABLE} (beta = {beta:g}, r = {r:g}: {consequence}); "
        f"for these K1, K2, Q and r, beta must lie within about [{low:.3g}, {high:.3g}]",
    )


def _rescaled(
    scale: float, largest_Q: float, blocks: list[tuple], P: np.ndarray, *others: np.ndarray
) -> tuple[np.ndarray, ...]:
    """``scale`` times P and each other matrix; raise if one would leave the normal doubles.

    They were computed for Q / scale (:func:`_scale_of`) and are block diagonal over ``blocks``;
    P's eigenvalues and the other matrices' norms, times ``scale``, must be finite normal doubles.
    """
    spectra = [np.linalg.eigvalsh(P[block]) for block in blocks]
    low = min(float(spectrum[0]) for spectrum in spectra)
    high = max(float(spectrum[-1]) for spectrum in spectra)
    high = max(
        [high] + [float(np.linalg.norm(other[block], 2)) for other in others for block in blocks]
    )
    if _TINY <= scale * low and scale * high <= _LARGEST_ENTRY:
        return tuple(scale * matrix for matrix in (P, *others))
    unit = largest_Q / scale
    size = "small" if scale * low < _TINY else "large"
    raise ArgumentError(
        "Q",
        f"is too {size} for P and E, which scale with it, to be represented in double "
        f"precision (largest eigenvalue of Q {largest_Q:.3g}); keep its largest eigenvalue "
        f"within about [{_TINY / low * unit:.3g}, {_LARGEST_ENTRY / high * unit:.3g}]: "
        f"{_RANGE_HINTS['Q']}",
    )
