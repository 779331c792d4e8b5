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
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from delaytrack.plants.robot import P3DX
from delaytrack.plants.robot.kinematics import constraint_residual
from delaytrack.sim import SimResult

__all__ = ["SETTLING_S", "SLIP_COLUMNS", "comparison", "contact_findings", "wheel_slip"]

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
    :data:`SLIP_COLUMNS`."""
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
            "tv": both["tv"],
            "tv_contact": both["tv_contact"],
            "change_tv_pct": 100.0 * (both["tv_contact"] / both["tv"] - 1.0),
        }
    )
    for column in SLIP_COLUMNS:
        table[column] = both[column]
    return table


def _span(values: pd.Series, unit: str, digits: int = 0) -> str:
    return f"{values.min():+.{digits}f} to {values.max():+.{digits}f} {unit}"


def contact_findings(table: pd.DataFrame) -> list[str]:
    """What contacts changed, in sentences whose numbers all come from ``table``
    (:func:`comparison`)."""
    both = table.dropna(subset=["change_ae_pct", "change_tv_pct"])
    lost = table[table["change_ae_pct"].isna()]
    text = []
    if len(both):
        text.append(
            f"In the {len(both)} runs that stayed on the path on both robots, contact physics "
            f"changed the mean absolute error (x and y together) by "
            f"{_span(both['change_ae_pct'], '%')} (median {both['change_ae_pct'].median():+.0f} "
            f"%) and the control effort TV by {_span(both['change_tv_pct'], '%')} (median "
            f"{both['change_tv_pct'].median():+.0f} %)."
        )
        text.append(
            "The wheels slip: the axle's sideways velocity has an RMS of "
            f"{both['slip_sideways_rms_mm_s'].min():.2g}–{both['slip_sideways_rms_mm_s'].max():.2g}"
            " mm/s, the wheels' rim speed differs from their ground speed by an RMS of "
            f"{both['slip_rolling_rms_mm_s'].min():.2g}–{both['slip_rolling_rms_mm_s'].max():.2g}"
            f" mm/s, at most {both['slip_max_mm_s'].max():.3g} mm/s in any run (the robot "
            f"drives at about 400 mm/s; after the first {SETTLING_S:g} s, in which the robot, "
            "started at speed, settles onto its contacts)."
        )
        largest = both.loc[both["change_ae_pct"].abs().idxmax()]
        text.append(
            f"The largest change is {largest['controller']}'s in {largest['scenario']}: AE-x "
            f"{largest['ae_x_mm']:.3g} → {largest['ae_x_contact_mm']:.3g} mm, AE-y "
            f"{largest['ae_y_mm']:.3g} → {largest['ae_y_contact_mm']:.3g} mm, TV "
            f"{largest['tv']:.3g} → {largest['tv_contact']:.3g} N·m."
        )
        ranking = []
        for scenario, runs in both.groupby("scenario", sort=True):
            ae = dict(
                zip(
                    runs["controller"],
                    runs["ae_x_mm"] + runs["ae_y_mm"],
                    strict=True,
                )
            )
            ae_contact = dict(
                zip(
                    runs["controller"],
                    runs["ae_x_contact_mm"] + runs["ae_y_contact_mm"],
                    strict=True,
                )
            )
            order = sorted(ae, key=ae.get)
            order_contact = sorted(ae_contact, key=ae_contact.get)
            ranking.append((scenario, order == order_contact, " < ".join(order_contact)))
        same = [scenario for scenario, kept, _ in ranking if kept]
        text.append(
            f"Ordered by error, the controllers rank the same on both robots in {len(same)} of "
            f"{len(ranking)} scenarios ("
            + "; ".join(f"{scenario}: {order}" for scenario, _, order in ranking)
            + ", with contacts)."
        )
    if len(lost):
        text.append(
            "Left the path on one of the robots: "
            + ", ".join(f"{r.scenario} {r.controller}" for r in lost.itertuples())
            + "."
        )
    return text
