"""AROLC's certified delay bound beside the delays a run met: Theorem 1's ``h_m`` per run, and
the warning when a run's largest delay exceeds it.

Theorem 1 (Roy & Kar) certifies AROLC for every input delay ``0 <= h(t) < h_m`` with

    h_m = λ_min(Q) / ‖E‖₂,
    E = β P B1 (A1 P⁻¹ A1ᵀ + B1 P⁻¹ B1ᵀ + P⁻¹) B1ᵀ P + 2 (r / β) P,

from the run's gains ``K1, K2`` and weight ``Q`` (``AᵀP + PA = −Q``) and the paper's ``β = 1``,
``r = 1.1`` (:func:`~delaytrack.analysis.razumikhin_bound`). A delay beyond ``h_m`` is not
instability: the bound is a sufficient condition, and beyond it the guarantee ends, not the
loop.
"""

from __future__ import annotations

import contextlib
import contextvars
import functools
from collections.abc import Iterator, Sequence
from typing import TYPE_CHECKING

import numpy as np

from delaytrack._words import quantity_text
from delaytrack.analysis.razumikhin import PAPER_BETA, PAPER_R, razumikhin_bound
from delaytrack.controllers.arolc import AROLC
from delaytrack.warning import DelaytrackWarning

if TYPE_CHECKING:
    from delaytrack.controllers.base import Controller
    from delaytrack.delays.base import DelayProfile
    from delaytrack.sim.result import SimResult

__all__ = [
    "BeyondCertifiedBoundWarning",
    "beyond_certified_bound",
    "caller_states_the_delays",
    "certified_bounds",
    "largest_delays",
    "stated_by_the_caller",
]

#: Whether the warning is left to the caller, which states ``h_m`` itself
#: (:func:`stated_by_the_caller`).
_STATED: contextvars.ContextVar[bool] = contextvars.ContextVar("h_m_stated", default=False)


class BeyondCertifiedBoundWarning(DelaytrackWarning):
    """A run's largest delay exceeds AROLC's certified bound ``h_m`` (Theorem 1, with the run's
    ``K1``, ``K2``, ``Q`` and the paper's ``β = 1``, ``r = 1.1``).

    Exceeding ``h_m`` is not by itself instability: Theorem 1 is a sufficient condition, and
    beyond ``h_m`` the guarantee ends, not necessarily the loop. Whether the loop still tracks
    is then an empirical finding of the run. ``h_m`` and ``largest_delay`` (seconds) hold the
    numbers of the run quoted: of the runs beyond their bound, the one with the largest delay.
    """

    def __init__(self, message: str, h_m: float, largest_delay: float) -> None:
        super().__init__(message)
        self.h_m = h_m
        self.largest_delay = largest_delay


def certified_bounds(controllers: Sequence[Controller]) -> np.ndarray:
    """Theorem 1's ``h_m`` (seconds) of each controller: AROLC's with its ``K1``, ``K2``, ``Q``
    and the paper's ``β``, ``r``; NaN for any other controller (no certificate)."""
    known: dict[int, float] = {}
    bounds = np.full(len(controllers), np.nan)
    for i, controller in enumerate(controllers):
        if isinstance(controller, AROLC):
            if id(controller) not in known:  # a batch shares one controller often
                gains = (controller.K1, controller.K2, controller.Q)
                known[id(controller)] = _h_m(*(_key(gain) for gain in gains))
            bounds[i] = known[id(controller)]
    return bounds


def _key(matrix: np.ndarray) -> tuple[tuple[int, ...], bytes]:
    """A gain matrix as its shape and its float64 bytes in C order (:func:`_h_m`'s key)."""
    values = np.ascontiguousarray(matrix, dtype=np.float64)
    return values.shape, values.tobytes()


@functools.lru_cache(maxsize=128)
def _h_m(*gains: tuple[tuple[int, ...], bytes]) -> float:
    """Theorem 1's ``h_m`` of AROLC's ``K1``, ``K2``, ``Q``, each given by :func:`_key`:
    computed once per gains (about a millisecond, as long as a short run takes), then
    remembered."""
    K1, K2, Q = (np.frombuffer(data, dtype=np.float64).reshape(shape) for shape, data in gains)
    return razumikhin_bound(K1, K2, Q, PAPER_BETA, PAPER_R).h_m


def largest_delays(result: SimResult, delays: Sequence[DelayProfile]) -> np.ndarray:
    """The largest delay (seconds) each run met: the largest recorded ``h(t)`` when
    trajectories were recorded, else the profile's upper bound ``h_max``."""
    if result.has_trajectories:
        return np.nanmax(result.h, axis=1)
    return np.array([delay.h_max for delay in delays])


def beyond_certified_bound(
    controllers: Sequence[Controller], delays: Sequence[DelayProfile], result: SimResult
) -> BeyondCertifiedBoundWarning | None:
    """The warning for the runs whose largest delay exceeds their AROLC's ``h_m``, or None."""
    bounds = certified_bounds(controllers)
    largest = largest_delays(result, delays)
    beyond = np.flatnonzero(largest > bounds)  # NaN (no certificate) compares False
    if beyond.size == 0:
        return None
    # The run named: the largest delay among the runs beyond their bound.
    run = int(beyond[np.argmax(largest[beyond])])
    delay, bound = quantity_text(largest[run], "s", 4), quantity_text(bounds[run], "s", 4)
    if result.batch_size == 1:
        what = f"the largest delay {delay} exceeds AROLC's certified bound h_m = {bound}"
    else:
        what = (
            f"the largest delay exceeds AROLC's certified bound h_m in {beyond.size} of "
            f"{result.batch_size} runs (the most in run {run}: {delay} against h_m = {bound})"
        )
    status = result.status_names[run]
    ended = "" if status == "ok" else f"; that run did not finish ({status})"
    return BeyondCertifiedBoundWarning(
        f"{what} (Theorem 1 with the run's K1, K2, Q and the paper's beta = {PAPER_BETA:g}, "
        f"r = {PAPER_R:g}): beyond h_m the guarantee ends, which does not by itself mean "
        f"instability (the theorem is a sufficient condition){ended}",
        float(bounds[run]),
        float(largest[run]),
    )


@contextlib.contextmanager
def stated_by_the_caller() -> Iterator[None]:
    """Within it, :func:`~delaytrack.sim.simulate` issues no
    :class:`BeyondCertifiedBoundWarning` (nor a
    :class:`~delaytrack.sim.no_command.NoCommandArrivesWarning`): for the toolkit's jobs (the
    paper job, tuning, margins, sweeps, a scenario's run and the command line), which run
    beyond ``h_m`` (and delays as long as a run) on purpose and state it in their reports and
    outputs. Local to the thread or task that enters it."""
    token = _STATED.set(True)
    try:
        yield
    finally:
        _STATED.reset(token)


def caller_states_the_delays() -> bool:
    """Whether :func:`simulate`'s warnings about the runs' delays are left to its caller
    (:func:`stated_by_the_caller`)."""
    return _STATED.get()
