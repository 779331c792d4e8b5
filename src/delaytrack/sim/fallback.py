"""The message shown when a simulation cannot run compiled."""

from __future__ import annotations

import sys
import warnings
from types import FrameType
from typing import Any

#: This package's name: frames of its modules are not the user's.
_PACKAGE = __name__.partition(".")[0]

__all__ = ["PythonFallbackWarning"]


class PythonFallbackWarning(UserWarning):
    """The closed loop runs as plain Python (a plant or model given as Python callables).

    Results are the same as compiled (to rounding), but each run is one to two orders of
    magnitude slower. Write the plant's terms as a numba-compiled function and wrap it in
    :class:`~delaytrack.plants.CompiledPlant` to run at the built-in plants' speed.
    """

    @classmethod
    def warn(cls, plant: Any, controller: Any, reference: Any) -> None:
        """Issue :meth:`describe`'s warning at the user's line: the first caller outside this
        package (``simulate`` may be reached through a scenario, a sweep or the command line)."""
        frame = sys._getframe(1)  # stack level 2 (level 1 is this method)
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
            return cls(
                f"simulate() runs as plain Python because the {' and the '.join(slow)} "
                "is given as Python callables (about 100x slower than compiled). For compiled "
                "speed, write terms(t, q, qdot, params, M, N, G) with @numba.njit and wrap it in "
                "delaytrack.plants.CompiledPlant (see docs/performance.md)."
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


def _in_package(frame: FrameType) -> bool:
    """Whether ``frame`` runs code of one of this package's modules."""
    return frame.f_globals.get("__name__", "").partition(".")[0] == _PACKAGE
