"""The plain-Python engine: the message shown when a simulation cannot run compiled, and the
user's kernels as it runs them."""

from __future__ import annotations

import dataclasses
import sys
import time
import warnings
from types import FrameType
from typing import Any

from delaytrack._user_calls import named_errors
from delaytrack.components import Kernel, ReducedForm
from delaytrack.warning import DelaytrackWarning

#: This package's name: frames of its modules are not the user's.
_PACKAGE = __name__.partition(".")[0]

__all__ = ["OutOfTime", "PythonFallbackWarning", "python_kernel", "stepped_until"]


class PythonFallbackWarning(DelaytrackWarning):
    """The closed loop runs as plain Python (a plant or model given as Python callables).

    Results are the same as compiled (to rounding), but each run is one to two orders of
    magnitude slower. Write the plant's terms as a numba-compiled function and wrap it in
    :class:`~delaytrack.plants.CompiledPlant` to run at the built-in plants' speed.
    """

    @classmethod
    def warn(cls, plant: Any, controller: Any, reference: Any) -> None:
        """Issue :meth:`describe`'s warning at the user's line: the first caller outside this
        package (``simulate`` may be reached through a scenario, a sweep or the command line)."""
        frame: FrameType | None = sys._getframe(1)  # stack level 2 (level 1 is this method)
        level = 2
        while frame is not None and _in_package(frame):
            frame = frame.f_back
            level += 1
        warnings.warn(cls.describe(plant, controller, reference), stacklevel=level)

    @classmethod
    def describe(cls, plant: Any, controller: Any, reference: Any) -> PythonFallbackWarning:
        slow = [
            f"{role} {type(item).__name__}"
            for role, item in (("plant", plant), ("nominal model", controller.model))
            if not item.compiled
        ]
        if slow:
            verb = "are" if len(slow) > 1 else "is"
            return cls(
                f"simulate() runs as plain Python because the {' and the '.join(slow)} {verb} "
                "given as Python callables (about 100x slower than compiled). For compiled "
                "speed, write terms(t, q, qdot, params, M, N, G) with @numba.njit and wrap it in "
                "delaytrack.plants.CompiledPlant (the documentation's page 'Your own robot')."
            )
        what = (
            f"the reference kernel of {type(reference).__name__}"
            if not reference.compiled
            else f"the step of the controller {type(controller).__name__}"
        )
        return cls(
            f"simulate() runs as plain Python because {what} is not numba-compiled (about 100x "
            "slower than compiled). For compiled speed, decorate it with @numba.njit."
        )


def python_kernel(kernel: Kernel) -> Kernel:
    """``kernel`` as the plain-Python engine runs it (:meth:`Kernel.as_python`), its functions
    of the user's with what they raise during the run in one line naming them
    (:func:`~delaytrack._user_calls.named_errors`, as the compiled engine names a kernel that
    raised). This package's kernels are left as they are: a
    :class:`~delaytrack.plants.CallablePlant`'s names the user's functions it calls itself."""
    python = kernel.as_python()
    reduced = python.reduced

    def named(function: Any, timed: bool) -> Any:
        if function is None or Kernel(function).built_in:
            return function
        return named_errors(function, f"your kernel {Kernel(function).callable_names[0]}", timed)

    return Kernel(
        named(python.function, timed=True),
        named(python.command_map, timed=False),  # command_map(q, params, tau, command)
        python.identity_mass,
        python.sizes,
        named(python.stepper, timed=True),
        None
        if reduced is None
        else ReducedForm(
            named(reduced.velocity_map, timed=False),
            named(reduced.dynamics, timed=True),
            reduced.size,
        ),
    )


class OutOfTime(Exception):  # noqa: N818 - a signal between two parts, not an error
    """A run given a deadline (:func:`stepped_until`) was still going at it."""


def stepped_until(kernel: Kernel, deadline: float) -> Kernel:
    """The plain-Python ``kernel`` (a plant's, called at every stage of every plant step, or a
    controller's step, called once a tick) with each of its functions the engine calls during
    the run raising :class:`OutOfTime` instead of running after ``deadline``
    (:func:`time.perf_counter`'s seconds): a run interpreted first
    (:mod:`delaytrack._compile.interpret_first`) is abandoned, and compiled, when it takes
    longer than compiling it would."""

    def until(function: Any) -> Any:
        if function is None:
            return None

        def before_the_deadline(*arguments: Any) -> Any:
            if time.perf_counter() > deadline:
                raise OutOfTime
            return function(*arguments)

        return before_the_deadline

    reduced = kernel.reduced
    return dataclasses.replace(
        kernel,
        function=until(kernel.function),
        stepper=until(kernel.stepper),
        reduced=None
        if reduced is None
        else dataclasses.replace(reduced, dynamics=until(reduced.dynamics)),
    )


def _in_package(frame: FrameType) -> bool:
    """Whether ``frame`` runs code of one of this package's modules."""
    return frame.f_globals.get("__name__", "").partition(".")[0] == _PACKAGE
