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
from typing import Any

from delaytrack._compile.native_parts import (
    controller_step_name,
    controller_step_part,
    plant_integrator_name,
    plant_tick_part,
)
from delaytrack.delays._kernel import NO_KERNEL

__all__ = ["ahead", "compile_ahead", "parts_ahead"]

#: Parts a caller will need after the next first compile, as ``(name, part)`` pairs
#: (:func:`ahead`).
_AHEAD: contextvars.ContextVar[tuple] = contextvars.ContextVar("compile_ahead", default=())


@contextlib.contextmanager
def ahead(parts: Sequence[tuple[str, Any]]) -> Iterator[None]:
    """Within this context, a first compile also compiles ``parts`` (``(name, part)`` pairs of
    :class:`~delaytrack._compile.native_parts.NativePart` objects that are not compiled yet; a
    part given twice is kept once), shared with the same helper process; with those of the
    contexts around it."""
    distinct = {part: name for name, part in (*_AHEAD.get(), *parts)}
    token = _AHEAD.set(tuple((name, part) for part, name in distinct.items()))
    try:
        yield
    finally:
        _AHEAD.reset(token)


def parts_ahead() -> tuple:
    """The ``(name, part)`` pairs of :func:`ahead`, or none outside it."""
    return _AHEAD.get()


def compile_ahead(
    controllers: Iterable[Any], n: int, m: int, plants: Iterable[Any] = ()
) -> contextlib.AbstractContextManager[None]:
    """A context within which the first :func:`~delaytrack.sim.simulate` call that compiles
    anything also compiles the steps of ``controllers`` and the integrators of ``plants``.

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
    return ahead([*steps, *integrators])
