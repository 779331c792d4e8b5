"""Controllers' steps compiled ahead of the runs that need them: :func:`compile_ahead`.

The compile machinery defines it (:mod:`delaytrack._compile.ahead`); a study reaches it here,
beside :func:`~delaytrack.sim.simulate`, whose first compile it widens.
"""

from delaytrack._compile.ahead import compile_ahead

__all__ = ["compile_ahead"]
