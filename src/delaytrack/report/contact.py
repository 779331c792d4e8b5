"""The paper job's report section "With contact physics": the runs on the robot with real
wheels beside the analytic robot's, in sentences and a table.

Every number comes from the study (:class:`~delaytrack.experiments.contact.ContactFindings`
and the comparison table of :mod:`delaytrack.experiments.contact`); nothing is computed here.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from delaytrack.experiments.contact import SETTLING_S
from delaytrack.experiments.paper_setup import CONTACT_TIME_CONSTANTS, DT
from delaytrack.report.html import HtmlReport

if TYPE_CHECKING:
    from delaytrack.experiments.contact import ContactChange, ContactFindings
    from delaytrack.experiments.paper import PaperStudy

__all__ = ["contact_paragraphs", "write_contact_section"]

#: The columns of the section's table and their headings.
_COLUMNS = {
    "scenario": "scenario",
    "controller": "controller",
    "ae_x_mm": "AE-x mm",
    "ae_x_contact_mm": "AE-x contact mm",
    "ae_y_mm": "AE-y mm",
    "ae_y_contact_mm": "AE-y contact mm",
    "change_ae_pct": "AE change %",
    "tv_Nm": "TV N·m",
    "tv_contact_Nm": "TV contact N·m",
    "change_tv_pct": "TV change %",
    "slip_sideways_rms_mm_s": "sideways slip RMS mm/s",
    "slip_rolling_rms_mm_s": "rolling slip RMS mm/s",
}


def _percent(value: float) -> str:
    """A change in percent with its sign: whole percent from 10 % on, one decimal below (a
    decrease of 0.3 % is not written "+0 %"); a change that rounds to nothing is "0 %"."""
    value = float(value)
    if abs(value) >= 9.95:
        return f"{round(value):+d} %"
    if round(value, 1) == 0:
        return "0 %"
    return f"{value:+.1f} %"


def _changes(change: ContactChange) -> str:
    (ae_min, ae_max, ae_median), (tv_min, tv_max, tv_median) = change.ae, change.tv
    return (
        f"the mean absolute error (x and y together) by {_percent(ae_min)} to "
        f"{_percent(ae_max)} (median {_percent(ae_median)}) and the control effort TV by "
        f"{_percent(tv_min)} to {_percent(tv_max)} (median {_percent(tv_median)})"
    )


def _rankings(findings: ContactFindings) -> str:
    parts = [
        f"{r.scenario}: {' < '.join(r.analytic)} on both"
        if r.analytic == r.contact
        else f"{r.scenario}: {' < '.join(r.analytic)} on the analytic robot, "
        f"{' < '.join(r.contact)} with contacts"
        for r in findings.rankings
    ]
    return (
        f"Ordered by error, the controllers rank the same on both robots in "
        f"{findings.same_rankings} of {len(parts)} scenarios ({'; '.join(parts)})."
    )


def contact_paragraphs(findings: ContactFindings) -> list[str]:
    """What contacts changed, in sentences whose numbers all come from ``findings``."""
    text = []
    main = findings.main
    if main is not None:
        text.append(
            f"In the {main.runs} runs that stayed on the path on both robots, contact physics "
            f"(contact time constant {1e3 * main.time_constant:g} ms) changed {_changes(main)}."
        )
        sideways, rolling = findings.sideways_slip, findings.rolling_slip
        assert sideways is not None and rolling is not None  # set whenever main is
        text.append(
            "The wheels slip: the axle's sideways velocity has an RMS of "
            f"{sideways[0]:.2g}–{sideways[1]:.2g} mm/s, the wheels' rim speed differs from their "
            f"ground speed by an RMS of {rolling[0]:.2g}–{rolling[1]:.2g} mm/s, at most "
            f"{findings.largest_slip:.3g} mm/s in any run (the robot drives at "
            f"{findings.circle_speed:.3g} mm/s; "
            f"after the first {SETTLING_S:g} s, in which the robot, started at speed, settles "
            "onto its contacts)."
        )
        largest = findings.largest_change
        assert largest is not None  # set whenever main is
        text.append(
            f"The largest change is {largest.controller}'s in {largest.scenario}: AE-x "
            f"{largest.ae_x_mm:.3g} → {largest.ae_x_contact_mm:.3g} mm, AE-y "
            f"{largest.ae_y_mm:.3g} → {largest.ae_y_contact_mm:.3g} mm, TV "
            f"{largest.tv_Nm:.3g} → {largest.tv_contact_Nm:.3g} N·m."
        )
        text.append(_rankings(findings))
    for other in findings.others:
        text.append(
            f"With a contact time constant of {1e3 * other.time_constant:g} ms instead of "
            f"{1e3 * findings.time_constant:g} ms (shorter is stiffer), contact physics "
            f"changed {_changes(other)} ({other.runs} runs on the path on both robots; "
            "summary_contact.csv has them)."
        )
    where = {
        "analytic": "on the analytic robot only",
        "contact": "with contacts only",
        "both": "on both robots",
    }
    if findings.lost:
        text.append(
            "Left the path "
            + "; ".join(
                f"{where[name]}: "
                + ", ".join(f"{scenario} {controller}" for scenario, controller in runs)
                for name, runs in findings.lost.items()
            )
            + "."
        )
    return text


def write_contact_section(report: HtmlReport, study: PaperStudy) -> None:
    """The section "With contact physics" of the paper job's report (consistent path only)."""
    if study.reference != "consistent":
        return
    report.heading("With contact physics")
    findings = study.findings
    if study.contact is None:
        report.paragraph(
            "Not run: skipped on request (delaytrack reproduce --no-contact)."
            if findings.mujoco_installed
            else "Not run: this section needs MuJoCo (pip install -e '.[mujoco]' from a clone "
            "of delaytrack), which steps a model of the robot with real wheels.",
            note=True,
        )
        return
    report.paragraph(
        "Every run above again, on the robot with real wheels: a MuJoCo model of the P3-DX "
        "(delaytrack/data/p3dx.xml: the same masses, inertias, geometry and wheel friction as "
        "the analytic robot) whose wheels roll on the floor through friction contacts "
        f"(friction coefficient {findings.floor_friction:g}; MuJoCo's soft contacts, with its "
        f"default time constant of {1e3 * CONTACT_TIME_CONSTANTS[0]:g} ms, and again at "
        f"{', '.join(f'{1e3 * value:g}' for value in CONTACT_TIME_CONSTANTS[1:])} ms to see "
        "what their softness does) and whose platform rests on ball "
        "casters, with the same payload put on and taken off at run time. MuJoCo steps it at "
        f"dt = {1e3 * DT:g} ms (its implicitfast integrator); the controllers, gains, delays "
        "and payload seed are unchanged. The analytic robot cannot slip; here the wheels can, "
        "the platform pitches and rolls on its contacts, and the wheels' dry friction acts "
        "as MuJoCo's friction loss instead of a smoothed Coulomb law."
    )
    assert findings.contact is not None  # the findings hold one whenever the contact runs ran
    for text in contact_paragraphs(findings.contact):
        report.paragraph(text)
    main = study.contact[study.contact.contact_time_constant_s == CONTACT_TIME_CONSTANTS[0]]
    report.table(
        main[list(_COLUMNS)].rename(columns=_COLUMNS),
        "summary_contact.csv: each run on the analytic robot and with contacts (time constant "
        f"{1e3 * CONTACT_TIME_CONSTANTS[0]:g} ms; AE of x and y together for the change); slip "
        "from the residual of the rolling constraints; —: the run left the path.",
    )
