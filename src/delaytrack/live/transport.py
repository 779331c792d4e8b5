"""Zenoh sessions, key expressions and the handshake of the live loop.

Every node opens a Zenoh session in *peer* mode with multicast scouting off and explicit TCP
endpoints (``--listen tcp/127.0.0.1:7447``, ``--connect tcp/10.0.0.2:7447``), so a session
reaches exactly the peers it is told about, on one machine or across machines. Zenoh is the
transport under ROS 2's ``rmw_zenoh``. With :class:`PeerCertificates` (``--tls-ca``,
``--tls-certificate``, ``--tls-key``) the endpoints are TLS or QUIC and Zenoh authenticates
both ends of every link (mutual TLS): a peer without a certificate signed by the session's
authority is not connected, so it can neither send nor receive a message.

Keys live under a session prefix (``delaytrack/<session>/``):

- ``state``    robot → controller, :class:`~delaytrack.live.messages.StateMessage`;
- ``command``  controller → delay node, :class:`~delaytrack.live.messages.CommandMessage`;
- ``release``  delay node → robot, :class:`~delaytrack.live.messages.ReleaseMessage`;
- ``hello``    every node, JSON: role, process id, the hashes of what it runs, its machine's boot
  identifier, the roles it has seen agree with it, and (robot) the session start ``t0`` once
  everyone has shaken hands;
- ``clock``    a query the robot node answers with a reading of its monotonic clock.

The handshake (:class:`Handshake`): each node publishes its hello every 0.1 s. A node that sees
a peer whose hashes differ from its own refuses to run, naming the parts that differ (plant,
coordinates, ``T_c``, ``dt``, scenario). When every node has seen the other two agree with it,
the robot node — the owner of the plant's clock — announces ``t0`` a little in the future on
its monotonic clock, and every node starts its loop at ``t0``: on the same machine as it is, on
another machine mapped to its own clock through an offset measured by round trips
(:mod:`delaytrack.live.clock_sync`). Nodes may start in any
order; a node that sees no peer within ``--handshake-timeout`` gives up with a message naming
the missing roles.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
import threading
import time
from collections.abc import Mapping, Sequence
from typing import Any

from delaytrack._validation import is_real_number
from delaytrack.live.clock_sync import (
    SAME_CLOCK,
    ClockOffset,
    boot_id,
    estimate_clock_offset,
    serve_clock,
)
from delaytrack.live.messages import node_table
from delaytrack.live.tls import TLS_PROTOCOLS, PeerCertificates

__all__ = [
    "ROLES",
    "Handshake",
    "HandshakeError",
    "PortInUseError",
    "differing_parts",
    "open_session",
    "read_hello",
    "scenario_hashes",
]

ROLES = ("controller", "delay", "robot")


class HandshakeError(RuntimeError):
    """The peers could not agree (a different scenario) or did not appear in time."""


def zenoh_config(
    listen: Sequence[str], connect: Sequence[str], certificates: PeerCertificates | None = None
) -> Any:
    """A peer-mode Zenoh configuration with multicast scouting off and the given endpoints;
    with ``certificates``, TLS links that authenticate both ends (Zenoh's ``enable_mtls``)."""
    import zenoh

    config: dict[str, Any] = {
        "mode": "peer",
        "scouting": {"multicast": {"enabled": False}},
    }
    if listen or certificates is not None:
        # With certificates, only the endpoints given (none, for a node that only connects),
        # and only links TLS authenticates: Zenoh's default is to listen on TCP on every
        # interface, over which unauthenticated peers would link to the node.
        config["listen"] = {"endpoints": list(listen)}
    if certificates is not None:
        ca, certificate, key = certificates
        config["transport"] = {
            "link": {
                "protocols": list(TLS_PROTOCOLS),
                "tls": {
                    "root_ca_certificate": ca,
                    "listen_certificate": certificate,
                    "listen_private_key": key,
                    "connect_certificate": certificate,
                    "connect_private_key": key,
                    "enable_mtls": True,
                },
            }
        }
    if connect:
        # Retry connecting while a peer is not up yet: nodes may start in any order.
        config["connect"] = {
            "endpoints": list(connect),
            "timeout_ms": -1,
            "exit_on_failure": False,
        }
    return zenoh.Config.from_json5(json.dumps(config))


def open_session(
    listen: Sequence[str], connect: Sequence[str], certificates: PeerCertificates | None = None
) -> Any:
    """Open the Zenoh session (:func:`zenoh_config`); a listen endpoint that cannot be bound (a
    port in use: :class:`PortInUseError`) or a certificate Zenoh cannot use is an
    :class:`OSError` naming it."""
    import zenoh

    try:
        return zenoh.open(zenoh_config(listen, connect, certificates))
    except zenoh.ZError as error:
        text = str(error).splitlines()[0] if str(error) else type(error).__name__
        text = re.sub(r" at \S+\.rs:\d+\.?", "", text)  # where in Zenoh's Rust source
        in_use = "in use" in text.lower()
        hint = "; is a port in use? choose another with --listen/--connect or --port"
        raise (PortInUseError if in_use else OSError)(
            f"cannot open the Zenoh session (listen {list(listen)}, connect {list(connect)}): "
            f"{text}{hint if in_use else ''}"
        ) from None


class PortInUseError(OSError):
    """A listen endpoint of :func:`open_session` whose port another program holds."""


def declare_stream(session: Any, key: str) -> Any:
    """A publisher for one of the loop's streams (state, command, release): reliable, sent at
    once (``express``), at Zenoh's real-time priority, and *blocking* when the transmission
    queue is full. Zenoh's default for a put is to drop a message that waits more than about a
    millisecond for the queue, which on a loaded machine lost consecutive commands mid-session;
    the only commands a session loses are the ones the delay node drops on purpose."""
    import zenoh

    return session.declare_publisher(
        key,
        express=True,
        congestion_control=zenoh.CongestionControl.BLOCK,
        reliability=zenoh.Reliability.RELIABLE,
        priority=zenoh.Priority.REAL_TIME,
    )


def _digest(value: Any) -> str:
    text = json.dumps(value, sort_keys=True, separators=(",", ":"), default=repr)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _file_digest(path: str) -> str | None:
    """``sha256:<hash>`` of the file at the absolute ``path``, or None if it is not one."""
    if not os.path.isabs(path) or not os.path.isfile(path):
        return None
    with open(path, "rb") as handle:
        return "sha256:" + hashlib.file_digest(handle, "sha256").hexdigest()


def _portable(value: Any) -> Any:
    """``value`` (a scenario's plain data) with every file it names by absolute path — a data
    file, or the file of a ``"python:<file.py>:<function>"`` factory — replaced by the hash of
    its contents: the same scenario in another folder or on another machine gives the same
    data, and an edited file other data."""
    if isinstance(value, Mapping):
        return {key: _portable(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [_portable(item) for item in value]
    if isinstance(value, str):
        if value.startswith("python:"):
            file, colon, function = value[len("python:") :].rpartition(":")
            digest = _file_digest(file) if colon else None
            return f"python:{digest}:{function}" if digest else value
        return _file_digest(value) or value
    return value


#: How far (s) from now, beyond its start delay, a session start announced by a robot node is
#: believed: a hello with a start days ahead held the other nodes waiting.
MAX_START_DISTANCE = 60.0


def read_hello(payload: bytes) -> dict[str, Any] | None:
    """A node's hello read from its payload, or None when it is not one: a node's JSON table
    (:func:`~delaytrack.live.messages.node_table`) with ``hashes`` naming texts, ``agree`` a
    list of texts and ``t0`` a finite number or null. Any peer on the network may publish one:
    hashes that were a list, or a ``t0`` of NaN, stopped nodes in the handshake."""
    hello = node_table(payload, ROLES)
    if hello is None:
        return None
    hashes, agree, t0 = hello.get("hashes"), hello.get("agree", []), hello.get("t0")
    texts = isinstance(hashes, dict) and all(
        isinstance(key, str) and isinstance(value, str) for key, value in hashes.items()
    )
    listed = isinstance(agree, list) and all(isinstance(role, str) for role in agree)
    timed = t0 is None or (is_real_number(t0) and math.isfinite(t0))
    return hello if texts and listed and timed else None


def scenario_hashes(scenario: Any, plant: Any) -> dict[str, str]:
    """Hashes of what two nodes must agree on: the plant (its table and size), its coordinates
    (names and units), ``T_c``, ``dt`` and the whole scenario, with the files it names taken by
    their contents, not their paths (nodes on different machines keep them in other folders)."""
    data = _portable(scenario.to_dict())
    data.pop("duration", None)  # each node may be told another duration on its command line
    return {
        "plant": _digest([data["plant"], plant.n, plant.m]),
        "coordinates": _digest([plant.coordinate_names, plant.coordinate_units]),
        "T_c": _digest(scenario.T_c),
        "dt": _digest(scenario.dt),
        "scenario": _digest(data),
    }


def differing_parts(mine: Mapping[str, str], theirs: Mapping[str, Any]) -> str | None:
    """The parts (:func:`scenario_hashes`) whose hashes differ, named for a message (``"T_c,
    dt"``; ``"the rest of the scenario"`` when only that differs), or None when they agree."""
    differ = [part for part in mine if theirs.get(part) != mine[part]]
    if not differ:
        return None
    return ", ".join(part for part in differ if part != "scenario") or "the rest of the scenario"


class Handshake:
    """Hello exchange and start agreement (module docstring).

    Parameters
    ----------
    session : zenoh.Session
    prefix : str
        Key prefix of the session, ``delaytrack/<name>``.
    role : {"controller", "delay", "robot"}
    hashes : mapping
        :func:`scenario_hashes` of this node.
    start_delay : float
        Seconds between the moment the robot sees everyone agree and ``t0``.
    """

    def __init__(
        self,
        session: Any,
        prefix: str,
        role: str,
        hashes: Mapping[str, str],
        *,
        start_delay: float = 0.5,
        clock: Any = time.monotonic,
        boot: str | None = None,
    ) -> None:
        self.role, self.hashes, self.start_delay = role, dict(hashes), start_delay
        self._clock, self._boot = clock, boot_id() if boot is None else boot
        self._lock = threading.Lock()
        self._peers: dict[str, dict[str, Any]] = {}
        self.t0: float | None = None
        #: ``t0`` on the robot node's clock, the same number in every node of one session.
        self.robot_t0: float | None = None
        self.clock_offset: ClockOffset | None = SAME_CLOCK if role == "robot" else None
        self._session, self._clock_key = session, f"{prefix}/clock"
        self._publisher = session.declare_publisher(f"{prefix}/hello")
        self._subscriber = session.declare_subscriber(f"{prefix}/hello", self._on_hello)
        self._entities = [self._subscriber, self._publisher]
        if role == "robot":  # the session clock is the robot node's
            self._entities.append(serve_clock(session, self._clock_key, clock))

    def _on_hello(self, sample: Any) -> None:
        hello = read_hello(sample.payload.to_bytes())
        if hello is not None and hello["role"] != self.role:
            with self._lock:
                self._peers[hello["role"]] = hello

    def _agreeing(self) -> list[str]:
        with self._lock:
            return sorted(r for r, h in self._peers.items() if h.get("hashes") == self.hashes)

    def _hello(self) -> bytes:
        return json.dumps(
            {
                "role": self.role,
                "pid": os.getpid(),
                "hashes": self.hashes,
                "boot_id": self._boot,
                "agree": self._agreeing(),
                "t0": self.t0,
            }
        ).encode()

    def publish(self) -> None:
        """Publish this node's hello once (also while running: a late peer still sees it)."""
        self._publisher.put(self._hello())

    def _mismatch(self) -> str | None:
        with self._lock:
            peers = dict(self._peers)
        for role, hello in sorted(peers.items()):
            parts = differing_parts(self.hashes, hello["hashes"])  # a table (read_hello)
            if parts is not None:
                return (
                    f"the {role} node (pid {hello.get('pid')}) runs another scenario than this "
                    f"{self.role} node (they differ in {parts}); start every node with the same "
                    "scenario file"
                )
        return None

    def wait(self, timeout: float, stop: Any = lambda: False) -> float:
        """Exchange hellos until the session start ``t0`` is agreed; return it.

        Raises
        ------
        HandshakeError
            On a peer with other hashes, or when not every peer appeared within ``timeout``.
        """
        deadline = self._clock() + timeout
        others = [r for r in ROLES if r != self.role]
        while not stop():
            problem = self._mismatch()
            if problem is not None:
                for _ in range(3):  # let the others see this node's hello and refuse too
                    self.publish()
                    time.sleep(0.1)
                raise HandshakeError(problem)
            with self._lock:
                peers = dict(self._peers)
            if self.role == "robot":
                everyone = all(
                    r in peers and set(peers[r].get("agree", [])) >= set(ROLES) - {r}
                    for r in others
                ) and set(self._agreeing()) == set(others)
                if everyone and self.t0 is None:
                    self.t0 = self.robot_t0 = self._clock() + self.start_delay
            else:
                robot = peers.get("robot")
                if robot is not None and robot.get("t0") is not None:
                    offset = self._offset_to(robot)
                    t0 = float(robot["t0"]) - offset.offset_s
                    # a start the robot would announce: seconds ahead, not days (nor past)
                    if abs(t0 - self._clock()) <= self.start_delay + MAX_START_DISTANCE:
                        self.t0, self.robot_t0 = t0, float(robot["t0"])
            self.publish()
            if self.t0 is not None and (self.role != "robot" or self._clock() > self.t0 - 0.3):
                return self.t0
            # Once the robot announced t0, the others start then: so does it, whatever the
            # time left (it gave up between the announcement and t0, the others ran without it).
            if self.t0 is None and self._clock() > deadline:
                missing = [r for r in others if r not in peers]
                if missing:
                    what = f"no {' and no '.join(missing)} node answered"
                elif self.role == "robot":
                    what = "not every node saw the others agree with it"
                else:
                    what = "the robot node announced no start"
                raise HandshakeError(
                    f"{what} within {timeout:g} s (this {self.role} node waited for the others' "
                    "hello; check that they run with matching --listen/--connect endpoints and "
                    "the same --session)"
                )
            time.sleep(0.1)
        raise HandshakeError("stopped during the handshake")

    def _offset_to(self, robot: Mapping[str, Any]) -> ClockOffset:
        """The robot node's clock minus this node's (:mod:`delaytrack.live.clock_sync`): 0 on
        the same machine, estimated by round trips otherwise (once)."""
        if self.clock_offset is None:
            if self._boot is not None and robot.get("boot_id") == self._boot:
                self.clock_offset = SAME_CLOCK
            else:
                try:
                    self.clock_offset = estimate_clock_offset(
                        self._session, self._clock_key, self._clock
                    )
                except TimeoutError as error:
                    raise HandshakeError(str(error)) from None
        return self.clock_offset

    def close(self) -> None:
        for entity in self._entities:
            try:
                entity.undeclare()
            except Exception:  # noqa: BLE001 - closing a session undeclares anyway
                pass
