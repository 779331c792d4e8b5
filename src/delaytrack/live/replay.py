"""``delaytrack live replay DIR``: re-simulate a live session with its realised delays.

The sim-to-real check of the delay model. The robot node logged, for every change of the
command in force, the step ``a_i`` from which command ``k_i`` (sample time ``t_{k_i}``) was
applied (``applied.csv``). The replay turns these into a :class:`~delaytrack.delays.TraceDelay`
with knots ``(a_i, a_i - t_{k_i} - ε)``: between two knots ``t - h(t)`` runs linearly from
``t_{k_i}`` to ``t_{k_{i+1}}`` (plus ``ε``), so the simulator's rule (the latest command with
``t_k <= t - h(t)``) switches to command ``k_{i+1}`` at ``a_{i+1} - ε``, where the robot
switched (``ε = 10⁻⁶ dt`` keeps the switch clear of rounding); from the session's start to the
first knot, while ``u_init`` is applied, the first knot's delay. Lost packets are lost again with
the same seed (:class:`~delaytrack.sim.packet_loss.PacketLoss`), so the held commands agree.
The controller reads the state through the measurement noise the live controller applied
(``measurement_noise`` in ``controller.json``: the scenario's, or none when the session turned it
off); the noise is indexed by the controller tick, so the replay's tick ``k`` adds the noise the
live tick ``k`` added, also where the live controller computed on a state older than ``t_k``.

It then simulates the scenario (same plant, controller, reference, ``x0``, input limits) for the
session's duration, rounded down to a whole number of ``T_c``, and compares, at every controller
tick of the live session, the tracking errors ``e1 = q_d - q`` and the commands: max and RMS of
live minus replayed, against the RMS of the live tracking error, and the first time the
difference in tracking error exceeds 10 % of that RMS. What the simulation cannot reproduce is
listed with the result: zero input the robot applied on its safety timeout, ticks the controller
missed, states older than ``t_k`` that it computed on.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from delaytrack._io import json_text, write_text
from delaytrack.live._node import session_files
from delaytrack.live._tables import (
    RowsByIndex,
    SessionColumns,
    SessionTable,
    check_nodes_ran,
    check_tables_whole,
    json_table,
    read_table,
    session_columns,
)
from delaytrack.live.log import write_csv
from delaytrack.live.report import (
    format_agreement,
    not_reproduced_text,
    ticks_compared_text,
    write_report,
)
from delaytrack.live.transport import scenario_hashes
from delaytrack.warning import one_line

if TYPE_CHECKING:
    from delaytrack.delays import TraceDelay
    from delaytrack.scenario import BuiltScenario, Scenario
    from delaytrack.sim.result import SimResult

__all__ = ["replay", "replay_main"]


def replay(folder: str | Path, trust: list[str] | None = None) -> dict[str, Any]:
    """Re-simulate the session in ``folder``; write ``replay.csv`` and ``replay.json`` there and
    return the agreement (module docstring)."""
    return _replay(folder, trust)[0]


def _replay(folder: str | Path, trust: list[str] | None = None) -> tuple[dict[str, Any], Any, Any]:
    """:func:`replay`'s agreement, the scenario and the replayed :class:`SimResult`."""
    from delaytrack.scenario import Scenario

    folder = Path(folder)
    # A session folder may come from someone else: code beside its scenario is not trusted
    # for being there (the nodes name their factories by absolute path).
    scenario = Scenario.from_toml(
        folder / "scenario.toml", trust=list(trust or []), trust_its_folder=False
    )
    built = scenario.build()
    nodes = _session_nodes(folder / "summary.json")
    check_nodes_ran(
        folder,
        nodes,
        scenario_hashes(scenario, built.plant),
        f"{folder / 'scenario.toml'}",
        "the session folder's scenario.toml was changed after the session; the replay needs "
        "the scenario the nodes ran",
    )
    check_tables_whole(folder, nodes)
    robot, delay_node = nodes.get("robot") or {}, nodes.get("delay") or {}
    controller_node = nodes.get("controller") or {}
    t1 = _replayed_duration(folder, scenario.dt, scenario.T_c)
    trace = _realised_delay(folder, scenario.dt)
    columns = session_columns(built.plant)
    states = read_table(folder / "states.csv", None, indices=("j",)).required()
    ticks = read_table(folder / "ticks.csv", None, indices=("k",), texts=("status",)).required()
    # A session folder from before the controller measured recorded no noise: it read the truth.
    noise_spec = controller_node.get("measurement_noise")
    result = _resimulate(scenario, built, trace, t1, delay_node, noise_spec)
    compared = _compare(scenario, result, states, columns, ticks)
    stopped = result.status_names[0] != "ok"
    report = {
        "ticks_compared": len(compared.rows),
        "t1_s": t1,
        "status": result.status_names[0],
        "replay_stopped_at_s": float(result.t_stop[0]) if stopped else None,
        **_agreement(compared, columns),
        "measurement_noise": noise_spec,
        "not_reproduced": _not_reproduced(robot, controller_node, ticks),
    }
    _write_replay(folder, columns, compared.rows, report)
    return report, scenario, result


def _session_nodes(path: Path) -> dict[str, Any]:
    """The ``nodes`` of the session's ``summary.json`` (a table of tables), or a ValueError
    naming the file."""
    nodes = json_table(path, "session summary").get("nodes")
    if not isinstance(nodes, dict) or not all(isinstance(v, dict | None) for v in nodes.values()):
        raise ValueError(
            f"{path} is not a session summary: it needs a table 'nodes' of the nodes' tables "
            "(as delaytrack live run and live collect write it)"
        )
    return nodes


def _replayed_duration(folder: Path, dt: float, T_c: float) -> float:
    """``t1``: the session's duration rounded down to a whole number of ``T_c``, at least two."""
    end = read_table(folder / "steps.csv").required().rows * dt
    n_ticks = int(math.floor(end / T_c + 1e-9))
    if n_ticks < 2:
        raise ValueError(f"{folder}: the session is shorter than two controller periods")
    return n_ticks * T_c


def _realised_delay(folder: Path, dt: float) -> TraceDelay:
    """The delay the robot realised (``applied.csv``), as a trace (module docstring)."""
    from delaytrack.delays import TraceDelay

    path = folder / "applied.csv"
    columns = ("applied_s", "t_k_s")
    applied = read_table(path, columns)
    if not applied.rows:
        raise ValueError(f"{folder}: the robot applied no command; nothing to replay")
    epsilon = 1e-6 * dt
    numbers = applied.at(columns)
    bad = np.flatnonzero(~np.isfinite(numbers).all(axis=1))
    if bad.size:  # line 1 is the header
        raise ValueError(f"{path}, line {bad[0] + 2}: {columns} must be finite times in seconds")
    times = numbers[:, 0] - epsilon
    values = np.maximum(times - numbers[:, 1], 0.0)
    if times[0] > 0.0:  # before the first command arrived (u_init applied): its delay, held
        times, values = np.r_[0.0, times], np.r_[values[0], values]
    return TraceDelay(times, values, beyond="hold", source=str(folder / "applied.csv"))


def _resimulate(
    scenario: Scenario,
    built: BuiltScenario,
    trace: TraceDelay,
    t1: float,
    delay_node: dict[str, Any],
    noise_spec: dict[str, Any] | None,
) -> SimResult:
    """The scenario simulated to ``t1`` under the realised delay, with the session's packet
    loss and measurement noise."""
    from delaytrack.sim import simulate
    from delaytrack.sim.certified_bound import stated_by_the_caller
    from delaytrack.sim.measurement import MeasurementNoise
    from delaytrack.sim.packet_loss import PacketLoss

    loss_spec = delay_node.get("packet_loss") or {"probability": 0.0, "seed": 0}
    loss = PacketLoss(loss_spec["probability"], int(loss_spec["seed"]))
    with stated_by_the_caller():  # the session as it ran, beyond h_m or not
        return simulate(
            built.plant,
            built.controller,
            trace,
            built.x0,
            reference=built.reference,
            t1=t1,
            dt=scenario.dt,
            T_c=scenario.T_c,
            u_init=scenario.simulated_u_init,
            input_limits=scenario.simulated_input_limits,
            packet_loss=loss if loss.probability > 0 else None,
            measurement_noise=None if noise_spec is None else MeasurementNoise(**noise_spec),
        )


@dataclass(frozen=True)
class _Compared:
    """The live and replayed tracking errors and commands at the compared ticks (their
    differences computed once, for the summary and the per-coordinate table)."""

    #: The rows of ``replay.csv``: ``k``, ``t``, live and replayed ``e1``, live and replayed
    #: command.
    rows: list[list[Any]]
    live_errors: np.ndarray
    replayed_errors: np.ndarray
    live_commands: np.ndarray
    replayed_commands: np.ndarray

    @cached_property
    def error_differences(self) -> np.ndarray:
        """Live minus replayed tracking error, ``(ticks, n)``."""
        return self.live_errors - self.replayed_errors

    @cached_property
    def command_differences(self) -> np.ndarray:
        """Live minus replayed command, ``(ticks, m)``."""
        return self.live_commands - self.replayed_commands

    @cached_property
    def relative_rms(self) -> np.ndarray:
        """Each coordinate's RMS difference against its own live RMS error, in its own unit
        (metres and radians are not added)."""
        return _rms(self.error_differences) / _rms(self.live_errors)


def _compare(
    scenario: Scenario,
    result: SimResult,
    states: SessionTable,
    columns: SessionColumns,
    ticks: SessionTable,
) -> _Compared:
    """The live session against the replay at every tick with a logged state (a state or tick
    logged twice: its last row) that the replay reached (a replay that stopped, diverged or
    off the path, has no numbers after it: the live ticks after it are not compared)."""
    k = np.rint(result.t / scenario.T_c).astype(np.int64)
    state_rows = RowsByIndex(states["j"]).find(k * round(scenario.T_c / scenario.dt))
    compared = (state_rows >= 0) & ~np.isnan(result.e1[0]).any(axis=1)
    positions = columns.in_table(states, "positions")
    live_errors = result.reference[compared, 0] - states.at(positions, state_rows[compared])
    tick_rows = RowsByIndex(ticks["k"]).find(k[compared])
    live_commands = ticks.at(columns.in_table(ticks, "inputs"), tick_rows)
    replayed_errors, replayed_commands = result.e1[0][compared], result.commands[0][compared]
    side_by_side = np.hstack([live_errors, replayed_errors, live_commands, replayed_commands])
    rows = [
        [k_i, t_i, *row]
        for k_i, t_i, row in zip(
            k[compared].tolist(), result.t[compared].tolist(), side_by_side.tolist(), strict=True
        )
    ]
    return _Compared(rows, live_errors, replayed_errors, live_commands, replayed_commands)


def _agreement(compared: _Compared, columns: SessionColumns) -> dict[str, Any]:
    """How far live and replay differ: the worst coordinate's relative RMS (the headline),
    when and from when the tracking errors differ, and each coordinate's and input's numbers."""
    de, relative_each = compared.error_differences, compared.relative_rms
    times_compared = np.array([r[1] for r in compared.rows])
    beyond = np.nonzero(np.nanmax(np.abs(de) / _rms(compared.live_errors), axis=1) > 0.1)[0]
    worst = int(np.nanargmax(np.nanmax(np.abs(de), axis=1)))
    return {
        "error_difference_rms_relative": float(np.nanmax(relative_each)),
        "worst_coordinate": columns.names[int(np.nanargmax(relative_each))],
        "error_difference_max_at_s": float(times_compared[worst]),
        "diverges_from_s": float(times_compared[beyond[0]]) if beyond.size else None,
        "coordinates": _coordinates_agreement(compared, columns),
        "inputs": _inputs_agreement(compared, columns),
    }


def _coordinates_agreement(
    compared: _Compared, columns: SessionColumns
) -> dict[str, dict[str, Any]]:
    """Per coordinate: its unit, the live and replayed RMS tracking errors, and the max, RMS
    and relative RMS of their difference."""
    de, relative_each = compared.error_differences, compared.relative_rms
    rms_live_each, rms_replayed_each = _rms(compared.live_errors), _rms(compared.replayed_errors)
    rms_difference_each = _rms(de)
    return {
        name: {
            "unit": columns.coordinate_units[i] or "",
            "tracking_error_rms_live": float(rms_live_each[i]),
            "tracking_error_rms_replayed": float(rms_replayed_each[i]),
            "error_difference_max": float(np.nanmax(np.abs(de[:, i]))),
            "error_difference_rms": float(rms_difference_each[i]),
            "error_difference_rms_relative": float(relative_each[i]),
        }
        for i, name in enumerate(columns.names)
    }


def _inputs_agreement(compared: _Compared, columns: SessionColumns) -> dict[str, dict[str, Any]]:
    """Per input: its unit, and the max and RMS of live minus replayed command."""
    du = compared.command_differences
    rms_command_difference = _rms(du)
    return {
        f"u{j + 1}": {
            "unit": unit or "",
            "command_difference_max": float(np.nanmax(np.abs(du[:, j]))),
            "command_difference_rms": float(rms_command_difference[j]),
        }
        for j, unit in enumerate(columns.input_units)
    }


def _not_reproduced(
    robot: dict[str, Any], controller_node: dict[str, Any], ticks: SessionTable
) -> dict[str, Any]:
    """What the simulation cannot reproduce: the robot's zero input on timeout, the ticks the
    controller missed or computed without a state, on a stale one or one older than ``t_k``
    (a tick logged twice counted once, by its last row; a session from before the controller
    logged the state's age counts none older)."""
    rows = RowsByIndex(ticks["k"]).rows
    age = ticks.columns.get("state_age_ms", np.full(ticks.rows, np.nan))
    return {
        "robot_zero_input_on_timeout_steps": robot.get("timeout_zero_steps"),
        "controller_missed_ticks": controller_node.get("missed"),
        "controller_ticks_without_a_state": int(np.sum(ticks["status"][rows] == "no-state")),
        "controller_stale_ticks": controller_node.get("stale"),
        "controller_ticks_on_a_state_older_than_t_k": int(np.sum(age[rows] > 1e-6)),
    }


def _write_replay(
    folder: Path, columns: SessionColumns, rows: list[list[Any]], report: dict[str, Any]
) -> None:
    """``replay.csv`` (live beside replayed, tick by tick) and ``replay.json`` (the report)."""
    header = [
        "k",
        "t_s",
        *columns.errors("live"),
        *columns.errors("replay"),
        *columns.inputs("live"),
        *columns.inputs("replay"),
    ]
    write_csv(folder / "replay.csv", header, rows)
    write_text(folder / "replay.json", json_text(report, indent=1) + "\n")


def _rms(values: np.ndarray) -> np.ndarray:
    """The RMS of each column, over the rows where it is a number."""
    return np.sqrt(np.nanmean(values**2, axis=0))


def replay_main(args: Any) -> int:
    """The ``live replay`` command."""
    from delaytrack._output import record_outputs
    from delaytrack.scenario import ScenarioError

    folder = Path(args.folder)
    if not folder.is_dir():
        what = "is not a folder" if folder.exists() else "does not exist"
        print(f"error: {folder} {what}: give the folder of a live session", file=sys.stderr)
        return 2
    if not (folder / "summary.json").is_file():
        print(
            f"error: {folder} is not a live session folder (no summary.json; write one with "
            "delaytrack live run, or with delaytrack live collect DIR SCENARIO for nodes started "
            "one by one)",
            file=sys.stderr,
        )
        return 2
    try:
        report, scenario, replayed = _replay(folder, args.trust)
    except (ScenarioError, ValueError) as error:
        print(one_line(f"error: {error}"), file=sys.stderr)
        return 2
    # The session's report again, with the replayed run beside the live one.
    report_failed, note = write_report(folder, scenario, replayed=replayed, agreement=report)
    record_outputs(folder, session_files(folder))
    print(
        "\n".join(
            [
                f"replay of {folder} ({ticks_compared_text(report)}): live - replayed "
                "tracking error RMS at most "
                f"{100 * report['error_difference_rms_relative']:.2f} % of the live RMS "
                f"({report['worst_coordinate']})",
                *(f"  {line}" for line in format_agreement(report)),
                f"  not reproduced by the simulation: {not_reproduced_text(report)}",
                *([] if note is None else [f"note: {note}"]),
            ]
        )
    )
    return 1 if report_failed else 0
