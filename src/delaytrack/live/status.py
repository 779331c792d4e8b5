"""The status of a live session while it runs: what each node publishes once a second, and the
line printed from it.

Each node publishes, about once a second of session time, a small JSON object on the key
``delaytrack/<session>/status/<role>`` (sent from its loop after a tick's work, never waiting
for the transport: a status the transport cannot take at once is dropped)::

    {"role": "robot", "t": 12.0, "window_s": 1.0,
     "last": {...numbers over the last window_s seconds...},
     "total": {...counts since the session started...}}

``t`` is the session time of the status, in seconds; numbers that are not defined (a percentile
of nothing) are ``null``. The fields of ``last`` and ``total``:

- **controller**: ``last`` ``ticks``, ``tick_rate_hz`` (ticks run per second), ``missed``,
  ``stale`` (ticks that held or zeroed the command on a stale state), ``lateness_ms_p99``
  (wake-up lateness), ``compute_ms_p99``; ``total`` ``ticks``, ``missed``, ``stale``.
- **delay**: ``received`` (commands), ``lost`` (dropped on purpose, packet loss), ``gaps``
  (sequence numbers missing between the commands received: commands sent and not received,
  or ticks the controller missed), ``releases``; in ``last`` and ``total`` alike.
- **robot**: ``steps``, ``missed`` (steps whose wake-up was missed), ``zero_input`` (steps
  before the first command or on the command timeout), ``applied`` (commands that came into
  force for the first time); in ``last`` and ``total`` alike; and in ``last``
  ``realised_minus_h_abs_ms_p50`` and ``realised_minus_h_abs_ms_p99``: for the commands that
  came into force in the window, the realised delay (the step ``s`` from which command ``k`` is
  in force, minus its sample time ``t_k``) minus the delay profile ``h(s)`` at that step
  (absolute value): the delay rule ``t_k ≤ t − h(t)`` applied at the robot's steps makes it at
  most about one step ``dt``.

:func:`format_line` turns the latest status of each node into one line; ``delaytrack live run``
prints it from the statuses of its three nodes (:class:`StatusWatch`), a node started alone
from its own.
"""

from __future__ import annotations

import json
import math
import shutil
import sys
import threading
import time
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, TextIO

from delaytrack._validation import is_real_number
from delaytrack.live.messages import node_table

if TYPE_CHECKING:
    from delaytrack.live.tls import PeerCertificates

__all__ = [
    "STATUS_PERIOD",
    "StatusWatch",
    "decode_status",
    "encode_status",
    "format_line",
    "make_status",
    "status_key",
]

#: Seconds of session time between two statuses of a node.
STATUS_PERIOD = 1.0

#: The order of the parts of the line, and the roles a status may come from.
_ROLES = ("controller", "delay", "robot")

#: How long the launcher waits, once a status has arrived, for the other nodes' of the same
#: second before it prints the line (the nodes publish within a few tens of milliseconds).
_GATHER_S = 0.25


def status_key(prefix: str, role: str) -> str:
    """The key a node publishes its status on: ``<prefix>/status/<role>``."""
    return f"{prefix}/status/{role}"


def _defined(value: Any) -> Any:
    """``value`` as JSON holds it: a number that is not finite becomes None."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def make_status(
    role: str, t: float, window: float, last: Mapping[str, Any], total: Mapping[str, Any]
) -> dict[str, Any]:
    """A node's status (module docstring): numbers that are not finite replaced by None."""
    return {
        "role": role,
        "t": float(t),
        "window_s": float(window),
        "last": {name: _defined(value) for name, value in last.items()},
        "total": {name: _defined(value) for name, value in total.items()},
    }


def encode_status(status: Mapping[str, Any]) -> bytes:
    """The payload of a status: JSON text (UTF-8)."""
    return json.dumps(status, allow_nan=False).encode()


def decode_status(payload: bytes) -> dict[str, Any] | None:
    """A status read from its payload, or None when it is not one of a node of the loop: a
    node's JSON table (:func:`~delaytrack.live.messages.node_table`) whose ``last`` and
    ``total`` tables hold numbers (or nulls) only. Any peer on the network may publish one: a
    number that is text stopped the launcher."""
    status = node_table(payload, _ROLES)
    if status is None:
        return None
    for part in ("last", "total"):
        table = status.get(part)
        if not isinstance(table, dict) or not all(
            value is None or is_real_number(value) for value in table.values()
        ):
            return None
    return status


def _ms(value: Any) -> str:
    return "n/a" if value is None else f"{value:.2f} ms"


def _part(status: Mapping[str, Any]) -> str:
    """One node's part of the line."""
    role, last, total = status["role"], status["last"], status["total"]
    if role == "controller":
        rate = last.get("tick_rate_hz")
        return (
            f"controller {'n/a' if rate is None else f'{rate:.0f}'} Hz, lateness p99 "
            f"{_ms(last.get('lateness_ms_p99'))}, {total.get('missed')} missed, "
            f"{total.get('stale')} stale"
        )
    if role == "delay":
        return (
            f"delay {total.get('received')} received, {total.get('lost')} lost, "
            f"{total.get('gaps')} gaps"
        )
    return (
        f"robot {total.get('missed')} missed, {total.get('zero_input')} without a command, "
        f"realised-h |.| p99 {_ms(last.get('realised_minus_h_abs_ms_p99'))}"
    )


def format_line(statuses: Mapping[str, Mapping[str, Any]]) -> str:
    """One line from the latest status of each node (keyed by role), in the order controller,
    delay, robot, starting with the latest session time: ``t=12 s | controller 100 Hz, lateness
    p99 0.43 ms, 0 missed, 0 stale | delay 1200 received, 0 lost, 0 gaps | robot 0 missed, 105
    without a command, realised-h |.| p99 1.02 ms``. The counts are totals since the start; the rate
    and the percentiles are over the last second."""
    t = max(float(status["t"]) for status in statuses.values())
    parts = [_part(statuses[role]) for role in _ROLES if role in statuses]
    return " | ".join([f"t={t:.0f} s", *parts])


class StatusWatch:
    """The status line of ``delaytrack live run``: a Zenoh session of its own, listening on an
    endpoint the nodes connect to, subscribed to ``<prefix>/status/*``; :meth:`show` prints the
    line on ``stream`` shortly after a new second's statuses have arrived.

    On a terminal the line is rewritten in place when it fits the terminal's width; otherwise
    (a file, a pipe, a narrow terminal) one line is printed per second.

    Parameters
    ----------
    listen : str
        The Zenoh endpoint the nodes connect to (``tcp/127.0.0.1:PORT``).
    prefix : str
        The session's key prefix, ``delaytrack/<session>``.
    stream : text file, optional
        Where the line goes (standard error by default).
    certificates : PeerCertificates, optional
        Mutual TLS with the nodes (``listen`` then a TLS endpoint).

    Raises
    ------
    OSError
        When the Zenoh session cannot be opened.
    """

    def __init__(
        self,
        listen: str,
        prefix: str,
        stream: TextIO | None = None,
        certificates: PeerCertificates | None = None,
    ):
        from delaytrack.live.transport import open_session

        self._stream: Any = sys.stderr if stream is None else stream
        self._rewrite = self._stream.isatty()
        self._line_open = False  # a line rewritten in place, not yet ended
        self._lock = threading.Lock()
        self._latest: dict[str, dict[str, Any]] = {}
        self._arrived: float | None = None  # when the first status not yet printed arrived
        self._session = open_session([listen], [], certificates)
        self._subscriber = self._session.declare_subscriber(f"{prefix}/status/*", self._on_status)

    def _on_status(self, sample: Any) -> None:  # the Zenoh callback
        status = decode_status(sample.payload.to_bytes())
        if status is None:
            return
        with self._lock:
            self._latest[status["role"]] = status
            if self._arrived is None:
                self._arrived = time.monotonic()

    def show(self, *, now: bool = False) -> None:
        """Print the line if statuses arrived since the last one, once the other nodes' of the
        same second have had time to arrive (at once with ``now``)."""
        with self._lock:
            ready = self._arrived is not None and (
                now or time.monotonic() - self._arrived >= _GATHER_S
            )
            if not ready:
                return
            self._arrived = None
            statuses = dict(self._latest)
        line = format_line(statuses)
        if self._rewrite and len(line) < shutil.get_terminal_size().columns:
            self._write(f"\r{line}\x1b[K")
            self._line_open = True
        else:
            self._write(("\n" if self._line_open else "") + line + "\n")
            self._line_open = False

    def _write(self, text: str) -> None:
        """Write ``text`` to the stream, until its reader is gone: a reader that closed it
        (``2>&1 | head -1``) ends the status lines, not the session (the launcher died of it,
        its nodes with it, and no summary was written)."""
        if self._stream is None:
            return
        try:
            self._stream.write(text)
            self._stream.flush()
        except (BrokenPipeError, ValueError):  # a closed pipe, or a stream closed
            self._stream = None

    def close(self) -> None:
        """Print what arrived since the last line, end the line and close the Zenoh session."""
        self.show(now=True)
        if self._line_open:
            self._write("\n")
            self._line_open = False
        try:
            self._subscriber.undeclare()
        except Exception:  # noqa: BLE001, S110 - closing the session undeclares anyway
            pass
        self._session.close()
