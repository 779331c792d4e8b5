"""The binary search of the compiled kernels (delaytrack._sorted_search) gives NumPy's index."""

from __future__ import annotations

import math

import numba
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from delaytrack._sorted_search import count_at_or_before

_finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False)


@numba.njit
def _compiled(values, t):
    return count_at_or_before(values, t)


@settings(max_examples=300, deadline=None)
@given(
    values=st.lists(_finite, min_size=0, max_size=12).map(sorted),
    t=st.one_of(_finite, st.sampled_from([math.nan, math.inf, -math.inf])),
    at_a_value=st.booleans(),
)
def test_the_index_is_numpys_searchsorted_to_the_right(values, t, at_a_value):
    array = np.asarray(values, dtype=float)
    if at_a_value and array.size:
        t = float(array[len(values) // 2])  # exactly on a value (repeated values included)
    expected = int(np.searchsorted(array, t, side="right"))
    assert count_at_or_before(array, t) == expected  # as Python
    assert _compiled(array, t) == expected
