"""Where a time falls among sorted times, in compiled kernels: a binary search.

numba's ``np.searchsorted`` is written for any dtype, with NumPy's order of complex numbers and
NaN; compiled inside a kernel it took 0.37 s of CPU of every first compile of a plant's
integrator (the delay profiles' knots), for a few comparisons of sorted doubles. The search
below gives the same index for sorted doubles without NaN, and a NaN time after all of them, as
``np.searchsorted`` does.
"""

from __future__ import annotations

from delaytrack._compile.jit import inline_kernel

__all__ = ["count_at_or_before"]


@inline_kernel
def count_at_or_before(sorted_values, t):
    """How many of ``sorted_values`` (1-D, ascending, no NaN) are at or before ``t``:
    ``np.searchsorted(sorted_values, t, side="right")``, by bisection (a NaN ``t`` counts as
    after all of them)."""
    lo, hi = 0, sorted_values.shape[0]
    while lo < hi:
        middle = (lo + hi) // 2
        if t < sorted_values[middle]:
            hi = middle
        else:
            lo = middle + 1
    return lo
