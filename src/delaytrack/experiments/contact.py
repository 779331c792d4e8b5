"""The paper's robot experiment with contact physics beside the analytic robot: wheel slip, and
what contacts change in the tracking error and the control effort.

The analytic robot (:class:`~delaytrack.plants.robot.PayloadRobot`) rolls without slipping by
construction: its velocities satisfy the constraints ``Λ(q) q̇ = 0`` (no sideways motion of the
axle, each wheel rolling). On the robot with real wheels
(:class:`~delaytrack.plants.robot.MujocoWheeledRobot`) friction contacts hold the wheels, and the
residual of the same constraints is the **wheel slip**: row 1 of ``Λ q̇`` is the axle's
sideways velocity, rows 2 and 3 each wheel's rim speed minus its ground speed (m/s). The
robot starts at full speed at the height where its wheels just touch the floor, and settles onto
its contacts in the first tens of milliseconds, slipping; slip is measured after
:data:`SETTLING_S`.

The numbers the report quotes are :class:`ContactFindings` (:func:`contact_findings`); the
sentences are :func:`delaytrack.report.contact.contact_paragraphs`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from delaytrack.plants.robot import P3DX
from delaytrack.plants.robot.kinematics import constraint_residual
from delaytrack.plants.robot.reference import CIRCLE_RADIUS, CIRCLE_RATE
from delaytrack.sim import SimResult

__all__ = [
    "SETTLING_S",
    "SLIP_COLUMNS",
    "ContactChange",
    "ContactFindings",
    "ContactRun",
    "Ranking",
    "comparison",
    "contact_findings",
    "wheel_slip",
]

#: Seconds at the start of a run left out of the slip (the robot settling onto its contacts).
SETTLING_S = 0.5
#: Wheel slip of a run (mm/s): RMS of the axle's sideways velocity, RMS of the wheels'
#: rim-minus-ground speed (both wheels), and the largest of them all.
SLIP_COLUMNS = ["slip_sideways_rms_mm_s", "slip_rolling_rms_mm_s", "slip_max_mm_s"]


def wheel_slip(result: SimResult) -> np.ndarray:
    """:data:`SLIP_COLUMNS` (batch, 3) of robot runs, from ``Λ(q) q̇`` (module docstring) at
    every recorded state from :data:`SETTLING_S` on, before the run stopped (P3-DX geometry)."""
    residual = 1e3 * constraint_residual(result.x, P3DX.wheel_radius, P3DX.half_track, P3DX.d)
    slip = np.full((result.batch_size, len(SLIP_COLUMNS)), np.nan)
    for i in range(result.batch_size):
        kept = np.all(np.isfinite(residual[i]), axis=1) & (result.t >= SETTLING_S)
        if kept.any():
            run = residual[i][kept]
            slip[i] = [
                np.sqrt(np.mean(run[:, 0] ** 2)),
                np.sqrt(np.mean(run[:, 1:] ** 2)),
                np.abs(run).max(),
            ]
    return slip


def comparison(analytic: pd.DataFrame, contact: pd.DataFrame) -> pd.DataFrame:
    """Per (scenario, controller): AE of x and y (mm) and TV (N·m) on each robot, their change
    with contacts (%), and the wheel slip; ``contact`` has the summary columns plus
    :data:`SLIP_COLUMNS`.

    The changes are ``100 ((AE-x' + AE-y') / (AE-x + AE-y) − 1)`` and ``100 (TV' / TV − 1)``,
    primed on the robot with real wheels.
    """
    both = analytic.merge(contact, on=["scenario", "controller"], suffixes=("", "_contact"))
    table = pd.DataFrame(
        {
            "scenario": both["scenario"],
            "controller": both["controller"],
            "ae_x_mm": both["ae_x_mm"],
            "ae_x_contact_mm": both["ae_x_mm_contact"],
            "ae_y_mm": both["ae_y_mm"],
            "ae_y_contact_mm": both["ae_y_mm_contact"],
            "change_ae_pct": 100.0
            * (
                (both["ae_x_mm_contact"] + both["ae_y_mm_contact"])
                / (both["ae_x_mm"] + both["ae_y_mm"])
                - 1.0
            ),
            "tv_Nm": both["tv_Nm"],
            "tv_contact_Nm": both["tv_Nm_contact"],
            "change_tv_pct": 100.0 * (both["tv_Nm_contact"] / both["tv_Nm"] - 1.0),
        }
    )
    for column in SLIP_COLUMNS:
        table[column] = both[column]
    return table


@dataclass(frozen=True)
class ContactChange:
    """What contact physics changed in the runs that stayed on the path on both robots, at one
    contact time constant.

    Attributes
    ----------
    time_constant : float
        MuJoCo's contact time constant of the runs (s).
    runs : int
        Runs on the path on both robots.
    ae, tv : tuple of float
        Smallest, largest and median change (%) of the mean absolute error (x and y together)
        and of the control effort TV (:func:`comparison`).
    """

    time_constant: float
    runs: int
    ae: tuple[float, float, float]
    tv: tuple[float, float, float]


@dataclass(frozen=True)
class ContactRun:
    """One run on both robots: AE of x and y (mm) and TV (N·m), analytic then with contacts."""

    scenario: str
    controller: str
    ae_x_mm: float
    ae_x_contact_mm: float
    ae_y_mm: float
    ae_y_contact_mm: float
    tv_Nm: float
    tv_contact_Nm: float


@dataclass(frozen=True)
class Ranking:
    """A scenario's controllers ordered by error (AE-x + AE-y, smallest first) on each robot."""

    scenario: str
    analytic: tuple[str, ...]
    contact: tuple[str, ...]


@dataclass(frozen=True)
class ContactFindings:
    """Every number the report's contact findings quote (:func:`contact_findings`).

    Attributes
    ----------
    time_constant : float
        The main runs' contact time constant (s): the first of the table's.
    main : ContactChange or None
        The main runs that stayed on the path on both robots; None when none did (then the
        slip ranges, ``largest_slip`` and ``largest_change`` are None and ``rankings`` empty).
    sideways_slip, rolling_slip : tuple of float or None
        Smallest and largest, over those runs, of the RMS sideways slip of the axle and of the
        RMS rolling slip of the wheels (mm/s).
    largest_slip : float or None
        The largest slip of any of those runs (mm/s).
    largest_change : ContactRun or None
        The run whose error changed most (in absolute value).
    rankings : tuple of Ranking
        Per scenario, in name order.
    same_rankings : int
        Scenarios whose ranking is the same on both robots.
    others : tuple of ContactChange
        The other time constants, in the table's order (those with a run on the path on both
        robots).
    lost : dict
        Where the main runs that left the path (or diverged) did: ``"analytic"`` (on the
        analytic robot only), ``"contact"`` (with contacts only), ``"both"`` -> their
        ``(scenario, controller)``.
    circle_speed : float
        The speed along the consistent circle (mm/s), beside which the slip is read.
    """

    time_constant: float
    main: ContactChange | None
    sideways_slip: tuple[float, float] | None
    rolling_slip: tuple[float, float] | None
    largest_slip: float | None
    largest_change: ContactRun | None
    rankings: tuple[Ranking, ...]
    same_rankings: int
    others: tuple[ContactChange, ...]
    lost: dict[str, tuple[tuple[str, str], ...]]
    circle_speed: float = 1e3 * CIRCLE_RADIUS * CIRCLE_RATE


def _change(runs: pd.DataFrame, time_constant: float) -> ContactChange:
    ae, tv = runs["change_ae_pct"], runs["change_tv_pct"]
    return ContactChange(
        time_constant=float(time_constant),
        runs=len(runs),
        ae=(float(ae.min()), float(ae.max()), float(ae.median())),
        tv=(float(tv.min()), float(tv.max()), float(tv.median())),
    )


def _order(runs: pd.DataFrame, ae_x: str, ae_y: str) -> tuple[str, ...]:
    error = dict(zip(runs["controller"], runs[ae_x] + runs[ae_y], strict=True))
    return tuple(sorted(error, key=error.__getitem__))


def _range(column: pd.Series) -> tuple[float, float]:
    return float(column.min()), float(column.max())


def contact_findings(table: pd.DataFrame) -> ContactFindings:
    """What contacts changed, from ``table`` (:func:`comparison`, with a column
    ``contact_time_constant_s``: the first time constant's runs are the main ones, the others
    how much the contacts' softness matters)."""
    constants = list(dict.fromkeys(table["contact_time_constant_s"]))
    main = table[table["contact_time_constant_s"] == constants[0]]
    both = main.dropna(subset=["change_ae_pct", "change_tv_pct"])
    rankings = tuple(
        Ranking(
            scenario=scenario,
            analytic=_order(cases, "ae_x_mm", "ae_y_mm"),
            contact=_order(cases, "ae_x_contact_mm", "ae_y_contact_mm"),
        )
        for scenario, cases in both.groupby("scenario", sort=True)
    )
    others = []
    for constant in constants[1:]:
        other = table[table["contact_time_constant_s"] == constant].dropna(
            subset=["change_ae_pct", "change_tv_pct"]
        )
        if len(other):
            others.append(_change(other, constant))
    largest = both.loc[both["change_ae_pct"].abs().idxmax()] if len(both) else None
    return ContactFindings(
        time_constant=float(constants[0]),
        main=_change(both, constants[0]) if len(both) else None,
        sideways_slip=_range(both["slip_sideways_rms_mm_s"]) if len(both) else None,
        rolling_slip=_range(both["slip_rolling_rms_mm_s"]) if len(both) else None,
        largest_slip=float(both["slip_max_mm_s"].max()) if len(both) else None,
        largest_change=None
        if largest is None
        else ContactRun(**{name: largest[name] for name in ContactRun.__dataclass_fields__}),
        rankings=rankings,
        same_rankings=sum(ranking.analytic == ranking.contact for ranking in rankings),
        others=tuple(others),
        lost=_lost(main),
    )


def _lost(runs: pd.DataFrame) -> dict[str, tuple[tuple[str, str], ...]]:
    """:attr:`ContactFindings.lost` of ``runs`` (a run off the path has no AE)."""
    analytic = runs[["ae_x_mm", "ae_y_mm"]].isna().any(axis=1)
    contact = runs[["ae_x_contact_mm", "ae_y_contact_mm"]].isna().any(axis=1)
    where = {
        "analytic": analytic & ~contact,
        "contact": contact & ~analytic,
        "both": analytic & contact,
    }
    return {
        name: tuple((r.scenario, r.controller) for r in runs[mask].itertuples())
        for name, mask in where.items()
        if mask.any()
    }
