"""The paper's experiment (the paper's Section III): the PIONEER-3 robot with payload under S1–S4.

:func:`run_study` runs it and returns a :class:`PaperStudy` that holds every number its report
quotes (:class:`~delaytrack.experiments.paper_findings.PaperFindings`);
:func:`delaytrack.jobs.paper.run_paper` runs it and writes the report
(:mod:`delaytrack.report.paper`) to ``<out_dir>/``:

- ``summary.csv``: one row per (scenario, controller) with the columns of
  :data:`SUMMARY_COLUMNS` (AE, %AE, RMS and max error of x and y in mm, TV of the commanded wheel
  torques in N·m), then ``status`` and ``t_stop_s`` (the time the run stopped, s); runs that
  diverged or left the path have empty metrics, their ``status`` says why (and the report
  flags them);
- ``summary_tuned_arolc.csv``: the same columns for AROLC tuned by the baselines' procedure
  (controller ``AROLC-tuned``; :mod:`delaytrack.experiments.tuning`);
- ``tables.md``: the paper's Tables I–III with our numbers beside the paper's;
- ``dt_check.csv``: the metrics with ``dt`` halved and the largest relative change per run;
- ``summary_contact.csv`` (consistent path, with MuJoCo installed): every run again on the robot
  with real wheels (:class:`~delaytrack.plants.robot.MujocoWheeledRobot`, the same payload), its
  AE and TV beside the analytic robot's and its wheel slip (:mod:`delaytrack.experiments.contact`);
- ``figures/*.png|svg``: the S1 x–y path of each controller, |e_x| and |e_y| over time (S1, S2 and
  S3, S4), ĉ(t) and h(t);
- ``report.html``: self-contained; every modelling decision, the tables, the claims check, the
  dt-halving check and the figures.

Set-up (:mod:`delaytrack.experiments.paper_setup`; the decisions are stated again in the report):

- **Truth plant**: :class:`~delaytrack.plants.robot.PayloadRobot` with the robot package's
  defaults (P3-DX parameters, wheel friction) and the paper's payload (3.5 kg, 5 s on / 5 s off, a
  random point of the top plate) with ONE payload seed, :data:`PAYLOAD_SEED`, shared by
  every controller and scenario, so every controller faces the same disturbance.
- **Nominal model** of every controller: :class:`~delaytrack.plants.robot.NominalRobot` (no
  payload, no friction), commands ``τ_w = S(q)ᵀ τ``.
- **Controllers**: AROLC with the paper's gains, the plain outer loop (AROLC without Δu), PCON
  (S1, S2; given the true delay) and PCONf (S3, S4; ``h̄`` = the scenario's delay) with the gains
  of ``delaytrack/data/baseline_gains.toml`` (:mod:`delaytrack.experiments.tuning`), and
  ``AROLC-tuned``: AROLC with the gains the same procedure chose for it (same file; reported
  separately, not certified by Theorem 1 for S1–S4).
- **Settings**: 60 s, ``dt`` = 1 ms, ``T_c`` = 10 ms (none of them is in the paper).
- **Left the path**: the engine's rule (:data:`ERROR_BOUND`): a run whose x or y error exceeds
  10 m stops there with status ``left the path``, its metrics NaN.

Each controller kind runs its four scenarios as one batched simulation (PCON and PCONf share a
kernel, so the baselines are one batch too).
"""

from __future__ import annotations

import contextlib
import importlib.util
import time
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from delaytrack._deprecated import moved_names
from delaytrack.analysis import RazumikhinBound, razumikhin_bound
from delaytrack.controllers import AROLC, OuterLoop
from delaytrack.experiments import tuning
from delaytrack.experiments.contact import SLIP_COLUMNS, comparison, wheel_slip
from delaytrack.experiments.convergence import (
    DtCheck,
    dt_check_table,
    dt_check_verdict,
    largest_change,
)
from delaytrack.experiments.pairing import AROLC_GAINS, BASELINE, DELAY_CLASS
from delaytrack.experiments.paper_findings import (
    PaperFindings,
    claims,
    paper_findings,
    tuned_as_arolc,
)
from delaytrack.experiments.paper_setup import (
    BETA,
    CONTACT_TIME_CONSTANTS,
    DIAMETER_MM,
    DT,
    DURATION,
    ERROR_BOUND,
    METRICS,
    PAPER_TABLE,
    PAYLOAD_SEED,
    SCENARIOS,
    SUMMARY_COLUMNS,
    T_C,
    TUNED,
    R,
    controller_name,
)
from delaytrack.metrics import (
    max_abs_error,
    mean_absolute_error,
    percent_of,
    rms_error,
    total_variation,
)
from delaytrack.plants import ELPlant
from delaytrack.plants.mujoco import import_mujoco
from delaytrack.plants.robot import (
    MujocoWheeledRobot,
    NominalRobot,
    PayloadRobot,
    initial_state,
    paper_reference,
)
from delaytrack.sim import SimResult, compile_ahead, simulate
from delaytrack.sim.certified_bound import stated_by_the_caller

__all__ = [
    "ERROR_BOUND",
    "PAPER_TABLE",
    "PAYLOAD_SEED",
    "SCENARIOS",
    "SUMMARY_COLUMNS",
    "TUNED",
    "PaperFindings",
    "PaperStudy",
    "claims",
    "contact_ahead",
    "run_study",
    "with_tuned_arolc",
]

#: Running the study and writing its report is a job (:mod:`delaytrack.jobs.paper`).
__getattr__ = moved_names(
    __name__,
    {
        "run_paper": "delaytrack.jobs.paper:run_paper",
        "reproduce": "delaytrack.jobs.paper:reproduce",
        "write_study": "delaytrack.report.paper:write_study",
    },
)


@dataclass(frozen=True)
class PaperStudy:
    """Everything :func:`run_study` computed.

    Attributes
    ----------
    reference : str
        ``"consistent"`` or ``"literal"``.
    results : dict
        ``kind -> SimResult`` batched over :data:`SCENARIOS` (kinds ``AROLC``, ``baseline``,
        ``OuterLoop``; element ``i`` is the ``i``-th scenario).
    summary : DataFrame
        :data:`SUMMARY_COLUMNS`, one row per (scenario, controller).
    status : DataFrame
        ``scenario, controller, status, t_stop`` of every run.
    dt_check : DataFrame or None
        Metrics at ``dt/2`` with the largest relative change per run.
    gains : dict
        The chosen gains as read from the gains file (:func:`tuning.load_gains`: kind -> gain
        set -> gains).
    tuning_record : mapping
        The whole gains file (:func:`tuning.load_tuning_record`), read once.
    tuned_summary : DataFrame
        :data:`SUMMARY_COLUMNS` for the tuned AROLC (controller ``AROLC-tuned``; the gain set
        of each scenario's delay class).
    contact : DataFrame or None
        Every run on the robot with real wheels beside the analytic robot
        (:func:`~delaytrack.experiments.contact.comparison`); None when not run.
    bound : RazumikhinBound
    findings : PaperFindings
        Every other number the report quotes.
    duration, seconds : float
        Simulated seconds per run; wall time of the simulations.
    """

    reference: str
    results: dict[str, SimResult]
    summary: pd.DataFrame
    status: pd.DataFrame
    dt_check: pd.DataFrame | None
    gains: dict[str, dict[str, dict[str, float]]]
    tuning_record: Mapping[str, Any]
    bound: RazumikhinBound
    tuned_summary: pd.DataFrame
    contact: pd.DataFrame | None
    findings: PaperFindings
    duration: float
    seconds: float

    def run(self, scenario: str, kind: str) -> SimResult:
        """One run: ``kind`` is ``AROLC``, ``OuterLoop``, ``baseline``, ``PCON`` or ``PCONf``."""
        kind = "baseline" if kind in ("PCON", "PCONf") else kind
        return self.results[kind][list(SCENARIOS).index(scenario)]

    @property
    def dt_max_change(self) -> float:
        """Largest relative change of any metric when ``dt`` is halved (NaN if not checked)."""
        return largest_change(self.dt_check)

    @property
    def dt_verdict(self) -> DtCheck | None:
        """The dt-halving check's verdict (None if not checked)."""
        return dt_check_verdict(self.dt_check)


def _controllers(gains: dict[str, dict[str, dict[str, float]]], reference: str) -> dict[str, list]:
    nominal = NominalRobot()
    baselines, tuned = [], []
    for scenario, delay in SCENARIOS.items():
        kind, gain_set = BASELINE[scenario], DELAY_CLASS[scenario]
        h_bar = float(delay.h_max) if kind == "PCONf" else None
        baselines.append(
            tuning.make_controller(kind, gains[kind][gain_set], h_bar=h_bar, reference=reference)
        )
        tuned.append(tuning.make_controller("AROLC", gains["AROLC"][gain_set]))
    return {
        "AROLC": [AROLC(nominal, **AROLC_GAINS)],
        "baseline": baselines,
        "OuterLoop": [OuterLoop(nominal, K1=AROLC_GAINS["K1"], K2=AROLC_GAINS["K2"])],
        TUNED: tuned,
    }


def _summary(results: dict[str, SimResult]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The summary rows (NaN metrics for a run that did not finish) and every run's status."""
    rows, status = [], []
    for kind, result in results.items():
        ae = 1e3 * mean_absolute_error(result)[:, :2]
        rms = 1e3 * rms_error(result)[:, :2]
        peak = 1e3 * max_abs_error(result)[:, :2]
        tv = total_variation(result)
        for i, scenario in enumerate(SCENARIOS):
            name = controller_name(scenario, kind)
            rows.append(
                {
                    "scenario": scenario,
                    "controller": name,
                    "ae_x_mm": ae[i, 0],
                    "ae_y_mm": ae[i, 1],
                    "pct_ae_x": percent_of(ae[i, 0], DIAMETER_MM),
                    "pct_ae_y": percent_of(ae[i, 1], DIAMETER_MM),
                    "tv_Nm": tv[i],
                    "rms_x_mm": rms[i, 0],
                    "rms_y_mm": rms[i, 1],
                    "max_x_mm": peak[i, 0],
                    "max_y_mm": peak[i, 1],
                }
            )
            status.append(
                {
                    "scenario": scenario,
                    "controller": name,
                    "status": result.status_names[i],
                    "t_stop": float(result.t_stop[i]),
                }
            )
    order = {"AROLC": 0, TUNED: 0, "PCON": 1, "PCONf": 1, "OuterLoop": 2}

    def sort(frame: pd.DataFrame) -> pd.DataFrame:
        keys = frame["scenario"] + frame["controller"].map(order).astype(str)
        return frame.iloc[np.argsort(keys.to_numpy(), kind="stable")].reset_index(drop=True)

    return sort(pd.DataFrame(rows, columns=SUMMARY_COLUMNS)), sort(pd.DataFrame(status))


def _simulate_all(
    controllers: dict[str, list],
    reference: str,
    duration: float,
    dt: float,
    bar: tqdm,
    plant: ELPlant | None = None,
) -> dict[str, SimResult]:
    ref = paper_reference(reference)
    x0 = initial_state(ref)
    if plant is None:
        plant = PayloadRobot(seed=PAYLOAD_SEED, duration=max(duration, DURATION))
    results = {}
    # Every controller's step is compiled with the first run that compiles anything (and its
    # helper), not one by one before each controller's run; so are the functions that give the
    # reference's values where a run stopped early and the delays the findings sample.
    every = [c for batch in controllers.values() for c in batch]
    with compile_ahead(every, plant.n, plant.m, values=(ref, *SCENARIOS.values())):
        for kind, batch in controllers.items():
            bar.set_postfix_str(f"{kind}, {type(plant).__name__}, dt = {dt:g} s")
            with stated_by_the_caller():  # the paper's report states h_m
                results[kind] = simulate(
                    plant,
                    batch,
                    list(SCENARIOS.values()),
                    x0,
                    reference=ref,
                    t1=duration,
                    dt=dt,
                    T_c=T_C,
                    error_bound=ERROR_BOUND,
                )
            bar.update()
    return results


def _contact_table(
    analytic: pd.DataFrame, wheels: dict[float, dict[str, SimResult]]
) -> pd.DataFrame:
    """The runs on the robot with real wheels (per contact time constant) beside the analytic
    robot's, with wheel slip."""
    tables = []
    for time_constant, results in wheels.items():
        rows = []
        for kind, result in results.items():
            for scenario, slip in zip(SCENARIOS, wheel_slip(result), strict=True):
                row = {"scenario": scenario, "controller": controller_name(scenario, kind)}
                rows.append(row | dict(zip(SLIP_COLUMNS, slip, strict=True)))
        contact, _ = _summary(results)
        table = comparison(
            analytic, contact.merge(pd.DataFrame(rows), on=["scenario", "controller"])
        )
        table.insert(2, "contact_time_constant_s", time_constant)
        tables.append(table)
    return pd.concat(tables, ignore_index=True)


def contact_ahead(
    duration: float = DURATION, contact: bool | None = None
) -> contextlib.AbstractContextManager[None]:
    """A context within which the next first compile also compiles the integrator of the robot
    with real wheels (:func:`~delaytrack.sim.compile_ahead`), when the consistent run will run
    on it (``contact``, or by default when MuJoCo is installed): a job that runs the literal
    run first then compiles it on both cores with that run's parts, instead of alone later."""
    if not _with_contact("consistent", contact, _mujoco_installed(contact)):
        return contextlib.nullcontext()
    # one integrator serves every contact time constant (they are parameters, not code)
    robot = _robot_with_wheels(duration, CONTACT_TIME_CONSTANTS[0])
    return compile_ahead([], robot.n, robot.m, plants=[robot])


#: The start of MuJoCo's warning of an unstable simulation, as a Python warning
#: (:func:`~delaytrack.plants.mujoco.plant.import_mujoco`).
_UNSTABLE = "MuJoCo: Nan, Inf or huge value"


def _robot_with_wheels(duration: float, time_constant: float) -> MujocoWheeledRobot:
    """The robot of the contact runs: the payload schedule of the analytic robot's runs, wheels
    on the floor with contacts of ``time_constant`` (s)."""
    return MujocoWheeledRobot(
        seed=PAYLOAD_SEED,
        duration=max(duration, DURATION),
        contact_time_constant=time_constant,
    )


def _with_contact(reference: str, contact: bool | None, mujoco_installed: bool) -> bool:
    """Whether the study on ``reference`` runs on the robot with real wheels: ``contact``, by
    default when MuJoCo is installed and the path is the consistent one."""
    if contact is None:
        return reference == "consistent" and mujoco_installed
    return contact


def _mujoco_installed(contact: bool | None) -> bool:
    """Whether MuJoCo is installed: importable, when whether the runs with real wheels run
    depends on it (``contact`` None); else found, for the report's note alone (without
    importing it, a tenth of a second)."""
    if contact is not None:
        return importlib.util.find_spec("mujoco") is not None
    try:
        import_mujoco()
    except ImportError:
        return False
    return True


def _split(
    summary: pd.DataFrame, status: pd.DataFrame
) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame]:
    """``summary.csv`` (without the tuned AROLC), every run's status, the tuned AROLC's rows."""
    tuned = summary.controller == TUNED
    return (
        summary[~tuned].reset_index(drop=True),
        status,
        summary[tuned].reset_index(drop=True),
    )


def _order_like(frame: pd.DataFrame, like: pd.DataFrame) -> pd.DataFrame:
    keys = frame.set_index(["scenario", "controller"])
    order = list(like[["scenario", "controller"]].itertuples(index=False, name=None))
    return keys.loc[order].reset_index()


def run_study(
    *,
    reference: str = "consistent",
    duration: float = DURATION,
    progress: bool = True,
    check_dt: bool = True,
    gains_path: tuning.GainsSource = None,
    contact: bool | None = None,
) -> PaperStudy:
    """Run S1–S4 for every controller (and again at ``dt/2`` if ``check_dt``; and on the
    robot with real wheels if ``contact``: by default when MuJoCo is installed and the path is
    the consistent one), and compute every number of the report."""
    mujoco_installed = _mujoco_installed(contact)
    contact = _with_contact(reference, contact, mujoco_installed)
    record = tuning.load_tuning_record(gains_path)
    gains = tuning.load_gains(record)
    controllers = _controllers(gains, reference)
    bound = razumikhin_bound(
        AROLC_GAINS["K1"], AROLC_GAINS["K2"], AROLC_GAINS["Q"], BETA, R, n=NominalRobot.n
    )
    steps = len(controllers) * (1 + int(check_dt) + len(CONTACT_TIME_CONSTANTS) * int(contact))
    start = time.perf_counter()
    with tqdm(total=steps, desc=f"paper ({reference})", unit="batch", disable=not progress) as bar:
        results = _simulate_all(controllers, reference, duration, DT, bar)
        halved = _simulate_all(controllers, reference, duration, DT / 2, bar) if check_dt else None
        wheels = {}
        with warnings.catch_warnings():
            # MuJoCo's word that a run became unstable: the run's status says so (it diverged
            # or left the path) and the report counts it; other MuJoCo warnings are shown.
            warnings.filterwarnings("ignore", _UNSTABLE, RuntimeWarning)
            for time_constant in CONTACT_TIME_CONSTANTS if contact else ():
                robot = _robot_with_wheels(duration, time_constant)
                wheels[time_constant] = _simulate_all(
                    controllers, reference, duration, DT, bar, plant=robot
                )
    seconds = time.perf_counter() - start
    analytic, status = _summary(results)
    summary, status, tuned_summary = _split(analytic, status)
    dt_check = None
    if halved is not None:
        fine, _ = _summary(halved)
        both = pd.concat([summary, tuned_summary], ignore_index=True)
        dt_check = dt_check_table(both, _order_like(fine, both), METRICS)
    contact_table = _contact_table(analytic, wheels) if wheels else None
    return PaperStudy(
        reference=reference,
        results=results,
        summary=summary,
        status=status,
        dt_check=dt_check,
        gains=gains,
        tuning_record=record,
        bound=bound,
        tuned_summary=tuned_summary,
        contact=contact_table,
        findings=paper_findings(
            reference=reference,
            duration=duration,
            results=results,
            summary=summary,
            status=status,
            tuned_summary=tuned_summary,
            gains=gains,
            record=record,
            bound=bound,
            dt_check=dt_check,
            contact=contact_table,
            mujoco_installed=mujoco_installed,
        ),
        duration=duration,
        seconds=seconds,
    )


def with_tuned_arolc(study: PaperStudy) -> pd.DataFrame:
    """``summary`` with the paper-gain AROLC rows replaced by the tuned AROLC's (named
    ``AROLC``), so that :func:`claims` checks the claims for the tuned AROLC.

    Deprecated (warns): use :func:`~delaytrack.experiments.paper_findings.tuned_as_arolc`
    ``(study.summary, study.tuned_summary)``; the claims it gives are
    ``study.findings.tuned_claims``.
    """
    warnings.warn(
        "delaytrack.experiments.paper.with_tuned_arolc is deprecated; use "
        "delaytrack.experiments.paper_findings.tuned_as_arolc(study.summary, "
        "study.tuned_summary) (the old name will be removed in a later release)",
        DeprecationWarning,
        stacklevel=2,
    )
    return tuned_as_arolc(study.summary, study.tuned_summary)
