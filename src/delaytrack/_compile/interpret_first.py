"""Interpret first: a combination's first runs as plain Python while that is quicker than
compiling it.

A first run of a combination of plant, controller, reference and delay that is neither in
memory nor in numba's disk cache waits for numba to compile the engine and its parts, from
seconds to tens of seconds, however short the run. The plain-Python engine computes the same
numbers (bit for bit where NumPy and numba use the same maths library: checked on Linux with
x86-64) at roughly 0.05–0.1 ms a plant step for a small plant, so a short first run is done
before the compile would be.

The rule is the rent-or-buy rule of a tiered just-in-time compiler. The *budget* of a
combination is what compiling it would cost (the parts' rough costs,
:mod:`delaytrack._compile.native_parts`, shared between two cores when there are two). While
the time spent interpreting it is below the budget, a run is interpreted with a deadline at the
budget's end, checked before every plant step and controller tick: a run still going then is
abandoned and compiled. So the time spent interpreting exceeds the budget by at most one plant
step (the package's functions run as plain Python, compiling nothing:
:func:`~delaytrack._compile.jit.as_python`), and a user who ends up compiling waits at most
about twice as long as compiling at once, while one whose runs stay short never waits for a
compile. A run whose estimate (its plant steps at the pace of the combination's last completed
interpreted run, less numba's compiling, :data:`SECONDS_PER_STEP` before one) does not fit in
what is left of the budget is compiled at once. The time spent is kept in numba's cache folder
and adds up over processes (each run adds its own under a file lock), so that a script run
again and again compiles once its runs together have cost as much.

An interpreted run that raises (plain Python raises where compiled code gives ``inf`` or
``NaN``, such as ``math.exp`` overflowing) is run again compiled, whose outcome is the result.
A kernel of the user's compiled with ``fastmath`` is compiled at once (its compiled arithmetic
differs from Python's in the last bits), and so is one that returns an array (the compiled
engine refuses it), and every run within
:func:`~delaytrack.sim.compile_ahead` (compiling asked for). Set the environment variable
``DELAYTRACK_INTERPRET_FIRST`` to ``0`` to compile at once (as
``simulate(..., engine="compiled")`` does); ``1`` or unset interprets first.
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
from pathlib import Path

import numba

from delaytrack._compile.ahead import parts_ahead
from delaytrack._compile.fingerprint import compiled_functions_reached
from delaytrack._compile.functions import users_compiled
from delaytrack._compile.guards import holds_managed_memory
from delaytrack._compile.native_parts import NativePart
from delaytrack._compile.stage import compile_cost, refuse_changed_kernels
from delaytrack._file_lock import exclusive
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
#: combination has been timed (measured, every function of the package as plain Python: 0.066 ms
#: for the paper's robot under AROLC, 0.062 ms for a pendulum of the user's with the controller
#: every second step; a plant of 30 coordinates takes 3.5 ms, which the deadline catches).
SECONDS_PER_STEP = 1e-4

_LOCK = threading.Lock()


@dataclass
class _Spent:
    """What interpreting one combination has cost, as this process last read or wrote it."""

    seconds: float
    #: Seconds per plant step and run of its last completed interpreted run, less numba's
    #: compiling.
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


def _record(combination: str) -> Path:
    """The file that keeps the seconds spent interpreting ``combination``, in numba's cache
    folder (of this exact source)."""
    return Path(numba.config.CACHE_DIR) / "interpreted" / combination  # type: ignore[attr-defined]


def _read(path: Path) -> float:
    """The seconds a record holds (0 when there is none, or it cannot be read)."""
    with contextlib.suppress(OSError, ValueError):
        seconds = float(path.read_text(encoding="ascii"))
        if math.isfinite(seconds) and seconds > 0.0:
            return seconds
    return 0.0


def _spent(combination: str) -> _Spent:
    """The time spent on ``combination`` so far, its record read the first time."""
    spent = _SPENT.get(combination)
    if spent is None:
        spent = _SPENT[combination] = _Spent(_read(_record(combination)))
    return spent


def _add(combination: str, seconds: float) -> float:
    """Add ``seconds`` to the record of ``combination`` (read again under a file lock, so that
    processes interpreting at once add up) and return the total."""
    path = _record(combination)
    with contextlib.suppress(OSError):
        path.parent.mkdir(parents=True, exist_ok=True)
        with exclusive(f"{path}.lock"), atomic_path(path) as temporary:
            total = _read(path) + seconds
            temporary.write_text(repr(total), encoding="ascii")
        return total
    return _spent(combination).seconds + seconds  # no record: this process's count


def seconds_text(seconds: float) -> str:
    """``seconds`` as a notice says it: ``"0.04 s"``, ``"3 s"``, ``"12 s"``, ``"2.5 min"``."""
    if seconds < 0.01:
        return "under 0.01 s"
    if seconds < 1.0:
        return f"{seconds:.2f} s" if seconds < 0.1 else f"{seconds:.1f} s"
    if seconds < 120.0:
        return f"{seconds:.0f} s"
    return f"{seconds / 60:.1f} min"


@dataclass(frozen=True)
class Interpreting:
    """A run to interpret instead of compiling (:func:`interpret`).

    Parameters
    ----------
    combination : str
        The compiled code it would need.
    seconds : float
        How long it may take: what is left of the combination's budget. A run still going then
        is abandoned, and compiled.
    """

    combination: str
    seconds: float

    def done(self, seconds: float, compiling: float, steps_run: int | None) -> None:
        """Record that the run took ``seconds``, of which ``compiling`` numba's compiling (of
        the helpers of the user's that the user's kernels call): it completed ``steps_run``
        plant steps (its runs stopped where they stopped), or None when it did not complete."""
        total = _add(self.combination, seconds)
        with _LOCK:
            spent = _spent(self.combination)
            spent.seconds = max(spent.seconds, total)
            if steps_run:
                spent.pace = max(seconds - compiling, 0.0) / steps_run


def _compiled_as_python(build: Build) -> bool:
    """Whether a compiled function of the user's that the run reaches would run otherwise as
    Python than compiled: one with ``fastmath`` (other rounding), or one that returned an array
    where it was called (the compiled engine refuses it)."""
    for kernel in build.kernels(0):
        for root in kernel.roots:
            if not users_compiled(root):
                continue
            for function in compiled_functions_reached(root):
                if function.targetoptions.get("fastmath"):
                    return True
            for compiled in root.overloads.values():
                if holds_managed_memory(compiled.signature.return_type):
                    return True
    return False


def _announce(left: float, budget: float) -> None:
    """One line on standard error the first time a process interprets a combination."""
    more = "" if left >= budget else f" more of the {seconds_text(budget)}"
    print(
        "delaytrack: the compiled code this run needs is not ready: running it as plain Python "
        f"(the same numbers) for up to about {seconds_text(left)}{more} that compiling would "
        f"take; a run still going then is compiled ({INTERPRETING}=0 compiles at once)",
        file=sys.stderr,
        flush=True,
    )


def _turned_on() -> bool:
    """:data:`INTERPRETING`: ``1`` or unset (on), ``0`` (off); anything else refused."""
    setting = os.environ.get(INTERPRETING, "").strip()
    if setting not in ("", "0", "1"):
        raise ValueError(
            f"the environment variable {INTERPRETING} is {setting!r}; it must be 0 (compile at "
            "once) or 1 (interpret a short first run), or unset (1)"
        )
    return setting != "0"


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
    if not _turned_on() or parts_ahead():
        return None  # turned off, or compiling asked for (compile_ahead)
    parts, cost = compile_cost(build, first_chunk)
    if cost <= 0.0 or _compiled_as_python(build):
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
        _announce(left, budget)
    return Interpreting(combination, left)
