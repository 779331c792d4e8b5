"""What the three nodes share: loading the scenario, the Zenoh session, the handshake, signals,
the status line and the run's life cycle (:func:`run_node`)."""

from __future__ import annotations

import json
import math
import signal
import sys
import threading
import time
from collections import deque
from pathlib import Path
from typing import Any

import numpy as np

from delaytrack.live.transport import Handshake, HandshakeError, open_session, scenario_hashes

__all__ = ["NodeBase", "Received", "StopFlag", "load_scenario", "percentile", "run_node"]

#: Exit codes: 0 done (also when stopped by SIGTERM), 2 refused (a usage error, a scenario
#: that differs from a peer's, no peer in time), 130 stopped by SIGINT.
EXIT_OK, EXIT_REFUSED, EXIT_INTERRUPTED = 0, 2, 130


class StopFlag:
    """Set by SIGINT/SIGTERM (and by the node itself); the loops check it at every wake-up."""

    def __init__(self) -> None:
        self.signal: int | None = None
        self._event = threading.Event()

    def __call__(self) -> bool:
        return self._event.is_set()

    def set(self, signum: int | None = None) -> None:
        if self.signal is None:
            self.signal = signum
        self._event.set()

    def install(self) -> None:
        for signum in (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, lambda s, _frame: self.set(s))


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


def load_scenario(source: str, trust: list[str]) -> Any:
    """A scenario file, or the name of a shipped scenario (``two_link_S1``)."""
    from delaytrack.experiments import builtin_scenario_names, builtin_scenario_path
    from delaytrack.experiments.scenario import Scenario

    path = Path(source)
    if not path.exists() and path.suffix != ".toml" and source in builtin_scenario_names():
        path = builtin_scenario_path(source)
    return Scenario.from_toml(path, trust=trust)


class NodeBase:
    """One node: built from the scenario, declared on a Zenoh session, run from ``t0``.

    Subclasses set :attr:`role` and implement :meth:`declare`, :meth:`loop` and
    :meth:`outputs`.
    """

    role: str = ""

    def __init__(self, scenario: Any, built: Any, args: Any) -> None:
        self.scenario, self.built, self.args = scenario, built, args
        self.duration = float(args.duration if args.duration is not None else scenario.duration)
        if not self.duration > 0:
            raise ValueError(f"--duration must be > 0 seconds; got {self.duration!r}")
        self.out = Path(args.out)
        self.dt, self.T_c = scenario.dt, scenario.T_c
        self.steps_per_tick = round(self.T_c / self.dt)
        self.quiet = bool(getattr(args, "quiet", False))
        self.entities: list[Any] = []
        self.log: Any = None
        self.t0 = math.nan
        self._last_status = 0.0

    def declare(self, session: Any, prefix: str) -> None:
        raise NotImplementedError

    def loop(self, t0: float, stop: StopFlag, handshake: Handshake) -> None:
        raise NotImplementedError

    def outputs(self) -> dict[str, Any]:
        """Write the node's tables; return its summary (numbers)."""
        raise NotImplementedError

    def status(self, now: float, text: str) -> None:
        """A status line on stderr every second (not with ``--quiet``)."""
        if self.quiet or now - self._last_status < 1.0:
            return
        self._last_status = now
        print(f"[{self.role} t={now:6.2f}s] {text}", file=sys.stderr, flush=True)

    def metadata(self) -> dict[str, str]:
        return {
            "role": self.role,
            "scenario": self.scenario.name,
            "dt": repr(self.dt),
            "T_c": repr(self.T_c),
            "duration": repr(self.duration),
            "hashes": json.dumps(scenario_hashes(self.scenario, self.built.plant)),
        }


def missing_extra() -> str | None:
    """The message for a missing optional dependency of the live loop, or None."""
    import importlib.util

    missing = [m for m in ("zenoh", "mcap", "mcap_ros2") if importlib.util.find_spec(m) is None]
    if missing:
        return (
            f"the live loop needs {', '.join(missing)}: install the optional extra with "
            "pip install 'delaytrack[live]'"
        )
    return None


def run_node(node_class: type[NodeBase], args: Any) -> int:
    """Load, warm up, shake hands, run and write one node; return its exit code."""
    from delaytrack.experiments import ScenarioError

    if (problem := missing_extra()) is not None:
        print(f"error: {problem}", file=sys.stderr)
        return EXIT_REFUSED

    stop = StopFlag()
    stop.install()
    try:
        scenario = load_scenario(args.scenario, list(args.trust))
        built = scenario.build()
        node = node_class(scenario, built, args)
    except (ScenarioError, ValueError) as error:
        print(f"error: {error}".replace("\n", "\\n"), file=sys.stderr)
        return EXIT_REFUSED
    node.out.mkdir(parents=True, exist_ok=True)
    prefix = f"delaytrack/{args.session}"
    try:
        session = open_session(args.listen, args.connect)
    except OSError as error:
        print(f"error: {error}", file=sys.stderr)
        return EXIT_REFUSED
    handshake = None
    code = EXIT_OK
    try:
        handshake = Handshake(
            session,
            prefix,
            node.role,
            scenario_hashes(scenario, built.plant),
            start_delay=args.start_delay,
        )
        node.declare(session, prefix)
        try:
            t0 = handshake.wait(args.handshake_timeout, stop)
        except HandshakeError as error:
            if stop():
                return EXIT_INTERRUPTED if stop.signal == signal.SIGINT else EXIT_OK
            print(f"error: {error}", file=sys.stderr)
            return EXIT_REFUSED
        node.t0 = t0
        try:
            node.loop(t0, stop, handshake)
        finally:
            if node.log is not None:
                node.log.close()
        summary = node.outputs()
        summary["stopped_by"] = signal.Signals(stop.signal).name if stop.signal else "duration"
        (node.out / f"{node.role}.json").write_text(json.dumps(summary, indent=1) + "\n")
        if stop.signal == signal.SIGINT:
            code = EXIT_INTERRUPTED
    finally:
        for entity in node.entities:
            try:
                entity.undeclare()
            except Exception:  # noqa: BLE001, S110 - the session's close undeclares anyway
                pass
        if handshake is not None:
            handshake.close()
        session.close()
    return code
