"""What a predictor is told of the delay: PCON's delay-knowledge model.

The paper's PCON assumes the delay ``h(t)`` known exactly. To ask what happens when it is not,
PCON is told, at tick ``t_k``,

    ĥ_k = max(0, s h(t_k) + b + σ ξ_k)

with a scale ``s`` (``2`` tells twice the delay), an offset ``b`` (s) and noise of standard
deviation ``σ`` (s); ``s = 1, b = σ = 0`` is the paper's exact knowledge. A window cannot be
negative: an estimate below zero is used as zero (no prediction).

``ξ_k`` is :func:`~delaytrack._counter_noise.standard_noise` of the seed and the tick index
``k = round(t_k / T_c)``: approximately standard normal, always within ±6, the same for a run
alone, in a batch and on any thread.
"""

from __future__ import annotations

import math
from typing import TypedDict

import numpy as np

from delaytrack._compile.jit import hot_kernel
from delaytrack._counter_noise import standard_noise

__all__ = ["DelayKnowledge", "told_delay", "told_delays"]


class DelayKnowledge(TypedDict, total=False):
    """What PCON is told of the delay: the keywords of :class:`~delaytrack.controllers.PCON`
    that set ``s`` (``delay_scale``), ``b`` (``delay_offset``), ``σ`` (``delay_noise``) and the
    seed of ``ξ_k`` (``noise_seed``); an absent key keeps PCON's default (exact knowledge)."""

    delay_scale: float
    delay_offset: float
    delay_noise: float
    noise_seed: int


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
