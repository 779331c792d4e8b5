"""What a predictor is told of the delay: PCON's delay-knowledge model.

The paper's PCON assumes the delay ``h(t)`` known exactly. To ask what happens when it is not,
PCON is told, at tick ``t_k``,

    ĥ_k = max(0, s h(t_k) + b + σ ξ_k)

with a scale ``s`` (``2`` tells twice the delay), an offset ``b`` (s) and noise of standard
deviation ``σ`` (s); ``s = 1, b = σ = 0`` is the paper's exact knowledge. A window cannot be
negative: an estimate below zero is used as zero (no prediction).

``ξ_k`` is approximately standard normal: the sum of twelve uniforms on (0, 1) minus 6 (the
Irwin–Hall distribution: mean 0, variance 1, always within ±6). The uniforms come from a
counter-based generator keyed by the seed and the tick index ``k = round(t_k / T_c)`` (a 32-bit
integer hash, C. Wellons' "lowbias32" with its improved constants), so that a run gives the same
estimates alone, in a batch and on any thread, with no generator state to carry.
"""

from __future__ import annotations

import math

import numpy as np

from delaytrack._jit import hot_kernel

__all__ = ["NOISE_BOUND", "hash32", "standard_noise", "told_delay", "told_delays"]

#: ``|ξ_k| <= 6`` always (twelve uniforms minus 6).
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
def standard_noise(seed, k):
    """``ξ_k`` of the module docstring for ``seed`` and tick index ``k`` (integers)."""
    base = hash32(seed)
    total = 0.0
    for i in range(12):
        total += (hash32(base + 12 * k + i) + 0.5) / _TWO_32
    return total - 6.0


@hot_kernel
def told_delay(h, t, T_c, scale, offset, noise, seed):
    """``ĥ_k`` (s) of the module docstring at time ``t`` for the true delay ``h``."""
    told = scale * h + offset
    if noise > 0.0:
        told += noise * standard_noise(seed, int(math.floor(t / T_c + 0.5)))
    return max(told, 0.0)


def told_delays(
    h: np.ndarray,
    t: np.ndarray,
    T_c: float,
    scale: float = 1.0,
    offset: float = 0.0,
    noise: float = 0.0,
    seed: int = 0,
) -> np.ndarray:
    """:func:`told_delay` at every ``(h, t)`` pair: what PCON is told at those ticks."""
    h, t = np.broadcast_arrays(np.asarray(h, dtype=float), np.asarray(t, dtype=float))
    return np.array(
        [
            told_delay(float(a), float(b), T_c, scale, offset, noise, int(seed))
            for a, b in zip(h.ravel(), t.ravel(), strict=True)
        ]
    ).reshape(h.shape)
