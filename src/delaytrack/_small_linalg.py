"""Allocation-free dense algebra for the small systems (n <= ~10) of the compiled inner loop.

``numpy.linalg.solve`` in numba copies its operands and calls LAPACK: on a 2×2 to 5×5 system that
per-call overhead costs more than the arithmetic, and the plant's right-hand side solves one such
system at every RK4 stage. These loops do the same Gaussian elimination in place. Likewise
``a @ x``, which numba hands to BLAS: on a 5×5 matrix the call costs more than the product, and
OpenBLAS's worker threads then spin on the other cores, which a parallel batch needs.
"""

from __future__ import annotations

import math

from delaytrack._compile.jit import inline_kernel, inline_part, shared_kernel

__all__ = ["SYMMETRY_TOLERANCE", "matvec", "solve_in_place", "solve_mass_in_place"]

#: Relative asymmetry of a mass matrix that :func:`solve_mass_in_place` accepts, as the check of
#: a symmetric matrix given as input (:func:`delaytrack._validation.as_spd_matrix`) does.
SYMMETRY_TOLERANCE = 1e-10


@inline_kernel
def _is_diagonal(a):
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            if i != j and a[i, j] != 0.0:
                return False
    return True


@inline_kernel
def _diagonal_is_positive(a):
    for i in range(a.shape[0]):
        if not a[i, i] > 0.0:
            return False
    return True


@inline_kernel
def _is_symmetric(a):
    """Whether ``a[i, j]`` and ``a[j, i]`` agree to :data:`SYMMETRY_TOLERANCE` of
    ``|a[i, i]| + |a[j, j]|`` for every pair (non-finite entries are left to the solve)."""
    for i in range(a.shape[0]):
        for j in range(i + 1, a.shape[0]):
            difference = a[i, j] - a[j, i]
            if difference != 0.0 and abs(difference) > SYMMETRY_TOLERANCE * (
                abs(a[i, i]) + abs(a[j, j])
            ):
                return False
    return True


@inline_kernel
def _solve_diagonal(a, b):
    """:func:`solve_in_place` or :func:`solve_mass_in_place` of a diagonal ``a``: by division.
    Returns ``(solved, definite)`` as :func:`solve_mass_in_place`."""
    for i in range(b.shape[0]):
        if not (a[i, i] != 0.0 and math.isfinite(a[i, i])):
            return False, a[i, i] != 0.0
        b[i] /= a[i, i]
    return True, _diagonal_is_positive(a)


@inline_kernel
def _eliminate(a, b, exchange_rows):
    """Solve ``a x = b`` in place by Gaussian elimination, with partial pivoting when
    ``exchange_rows``, and back substitution. Returns ``(solved, positive)``: ``solved`` is
    False (``b`` unspecified) at a pivot that is exactly zero or not finite, where ``positive``
    is whether it is not zero; else ``positive`` is whether every pivot is ``> 0``."""
    n = b.shape[0]
    positive = True
    for column in range(n):
        if exchange_rows:
            pivot_row = column
            largest = abs(a[column, column])
            for row in range(column + 1, n):
                if abs(a[row, column]) > largest:
                    largest = abs(a[row, column])
                    pivot_row = row
            if pivot_row != column:
                for j in range(column, n):
                    a[column, j], a[pivot_row, j] = a[pivot_row, j], a[column, j]
                b[column], b[pivot_row] = b[pivot_row], b[column]
        pivot = a[column, column]
        if not (pivot != 0.0 and math.isfinite(pivot)):
            return False, pivot != 0.0
        positive = positive and pivot > 0.0
        inverse = 1.0 / pivot
        for row in range(column + 1, n):
            factor = a[row, column] * inverse
            if factor != 0.0:
                for j in range(column + 1, n):
                    a[row, j] -= factor * a[column, j]
                b[row] -= factor * b[column]
    for row in range(n - 1, -1, -1):
        total = b[row]
        for j in range(row + 1, n):
            total -= a[row, j] * b[j]
        b[row] = total / a[row, row]
    return True, positive


@shared_kernel
def solve_in_place(a, b):
    """Solve ``a x = b`` by Gaussian elimination with partial pivoting; ``b`` becomes ``x``.

    ``a`` (n, n) is overwritten by its elimination factors. Returns False (and ``b``
    unspecified) when a pivot is exactly zero or not finite (``a`` singular or holding NaN). A
    nearly singular ``a`` gives a huge solution. A diagonal ``a`` is solved by division.
    """
    solved, _ = _solve_diagonal(a, b) if _is_diagonal(a) else _eliminate(a, b, True)
    return solved


@shared_kernel
def solve_mass_in_place(a, b):
    """Solve ``M x = b`` for a mass matrix ``M = a``, which must be symmetric positive
    definite; ``b`` becomes ``x``.

    Gaussian elimination without row exchanges: on a symmetric positive definite matrix it is
    stable without them, and its pivots are those of ``M``'s ``L D Lᵀ`` factors, so that ``M``
    is positive definite exactly when every pivot is ``> 0``. Returns ``(solved, definite)``:
    ``solved`` is False (and ``b`` unspecified) when a pivot is exactly zero or not finite;
    ``definite`` is False when ``M`` is not symmetric (:func:`_is_symmetric`) or a pivot is
    ``<= 0``, and True when a pivot is not finite (nothing is known: ``x`` is then NaN and the
    run diverges). The solution is that of partial pivoting bit for bit where partial pivoting
    would exchange no rows (a diagonal that dominates its column, as the two-link arm's does).
    ``a`` is overwritten by its elimination factors; a diagonal ``a`` is solved by division.
    """
    if _is_diagonal(a):
        return _solve_diagonal(a, b)
    symmetric = _is_symmetric(a)
    solved, positive = _eliminate(a, b, False)
    return solved, positive and (symmetric or not solved)


@inline_part
def matvec(values, start, rows, columns, x, out):
    """``out = A x`` for a small (rows, columns) matrix ``A`` stored row-major in ``values`` from
    index ``start`` (``x`` holds at least ``columns`` entries), by loops (no BLAS call), summed
    in index order.

    The matrix is read in place, not as a reshaped view of ``values``: a reshape compiles
    numba's shape checks and its runtime into every caller. The sizes are arguments, so that a
    caller that knows them when it is compiled gets the loops unrolled."""
    for i in range(rows):
        total = 0.0
        row = start + i * columns
        for j in range(columns):
            total += values[row + j] * x[j]
        out[i] = total
