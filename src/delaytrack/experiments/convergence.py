"""The dt-halving check of the experiments: rerun with dt / 2 and compare every metric (its
report section: :mod:`delaytrack.report.dt_check`).

The results must not hinge on the plant step; halving dt (T_c unchanged) may move no
summary metric by more than 1 %.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import pandas as pd

from delaytrack._deprecated import moved_names
from delaytrack.experiments.relative_change import relative_difference

__all__ = ["DT_TOLERANCE", "DtCheck", "dt_check_table", "dt_check_verdict", "largest_change"]

#: Its report section now lives with the reports.
__getattr__ = moved_names(__name__, {"write_dt_check": "delaytrack.report.dt_check:write_dt_check"})

#: Largest accepted relative change of a metric when dt is halved.
DT_TOLERANCE = 0.01


def dt_check_table(
    coarse: pd.DataFrame, fine: pd.DataFrame, metrics: Sequence[str]
) -> pd.DataFrame:
    """``fine`` (the dt / 2 metrics) with the largest relative change per run against ``coarse``."""
    table = fine.copy()
    table["max_relative_change"] = relative_difference(coarse, fine, list(metrics)).max(axis=1)
    return table


def largest_change(dt_check: pd.DataFrame | None) -> float:
    """Largest relative change of any metric (NaN when the check was not run)."""
    if dt_check is None:
        return math.nan
    return float(dt_check["max_relative_change"].max())


@dataclass(frozen=True, eq=False)
class DtCheck:
    """The dt-halving check and its verdict against :data:`DT_TOLERANCE`.

    Attributes
    ----------
    table : DataFrame
        :func:`dt_check_table`: the metrics at dt / 2 and each run's largest relative change.
    tolerance : float
        :data:`DT_TOLERANCE`.
    """

    table: pd.DataFrame
    tolerance: float = DT_TOLERANCE

    @property
    def largest(self) -> float:
        """The largest relative change of any metric of any run."""
        return largest_change(self.table)

    @property
    def above(self) -> pd.DataFrame:
        """The rows of ``table`` whose largest change is at or above the tolerance."""
        return self.table[self.table.max_relative_change >= self.tolerance]

    @property
    def within_tolerance(self) -> bool:
        """Whether every metric moved by less than the tolerance."""
        return self.largest < self.tolerance


def dt_check_verdict(dt_check: pd.DataFrame | None) -> DtCheck | None:
    """The :class:`DtCheck` of a :func:`dt_check_table` (None when the check was not run)."""
    return None if dt_check is None else DtCheck(dt_check)
