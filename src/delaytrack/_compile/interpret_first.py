"""Interpret first: a combination's first runs as plain Python while that is quicker than
compiling it.

A first run of a combination of plant, controller, reference and delay that is neither in
memory nor in numba's disk cache waits for numba to compile the engine and its parts, from
seconds to tens of seconds, however short the run. The plain-Python engine computes the same
numbers (bit for bit where NumPy and numba use the same maths library, as on Linux and macOS
with x86-64) at roughly 0.05–0.1 ms a plant step for a small plant, so a short first run is done
before the compile would be.

The rule is the rent-or-buy rule of a tiered just-in-time compiler. The *budget* of a
combination is what compiling it would cost (the parts' rough costs,
:mod:`delaytrack._compile.native_parts`, shared between two cores when there are two). While
the time spent interpreting it is below the budget, a run is interpreted with a deadline at the
budget's end: a run still going then is abandoned and compiled. So the time spent interpreting
never exceeds the budget (by more than one controller tick), and a user who ends up compiling
waits at most about twice as long as compiling at once, while one whose runs stay short never
waits for a compile. A run whose estimate (its plant steps at the pace of the combination's
last completed interpreted run, :data:`SECONDS_PER_STEP` before one) does not fit in what is
left of the budget is compiled at once. The time spent is kept in numba's cache folder, so that
it adds up over processes: a script run again and again compiles once its runs together have
cost as much.

An interpreted run that raises (plain Python raises where compiled code gives ``inf`` or
``NaN``, such as ``math.exp`` overflowing) is run again compiled, whose outcome is the result.
A kernel of the user's compiled with ``fastmath`` is compiled at once (its compiled arithmetic
differs from Python's in the last bits), and so is every run within
:func:`~delaytrack.sim.compile_ahead` (compiling asked for). Set the environment variable
``DELAYTRACK_INTERPRET_FIRST`` to ``0`` to compile at once (as
``simulate(..., engine="compiled")`` does).
"""

from __future__ import annotations

import contextlib
import hashlib
import math
import os
import sys
import threading
from collections.abc import Callable
from dataclasses import dataclass

from delaytrack._compile.ahead import parts_ahead
from delaytrack._compile.disk_cache import cache_directory
from delaytrack._compile.fingerprint import compiled_functions_reached
from delaytrack._compile.functions import users_compiled
from delaytrack._compile.native_parts import NativePart
from delaytrack._compile.stage import compile_cost, refuse_changed_kernels
from delaytrack._io import atomic_path
from delaytrack.sim._build import Build
from delaytrack.sim._machine import available_cores
from delaytrack.sim.engine import Kernels

__all__ = [
    "INTERPRETING",
    "SECONDS_PER_STEP",
    "Interpreting",
    "interpret",
    "seconds_text",
]

#: The environment variable that turns interpreting first off (``0``).
INTERPRETING = "DELAYTRACK_INTERPRET_FIRST"

#: Seconds of one plant step of one run in the plain-Python engine, before a run of the
#: combination has been timed (measured: 0.04 ms for the paper's robot under AROLC, 0.11 ms for
#: a pendulum of the user's with the controller every second step; a plant of 30 coordinates
#: takes 3.5 ms, which the deadline catches).
SECONDS_PER_STEP = 1e-4

_LOCK = threading.Lock()


@dataclass
class _Spent:
    """What interpreting one combination has cost (this process's, and others' before it)."""

    seconds: float
    #: Seconds per plant step and run of its last completed interpreted run.
    pace: float = SECONDS_PER_STEP
    #: Whether this process has said that it interprets the combination.
    announced: bool = False


#: Per combination (:func:`_combination`).
_SPENT: dict[str, _Spent] = {}


def _combination(parts: tuple[NativePart, ...]) -> str:
    """A name of the compiled code that ``parts`` need, the same in every process (the
    functions and their argument types, a kernel of the user's by its code's fingerprint)."""
    text = "\n".join(
        f"{part.function.py_func.__module__}.{part.function.py_func.__qualname__}"
        f"{tuple(map(str, part.signature))}"
        for part in parts
    )
    return hashlib.sha256(text.encode()).hexdigest()[:24]


def _record(combination: str) -> os.PathLike[str]:
    """The file that keeps the seconds spent interpreting ``combination``, in numba's cache
    folder (of this exact source)."""
    return cache_directory() / "interpreted" / combination


def _spent(combination: str) -> _Spent:
    """The time spent on ``combination`` so far, read from its record the first time."""
    spent = _SPENT.get(combination)
    if spent is None:
        seconds = 0.0
        with contextlib.suppress(OSError, ValueError):
            with open(_record(combination), encoding="ascii") as file:
                seconds = max(0.0, float(file.read()))
        spent = _SPENT[combination] = _Spent(seconds if math.isfinite(seconds) else 0.0)
    return spent


def seconds_text(seconds: float) -> str:
    """``seconds`` as a notice says it: ``"0.04 s"``, ``"3 s"``, ``"12 s"``, ``"2 min"``."""
    if seconds < 1.0:
        return f"{seconds:.2g} s"
    if seconds < 120.0:
        return f"{seconds:.0f} s"
    return f"{seconds / 60:.0f} min"


@dataclass(frozen=True)
class Interpreting:
    """A run to interpret instead of compiling (:func:`interpret`).

    Parameters
    ----------
    combination : str
        The compiled code it would need.
    steps : int
        Its plant steps, over every run of its batch.
    seconds : float
        How long it may take: what is left of the combination's budget. A run still going then
        is abandoned, and compiled.
    """

    combination: str
    steps: int
    seconds: float

    def done(self, seconds: float, steps_run: int | None) -> None:
        """Record that the run took ``seconds``: it completed ``steps_run`` plant steps (its
        runs stopped where they stopped), or None when it did not complete."""
        with _LOCK:
            spent = _spent(self.combination)
            spent.seconds += seconds
            if steps_run:
                spent.pace = seconds / steps_run
            total = spent.seconds
        with contextlib.suppress(OSError), atomic_path(_record(self.combination)) as path:
            path.write_text(repr(total), encoding="ascii")


def _fastmath(build: Build) -> bool:
    """Whether a compiled function of the user's that the run reaches uses ``fastmath``."""
    return any(
        bool(function.targetoptions.get("fastmath"))
        for kernel in build.kernels(0)
        for root in kernel.roots
        if users_compiled(root)
        for function in compiled_functions_reached(root)
    )


def _announce(seconds: float) -> None:
    """One line on standard error the first time a process interprets a combination."""
    print(
        "delaytrack: this plant, controller, reference and delay are not compiled yet: running "
        f"them as plain Python (the same numbers) for at most about {seconds_text(seconds)}, "
        f"what compiling them would take, then compiling them ({INTERPRETING}=0 compiles at "
        "once)",
        file=sys.stderr,
        flush=True,
    )


def interpret(build: Build, first_chunk: Callable[[Kernels], tuple]) -> Interpreting | None:
    """Whether to interpret the compiled ``build``'s run (an :class:`Interpreting`, whose
    :meth:`~Interpreting.done` records its time) or to compile it (None), by the rule of this
    module.

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
    if os.environ.get(INTERPRETING, "").strip() == "0" or parts_ahead():
        return None  # turned off, or compiling asked for (compile_ahead)
    parts, cost = compile_cost(build, first_chunk)
    if cost <= 0.0 or _fastmath(build):
        return None
    plan = build.plan
    steps = plan.batch * plan.n_ticks * plan.steps_per_tick
    combination = _combination(parts)
    budget = cost / min(2, available_cores())
    with _LOCK:
        spent = _spent(combination)
        left = budget - spent.seconds
        if spent.pace * steps > left:
            return None
        announce, spent.announced = not spent.announced, True
    refuse_changed_kernels(build)  # as compiling would: the run must not depend on the path
    if announce:
        _announce(left)
    return Interpreting(combination, steps, left)
