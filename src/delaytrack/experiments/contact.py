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


def _percent(value: float) -> str:
    return f"{round(float(value)):+d} %"  # rounded first: no "-0 %"


def _changes(runs: pd.DataFrame) -> str:
    ae, tv = runs["change_ae_pct"], runs["change_tv_pct"]
    return (
        f"the mean absolute error (x and y together) by {_percent(ae.min())} to "
        f"{_percent(ae.max())} (median {_percent(ae.median())}) and the control effort TV by "
        f"{_percent(tv.min())} to {_percent(tv.max())} (median {_percent(tv.median())})"
    )


def _order(runs: pd.DataFrame, ae_x: str, ae_y: str) -> list[str]:
    error = dict(zip(runs["controller"], runs[ae_x] + runs[ae_y], strict=True))
    return sorted(error, key=error.get)


def _rankings(runs: pd.DataFrame) -> str:
    parts, same = [], 0
    for scenario, cases in runs.groupby("scenario", sort=True):
        analytic = _order(cases, "ae_x_mm", "ae_y_mm")
        contact = _order(cases, "ae_x_contact_mm", "ae_y_contact_mm")
        if analytic == contact:
            same += 1
            parts.append(f"{scenario}: {' < '.join(analytic)} on both")
        else:
            parts.append(
                f"{scenario}: {' < '.join(analytic)} on the analytic robot, "
                f"{' < '.join(contact)} with contacts"
            )
    return (
        f"Ordered by error, the controllers rank the same on both robots in {same} of "
        f"{len(parts)} scenarios ({'; '.join(parts)})."
    )


def contact_findings(table: pd.DataFrame) -> list[str]:
    """What contacts changed, in sentences whose numbers all come from ``table``
    (:func:`comparison`, with a column ``contact_time_constant_s``: the first time constant's
    runs are the main ones, the others how much the contacts' softness matters)."""
    constants = list(dict.fromkeys(table["contact_time_constant_s"]))
    main = table[table["contact_time_constant_s"] == constants[0]]
    both = main.dropna(subset=["change_ae_pct", "change_tv_pct"])
    lost = main[main["change_ae_pct"].isna()]
    text = []
    if len(both):
        text.append(
            f"In the {len(both)} runs that stayed on the path on both robots, contact physics "
            f"(contact time constant {1e3 * constants[0]:g} ms) changed {_changes(both)}."
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
        text.append(_rankings(both))
    for constant in constants[1:]:
        other = table[table["contact_time_constant_s"] == constant].dropna(
            subset=["change_ae_pct", "change_tv_pct"]
        )
        if len(other):
            text.append(
                f"With a contact time constant of {1e3 * constant:g} ms instead of "
                f"{1e3 * constants[0]:g} ms (shorter is stiffer), contact physics "
                f"changed {_changes(other)} ({len(other)} runs on the path on both robots; "
                "summary_contact.csv has them)."
            )
    if len(lost):
        text.append(
            "Left the path on one of the robots: "
            + ", ".join(f"{r.scenario} {r.controller}" for r in lost.itertuples())
            + "."
        )
    return text
