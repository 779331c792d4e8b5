"""``delaytrack live run``: start the three nodes as processes, wait, collect the session folder.

The launcher checks the scenario and the output folder, picks three free TCP ports on
127.0.0.1 (or ``--port``, ``--port + 1``, ``--port + 2``), and starts the robot, delay and
controller nodes as ``python -m delaytrack.live <role> ...`` in a full mesh (each listens on its
port and connects to the ports of the nodes started before it). The nodes shake hands and the
robot announces the start ``t0`` on the shared monotonic clock (:mod:`delaytrack.live.transport`);
each node stops by itself at ``t0 + duration``. SIGINT/SIGTERM to the launcher is passed on to
the nodes as SIGTERM, which stop cleanly and finish their logs. The nodes print nothing of their
own status; unless ``--quiet``, the launcher prints one line a second on stderr from the
statuses they publish (:mod:`delaytrack.live.status`).

It then writes ``delays.csv`` (one row per command: its stamps, lost or not, when the robot
first applied it, the realised delay and ``h`` there), ``summary.json``, the scenario as run
(``scenario.toml``), and prints a short summary.
"""

from __future__ import annotations

import json
import math
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from delaytrack._io import json_text, write_text
from delaytrack._validation import is_real_number
from delaytrack.live._node import (
    EXIT_PORT_TAKEN,
    LAUNCHER_PID,
    check_realtime,
    load_scenario,
    percentile,
    remove_files,
    session_duration,
    session_files,
)
from delaytrack.live._tables import (
    ROLE_FILES,
    RowsByIndex,
    check_nodes_ran,
    check_one_session,
    check_tables_whole,
    json_table,
    ms,
    node_record,
    read_table,
    values_at,
)
from delaytrack.live.log import write_csv
from delaytrack.live.report import (
    FIGURES,
    delay_node_text,
    lengths_text,
    links_text,
    node_lengths,
    robot_stop,
)
from delaytrack.live.status import StatusWatch
from delaytrack.live.transport import PortInUseError, scenario_hashes
from delaytrack.warning import one_line

__all__ = ["collect", "run_session"]

ROLES = ("robot", "delay", "controller")


def _free_ports(count: int) -> list[int]:
    sockets = []
    try:
        for _ in range(count):
            s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            s.bind(("127.0.0.1", 0))
            sockets.append(s)
        return [s.getsockname()[1] for s in sockets]
    finally:
        for s in sockets:
            s.close()


def _endpoint(port: int, certificates: Any) -> str:
    """The Zenoh endpoint on this machine at ``port``: TCP, or with ``certificates`` TLS at
    ``localhost`` (the name their certificate gives)."""
    return f"tcp/127.0.0.1:{port}" if certificates is None else f"tls/localhost:{port}"


def _ended_early(folder: Path, role: str, code: int | None) -> bool:
    """Whether the node ``role`` has exited before the session's end: with an error, or with 0
    after a stop signal of its own (its ``<role>.json`` says what stopped it)."""
    if code is None:
        return False
    if code != 0:
        return True
    try:
        stopped_by = json_table(folder / f"{role}.json", "node's record").get("stopped_by")
    except (OSError, ValueError):
        return True  # exited 0 without its record: not a normal end
    return stopped_by != "duration"


#: How a node starts: ``python -P`` (no folder put first on its module search path: a module of
#: the working folder, sent beside a scenario, would run before the node's own), then with this
#: process's module search path (the argument after the code), so that it imports what this
#: process imports (an uninstalled copy of the package, a factory's module it found), then
#: ``python -m delaytrack.live`` with the arguments that follow.
NODE_START = (
    sys.executable,
    "-P",
    "-c",
    "import json, runpy, sys\n"
    "sys.path[:] = json.loads(sys.argv.pop(1))\n"
    "runpy.run_module('delaytrack.live', run_name='__main__', alter_sys=True)\n",
)


def node_commands(
    args: Any,
    folder: Path,
    ports: list[int],
    session: str,
    watch: str | None = None,
    picked: bool = False,
) -> dict[str, list[str]]:
    """The command line of each node (each ``--quiet``: the launcher prints the status); each
    also connects to the launcher's status watch at the endpoint ``watch``, if given. With
    ``picked`` (ports the launcher picked, not the user's), a node whose port is taken when it
    listens exits with :data:`~delaytrack.live._node.EXIT_PORT_TAKEN`, silently."""
    endpoint = {
        role: _endpoint(port, args.certificates) for role, port in zip(ROLES, ports, strict=True)
    }
    commands = {}
    for i, role in enumerate(ROLES):
        command = [
            *NODE_START,
            json.dumps(sys.path),
            role,
            str(args.scenario),
            "--out",
            str(folder),
            "--session",
            session,
            "--listen",
            endpoint[role],
            "--handshake-timeout",
            repr(args.handshake_timeout),
        ]
        for earlier in ROLES[:i]:
            command += ["--connect", endpoint[earlier]]
        if watch is not None:
            command += ["--connect", watch]
        if args.duration is not None:
            command += ["--duration", repr(args.duration)]
        for name in args.trust:
            command += ["--trust", name]
        command.append("--quiet")
        if picked:
            command.append("--picked-ports")
        if role == "delay" and args.loss is not None:
            command += ["--loss", repr(args.loss), "--loss-seed", str(args.loss_seed)]
        if role == "delay" and getattr(args, "lead", None) is not None:
            command += ["--lead", repr(args.lead)]
        if role == "robot" and getattr(args, "bridge", None) is not None:
            command += ["--bridge", args.bridge]
        if getattr(args, "realtime", None) is not None:
            command += ["--realtime", str(args.realtime)]
        if role == "controller" and getattr(args, "no_measurement_noise", False):
            command.append("--no-measurement-noise")
        if args.certificates is not None:
            ca, certificate, key = args.certificates
            command += ["--tls-ca", ca, "--tls-certificate", certificate, "--tls-key", key]
        commands[role] = command
    return commands


def run_session(args: Any) -> int:
    """Run a session (module docstring); return the exit code."""
    from delaytrack._output import claim_output_folder
    from delaytrack.live._node import missing_extra
    from delaytrack.scenario import ScenarioError

    if (problem := missing_extra()) is not None:
        print(one_line(f"error: {problem}"), file=sys.stderr)
        return 2
    try:
        scenario, built, duration, folder = _checked_session(args)
    except (ScenarioError, ValueError, OSError) as error:
        print(one_line(f"error: {error}"), file=sys.stderr)
        return 2
    try:
        claim_output_folder(folder)
        started_nodes = _start_nodes(args, scenario, folder, duration)
    except OSError as error:
        print(one_line(f"error: {error}"), file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted before the session started", file=sys.stderr)
        return 130
    if started_nodes is None:
        print(
            f"error: the session did not start: {PORT_ATTEMPTS} times in a row, another "
            "program took a port picked for it before its node could listen on it; give free "
            "ports with --port",
            file=sys.stderr,
        )
        return 1
    codes, interrupted, started, (stuck, why) = started_nodes
    for role in stuck:
        print(
            f"error: the {role} node did not end in time ({why}): it was stopped ({stuck[role]}); "
            f"its tables may be missing, {role}.mcap holds what it logged",
            file=sys.stderr,
        )
    failed = {role: code for role, code in codes.items() if code not in (0,)}
    if not _logged(folder):
        # No session (an earlier one's logs were removed): stopped, refused by a node (said
        # by the node), or a node killed or stopped, before the start. Nothing to collect.
        if interrupted:
            print("interrupted before the session started", file=sys.stderr)
            return 130
        if failed and all(code > 0 for code in failed.values()):
            return max(failed.values())
        ended = ", ".join(_exit_text(role, code) for role, code in codes.items())
        print(f"error: the session did not start; its nodes ended: {ended}", file=sys.stderr)
        return 1
    try:
        summary = collect(folder, scenario, built)
        summary["exit_codes"] = codes
        summary["wall_s"] = time.monotonic() - started
        summary["load_average"] = list(os.getloadavg())
        report_failed, note = _write_summary_and_report(folder, scenario, summary)
    except KeyboardInterrupt:
        print(
            "interrupted while writing the session's summary and report; the nodes' files are "
            f"whole: delaytrack live collect {folder} SCENARIO writes them",
            file=sys.stderr,
        )
        return 130
    except ValueError as error:  # a node's file the summary cannot read
        print(f"error: the session's summary could not be written: {error}", file=sys.stderr)
        return 1
    if stuck:
        failed.update({role: codes[role] or 1 for role in stuck})
    _print_summary(summary, folder, note, shown=not args.quiet or bool(failed))
    return _session_exit_code(interrupted, failed, report_failed)


#: How many times ``live run`` picks ports for a session whose nodes find a port taken by
#: another program before they listen on it (the picked ports are free when picked, but
#: another program, such as another session, may take one before the node binds it).
PORT_ATTEMPTS = 5


def _start_nodes(
    args: Any, scenario: Any, folder: Path, duration: float
) -> tuple[dict[str, int], list[int], float, tuple[dict[str, str], str]] | None:
    """Start the session's nodes on ports picked for them and wait for their end
    (:func:`_run_nodes`, whose result this returns). When a node, or the status watch, finds
    its picked port taken before the session began, start again on new ports, up to
    :data:`PORT_ATTEMPTS` times (None when every time found a port taken)."""
    session = f"run-{os.getpid()}-{int(time.time())}"
    for _ in range(PORT_ATTEMPTS):
        try:
            commands, watch = _prepare_attempt(args, scenario, folder, session)
        except PortInUseError:  # the watch's port
            continue
        ended = _run_nodes(commands, folder, watch, args.handshake_timeout, duration)
        codes, interrupted = ended[0], ended[1]
        if interrupted or EXIT_PORT_TAKEN not in codes.values() or _logged(folder):
            return ended
    return None


def _prepare_attempt(
    args: Any, scenario: Any, folder: Path, session: str
) -> tuple[dict[str, list[str]], StatusWatch | None]:
    """Ready ``folder`` for a start of the session's nodes and pick their ports: the nodes'
    commands and the status watch (listening, or None with ``--quiet``). Raises
    :class:`~delaytrack.live.transport.PortInUseError` when the watch's port was taken since
    it was picked, and ``OSError`` for a folder that cannot be written."""
    _remove_earlier_session(folder)
    # The nodes read the scenario as written here, so a shipped name and the replay agree.
    scenario.to_toml(folder / "scenario.toml")
    ports = _free_ports(3) if args.port is None else [args.port + i for i in range(3)]
    # The status watch listens before the nodes start, and they connect to it: a watch that
    # connected to them could miss a short session while its connections were retried.
    watched = None if args.quiet else _endpoint(_free_ports(1)[0], args.certificates)
    watch = (
        None
        if watched is None
        else StatusWatch(watched, f"delaytrack/{session}", certificates=args.certificates)
    )
    return node_commands(args, folder, ports, session, watched, args.port is None), watch


def _logged(folder: Path) -> bool:
    """Whether a node of the session in ``folder`` has started its log (the session began)."""
    return any((folder / f"{role}.mcap").exists() for role in ROLES)


#: The files a session's launcher writes besides the nodes' (``replay`` writes the last two).
SESSION_FILES = (
    "scenario.toml",
    "summary.json",
    "delays.csv",
    "metrics.csv",
    "report.html",
    "replay.csv",
    "replay.json",
    *(f"figures/{name}.png" for name in FIGURES),
)


def _remove_earlier_session(folder: Path) -> None:
    """Remove the files of an earlier session in ``folder`` (the nodes', the summary's, the
    report's and the replay's; nothing else), so that none of its tables is taken for this
    one's."""
    names = [*SESSION_FILES, *(name for files in ROLE_FILES.values() for name in files)]
    remove_files(folder, names)


def _checked_session(args: Any) -> tuple[Any, Any, float, Path]:
    """The scenario, ``scenario.build()``, the session's duration and the output folder, all
    checked before any node starts (raises ``ScenarioError``, ``ValueError`` or ``OSError``)."""
    from delaytrack._output import check_output_folder
    from delaytrack.live.bridge import bridge_factory
    from delaytrack.live.delay import check_session_delay, session_lead

    scenario = load_scenario(str(args.scenario), list(args.trust))
    built = scenario.build()
    if scenario.measurement_noise is not None:  # the controller's check, before any node
        scenario.simulated_measurement_noise.params(built.plant.n)
    duration = session_duration(scenario, args.duration)
    check_session_delay(built.delay, duration)  # as the delay node checks it
    session_lead(getattr(args, "lead", None), built.delay, scenario.dt, duration)  # the same
    if getattr(args, "bridge", None) is not None:
        bridge_factory(args.bridge)  # the robot node builds and checks the bridge itself
    check_realtime(getattr(args, "realtime", None))  # once here, not once per node
    folder = check_output_folder(args.out, "--out")
    return scenario, built, duration, folder


def _run_nodes(
    commands: dict[str, list[str]],
    folder: Path,
    watch: StatusWatch | None,
    handshake_timeout: float,
    duration: float,
) -> tuple[dict[str, int], list[int], float, tuple[dict[str, str], str]]:
    """Start the nodes, pass SIGINT/SIGTERM on to them as SIGTERM and wait for their end;
    return their exit codes, the signals that interrupted the session, its start on the
    monotonic clock and the nodes stopped for not ending in time, with why
    (:func:`_wait_for_nodes`)."""
    processes: dict[str, subprocess.Popen[bytes]] = {}
    interrupted: list[int] = []

    def forward(signum: int, _frame: Any) -> None:
        interrupted.append(signum)
        _terminate(processes)

    previous = {s: signal.signal(s, forward) for s in (signal.SIGINT, signal.SIGTERM)}
    started = time.monotonic()
    try:
        # A node stops when this process ends, even killed (:func:`end_with_launcher`).
        environment = {**os.environ, LAUNCHER_PID: str(os.getpid())}
        for role in ROLES:
            if interrupted:  # stopped while the nodes start: the rest are not started
                break
            processes[role] = subprocess.Popen(commands[role], env=environment)
        if interrupted:  # the signal may have come inside Popen, before the node was listed
            _terminate(processes)
        grace = ending_grace(duration)
        limit = started + handshake_timeout + duration + grace
        stuck = _wait_for_nodes(processes, folder, watch, limit, grace)
        codes = {role: process.wait() for role, process in processes.items()}
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        if watch is not None:
            watch.close()
    return codes, interrupted, started, stuck


def ending_grace(duration: float) -> float:
    """Seconds a node may take to end after another node of a session of ``duration`` seconds
    ended (or the session was told to stop): 60 s and 5 % of the session, for a bridge's
    ``close()`` to leave the robot safe and for writing the tables of a long session."""
    return 60.0 + 0.05 * duration


def _wait_for_nodes(
    processes: dict[str, subprocess.Popen[bytes]],
    folder: Path,
    watch: StatusWatch | None,
    limit: float,
    grace: float,
) -> tuple[dict[str, str], str]:
    """Wait while any node runs, showing the status: a node that ended early ends the session.
    A node still running ``grace`` seconds after another ended (the session over, or stopped),
    or past ``limit`` (monotonic clock), is stopped: SIGTERM, then SIGKILL 5 s on. Returns the
    roles stopped so (and how) and why."""
    ended = False
    exited: set[str] = set()  # the nodes whose end has been looked at (once each)
    deadline, why = limit, "the session's end, its handshake time and the grace passed"
    while any(p.poll() is None for p in processes.values()):
        now = time.monotonic()
        if now > deadline:
            stuck = {role: "SIGTERM" for role, p in processes.items() if p.poll() is None}
            _terminate(processes)
            given_up = time.monotonic() + 5.0
            for role in stuck:
                try:
                    processes[role].wait(timeout=max(0.0, given_up - time.monotonic()))
                except subprocess.TimeoutExpired:
                    processes[role].kill()
                    stuck[role] = "SIGTERM, then SIGKILL 5 s on"
            return stuck, why
        newly = [r for r, p in processes.items() if r not in exited and p.poll() is not None]
        exited.update(newly)
        if newly and now + grace < deadline:  # the others end about as soon, or are stopped
            deadline = now + grace
            why = f"{grace:g} s after the {newly[0]} node ended"
        if not ended and any(_ended_early(folder, r, processes[r].poll()) for r in newly):
            # A node that failed, refused or was stopped ends the session: the others stop
            # (once: a second SIGTERM could reach a node exiting, without its handler).
            ended = True
            _terminate(processes)
        if watch is not None:
            watch.show()
        time.sleep(0.05)
    return {}, ""


def _terminate(processes: dict[str, subprocess.Popen[bytes]]) -> None:
    """Send SIGTERM to each node still running."""
    for process in processes.values():
        if process.poll() is None:
            process.send_signal(signal.SIGTERM)


def _write_summary_and_report(
    folder: Path, scenario: Any, summary: dict[str, Any]
) -> tuple[bool, str | None]:
    """Write ``summary.json`` and the report, and record the session's files; whether the
    report failed, and its note (:func:`~delaytrack.live.report.write_report`)."""
    from delaytrack._output import record_outputs
    from delaytrack.live.report import write_report

    write_text(folder / "summary.json", json_text(summary, indent=1, default=str) + "\n")
    written = write_report(folder, scenario)
    record_outputs(folder, session_files(folder))
    return written


def _print_summary(summary: dict[str, Any], folder: Path, note: str | None, shown: bool) -> None:
    """Print the session's summary (when ``shown``), then the report's ``note``, if any."""
    if shown:
        print(format_summary(summary, folder))
    if note is not None:
        print(f"note: {note}")


def _session_exit_code(interrupted: list[int], failed: dict[str, int], report_failed: bool) -> int:
    """The exit code of a session that ran: 130 when interrupted, else a failed node's (said on
    stderr), else 1 when the report failed."""
    if interrupted:
        return 130
    if failed:
        print(
            f"error: node(s) {', '.join(_exit_text(r, c) for r, c in failed.items())} did not "
            "finish cleanly; their MCAP logs hold the session up to where they stopped",
            file=sys.stderr,
        )
        return max(failed.values()) if all(c > 0 for c in failed.values()) else 1
    return 1 if report_failed else 0


def _exit_text(role: str, code: int) -> str:
    """``robot (exit 1)`` or ``robot (killed by SIGKILL)``."""
    if code < 0:
        try:
            return f"{role} (killed by {signal.Signals(-code).name})"
        except ValueError:
            pass
    return f"{role} (exit {code})"


#: What each node leaves in its folder, which ``live collect`` needs from all three.
NODE_FILES = {
    "controller": ("controller.json", "ticks.csv"),
    "delay": ("delay.json", "releases.csv"),
    "robot": ("robot.json", "steps.csv", "states.csv", "applied.csv"),
}


def collect_main(args: Any) -> int:
    """``delaytrack live collect DIR SCENARIO``: the summary, ``delays.csv`` and the report of a
    session whose nodes were started one by one (on one machine, or on several, their folders'
    files copied into one), as ``live run`` writes them; ``live replay DIR`` then works."""
    from delaytrack._output import check_output_folder
    from delaytrack.scenario import ScenarioError

    try:
        folder = check_output_folder(args.folder, "DIR")
        missing = [
            name for names in NODE_FILES.values() for name in names if not (folder / name).is_file()
        ]
        unfinished = [
            role
            for role in ROLES
            if (folder / f"{role}.mcap").is_file() and not (folder / f"{role}.json").is_file()
        ]
        if unfinished:  # its log is there, not what it writes at its end
            raise ValueError(
                f"{folder}: the {' and '.join(unfinished)} node did not finish (its log "
                f"{', '.join(f'{r}.mcap' for r in unfinished)} is there, not the record and "
                "tables a node writes at its end): a summary needs every node's; the logs read "
                "as they are up to where they stop"
            )
        if missing:
            raise ValueError(
                f"{folder} lacks {', '.join(missing)}: put the files the three nodes wrote into "
                "one folder (each node writes its own role's files)"
            )
        scenario = load_scenario(str(args.scenario), list(args.trust))
        built = scenario.build()
        summary = collect(folder, scenario, built, given=str(args.scenario))
    except (ScenarioError, ValueError, OSError) as error:
        print(one_line(f"error: {error}"), file=sys.stderr)
        return 2
    scenario.to_toml(folder / "scenario.toml")
    summary.update(_launcher_facts(folder / "summary.json", summary["nodes"]))
    remove_files(folder, ("replay.csv", "replay.json"))  # of the summary before, if any
    summary["stopped_by"] = {
        role: (summary["nodes"][role] or {}).get("stopped_by") for role in ROLES
    }
    report_failed, note = _write_summary_and_report(folder, scenario, summary)
    _print_summary(summary, folder, note, shown=not args.quiet)
    return 1 if report_failed else 0


def _launcher_facts(path: Path, nodes: dict[str, Any]) -> dict[str, Any]:
    """What ``live run`` measured of a session (the nodes' exit codes, its wall time and load)
    from its ``summary.json``, kept when ``live collect`` writes the summary again: only when
    that summary is of the same session (its node records are ``nodes``); none otherwise."""
    try:
        summary = json_table(path, "session summary")
    except (OSError, ValueError):
        return {}
    if summary.get("nodes") != json.loads(json_text(nodes)):
        return {}
    return {key: summary[key] for key in ("exit_codes", "wall_s", "load_average") if key in summary}


def collect(folder: Path, scenario: Any, built: Any, given: str | None = None) -> dict[str, Any]:
    """Merge the nodes' tables into ``delays.csv``; return the session's summary. ``built`` is
    ``scenario.build()``. A table or record that is not the toolkit's is a ValueError naming
    it, and so is a scenario other than the one the nodes ran, when it was ``given`` (its file
    or name, for the message) rather than the launcher's own."""
    delay = built.delay
    nodes = {role: node_record(folder / f"{role}.json") for role in ROLES}
    if given is not None:
        check_nodes_ran(
            folder,
            nodes,
            scenario_hashes(scenario, built.plant),
            given,
            "give the scenario file the nodes ran",
        )
    check_one_session(folder, nodes)
    check_tables_whole(folder, nodes)
    ticks = read_table(folder / "ticks.csv", ("t_s", "send_s"), indices=("k",), texts=("status",))
    releases = read_table(
        folder / "releases.csv",
        ("t_k_s", "received_s", "lost", "released_s"),
        indices=("seq",),
    )
    applied_rows = read_table(folder / "applied.csv", ("applied_s",), indices=("seq",))
    sent_mask = ticks["status"] != "no-state"
    sent_t, sent_at = ticks["t_s"][sent_mask], ticks["send_s"][sent_mask]
    sent_by_k = RowsByIndex(ticks["k"][sent_mask])
    received_by_seq = RowsByIndex(releases["seq"])
    # the first time each command was applied (a command is applied once; a later row repeats it)
    sequence = np.union1d(sent_by_k.indices, received_by_seq.indices)
    sent, received = sent_by_k.find(sequence), received_by_seq.find(sequence)
    applied = values_at(
        applied_rows["applied_s"], RowsByIndex(applied_rows["seq"], first=True).find(sequence)
    )
    issued = np.where(sent >= 0, values_at(sent_t, sent), values_at(releases["t_k_s"], received))
    sent_s = values_at(sent_at, sent)
    lost = np.where(received >= 0, values_at(releases["lost"], received) == 1, -1).astype(np.int64)
    # h at every time at once (one call of its compiled code, not two a command)
    h_applied = np.full(applied.shape, math.nan)
    came = np.isfinite(applied)
    h_applied[came] = delay.h(applied[came])
    h_issued = np.asarray(delay.h(issued), dtype=float)
    realised = applied - issued
    error = (realised - h_applied) * 1e3
    numbers = np.stack(
        [
            issued,
            sent_s,
            values_at(releases["received_s"], received),
            values_at(releases["released_s"], received),
            applied,
            realised,
            h_applied,
            h_issued,
            error,
        ],
        axis=-1,
    )

    def rows() -> Iterator[list[Any]]:
        """The rows of ``delays.csv``, one at a time."""
        for seq, lost_seq, row in zip(sequence.tolist(), lost.tolist(), numbers, strict=True):
            t_k, sent_at_k, received_at, released_at, *later = row.tolist()
            yield [seq, t_k, sent_at_k, received_at, lost_seq, released_at, *later]

    write_csv(
        folder / "delays.csv",
        [
            "seq",
            "t_k_s",
            "sent_s",
            "received_s",
            "lost",
            "released_s",
            "applied_s",
            "realised_delay_s",
            "h_s",
            "h_at_t_k_s",
            "realised_minus_h_ms",
        ],
        rows(),
    )
    robot_steps = read_table(folder / "steps.csv").rows
    end = robot_steps * scenario.dt
    steps, due = _due_steps(issued, delay, scenario.dt, end)
    # due at one of the robot's steps (the last of ``steps`` is the session's end)
    within = due < steps.size - 1
    superseded = _superseded(issued, (lost == 0) & within, due)
    held = (lost == 0) & ~came
    # Without the robot's steps (a robot node killed, or stuck and stopped, writes no tables)
    # the session's end on the step grid is unknown: so is which command came due before it.
    counted_by_step = robot_steps > 0
    listened = (nodes.get("delay") or {}).get("session_s")
    if not is_real_number(listened):  # a record without it (or not a number)
        listened = -math.inf
    return {
        "scenario": scenario.name,
        "T_c_s": scenario.T_c,
        "dt_s": scenario.dt,
        "commands": int(sequence.size),
        "lost": int(np.sum(lost == 1)),
        # Commands sent while the delay node listened that never reached it (the transport's
        # losses, as opposed to the injected ones counted in "lost").
        "not_received": int(np.sum((lost == -1) & (sent_s <= listened))),
        "sent_after_listening": int(np.sum((lost == -1) & ~(sent_s <= listened))),
        "applied": int(np.sum(came)),
        # Received commands the rule would have applied at one of the robot's steps that never
        # were (those a newer one superseded at the step they came due are counted apart), and
        # those not due before the session ended.
        "never_applied": int(np.sum(held & within & ~superseded)) if counted_by_step else None,
        "superseded_on_the_step_grid": (
            int(np.sum(held & superseded)) if counted_by_step else None
        ),
        "due_after_the_end": int(np.sum(held & ~within)) if counted_by_step else None,
        "realised_minus_h_ms_p50": percentile(error, 50),
        "realised_minus_h_abs_ms_p99": percentile(np.abs(error), 99),
        "realised_minus_h_abs_ms_max": percentile(np.abs(error), 100),
        "realised_minus_h_abs_ms_p99_of_the_rule": percentile(
            np.abs(_rule_error_ms(issued[came], due[came], steps, delay)), 99
        ),
        "node_lengths_s": node_lengths(nodes, scenario.dt, scenario.T_c),
        "nodes": nodes,
    }


def _due_steps(t_k: np.ndarray, delay: Any, dt: float, end: float) -> tuple[np.ndarray, np.ndarray]:
    """The robot's step times up to ``end``, and for each command issued at ``t_k`` the index
    of the first step ``s`` where the rule allows it, ``t_k <= s − h(s)`` (the number of steps
    where none does)."""
    steps = np.arange(round(end / dt) + 1) * dt
    reach = np.maximum.accumulate(steps - delay.h(steps))  # the newest t_k usable by step s
    return steps, np.searchsorted(reach, t_k - 1e-9 * dt)


def _superseded(t_k: np.ndarray, taken: np.ndarray, due: np.ndarray) -> np.ndarray:
    """Whether each command is superseded on the step grid: a newer one of those ``taken`` (by
    the delay node, due within the session) is due at the same step (``due``,
    :func:`_due_steps`), and the rule applies the newest. Where ``h`` falls, ``s − h(s)``
    advances by ``dt (1 − ḣ)`` a step, past two commands when ``T_c`` is ``dt``."""
    newest = np.full(due.shape, -np.inf)
    order = np.flatnonzero(taken)
    if order.size:
        latest = np.full(int(due[order].max()) + 1, -np.inf)
        np.maximum.at(latest, due[order], t_k[order])
        newest[order] = latest[due[order]]
    return taken & (t_k < newest)


def _rule_error_ms(t_k: np.ndarray, due: np.ndarray, steps: np.ndarray, delay: Any) -> np.ndarray:
    """For each command the robot applied (issued at ``t_k``, first due at step ``due`` of the
    robot's ``steps``, :func:`_due_steps`), ``realised − h`` in ms had it come into force at
    that step: what the exact rule gives on the step grid with no lateness at all (``s − h(s)``
    advances by ``dt (1 − ḣ)`` a step, so this reaches beyond ``dt`` where ``h`` falls)."""
    inside = due < steps.size
    s = steps[due[inside]]
    return (s - t_k[inside] - delay.h(s)) * 1e3


def _robot_stop_text(robot: dict[str, Any]) -> str:
    """``""``, or why the robot node stopped before the session's end (:func:`robot_stop`):
    the session ended early there; or that its bridge failed when closed, after the end."""
    stop = robot_stop(robot)
    if stop is None:
        return ""
    how, failure = stop
    if how == "failed when closed":  # after the session's end: it did not end it
        return f"; its bridge failed when closed, after the session: {failure}"
    return f"; it {how} and stopped the session early: {failure}"


def format_summary(summary: dict[str, Any], folder: Path) -> str:
    """A few lines for the terminal; a node that wrote no record (it did not finish) is said
    to have none, not shown as zeros."""
    nodes = summary["nodes"]
    c = nodes.get("controller") or {}
    r = nodes.get("robot") or {}
    d = nodes.get("delay") or {}
    lines = {
        "controller": f"  controller: {c.get('ticks', 0)} ticks, {c.get('missed', 0)} missed, "
        f"lateness p50 {ms(c.get('lateness_ms_p50'))} p99 {ms(c.get('lateness_ms_p99'))}, "
        f"compute p99 {ms(c.get('compute_ms_p99'))}, {c.get('older_state', 0)} on a state older "
        f"than t_k, stale {c.get('stale', 0)}",
        "delay": f"  delay node: {delay_node_text(d, summary)}",
        "robot": f"  robot: {r.get('steps', 0)} steps, {r.get('missed_steps', 0)} missed, "
        f"lateness p99 {ms(r.get('lateness_ms_p99'))}, u_init {r.get('no_command_steps', 0)} "
        f"steps before the first command + zero input {r.get('timeout_zero_steps', 0)} on "
        "timeout" + _robot_stop_text(r),
    }
    for role in ROLES:
        if nodes.get(role) is None:
            title = "delay node" if role == "delay" else role
            lines[role] = (
                f"  {title}: no record ({role}.json): the node did not finish; {role}.mcap holds "
                "what it logged"
            )
    never_applied = summary["never_applied"]
    if nodes.get("robot") is None or never_applied is None:
        never_applied = "n/a (the robot node logged no step table)"
    apart = [
        f"{count} {what}"
        for count, what in (
            (summary.get("superseded_on_the_step_grid"), "superseded at the step they came due"),
            (summary.get("due_after_the_end"), "not due before the end"),
        )
        if count
    ]
    if apart:
        never_applied = f"{never_applied} ({'; '.join(apart)})"
    return "\n".join(
        [
            f"live session {summary['scenario']} (T_c = {summary['T_c_s'] * 1e3:g} ms, "
            f"dt = {summary['dt_s'] * 1e3:g} ms) -> {folder}",
            lines["controller"],
            lines["delay"],
            lines["robot"],
            f"  links between the nodes: {links_text(nodes)}",
            f"  realised delay - h(t_applied): p50 {ms(summary['realised_minus_h_ms_p50'])}, "
            f"|.| p99 {ms(summary['realised_minus_h_abs_ms_p99'])} (the exact rule on the step "
            f"grid alone: {ms(summary.get('realised_minus_h_abs_ms_p99_of_the_rule'))}); "
            f"commands never applied: {never_applied}",
            *(
                [f"  warning: {text}"]
                if (text := lengths_text(summary.get("node_lengths_s"))) is not None
                else []
            ),
        ]
    )
