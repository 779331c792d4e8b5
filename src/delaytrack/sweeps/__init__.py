"""Sweeps: many runs of a scenario over a grid and seeded random draws, in resumable work units.

- :mod:`delaytrack.sweeps.spec`: :class:`SweepSpec` (a sweep file: base scenario, ``[grid]``,
  ``[random]``, ``unit_size``), its runs and its hashed :class:`Unit`\\ s.
- :mod:`delaytrack.sweeps.parts`: :func:`run_unit` (one unit with the batched engine),
  :func:`write_part` (one atomic Parquet part per unit) and :func:`finished_units` (resume).
- :mod:`delaytrack.sweeps.executors`: where units run (:class:`LocalExecutor`, all local cores;
  :class:`DaskExecutor`, a ``dask.distributed`` cluster).
- :mod:`delaytrack.sweeps.runner`: :func:`run_sweep` (the units not done yet, a progress bar,
  Ctrl-C safe) and :class:`SweepOutcome`.
- :mod:`delaytrack.sweeps.summary`: the summary table per controller × delay class and the
  facts a sweep's report states; :mod:`delaytrack.report.sweep` writes the summary, figures and
  the HTML report (:func:`~delaytrack.report.sweep.write_sweep_outputs`).
"""

from delaytrack._deprecated import moved_names
from delaytrack.sweeps.executors import DaskExecutor, LocalExecutor, make_executor
from delaytrack.sweeps.parts import PartsScan, finished_units, run_unit, write_part
from delaytrack.sweeps.runner import SweepInterrupted, SweepOutcome, SweepUnitsFailed, run_sweep
from delaytrack.sweeps.spec import DISTRIBUTIONS, Run, SweepError, SweepSpec, Unit
from delaytrack.sweeps.summary import summary_table

__all__ = [
    "DISTRIBUTIONS",
    "DaskExecutor",
    "LocalExecutor",
    "PartsScan",
    "Run",
    "SweepError",
    "SweepInterrupted",
    "SweepOutcome",
    "SweepSpec",
    "SweepUnitsFailed",
    "Unit",
    "finished_units",
    "make_executor",
    "run_sweep",
    "run_unit",
    "summary_table",
    "write_part",
]

#: A sweep's report is :mod:`delaytrack.report.sweep`'s (a report, above the sweeps).
__getattr__ = moved_names(
    __name__, {"write_sweep_outputs": "delaytrack.report.sweep:write_sweep_outputs"}
)
