"""Allocation-free dense algebra for the small systems (n <= ~10) of the compiled inner loop.

``numpy.linalg.solve`` in numba copies its operands and calls LAPACK: on a 2×2 to 5×5 system that
per-call overhead costs more than the arithmetic, and the plant's right-hand side solves one such
system at every RK4 stage. These loops do the same Gaussian elimination in place. Likewise
``a @ x``, which numba hands to BLAS: on a 5×5 matrix the call costs more than the product, and
OpenBLAS's worker threads then spin on the other cores, which a parallel batch needs.
"""

from __future__ import annotations

import math

from delaytrack._jit import inline_kernel

__all__ = ["matvec", "solve_in_place"]


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
def solve_in_place(a, b):
    """Solve ``a x = b`` by Gaussian elimination with partial pivoting; ``b`` becomes ``x``.

    ``a`` (n, n) is overwritten by its elimination factors. Returns ``(solved, definite)``.
    ``solved`` is False (and ``b`` unspecified) when a pivot is exactly zero or not finite
    (``a`` singular or holding NaN). A nearly singular ``a`` gives a huge solution, which the
    simulator's divergence bound stops. ``definite`` is False when the elimination shows that
    ``a``, taken as symmetric (a mass matrix), is not positive definite: a pivot of exactly
    zero; without row exchanges a pivot ``<= 0`` (the pivots are then those of ``a``'s
    ``L D Lᵀ``: exact); with them a determinant ``<= 0`` or a diagonal entry ``<= 0``
    (necessary conditions, exact for ``n <= 2``). It is True when a pivot is not finite
    (nothing is known). The checks only read the pivots: the solution is the same bit for bit.
    A diagonal ``a`` (the constrained robot's ``M = I``) is solved by division.
    """
    n = b.shape[0]
    if _is_diagonal(a):
        for i in range(n):
            if not (a[i, i] != 0.0 and math.isfinite(a[i, i])):
                return False, a[i, i] != 0.0
            b[i] /= a[i, i]
        return True, _diagonal_is_positive(a)
    positive_diagonal = _diagonal_is_positive(a)
    exchanges = 0
    negative_pivots = 0
    for column in range(n):
        pivot_row = column
        largest = abs(a[column, column])
        for row in range(column + 1, n):
            if abs(a[row, column]) > largest:
                largest = abs(a[row, column])
                pivot_row = row
        if not (largest > 0.0 and largest < float("inf")):
            return False, largest != 0.0
        if pivot_row != column:
            exchanges += 1
            for j in range(column, n):
                a[column, j], a[pivot_row, j] = a[pivot_row, j], a[column, j]
            b[column], b[pivot_row] = b[pivot_row], b[column]
        if a[column, column] < 0.0:
            negative_pivots += 1
        inverse = 1.0 / a[column, column]
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
    if exchanges == 0:
        return True, negative_pivots == 0
    return True, positive_diagonal and (negative_pivots + exchanges) % 2 == 0


@inline_kernel
def matvec(a, x, out):
    """``out = a @ x`` for a small (r, c) matrix and (c,) vector, by loops (no BLAS call)."""
    for i in range(a.shape[0]):
        total = 0.0
        for j in range(a.shape[1]):
            total += a[i, j] * x[j]
        out[i] = total
