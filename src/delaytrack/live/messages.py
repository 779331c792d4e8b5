"""Wire format of the live loop's messages, and their ROS 2 message definitions for the logs.

On the wire (Zenoh payloads) every message is a fixed little-endian header, whose last field
counts the float64 values that follow (:class:`_Frame`), so that a node decodes it in a few
microseconds. Times are seconds on the *session
clock*: ``time.monotonic() - t0`` of the process that stamped them, where ``t0`` is the session
start agreed at the handshake (:mod:`delaytrack.live.transport`). Model times (a state's sample
time, a command's tick time ``t_k``) are the times of the simulated world, on the grid
``j·dt`` / ``k·T_c``; the session clock is locked to them (the robot steps ``j`` at
``t0 + j·dt``).

Three kinds travel:

- :class:`StateMessage` (robot → controller): ``x(s)`` at the sample time ``s``;
- :class:`CommandMessage` (controller → delay node): the command of tick ``k``, its sample time
  ``t_k``, the sample time of the state it was computed from;
- :class:`ReleaseMessage` (delay node → robot): a command released under the delay rule, with
  the robot step ``apply_at`` from which it is in force.

In the MCAP logs the same contents are written with ROS 2 schemas: the state as
``sensor_msgs/msg/JointState`` and the commands as ``delaytrack_msgs/msg/LiveCommand``
(:data:`COMMAND_MSG`), so that ``ros2 bag``, Foxglove and the ``mcap`` readers open them.
"""

from __future__ import annotations

import json
import struct
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "COMMAND_MSG",
    "COMMAND_TYPE",
    "JOINT_STATE_MSG",
    "JOINT_STATE_TYPE",
    "CommandMessage",
    "ReleaseMessage",
    "StateMessage",
    "node_table",
]


#: The largest time (s) a message may carry, on the session clock or the model's: the logs
#: stamp times in whole seconds of 32 bits (a time of 1e12 s ended a node).
MAX_TIME = 1e9
#: The largest sequence number (a tick a millisecond for almost 9000 years).
MAX_SEQ = 2**48


class _Frame:
    """The bytes of one kind of message: a little-endian header of ``fields`` (:mod:`struct`
    codes) and a count ``c`` (``uint32``), then ``per_count · c`` little-endian float64 values.

    A message is taken only whole and well formed: exactly the bytes its count says, its
    sequence number (the first field) in ``[0, MAX_SEQ)``, its times (the float fields) finite
    and within ``MAX_TIME``, its values finite, and the count the receiver expects; anything
    else is a ValueError (a node drops the message and counts it), so that no peer's payload
    reaches a node's loop, its logs or a robot as a NaN, a wrong shape or a time a log cannot
    stamp.

    Parameters
    ----------
    fields : str
        The header's fields before the count, as :mod:`struct` format codes.
    model_time : tuple
        The name and index of the field holding the message's model time.
    per_count : int
        Values per unit of the count (2 for a state ``[q, q̇]`` counted by ``n``).
    """

    def __init__(self, fields: str, model_time: tuple[str, int], per_count: int = 1) -> None:
        self._header = struct.Struct(f"<{fields}I")
        self._times = [i for i, code in enumerate(fields) if code == "d"]
        self._model_time = model_time
        self._per_count = per_count

    def pack(self, fields: tuple[int | float, ...], values: np.ndarray) -> bytes:
        """The bytes of a message with the header ``fields`` and the array ``values``."""
        array = np.ascontiguousarray(values, dtype="<f8")
        return self._header.pack(*fields, array.size // self._per_count) + array.tobytes()

    def unpack(
        self, data: bytes, count: int | None = None, until: float = MAX_TIME
    ) -> tuple[Any, ...]:
        """The header's fields of ``data``, then its array (a copy); a ValueError unless it is
        well formed (the class docstring), with ``count`` values per unit when given and its
        model time at most ``until`` (a session's end: a later one would be kept, unused,
        until it ends)."""
        *fields, given = self._header.unpack_from(data)
        if len(data) != self._header.size + 8 * self._per_count * given:
            raise ValueError(f"{len(data)} bytes, not those of {given} values")
        if count is not None and given != count:
            raise ValueError(f"{given} values per unit, not {count}")
        if not 0 <= fields[0] < MAX_SEQ:
            raise ValueError(f"sequence number {fields[0]}")
        if not all(abs(fields[i]) <= MAX_TIME for i in self._times):  # NaN too
            raise ValueError("a time that is not finite or beyond MAX_TIME")
        name, index = self._model_time
        if not fields[index] <= until:
            raise ValueError(f"{name} {fields[index]} after the session's end")
        values = np.frombuffer(
            data, dtype="<f8", count=self._per_count * given, offset=self._header.size
        ).copy()
        if not np.all(np.isfinite(values)):
            raise ValueError("a value that is not finite")
        return (*fields, values)


_STATE = _Frame("qdd", ("sample_time", 1), per_count=2)  # seq, sample time, send time; n, x
_COMMAND = _Frame("qdddq", ("t_k", 1))  # seq, t_k, send time, state sample time, flags; m, u
_RELEASE = _Frame("qdddd", ("apply_at", 4))  # seq, t_k, command sent, released, apply_at; m, u

#: Flags of a command: the controller held its previous command because its latest state was
#: older than the limit (``--state-timeout``).
HELD_STALE = 1


@dataclass(frozen=True)
class StateMessage:
    """The robot's state ``x(s) = [q, q̇]`` at sample time ``s`` (model time, seconds)."""

    seq: int
    sample_time: float
    send_time: float
    x: np.ndarray

    def encode(self) -> bytes:
        return _STATE.pack((self.seq, self.sample_time, self.send_time), self.x)

    @classmethod
    def decode(cls, data: bytes, size: int | None = None, until: float = MAX_TIME) -> StateMessage:
        """The message in ``data`` (:meth:`_Frame.unpack`)."""
        return cls(*_STATE.unpack(data, size, until))


@dataclass(frozen=True)
class CommandMessage:
    """The command of tick ``seq`` computed for sample time ``t_k`` from the state sampled at
    ``state_time``."""

    seq: int
    t_k: float
    send_time: float
    state_time: float
    flags: int
    u: np.ndarray

    def encode(self) -> bytes:
        return _COMMAND.pack(
            (self.seq, self.t_k, self.send_time, self.state_time, self.flags), self.u
        )

    @classmethod
    def decode(
        cls, data: bytes, size: int | None = None, until: float = MAX_TIME
    ) -> CommandMessage:
        """The message in ``data`` (:meth:`_Frame.unpack`)."""
        return cls(*_COMMAND.unpack(data, size, until))


@dataclass(frozen=True)
class ReleaseMessage:
    """Command ``seq`` released by the delay node at ``release_time`` (session clock), in force
    at the robot from its step at model time ``apply_at`` on."""

    seq: int
    t_k: float
    command_send_time: float
    release_time: float
    apply_at: float
    u: np.ndarray

    def encode(self) -> bytes:
        return _RELEASE.pack(
            (self.seq, self.t_k, self.command_send_time, self.release_time, self.apply_at), self.u
        )

    @classmethod
    def decode(
        cls, data: bytes, size: int | None = None, until: float = MAX_TIME
    ) -> ReleaseMessage:
        """The message in ``data`` (:meth:`_Frame.unpack`)."""
        return cls(*_RELEASE.unpack(data, size, until))


#: Largest JSON message (a node's hello or status) read: a node's is a few hundred bytes.
MAX_JSON_BYTES = 2**16


def node_table(payload: bytes, roles: tuple[str, ...]) -> dict[str, Any] | None:
    """The JSON table of a node's hello or status, or None when the payload is not one: at
    most :data:`MAX_JSON_BYTES`, JSON (nested as deep as it likes: no ``RecursionError``), a
    table whose ``role`` is one of ``roles``. Any peer on the network may publish one; the
    caller checks the table's own fields."""
    if len(payload) > MAX_JSON_BYTES:
        return None
    try:
        table = json.loads(payload)
    except (ValueError, RecursionError):
        return None
    return table if isinstance(table, dict) and table.get("role") in roles else None


# ---- ROS 2 message definitions for the MCAP logs ---------------------------------------------

#: ``sensor_msgs/msg/JointState`` with its dependencies, in the concatenated form that ROS 2
#: bags store (``MSG:`` sections separated by a line of ``=``).
JOINT_STATE_TYPE = "sensor_msgs/msg/JointState"
JOINT_STATE_MSG = """std_msgs/Header header
string[] name
float64[] position
float64[] velocity
float64[] effort
================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"""

#: The live loop's command message. Times are session-clock seconds (``time.monotonic() - t0``
#: of the process that stamped them; ``t0`` is in the log's ``session`` metadata); ``header``
#: carries ``t_k`` mapped to UNIX time for tools that sort by stamps.
COMMAND_TYPE = "delaytrack_msgs/msg/LiveCommand"
COMMAND_MSG = """std_msgs/Header header
int64 seq
float64 sample_time
float64 send_time
float64 receive_time
float64 release_time
float64 apply_at
float64 state_time
uint32 flags
float64[] command
================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"""
