"""Sweeps: many runs of a scenario over a grid and seeded random draws, in resumable work units.

- :mod:`delaytrack.sweeps.spec`: :class:`SweepSpec` (a sweep file: base scenario, ``[grid]``,
  ``[random]``, ``unit_size``), its runs and its hashed :class:`Unit`\\ s.
- :mod:`delaytrack.sweeps.parts`: :func:`run_unit` (one unit with the batched engine),
  :func:`write_part` (one atomic Parquet part per unit) and :func:`finished_units` (resume).
"""

from delaytrack.sweeps.parts import PartsScan, finished_units, run_unit, write_part
from delaytrack.sweeps.spec import DISTRIBUTIONS, Run, SweepError, SweepSpec, Unit

__all__ = [
    "DISTRIBUTIONS",
    "PartsScan",
    "Run",
    "SweepError",
    "SweepSpec",
    "Unit",
    "finished_units",
    "run_unit",
    "write_part",
]
