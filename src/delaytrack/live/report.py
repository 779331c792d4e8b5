"""The report of a live session: ``metrics.csv``, figures and a self-contained ``report.html``.

``delaytrack live run`` writes them when the session ends, and ``delaytrack live replay``
writes them again with the replayed simulation beside the live one. The session's tracking is
turned into a :class:`~delaytrack.sim.SimResult` of one run (:func:`live_result`): the robot's
state and the reference at every controller tick ``t_k``, the command the controller sent at
``t_k`` and the command the robot held over the step that starts there, ``h(t_k)``. So the
tracking metrics are the simulator's (:func:`delaytrack.metrics.metrics_table`, every tick)
and the tracking figures the simulator's (:mod:`delaytrack.report.figures`); the live loop's
own figures show the realised delay against ``h(t)`` and the distributions of wake-up
lateness and compute time.

Files (in the session folder): ``metrics.csv`` (AE, RMS and max tracking error per coordinate
and the commands' total variation, with units in the column names, :mod:`delaytrack.units`),
``figures/{tracking,error,commands,delay,timing}.png`` and ``report.html``.
"""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from delaytrack._io import read_file_bytes
from delaytrack._validation import is_real_number
from delaytrack.live._tables import (
    RowsByIndex,
    json_table,
    ms,
    per_second,
    read_table,
    session_columns,
)
from delaytrack.units import coordinate_units, value_with_unit

__all__ = [
    "delay_node_text",
    "error_bound_text",
    "format_agreement",
    "lengths_text",
    "links_text",
    "live_result",
    "metrics_with_units",
    "node_lengths",
    "not_reproduced_text",
    "robot_stop",
    "ticks_compared_text",
    "write_report",
    "write_session_report",
]


def live_result(folder: str | Path, scenario: Any, built: Any) -> Any:
    """The session in ``folder`` as a :class:`~delaytrack.sim.SimResult` of one run, recorded
    at every controller tick (module docstring).

    A tick at which the controller sent nothing (no state yet) counts as the command in force
    from the controller's side: zero before the first command (the simulator's ``u_init``),
    else the last one sent; NaN throughout when the controller wrote no ``ticks.csv`` (it did
    not finish). ``settings["commands_between_t"]`` are the first and the last tick's times
    with a command (NaN without one): the commands' TV counts between them
    (:func:`metrics_with_units`; NaN when none was sent), not from zero before the first. A session
    whose robot state became non-finite has the status ``diverged``.
    """
    from delaytrack.sim.result import SimResult

    folder = Path(folder)
    plant, reference = built.plant, built.reference
    m = plant.m
    steps_per_tick = round(scenario.T_c / scenario.dt)
    columns = session_columns(plant)
    states = read_table(folder / "states.csv", None, indices=("j",))
    if not states.rows:
        raise ValueError(f"{folder}: the robot logged no state (states.csv)")
    ticks = read_table(folder / "ticks.csv", None, indices=("k",), texts=("status",))
    steps = read_table(folder / "steps.csv", None, indices=("j",), texts=("status",))
    logged = RowsByIndex(states["j"])  # a state logged twice: its last row
    at_tick = logged.indices % steps_per_tick == 0
    ks = logged.indices[at_tick] // steps_per_tick
    t = ks * scenario.T_c
    x = states.at(columns.in_table(states, "states"), logged.rows[at_tick])
    ref = np.stack(reference.evaluate(t), axis=1)  # (R, 3, n): q_d, q̇_d, q̈_d
    tick_rows = RowsByIndex(ticks["k"]).find(ks)
    sent = ticks.at(columns.in_table(ticks, "inputs"), tick_rows)
    # no ticks.csv (the controller did not finish): no command known, not zeros
    logged_ticks = (folder / "ticks.csv").exists()
    commands = np.zeros((t.size, m)) if logged_ticks else np.full((t.size, m), np.nan)
    last = np.zeros(m) if logged_ticks else np.full(m, np.nan)
    # the first and the last tick with a command: the TV counts between them
    first_sent = last_sent = math.nan
    for i in range(t.size):
        if np.all(np.isfinite(sent[i])):
            last = sent[i]
            first_sent = t[i] if math.isnan(first_sent) else first_sent
            last_sent = t[i]
        commands[i] = last
    step_rows = RowsByIndex(steps["j"]).find(ks * steps_per_tick)
    applied = steps.at(columns.in_table(steps, "inputs"), step_rows)
    finite = bool(np.all(np.isfinite(x)))
    return SimResult(
        t=t,
        x=x[None],
        reference=ref,
        commands=commands[None],
        applied=applied[None],
        h=np.asarray(built.delay.h(t), dtype=float)[None],
        controller_state=np.zeros((1, t.size, 0)),
        controller_state_names=(),
        status=np.array([0 if finite else 1]),
        t_stop=np.array([t[-1]]),
        settings={
            "dt": scenario.dt,
            "T_c": scenario.T_c,
            "record_every": 1,
            "commands_between_t": (first_sent, last_sent),
        },
        coordinate_names=plant.coordinate_names,
        coordinate_units=getattr(plant, "coordinate_units", None),
        input_units=getattr(plant, "input_units", None),
        input_names=getattr(plant, "input_names", None),
    )


def metrics_with_units(
    result: Any, label: str, commands_between: tuple[float, float] | None = None
) -> Any:
    """:func:`delaytrack.metrics.metrics_table` of ``result`` with each metric's unit in its
    column name (``ae_x_m``, ``rms_phi_rad``, ``tv_Nm`` when the inputs share a unit). With
    ``commands_between`` (the first and last times of a live session's commands,
    :func:`live_result`), the commands' TV over the ticks between them: the live controller's
    (from its first command, not from zero before it, to its last, at the tick before the end,
    where the simulator issues one more), and a replay's over the same ticks."""
    from delaytrack._result_columns import metric_columns_with_units
    from delaytrack.metrics import metrics_table

    table = metrics_table(result, label=label)
    if commands_between is not None:
        first, last = commands_between
        within = (result.t >= first - 1e-9) & (result.t <= last + 1e-9)
        variation = np.abs(np.diff(result.commands[:, within, :], axis=1)).sum(axis=(1, 2))
        table["tv"] = np.where(result.ok & within.any(), variation, math.nan)  # as metrics_table
    return table.rename(columns=metric_columns_with_units(result))


def _delay_figure(folder: Path, delay: Any, dt: float) -> Any:
    from matplotlib.figure import Figure

    columns = ("applied_s", "realised_delay_s", "realised_minus_h_ms")
    delays = read_table(folder / "delays.csv", columns)
    came = np.isfinite(delays["applied_s"])
    applied, realised, difference = (delays[column][came] for column in columns)
    figure = Figure(figsize=(8.0, 5.4), dpi=110, layout="constrained")
    top, bottom = figure.subplots(2, 1, sharex=True)
    if applied.size:
        grid = np.linspace(0.0, float(applied.max()), 2000)
        top.plot(grid, 1e3 * np.asarray(delay.h(grid)), color="black", lw=1.0, label="h(t)")
    top.plot(applied, 1e3 * realised, ".", ms=2.5, color="C1", label="realised delay")
    top.set_ylabel("delay (ms)")
    top.legend(loc="upper right", fontsize="small")
    top.set_title("Realised delay of each command (from the step it was applied) against h(t)")
    bottom.plot(applied, difference, ".", ms=2.5, color="C1")
    bottom.axhline(0.0, color="black", lw=0.8)
    bottom.axhline(1e3 * dt, color="grey", lw=0.8, ls=":", label="one robot step")
    bottom.set_ylabel("realised delay − h (ms)")
    bottom.set_xlabel("t (s)")
    bottom.legend(loc="upper right", fontsize="small")
    for ax in (top, bottom):
        ax.grid(True, alpha=0.3)
    return figure


def _histogram(ax: Any, values: np.ndarray, what: str) -> None:
    values = values[np.isfinite(values)]
    if values.size:
        ax.hist(values, bins=60, color="C0")
        p50, p99 = np.percentile(values, [50, 99])
        for value, style, name in ((p50, "--", "p50"), (p99, ":", "p99")):
            ax.axvline(value, color="black", ls=style, lw=1.0, label=f"{name} {value:.3f} ms")
        ax.set_yscale("log")
        ax.legend(loc="upper right", fontsize="small")
    ax.set_xlabel(f"{what} (ms)")
    ax.set_ylabel("count")
    ax.grid(True, alpha=0.3)


def _timing_figure(folder: Path) -> Any:
    from matplotlib.figure import Figure

    ticks = read_table(folder / "ticks.csv", ("lateness_ms", "compute_ms"))
    steps = read_table(folder / "steps.csv", ("lateness_ms",))
    figure = Figure(figsize=(8.0, 7.2), dpi=110, layout="constrained")
    axes = figure.subplots(3, 1)
    _histogram(
        axes[0],
        ticks["lateness_ms"],
        "controller wake-up lateness",
    )
    _histogram(axes[1], ticks["compute_ms"], "controller compute time")
    _histogram(axes[2], steps["lateness_ms"], "robot step lateness")
    figure.suptitle("Timing of the session's ticks and steps (counts on a log scale)")
    return figure


def write_session_report(
    folder: str | Path, scenario: Any, *, replayed: Any = None, agreement: Any = None
) -> tuple[list[Path], str | None]:
    """Write ``metrics.csv``, the figures and ``report.html`` of the session in ``folder``;
    return their paths and the report's note on the scenario's ``error_bound``
    (:func:`error_bound_text`; None when the error stayed within it). With ``replayed`` (the
    replay's :class:`~delaytrack.sim.SimResult`) and ``agreement`` (what
    :func:`~delaytrack.live.replay.replay` returns) the live and replayed runs are drawn and
    measured side by side."""
    from delaytrack._io import write_bytes, write_frame
    from delaytrack.report.figures import png_bytes

    folder = Path(folder)
    built = scenario.build()
    summary = json_table(folder / "summary.json", "session's summary")
    live = live_result(folder, scenario, built)
    runs = {"live": live} if replayed is None else {"live": live, "replayed": replayed}
    metrics = _metrics(runs)
    stop = robot_stop((summary.get("nodes") or {}).get("robot") or {})
    if stop is not None and stop[0] != "failed when closed":  # tracked up to where it stopped
        how, _ = stop
        status = "diverged" if how == "diverged" else "robot failed"
        metrics.loc[metrics["label"] == "live", "status"] = status
    paths = [write_frame(metrics, folder / "metrics.csv")]
    figures = _figures(folder, scenario, built, runs)
    # Each figure drawn once: the same PNG in figures/ and in the report.
    images = {name: (png_bytes(figure), caption) for name, (figure, caption) in figures.items()}
    for name, (data, _caption) in images.items():
        paths.append(write_bytes(folder / "figures" / f"{name}.png", data))
    beyond = error_bound_text(live, scenario, built.plant)
    report = _html_report(
        folder, scenario, summary, live, metrics, agreement, images.values(), beyond
    )
    paths.append(report.write(folder / "report.html"))
    return paths, beyond


def _metrics(runs: dict[str, Any]) -> Any:
    """:func:`metrics_with_units` of each run, labelled by its name, in one table; the
    commands' TV of each over the live controller's ticks."""
    import pandas as pd

    between = runs["live"].settings.get("commands_between_t")
    tables = [metrics_with_units(result, label, between) for label, result in runs.items()]
    return pd.concat(tables, ignore_index=True).drop(columns=["run"])


#: The report's figures, ``figures/<name>.png``, in their order.
FIGURES = ("tracking", "error", "commands", "delay", "timing")


def _figures(folder: Path, scenario: Any, built: Any, runs: dict[str, Any]) -> dict[str, Any]:
    """The report's figures, each with its caption: name (:data:`FIGURES`) -> (figure,
    caption)."""
    from delaytrack.report.figures import commands_figure, error_figure, tracking_figure

    figures = [
        (tracking_figure(runs), "Each coordinate against its reference q_d"),
        (error_figure(runs), "Absolute tracking error |q_d − q| at the ticks"),
        (
            commands_figure({"live": runs["live"]}),
            "Commands sent by the controller (solid) and held by the robot over the step after "
            "each tick (dashed)",
        ),
        (
            _delay_figure(folder, built.delay, scenario.dt),
            "Realised delay of each command against h(t), and their difference",
        ),
        (
            _timing_figure(folder),
            "Wake-up lateness and compute time of the controller, lateness of the robot's steps",
        ),
    ]
    return dict(zip(FIGURES, figures, strict=True))


def _html_report(
    folder: Path,
    scenario: Any,
    summary: dict[str, Any],
    live: Any,
    metrics: Any,
    agreement: Any,
    images: Iterable[tuple[bytes, str]],
    beyond: str | None,
) -> Any:
    """The session's ``report.html``, not yet written; ``images`` are the figures' PNGs and
    captions, ``beyond`` :func:`error_bound_text`."""
    from delaytrack.report.html import HtmlReport

    nodes = _node_records(summary)
    report = HtmlReport(f"delaytrack live session: {summary.get('scenario', scenario.name)}")
    report.paragraph(
        "The controller, delay and robot nodes ran as separate processes over Zenoh; the delay "
        "node applied the toolkit's rule (the robot applies the latest command whose sample time "
        "t_k satisfies t_k ≤ t − h(t)) on the robot's step grid. Timings depend on the load of "
        "the machine at the time."
    )
    report.settings(_session_settings(summary, scenario, live))
    report.heading("Timing and the delay rule")
    report.settings(_timing_settings(summary, scenario, *nodes))
    report.heading("Tracking")
    report.table(metrics, "Tracking metrics over every controller tick (metrics.csv)")
    if beyond is not None:
        report.paragraph(f"Note: {beyond}.", note=True)
    if agreement is not None:
        report.heading("Replay: the simulation with the realised delays")
        report.settings(_replay_settings(agreement))
    for data, caption in images:
        report.figure(data, caption)
    report.heading("Scenario")
    scenario_file = folder / "scenario.toml"
    if scenario_file.is_file():
        report.code(read_file_bytes(scenario_file, "scenario file").decode("utf-8", "replace"))
    return report


def _node_records(summary: dict[str, Any]) -> tuple[dict[str, Any], ...]:
    """The controller's, the robot's and the delay node's records in the summary ({} when
    absent)."""
    nodes = summary.get("nodes") or {}
    return tuple(nodes.get(role) or {} for role in ("controller", "robot", "delay"))


def robot_stop(robot: dict[str, Any]) -> tuple[str, str] | None:
    """How the robot node failed, from its record (``robot.json``): ``("diverged", what)`` for
    the simulated robot's divergence, ``("failed", what)`` for its bridge's fault or a state
    it gave, both of which stopped the session early, ``("failed when closed", what)`` for its
    bridge's ``close()`` raising after the session ran to its end; None when it did not
    fail."""
    failure = robot.get("failure")
    if not isinstance(failure, str):
        return None
    if robot.get("failed_when_closed") is True:
        return "failed when closed", failure
    return ("diverged" if robot.get("diverged") is True else "failed"), failure


#: Nodes whose lengths differ by more than this ran with different ``--duration`` (a node's
#: own length is its duration to a tick or two).
LENGTHS_DIFFER_S = 0.5


def node_lengths(nodes: dict[str, Any], dt: float, T_c: float) -> dict[str, float | None]:
    """How long each node ran (s): the robot's steps times ``dt``, the controller's ticks times
    ``T_c``, the delay node's loop; None without a record."""
    robot, controller, delay = (nodes.get(role) or {} for role in ("robot", "controller", "delay"))
    lengths = {
        "robot": robot.get("steps", math.nan) * dt if robot else None,
        "controller": controller.get("ticks", math.nan) * T_c if controller else None,
        "delay": delay.get("session_s") if delay else None,
    }
    return {role: v if is_real_number(v) else None for role, v in lengths.items()}


def lengths_text(lengths: dict[str, Any] | None) -> str | None:
    """A warning when the nodes ran for lengths more than :data:`LENGTHS_DIFFER_S` apart
    (started with different ``--duration``), else None."""
    known = {role: v for role, v in (lengths or {}).items() if is_real_number(v)}
    if len(known) < 2 or max(known.values()) - min(known.values()) <= LENGTHS_DIFFER_S:
        return None
    shown = ", ".join(f"{role} {v:.3g} s" for role, v in known.items())
    return (
        f"the nodes ran for different lengths ({shown}: started with different --duration); "
        "past the shortest, the others ran without it"
    )


def links_text(nodes: dict[str, Any]) -> str:
    """Whether the nodes authenticated their peers (``mutual_tls`` in their records)."""
    secured = {role: (record or {}).get("mutual_tls") for role, record in nodes.items()}
    if secured and all(value is True for value in secured.values()):
        return "mutual TLS: every peer authenticated by its certificate"
    if all(value is False for value in secured.values()):
        return (
            "not authenticated: a peer on the network could send commands (mutual TLS: "
            "--tls-ca, --tls-certificate, --tls-key)"
        )
    return "; ".join(
        f"{role}: {'mutual TLS' if value else 'not authenticated' if value is False else 'n/a'}"
        for role, value in secured.items()
    )


def _session_settings(summary: dict[str, Any], scenario: Any, live: Any) -> dict[str, str]:
    """The report's first table: the scenario, its periods, the session's length and end."""
    nodes = summary.get("nodes") or {}
    ended = {
        role: (record or {}).get("stopped_by") or "no record (the node did not finish)"
        for role, record in nodes.items()
    }
    stop = robot_stop(nodes.get("robot") or {})
    if stop is not None:
        how, failure = stop
        label = "failure" if how == "failed" else how
        ended["robot"] = f"{label}: {failure}"
    return {
        "scenario": summary.get("scenario", scenario.name),
        "T_c": f"{scenario.T_c * 1e3:g} ms",
        "dt": f"{scenario.dt * 1e3:g} ms",
        "session": f"{live.t[-1]:g} s of model time ({summary.get('wall_s', math.nan):.1f} s "
        "wall, start-up included)",
        "exit codes": ", ".join(
            f"{role} {code}" for role, code in (summary.get("exit_codes") or {}).items()
        ),
        "how each node ended": "; ".join(f"{role}: {end}" for role, end in ended.items())
        + (f"; {differ}" if (differ := lengths_text(summary.get("node_lengths_s"))) else ""),
        "links between the nodes": links_text(nodes),
        "load average (1, 5, 15 min) at the end": ", ".join(
            f"{v:.2f}" for v in summary.get("load_average", [])
        )
        or "n/a",
    }


def delay_node_text(delay: dict[str, Any], summary: dict[str, Any]) -> str:
    """What the delay node received and released, from its record ``delay`` and the session's
    ``summary`` (the commands sent that never reached it): the printed summary's and the
    report's."""
    return (
        f"{delay.get('received', 0)} commands received, {delay.get('lost', 0)} lost (injected), "
        f"{summary.get('not_received', 0)} sent but never received, "
        f"{delay.get('released', 0)} releases, {delay.get('missed_steps', 0)} steps missed "
        "(woke too late to release for them)"
    )


def _timing_settings(
    summary: dict[str, Any],
    scenario: Any,
    controller: dict[str, Any],
    robot: dict[str, Any],
    delay: dict[str, Any],
) -> dict[str, str]:
    """The nodes' timing and the delay rule's outcome, from their records in the summary; the
    rows of a node that wrote no record (it did not finish) say n/a, not zeros."""
    return {
        **_unless_unfinished(
            "controller",
            controller,
            {
                "controller ticks": f"{controller.get('ticks', 0)} "
                f"({controller.get('missed', 0)} missed, "
                f"{controller.get('older_state', 0)} on a state older than t_k, "
                f"{controller.get('stale', 0)} on a stale state)",
                "controller wake-up lateness p50 / p99": f"{ms(controller.get('lateness_ms_p50'))}"
                f" / {ms(controller.get('lateness_ms_p99'))}",
                "controller compute time p50 / p99": f"{ms(controller.get('compute_ms_p50'))} / "
                f"{ms(controller.get('compute_ms_p99'))}",
                "state the controller's law read": _state_read(controller, scenario),
            },
        ),
        **_unless_unfinished(
            "robot",
            robot,
            {
                "robot steps": f"{robot.get('steps', 0)} ({robot.get('missed_steps', 0)} missed, "
                f"{robot.get('late_applications', 0)} applications later than their release "
                "step)",
                "robot step lateness p50 / p99": f"{ms(robot.get('lateness_ms_p50'))} / "
                f"{ms(robot.get('lateness_ms_p99'))}",
            },
        ),
        **_unless_unfinished(
            "delay",
            delay,
            {
                "delay node": f"{delay_node_text(delay, summary)}, "
                f"{per_second(delay.get('wakes_per_s'))} wake-ups/s, "
                f"lead {delay.get('lead_ms', 0):g} ms",
                "packet loss": _packet_loss_text(delay, scenario),
            },
        ),
        "realised delay − h(t) p50 / |.| p99": f"{ms(summary.get('realised_minus_h_ms_p50'))}"
        f" / {ms(summary.get('realised_minus_h_abs_ms_p99'))} (the exact rule on the robot's "
        f"step grid alone: {ms(summary.get('realised_minus_h_abs_ms_p99_of_the_rule'))})",
        **_unless_unfinished(
            "robot",
            robot,
            {
                "commands never applied": _count_or_na(summary.get("never_applied", 0)),
                "commands superseded on the step grid (a newer one due at the same step)": (
                    _count_or_na(summary.get("superseded_on_the_step_grid"))
                ),
                "commands not due before the session ended": _count_or_na(
                    summary.get("due_after_the_end")
                ),
            },
        ),
    }


def _unless_unfinished(role: str, record: dict[str, Any], rows: dict[str, str]) -> dict[str, str]:
    """``rows``, or each said n/a when the ``role`` node wrote no ``record`` (it did not
    finish)."""
    if record:
        return rows
    return dict.fromkeys(
        rows, f"n/a: the {role} node wrote no record ({role}.json; it did not finish)"
    )


def _count_or_na(count: Any) -> str:
    """A count of the session's summary, or n/a where the robot logged no step table."""
    return "n/a (the robot node logged no step table)" if count is None else str(count)


def _loss_text(spec: Any) -> str:
    if not isinstance(spec, dict) or not spec.get("probability"):
        return "none"
    return f"probability {spec['probability']:g}, seed {spec.get('seed', 0)}"


def _packet_loss_text(delay: dict[str, Any], scenario: Any) -> str:
    """The packet loss the delay node ran (its record), and the scenario's where that differs
    (``--loss``/``--loss-seed`` given to the session)."""
    ran = _loss_text(delay.get("packet_loss"))
    loss = scenario.simulated_packet_loss
    own = _loss_text(None if loss is None else loss.to_spec())
    return ran if ran == own else f"{ran} (--loss/--loss-seed; the scenario's: {own})"


def _state_read(controller: dict[str, Any], scenario: Any) -> str:
    """Which state the controller's law read: measured with noise, or the true state."""
    if controller.get("measurement_noise"):
        return f"measured with measurement_noise {json.dumps(controller['measurement_noise'])}"
    if controller.get("measurement_noise_off") and scenario.measurement_noise is not None:
        return (
            "the true state, --no-measurement-noise (the scenario's measurement_noise turned off)"
        )
    return "the true state"


def _replay_settings(agreement: dict[str, Any]) -> dict[str, str]:
    """The replay's agreement with the live run: the worst coordinate's difference, a line per
    coordinate and input (:func:`format_agreement`) and what the simulation does not
    reproduce."""
    rows = {
        "ticks compared": f"{agreement['ticks_compared']}{_replay_stop_text(agreement)}",
        "live − replayed tracking error, RMS, worst coordinate": (
            f"{100 * agreement['error_difference_rms_relative']:.2f} % of its live RMS "
            f"({agreement['worst_coordinate']})"
        ),
    }
    for line in format_agreement(agreement):
        name, _, text = line.partition(": ")
        rows[name] = text
    rows["not reproduced by the simulation"] = not_reproduced_text(agreement)
    return rows


def not_reproduced_text(agreement: dict[str, Any]) -> str:
    """What the simulation does not reproduce, in words: ``"robot zero input on timeout steps
    0, controller missed ticks 0, ..."``."""
    return ", ".join(
        f"{k.replace('_', ' ').replace('t k', 't_k')} {v}"  # t_k keeps its underscore
        for k, v in agreement["not_reproduced"].items()
    )


def ticks_compared_text(report: dict[str, Any]) -> str:
    """``"824 ticks compared"``, and where the replay stopped when it did: the live ticks after
    it are not compared."""
    return f"{report['ticks_compared']} ticks compared{_replay_stop_text(report)}"


def _replay_stop_text(report: dict[str, Any]) -> str:
    """``""``, or ``"; the replay stopped as 'diverged' at t = 1.6 s, and the live ticks after
    it are not compared"``."""
    if report.get("replay_stopped_at_s") is None:  # or a replay.json from before it was kept
        return ""
    return (
        f"; the replay stopped as '{report['status']}' at t = "
        f"{report['replay_stopped_at_s']:g} s, and the live ticks after it are not compared"
    )


def format_agreement(report: dict[str, Any]) -> list[str]:
    """The agreement, a line per coordinate and input, for the terminal and the report."""

    def unit(entry: dict[str, Any]) -> str:
        return f" {entry['unit']}" if entry["unit"] else ""

    lines = [
        f"{name}: tracking error RMS live {c['tracking_error_rms_live']:.4g}{unit(c)}, "
        f"replayed {c['tracking_error_rms_replayed']:.4g}{unit(c)}; live - replayed max "
        f"{c['error_difference_max']:.3g}{unit(c)}, RMS {c['error_difference_rms']:.3g}"
        f"{unit(c)} ({100 * c['error_difference_rms_relative']:.2f} % of the live RMS)"
        for name, c in report["coordinates"].items()
    ]
    lines += [
        f"{name}: live - replayed command max {c['command_difference_max']:.3g}{unit(c)}, "
        f"RMS {c['command_difference_rms']:.3g}{unit(c)}"
        for name, c in report["inputs"].items()
    ]
    return lines


def error_bound_text(live: Any, scenario: Any, plant: Any) -> str | None:
    """Where the live tracking error first passed the scenario's ``error_bound`` (a tick's
    ``|q_d - q|`` beyond it in some coordinate), where ``simulate`` stops a run as ``left the
    path``: the live robot is not stopped by it. None without a bound or when it held."""
    bound = np.broadcast_to(np.asarray(scenario.simulated_error_bound, dtype=float), (plant.n,))
    beyond = np.abs(live.e1[0]) > bound  # NaN (no state) compares False
    ticks = np.flatnonzero(beyond.any(axis=1))
    if ticks.size == 0:
        return None
    first = int(ticks[0])
    which = [
        value_with_unit(f"{name} {bound[i]:g}", unit)
        for i, (name, unit) in enumerate(coordinate_units(plant).items())
        if beyond[first, i]
    ]
    return (
        f"the tracking error passed the scenario's error_bound ({', '.join(which)}) at "
        f"t = {live.t[first]:g} s, where simulate stops a run as 'left the path'; the live "
        "session is not stopped by it and ran on (its metrics cover the whole session)"
    )


def write_report(folder: Path, scenario: Any, **replay: Any) -> tuple[bool, str | None]:
    """Write the session's metrics, figures and report (:mod:`delaytrack.live.report`);
    whether that failed (said on stderr: the logs and tables stay), and the report's note on
    the ``error_bound``, to print as ``note: ...`` after what the command prints of the
    session (:func:`write_session_report`)."""
    try:
        _paths, note = write_session_report(folder, scenario, **replay)
    except (ValueError, OSError, KeyError) as error:
        print(
            f"error: the session's report (metrics.csv, figures, report.html) could not be "
            f"written: {error}",
            file=sys.stderr,
        )
        return True, None
    return False, note
