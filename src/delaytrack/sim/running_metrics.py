"""Tracking and effort metrics accumulated inside the run, at every controller tick.

A sweep of thousands of runs needs the paper's metrics, not the trajectories: the engine adds
each tick's tracking error ``e1 = q_d - q``, command and applied input to a few sums per run, so
memory does not grow with the number of steps. Over the ticks ``k`` with ``t_k >= t_from`` (``K``
of them):

    AE_j  = (1/K) Σ_k |e1_j(t_k)|          RMS_j = sqrt((1/K) Σ_k e1_j(t_k)²)
    MAX_j = max_k |e1_j(t_k)|              TV    = Σ_k Σ_j |command_j(t_{k+1}) - command_j(t_k)|
    TV_applied = Σ_k Σ_j |ū_j(t_{k+1}) - ū_j(t_k)|

with ``ū(t_k)`` the input the plant receives just after tick ``k`` (the delayed command, saturated
to the input limits: the record ``applied``). These are the definitions of
:mod:`delaytrack.metrics` taken over every tick, so they equal ``metrics_table`` of a result
recorded with ``record_every = 1`` (up to the order of the sums). Layout of one run's accumulator
(``3n + 3`` floats): ``[Σ|e1| (n), Σe1² (n), max|e1| (n), TV, K, TV_applied]``.
"""

from __future__ import annotations

import numpy as np

from delaytrack._compile.jit import inline_kernel

__all__ = ["accumulate_applied", "accumulate_tick", "accumulator_size", "finish_metrics"]


def accumulator_size(n: int) -> int:
    """Floats per run of the accumulator for ``n`` coordinates."""
    return 3 * n + 3


@inline_kernel
def _variation(inputs, previous):
    """``Σ_j |inputs_j - previous_j|``: one tick's term of a total variation."""
    variation = 0.0
    for j in range(inputs.shape[0]):
        variation += abs(inputs[j] - previous[j])
    return variation


@inline_kernel
def accumulate_tick(sums, qd, q, command, previous_command, first):
    """Add tick ``(q_d, q, command)`` to ``sums``; ``first`` when it is the first tick counted."""
    n = q.shape[0]
    for j in range(n):
        error = abs(qd[j] - q[j])
        sums[j] += error
        sums[n + j] += error * error
        sums[2 * n + j] = max(sums[2 * n + j], error)
    if not first:
        sums[3 * n] += _variation(command, previous_command)
    sums[3 * n + 1] += 1.0


@inline_kernel
def accumulate_applied(sums, applied, previous_applied, first):
    """Add the input ``applied`` the plant receives just after a tick to ``TV_applied`` in
    ``sums`` (``3n + 3`` floats); ``first`` when it is the first tick counted."""
    if not first:
        sums[sums.shape[0] - 1] += _variation(applied, previous_applied)


def finish_metrics(sums: np.ndarray, ok: np.ndarray) -> dict[str, np.ndarray]:
    """``{"ae", "rms", "max" (B, n), "tv", "tv_applied" (B,)}`` from accumulators
    ``sums (B, 3n + 3)``.

    Runs that are not ``ok`` get NaN, as in :mod:`delaytrack.metrics` (their sums describe a
    shorter experiment that ended in a blow-up).
    """
    n = (sums.shape[1] - 3) // 3
    count = sums[:, 3 * n + 1 : 3 * n + 2]
    # Σ|e1| and Σe1² over K; a run that stopped before its window opened counted no tick.
    means = np.divide(
        sums[:, : 2 * n], count, out=np.full((sums.shape[0], 2 * n), np.nan), where=count > 0.0
    )
    metrics = {
        "ae": means[:, :n].copy(),
        "rms": np.sqrt(means[:, n:]),
        "max": sums[:, 2 * n : 3 * n].copy(),
        "tv": sums[:, 3 * n].copy(),
        "tv_applied": sums[:, 3 * n + 2].copy(),
    }
    if not ok.all():
        for values in metrics.values():
            values[~ok] = np.nan
    return metrics
