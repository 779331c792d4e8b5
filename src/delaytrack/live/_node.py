"""What the three nodes share: loading the scenario, the session's length, the output folder,
the Zenoh session, the handshake, signals, the status (:mod:`delaytrack.live.status`) and the
run's life cycle (:func:`run_node`).

A node writes into its ``--out`` folder as every command of the toolkit writes its results
folder (:mod:`delaytrack._output`): the folder, with ``..`` and links resolved, must be new,
empty or one this toolkit wrote, and holds no link; the node marks it before writing and
records its files at the end (:func:`claim_node_folder`, :func:`record_node_files`). The three
nodes of a session may share one folder (each writes its own role's files) or use one each. The
nodes that share a folder claim and record it in turn, under a lock on the folder's path, so
that one node's check never sees another's marker half-written.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import signal
import sys
import tempfile
import threading
import time
from collections import deque
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from delaytrack._file_lock import exclusive
from delaytrack._io import json_text, write_text
from delaytrack._output import check_output_folder, claim_output_folder, record_outputs
from delaytrack.live._tables import ROLE_FILES, table_bytes, table_digests
from delaytrack.live.status import (
    STATUS_PERIOD,
    encode_status,
    format_line,
    make_status,
    status_key,
)
from delaytrack.live.transport import (
    Handshake,
    HandshakeError,
    PortInUseError,
    open_session,
    scenario_hashes,
)
from delaytrack.sim.simulate import MAX_STEPS, physical_memory
from delaytrack.warning import one_line

__all__ = [
    "EXIT_PORT_TAKEN",
    "LAUNCHER_PID",
    "NodeBase",
    "Received",
    "StopFlag",
    "check_realtime",
    "claim_node_folder",
    "load_scenario",
    "percentile",
    "record_node_files",
    "remove_files",
    "run_node",
    "session_duration",
    "session_files",
]

#: Memory a live session holds per plant step until it ends, all nodes on one machine: the
#: robot's row of the step, its states and the other nodes' rows of ticks and releases. The
#: three nodes' resident sizes grew by about 2 KiB a step together with the controller at every
#: step (``T_c = dt``, 1 ms), the most rows a step can bring (measured over 14 s).
BYTES_PER_STEP = 2048

#: Exit codes: 0 done (also when stopped by SIGTERM), 1 stopped by a failure of its own (the
#: robot's state), 2 refused (a usage error, a scenario that differs from a peer's, no peer in
#: time), 130 stopped by SIGINT.
EXIT_OK, EXIT_FAILED, EXIT_REFUSED, EXIT_INTERRUPTED = 0, 1, 2, 130

#: The exit code of a node started by ``delaytrack live run`` on ports it picked (the hidden
#: ``--picked-ports``) when its listen port was taken by another program in between, before
#: the session started: a temporary failure (``EX_TEMPFAIL``), said by no message, on which
#: the launcher picks new ports and starts the nodes again.
EXIT_PORT_TAKEN = 75

#: The environment variable by which ``delaytrack live run`` gives its nodes its process id:
#: a node it started stops (as on SIGTERM) when the launcher is gone, killed or not.
LAUNCHER_PID = "DELAYTRACK_LIVE_LAUNCHER_PID"


class StopFlag:
    """Set by SIGINT/SIGTERM (and by the node itself); the loops check it at every wake-up.

    A plain attribute, set without a lock: a signal handler runs in the main thread between
    two of its bytecodes, so a handler that took a lock (``threading.Event.set`` does) would
    wait forever for one the main thread held when the signal came, or that a first handler
    held when a second signal interrupted it (Ctrl-C under ``live run`` brings SIGINT, then
    the launcher's SIGTERM)."""

    def __init__(self) -> None:
        self.signal: int | None = None
        self._set = False

    def __call__(self) -> bool:
        return self._set

    def set(self, signum: int | None = None) -> None:
        if self.signal is None:
            self.signal = signum
        self._set = True

    def install(self) -> None:
        for signum in (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, lambda s, _frame: self.set(s))

    @staticmethod
    def ignore_from_now() -> None:
        """Ignore SIGINT/SIGTERM while the process exits, its work done: Python restores the
        default handlers when it shuts down, so a stop signal arriving then (the launcher
        stopping the session because another node failed) would kill it with -15 and hide the
        code it exited with."""
        for signum in (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, signal.SIG_IGN)


class Received:
    """A bounded queue of decoded messages with their receive time (``time.monotonic``), filled
    by a Zenoh callback thread and drained by the node's loop; what overflows is counted. A
    loop may sleep until something arrives (:meth:`wait`), or only something that
    ``wake(message)`` says matters now (the others wait in the queue for the next drain)."""

    def __init__(self, decode: Any, capacity: int = 4096, wake: Any = None) -> None:
        self._decode = decode
        self._wake = wake
        self._queue: deque[tuple[Any, float]] = deque()
        self._capacity = capacity
        self._lock = threading.Lock()
        self._arrived = threading.Event()
        self.dropped = 0

    def __call__(self, sample: Any) -> None:  # the Zenoh callback
        received = time.monotonic()
        try:
            message = self._decode(sample.payload.to_bytes())
        except Exception:  # noqa: BLE001 - a malformed payload is dropped and counted
            self.dropped += 1
            return
        with self._lock:
            if len(self._queue) >= self._capacity:
                self._queue.popleft()
                self.dropped += 1
            self._queue.append((message, received))
        if self._wake is None or self._wake(message):
            self._arrived.set()

    def drain(self) -> list[tuple[Any, float]]:
        with self._lock:
            self._arrived.clear()
            items = list(self._queue)
            self._queue.clear()
        return items

    def wait(self, timeout: float) -> bool:
        """Sleep until a message arrives that :meth:`drain` has not taken yet, at most
        ``timeout`` seconds; whether one did."""
        return self._arrived.wait(max(timeout, 0.0))


def percentile(values: Any, q: float) -> float:
    array = np.asarray(values, dtype=float)
    array = array[np.isfinite(array)]
    return float(np.percentile(array, q)) if array.size else math.nan


def session_duration(scenario: Any, duration: float | None) -> float:
    """The length of a live session in seconds: ``duration`` (``--duration``), or the
    scenario's when it is None.

    Raises
    ------
    ValueError
        When it is shorter than two controller periods, or has more plant steps of ``dt``
        than a session holds: the nodes keep a row of every step in memory until the session
        ends (:data:`BYTES_PER_STEP`, within this machine's memory), and a scenario's run has
        at most :data:`~delaytrack.sim.simulate.MAX_STEPS` steps.
    """
    length = float(scenario.duration if duration is None else duration)
    name = "the scenario's duration" if duration is None else "--duration"
    if not length >= 2 * scenario.T_c:  # NaN too
        raise ValueError(
            f"{name} must be at least two controller periods, 2 T_c = {2 * scenario.T_c:g} s "
            f"(a session of one tick cannot be replayed); got {length!r}"
        )
    steps = length / scenario.dt
    limit = min(MAX_STEPS, physical_memory() / BYTES_PER_STEP)
    if steps > limit:
        raise ValueError(
            f"{name} {length:g} s is {steps:.3g} plant steps of dt = {scenario.dt:g} s; a live "
            f"session has at most {limit:.3g} steps ({limit * scenario.dt:.6g} s) on this "
            f"machine: its nodes keep about {BYTES_PER_STEP} bytes of every step in memory "
            f"until it ends, and a run has at most {MAX_STEPS:.0e} steps; shorten --duration"
        )
    return length


def _folder_turn(out: str) -> contextlib.AbstractContextManager[None]:
    """An exclusive lock between processes named after the folder ``out`` resolved, held on a
    file in the temporary-files folder and deleted when given back: nothing is written into
    ``out`` itself, which may not exist yet. Without ``fcntl`` (Windows), no lock."""
    resolved = os.path.realpath(os.path.expanduser(out))
    key = hashlib.sha256(os.fsencode(resolved)).hexdigest()[:16]
    lock = Path(tempfile.gettempdir()) / f"delaytrack-folder-{key}.lock"
    return exclusive(str(lock), remove=True)


def claim_node_folder(out: str) -> Path:
    """Check the folder ``out`` (``--out``) of a node and mark it as this toolkit's before the
    node writes its first file (module docstring); return it, resolved.

    Raises
    ------
    OutputFolderError
        When it cannot be written, is a file, holds files this toolkit did not write or holds
        a symbolic link; the message names ``--out``.
    """
    with _folder_turn(out):
        return claim_output_folder(check_output_folder(out, "--out"))


def remove_files(folder: Path, names: Iterable[str]) -> None:
    """Remove the files ``names`` (relative to ``folder``) that exist, in turn with the nodes
    that share the folder."""
    with _folder_turn(str(folder)):
        for name in names:
            (folder / name).unlink(missing_ok=True)


#: ``prctl``'s option that sets the signal a process gets when its parent ends (linux/prctl.h).
_PR_SET_PDEATHSIG = 1


def end_with_launcher(stop: StopFlag) -> None:
    """In a node started by ``delaytrack live run`` (:data:`LAUNCHER_PID` set): ask the kernel
    for SIGTERM when the launcher ends (Linux's ``PR_SET_PDEATHSIG``), and stop at once if it
    has ended already, so that no node outlives a launcher that was killed."""
    launcher = os.environ.get(LAUNCHER_PID)
    if not launcher:
        return
    import ctypes

    with contextlib.suppress(OSError, AttributeError):  # not Linux: the check below only
        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)
    if str(os.getppid()) != launcher:
        stop.set(signal.SIGTERM)


def session_files(folder: Path) -> list[Path]:
    """Every file in a session folder, figures included, but the hidden ones (the folder's
    marker, files being written): the files for the folder's record."""
    return [
        path
        for path in sorted(folder.rglob("*"))
        if path.is_file()
        and not any(part.startswith(".") for part in path.relative_to(folder).parts)
    ]


def record_node_files(folder: Path) -> None:
    """Record the files of ``folder`` in its marker once a node has written its own
    (:func:`delaytrack._output.record_outputs`), in turn with the nodes that share it. Every
    file is recorded and none removed: the folder may hold the files of the other nodes of the
    session, which they write outside this turn (a table another node renamed into place
    while this one listed the folder was removed as the earlier session's)."""
    with _folder_turn(str(folder)):
        record_outputs(folder, session_files(folder), remove_others=False)


def load_scenario(source: str, trust: list[str]) -> Any:
    """A scenario file, or the name of a shipped scenario (``two_link_S1``)."""
    from delaytrack.scenario import Scenario
    from delaytrack.scenario.builtin import scenario_file_or_builtin

    return Scenario.from_toml(scenario_file_or_builtin(source), trust=trust)


class NodeBase:
    """One node: built from the scenario, declared on a Zenoh session, run from ``t0``.

    Subclasses set :attr:`role` and implement :meth:`declare`, :meth:`loop` and
    :meth:`outputs`.
    """

    role: str = ""

    def __init__(self, scenario: Any, built: Any, args: Any) -> None:
        self.scenario, self.built, self.args = scenario, built, args
        self.duration = session_duration(scenario, args.duration)
        self.hashes = scenario_hashes(scenario, built.plant)
        self.out = Path(args.out)
        self.dt, self.T_c = scenario.dt, scenario.T_c
        self.steps_per_tick = round(self.T_c / self.dt)
        self.quiet = bool(getattr(args, "quiet", False))
        self.entities: list[Any] = []
        self.log: Any = None
        self.failure: str | None = None  # what stopped the node early, said on stderr
        self.t0 = math.nan
        self._last_status = 0.0  # session time of the last status
        self._status_publisher: Any = None
        self._status_totals: dict[str, Any] = {}  # the totals of the last status

    def declare(self, session: Any, prefix: str) -> None:
        raise NotImplementedError

    def _latest_time(self) -> float:
        """The latest model time (s) a message of this session may carry: its end, and a
        second more (a message of a later time would be kept, unused, until the end)."""
        return self.duration + 1.0

    def loop(self, t0: float, stop: StopFlag, handshake: Handshake) -> None:
        raise NotImplementedError

    def outputs(self) -> dict[str, Any]:
        """Write the node's tables; return its summary (numbers)."""
        raise NotImplementedError

    def close(self) -> None:
        """Release what the node holds besides its Zenoh session (the robot's bridge); called
        once the node is done, however it ended."""

    def declare_status(self, session: Any, prefix: str) -> None:
        """Declare the publisher of the node's status, ``<prefix>/status/<role>``
        (:mod:`delaytrack.live.status`): Zenoh's default, which drops a status the transport
        cannot take at once rather than wait."""
        self._status_publisher = session.declare_publisher(status_key(prefix, self.role))
        self.entities.append(self._status_publisher)

    def status_numbers(self, window: float) -> tuple[dict[str, Any], dict[str, Any]]:
        """The node's status numbers (:mod:`delaytrack.live.status`): those measured over the
        last ``window`` seconds (rates, percentiles) and its counts since the start."""
        raise NotImplementedError

    def status(self, now: float) -> None:
        """At the session time ``now``, once :data:`~delaytrack.live.status.STATUS_PERIOD` has
        passed since the last: publish the node's status (:meth:`status_numbers`, with each
        count's increase over the window) and, unless ``--quiet``, print it on stderr as one
        line."""
        window = now - self._last_status
        if window < STATUS_PERIOD:
            return
        self._last_status = now
        measured, totals = self.status_numbers(window)
        last = {name: count - self._status_totals.get(name, 0) for name, count in totals.items()}
        self._status_totals = totals
        status = make_status(self.role, now, window, {**last, **measured}, totals)
        if self._status_publisher is not None:
            self._status_publisher.put(encode_status(status))
        if not self.quiet:
            print(format_line({self.role: status}), file=sys.stderr, flush=True)

    def metadata(self) -> dict[str, str]:
        return {
            "role": self.role,
            "scenario": self.scenario.name,
            "dt": repr(self.dt),
            "T_c": repr(self.T_c),
            "duration": repr(self.duration),
            "hashes": json.dumps(self.hashes),
        }


def missing_extra() -> str | None:
    """The message for a missing optional dependency of the live loop, or None."""
    import importlib.util

    missing = [m for m in ("zenoh", "mcap", "mcap_ros2") if importlib.util.find_spec(m) is None]
    if missing:
        return (
            f"the live loop needs {', '.join(missing)}: install the optional extra with "
            "pip install -e '.[live]' (from a clone of delaytrack)"
        )
    return None


def enter_realtime(priority: int | None) -> None:
    """Run this thread (the node's loop) under SCHED_FIFO at ``priority``, as a ros2_control
    loop does: a woken loop then preempts every process of the normal policy. Zenoh's threads
    keep the normal policy.

    Raises
    ------
    ValueError
        When the policy cannot be set (not Linux, or no CAP_SYS_NICE / rtprio limit): asked
        for, it is refused rather than silently left out.
    """
    if priority is None:
        return
    import os

    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (AttributeError, OSError) as error:
        reason = getattr(error, "strerror", None) or "not available on this system"
        raise ValueError(
            f"--realtime {priority}: SCHED_FIFO could not be set ({reason}); give the user an "
            "rtprio limit (/etc/security/limits.conf) or CAP_SYS_NICE, or leave --realtime out"
        ) from None


def check_realtime(priority: int | None) -> None:
    """Whether :func:`enter_realtime` would succeed (the same ValueError when not), tried on a
    thread of its own that ends at once, so that the caller's threads keep their policy."""
    if priority is None:
        return
    failed: list[ValueError] = []

    def attempt() -> None:
        try:
            enter_realtime(priority)
        except ValueError as error:
            failed.append(error)

    thread = threading.Thread(target=attempt, name="delaytrack-realtime-check")
    thread.start()
    thread.join()
    if failed:
        raise failed[0]


def run_node(node_class: type[NodeBase], args: Any) -> int:
    """Load, warm up, shake hands, run and write one node; return its exit code. Stop signals
    set the node's :class:`StopFlag` until it returns, and are ignored after."""
    if (problem := missing_extra()) is not None:
        print(one_line(f"error: {problem}"), file=sys.stderr)
        return EXIT_REFUSED
    stop = StopFlag()
    stop.install()
    end_with_launcher(stop)
    try:
        return _run_node(node_class, args, stop)
    finally:
        stop.ignore_from_now()


def _run_node(node_class: type[NodeBase], args: Any, stop: StopFlag) -> int:
    from delaytrack.scenario import ScenarioError

    try:
        scenario = load_scenario(args.scenario, list(args.trust))
        built = scenario.build()
        node = node_class(scenario, built, args)
        enter_realtime(getattr(args, "realtime", None))
    except (ScenarioError, ValueError) as error:
        print(one_line(f"error: {error}"), file=sys.stderr)
        return EXIT_REFUSED
    try:
        node.out = claim_node_folder(args.out)
    except ValueError as error:  # OutputFolderError
        node.close()
        print(one_line(f"error: {error}"), file=sys.stderr)
        return EXIT_REFUSED
    # NumPy's first percentile imports its quantile code, about 8 ms: before the session, not
    # at the node's first status in its loop, where the robot missed steps at t = 1 s for it.
    percentile([0.0, 1.0], 50)
    prefix = f"delaytrack/{args.session}"
    try:
        session = open_session(args.listen, args.connect, args.certificates)
    except OSError as error:
        node.close()
        if isinstance(error, PortInUseError) and getattr(args, "picked_ports", False):
            return EXIT_PORT_TAKEN  # the launcher picks new ports: nothing to say
        print(one_line(f"error: {error}"), file=sys.stderr)
        return EXIT_REFUSED
    handshake = None
    code = EXIT_OK
    try:
        handshake = Handshake(
            session,
            prefix,
            node.role,
            node.hashes,
            start_delay=args.start_delay,
        )
        node.declare(session, prefix)
        node.declare_status(session, prefix)
        try:
            t0 = handshake.wait(args.handshake_timeout, stop)
        except HandshakeError as error:
            if stop():
                return EXIT_INTERRUPTED if stop.signal == signal.SIGINT else EXIT_OK
            hint = (
                "; with --tls-ca, also that each node's certificate is signed by that authority, "
                "still valid, and names the host the others reach it at"
                if args.certificates is not None
                else ""
            )
            print(one_line(f"error: {error}{hint}"), file=sys.stderr)
            return EXIT_REFUSED
        node.t0 = t0
        remove_files(node.out, ROLE_FILES[node.role])  # an earlier session's, if any
        try:
            node.loop(t0, stop, handshake)
        finally:
            if node.log is not None:
                node.log.close()
        # A signal that comes once the loop is over (the launcher ending the session because
        # another node ended) stopped nothing: the node ran to its end.
        stopped_by_signal = stop.signal
        summary = node.outputs()
        offset = handshake.clock_offset
        assert offset is not None  # the handshake agreed t0, so it knows the clock offset
        summary.update(offset.summary())
        summary["realtime_priority"] = getattr(args, "realtime", None)
        summary["mutual_tls"] = args.certificates is not None  # its peers authenticated
        summary["scenario_hashes"] = node.hashes  # what live collect checks its scenario by
        summary["table_bytes"] = table_bytes(node.out, node.role)  # and its tables whole
        summary["table_sha256"] = table_digests(node.out, node.role)
        # which session: collect refuses records of several sessions in one folder
        summary["session"] = {"name": args.session, "t0_robot_clock": handshake.robot_t0}
        summary["stopped_by"] = (
            signal.Signals(stopped_by_signal).name
            if stopped_by_signal
            else ("failure" if node.failure else "duration")
        )
        write_text(node.out / f"{node.role}.json", json_text(summary, indent=1) + "\n")
        record_node_files(node.out)
        if stopped_by_signal == signal.SIGINT:
            code = EXIT_INTERRUPTED
        elif node.failure is not None:
            code = EXIT_FAILED
    finally:
        node.close()
        for entity in node.entities:
            try:
                entity.undeclare()
            except Exception:  # noqa: BLE001, S110 - the session's close undeclares anyway
                pass
        if handshake is not None:
            handshake.close()
        session.close()
    return code
