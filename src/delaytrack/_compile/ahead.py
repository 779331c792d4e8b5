"""Parts asked for ahead: compiled with the next first compile, not one by one after it.

A job that runs several controllers in turn (the paper's table, the two-link study) would
otherwise compile each controller's step at the start of its own run, one at a time; asked for
ahead (:func:`compile_ahead`), they are compiled with the first run's parts, shared with the
same helper process (:mod:`delaytrack._compile.helper_process`).
"""

from __future__ import annotations

import contextlib
import contextvars
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import typeof

from delaytrack._compile.first_compile import code_ready
from delaytrack._compile.functions import is_compiled
from delaytrack._compile.helper_process import CompileJob
from delaytrack._compile.native_parts import (
    controller_step_name,
    controller_step_part,
    plant_integrator_name,
    plant_tick_part,
)
from delaytrack.components import Kernel
from delaytrack.delays._kernel import NO_KERNEL
from delaytrack.delays.base import DelayProfile

__all__ = ["CallAhead", "ahead", "compile_ahead", "parts_ahead", "values_ahead"]

#: Rough seconds of a first compile of a function of values called from Python (a reference's
#: or a delay profile's, 0.2–0.3 s), in the units of the parts' costs.
_VALUES_COST = 0.3

#: Parts a caller will need after the next first compile, as ``(name, part)`` pairs
#: (:func:`ahead`).
_AHEAD: contextvars.ContextVar[tuple] = contextvars.ContextVar("compile_ahead", default=())


@contextlib.contextmanager
def ahead(parts: Sequence[tuple[str, Any]]) -> Iterator[None]:
    """Within this context, a first compile also compiles ``parts`` (``(name, part)`` pairs of
    :class:`~delaytrack._compile.native_parts.NativePart` or :class:`CallAhead` objects that
    are not compiled yet; a part given twice is kept once), shared with the same helper
    process; with those of the contexts around it."""
    distinct = {part: name for name, part in (*_AHEAD.get(), *parts)}
    token = _AHEAD.set(tuple((name, part) for part, name in distinct.items()))
    try:
        yield
    finally:
        _AHEAD.reset(token)


def parts_ahead() -> tuple:
    """The ``(name, part)`` pairs of :func:`ahead`, or none outside it."""
    return _AHEAD.get()


@dataclass(frozen=True)
class CallAhead:
    """A compiled function called from Python, compiled with the next first compile for the
    types of its arguments (:func:`values_ahead`), as the parts are
    (:class:`~delaytrack._compile.native_parts.NativePart`).

    Parameters
    ----------
    function : numba dispatcher
    signature : tuple of numba types
    kernels : tuple of Kernel
        The components' kernels among its arguments.
    """

    function: Any
    signature: tuple
    kernels: tuple

    def ready(self) -> bool:
        """Whether its compiled code is in memory or in the disk cache."""
        return code_ready(self.function, self.signature, self.signature)

    def compile_job(self) -> CompileJob:
        """Its compile, for :func:`delaytrack._compile.helper_process.start`."""
        return CompileJob(self.function, self.signature, self.kernels, _VALUES_COST)

    def native(self) -> None:
        """Compile it here (or load it from the disk cache)."""
        self.function.compile(self.signature)


def values_ahead(component: Any) -> tuple[str, CallAhead] | None:
    """The function a reference's :meth:`~delaytrack.references.Reference.evaluate` or a delay
    profile's :meth:`~delaytrack.delays.DelayProfile.h` calls for its values at many times
    (their ``compiled_values``), to compile ahead, and how the first-compile notice names it;
    None when it is not compiled code."""
    function, arguments = component.compiled_values(np.empty(1))
    if not is_compiled(function):
        return None
    signature = tuple(map(typeof, arguments))  # a kernel's is its numba type
    kernels = tuple(argument for argument in arguments if isinstance(argument, Kernel))
    built_in = isinstance(component, DelayProfile) and component.engine_kernel is NO_KERNEL
    named = "the delay profiles' values" if built_in else f"{type(component).__name__}'s values"
    return named, CallAhead(function, signature, kernels)


def compile_ahead(
    controllers: Iterable[Any],
    n: int,
    m: int,
    plants: Iterable[Any] = (),
    values: Iterable[Any] = (),
) -> contextlib.AbstractContextManager[None]:
    """A context within which the first :func:`~delaytrack.sim.simulate` call that compiles
    anything also compiles the steps of ``controllers``, the integrators of ``plants`` and the
    functions that give the values of the references and delay profiles of ``values``.

    For a job that runs several controllers (or plants) in turn: their steps are then compiled
    beside the first run's parts (and on a second core when one is free), not one by one at the
    start of each run. Results are the same; only the first compile's time changes. A part
    that numba cannot compile is left to its own run, which reports it. Contexts inside one
    another add up.

    Parameters
    ----------
    controllers : iterable of Controller
        The controllers whose steps the job will run, each with its nominal model.
    n, m : int
        The plant's numbers of coordinates and inputs.
    plants : iterable of ELPlant, optional
        Plants (of ``n`` coordinates and ``m`` inputs) whose integrators later runs will need,
        under the built-in delay profiles.
    values : iterable of Reference or DelayProfile, optional
        References and delay profiles whose values the job asks for from Python at many times
        (:meth:`~delaytrack.references.Reference.evaluate`,
        :meth:`~delaytrack.delays.DelayProfile.h`; a simulation does for a reference when its
        first run stops early).

    Returns
    -------
    context manager

    Examples
    --------
    >>> from delaytrack.sim import compile_ahead, simulate
    >>> with compile_ahead([arolc, outer_loop], plant.n, plant.m):  # doctest: +SKIP
    ...     first = simulate(plant, arolc, delay, x0, **settings)
    ...     second = simulate(plant, outer_loop, delay, x0, **settings)
    """
    steps = [
        (
            controller_step_name(c),
            controller_step_part(c.engine_kernel, c.model.engine_kernel, n, m),
        )
        for c in controllers
    ]
    integrators = [
        (plant_integrator_name(plant), plant_tick_part(plant.engine_kernel, NO_KERNEL, n, m))
        for plant in plants
    ]
    evaluations = [part for part in map(values_ahead, values) if part is not None]
    return ahead([*steps, *integrators, *evaluations])
