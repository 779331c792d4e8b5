"""Seeded noise without generator state: a counter-based generator keyed by a seed and an index.

``standard_noise(seed, index)`` is approximately standard normal: the sum of twelve uniforms on
(0, 1) minus 6 (the Irwin–Hall distribution: mean 0, variance 1, always within ±6). The
uniforms come from a 32-bit integer hash (C. Wellons' "lowbias32" with its improved constants)
of the seed and the index, so a value depends on nothing but them: a run gives the same noise
alone, in a batch and on any thread, and nothing is carried from one call to the next.
"""

from __future__ import annotations

from delaytrack._compile.jit import hot_kernel

__all__ = ["NOISE_BOUND", "hash32", "standard_noise", "uniform"]

#: ``|standard_noise(...)| <= 6`` always (twelve uniforms minus 6).
NOISE_BOUND = 6.0
_MASK = 0xFFFFFFFF
_TWO_32 = 4294967296.0


@hot_kernel
def hash32(x):
    """A 32-bit integer hash of ``x mod 2³²`` (every product stays below 2⁶³)."""
    x = x & _MASK
    x ^= x >> 16
    x = (x * 0x21F0AAAD) & _MASK
    x ^= x >> 15
    x = (x * 0x735A2D97) & _MASK
    x ^= x >> 15
    return x


@hot_kernel
def uniform(seed, index):
    """A uniform number in (0, 1) for ``seed`` and ``index`` (integers): one of the twelve that
    :func:`standard_noise` sums, of a stream of its own (the index's hash, not ``12 index``)."""
    return (hash32(hash32(seed) ^ hash32(index + 0x5BD1E995)) + 0.5) / _TWO_32


@hot_kernel
def standard_noise(seed, index):
    """Approximately standard normal noise for ``seed`` and ``index`` (integers; module
    docstring)."""
    base = hash32(seed)
    total = 0.0
    for i in range(12):
        total += (hash32(base + 12 * index + i) + 0.5) / _TWO_32
    return total - 6.0
