"""Interpret first: a combination's first runs as plain Python while that is quicker than
compiling it.

A first run of a combination of plant, controller, reference and delay that is neither in
memory nor in numba's disk cache waits for numba to compile the engine and its parts, from
seconds to tens of seconds, however short the run. The plain-Python engine computes the same
numbers (bit for bit where NumPy and numba use the same maths library, as on Linux and macOS
with x86-64; to rounding otherwise) at roughly 0.05–0.1 ms a plant step, so a short first run
is done before the compile would be.

The rule is the rent-or-buy rule of a tiered just-in-time compiler: a run of a combination
that is not compiled yet is interpreted while the time this process has spent interpreting that
combination, with the run asked for (estimated at its last interpreted run's pace, or
:data:`SECONDS_PER_STEP` before it), stays within what compiling it would cost (the parts'
rough costs, :mod:`delaytrack._compile.native_parts`, shared between two cores when there are
two); after that it is compiled, and kept on disk for every later process. The time spent
interpreting never exceeds the compile it replaces, so a user who ends up compiling waits at
most about twice as long as compiling at once, and one whose runs stay short never waits for a
compile.

Within :func:`~delaytrack.sim.compile_ahead` runs are compiled, as asked. Set the environment
variable ``DELAYTRACK_INTERPRET_FIRST`` to ``0`` to compile at once (as
``simulate(..., engine="compiled")`` does).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Hashable
from dataclasses import dataclass

from delaytrack._compile.ahead import parts_ahead
from delaytrack._compile.stage import compile_cost, refuse_changed_kernels
from delaytrack.sim._build import Build
from delaytrack.sim._machine import available_cores
from delaytrack.sim.engine import Kernels

__all__ = [
    "ENVIRONMENT",
    "SECONDS_PER_STEP",
    "Interpreting",
    "choose",
    "interpret",
]

#: The environment variable that turns interpreting first off (``0``).
ENVIRONMENT = "DELAYTRACK_INTERPRET_FIRST"

#: Seconds of one plant step of one run in the plain-Python engine, before a run of the
#: combination has been timed (measured: 0.04 ms for the paper's robot under AROLC, 0.11 ms for
#: a pendulum of the user's with the controller every second step).
SECONDS_PER_STEP = 1e-4


@dataclass
class _Spent:
    """What interpreting one combination has cost this process."""

    seconds: float = 0.0
    #: Seconds per plant step and run of its last interpreted run.
    pace: float = SECONDS_PER_STEP


#: Per combination (the engine's parts, :func:`~delaytrack._compile.native_parts.engine_parts`).
_SPENT: dict[Hashable, _Spent] = {}


@dataclass(frozen=True)
class Interpreting:
    """A run interpreted instead of compiled (:func:`interpret`); :meth:`done` records its time.

    Parameters
    ----------
    combination : hashable
        The combination it runs.
    steps : int
        Its plant steps, over every run of the batch.
    """

    combination: Hashable
    steps: int

    def done(self, seconds: float) -> None:
        """Record that the run took ``seconds``."""
        spent = _SPENT.setdefault(self.combination, _Spent())
        spent.seconds += seconds
        spent.pace = seconds / max(self.steps, 1)


def _announce(steps: int, estimate: float, compile_seconds: float) -> None:
    """One line on standard error the first time a combination is interpreted."""
    print(
        "delaytrack: this plant, controller, reference and delay are not compiled yet: running "
        f"as plain Python ({steps:,} plant steps, about {estimate:.1g} s) rather than compiling "
        f"first (about {compile_seconds:.0f} s); compiled once interpreting them has cost as "
        f"much ({ENVIRONMENT}=0 compiles at once)",
        file=sys.stderr,
        flush=True,
    )


def interpret(build: Build, first_chunk: Callable[[Kernels], tuple]) -> Interpreting | None:
    """Whether to interpret the compiled ``build``'s run (an :class:`Interpreting`, to record
    its time) or to compile it (None): see the module's rule.

    Parameters
    ----------
    build : Build
        The compiled engine of a ``simulate`` call.
    first_chunk : callable
        The engine's arguments for the first chunk, as for
        :func:`~delaytrack._compile.stage.compile_engine`.

    Returns
    -------
    Interpreting or None
    """
    refuse_changed_kernels(build)
    if os.environ.get(ENVIRONMENT, "").strip() == "0" or parts_ahead():
        return None  # turned off, or compiling asked for (compile_ahead)
    combination, cost = compile_cost(build, first_chunk)
    plan = build.plan
    return choose(combination, plan.batch * plan.n_ticks * plan.steps_per_tick, cost)


def choose(combination: Hashable, steps: int, cost: float) -> Interpreting | None:
    """The rule of :func:`interpret`: interpret a run of ``combination`` of ``steps`` plant steps
    (over its whole batch) while this process's time interpreting it, with the run's
    estimate, stays within ``cost``, the rough seconds of compiling it on one core (0 when
    nothing is to compile), shared between up to two cores.

    Returns
    -------
    Interpreting or None
        What to record the run's time in, or None to compile.
    """
    if cost <= 0.0:
        return None
    budget = cost / min(2, available_cores())
    spent = _SPENT.get(combination, _Spent())
    estimate = spent.pace * steps
    if spent.seconds + estimate > budget:
        return None
    if combination not in _SPENT:
        _SPENT[combination] = spent
        _announce(steps, estimate, budget)
    return Interpreting(combination, steps)
