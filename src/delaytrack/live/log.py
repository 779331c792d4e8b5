"""MCAP logs with ROS 2 schemas, written as a node runs, and the nodes' CSV tables.

Each node writes ``<role>.mcap`` with ``mcap-ros2-support``: the robot's state as
``sensor_msgs/msg/JointState`` on ``/state``, commands as ``delaytrack_msgs/msg/LiveCommand``
(:data:`~delaytrack.live.messages.COMMAND_MSG`) on ``/command`` (controller), ``/release``
(delay node) and ``/applied`` (robot); the controller logs the state it received and the state
its law read (through the measurement model) as ``JointState`` on ``/received`` and
``/measured``. Session metadata (``t0`` on the monotonic clock and in
UNIX time, the scenario's hashes, ``dt``, ``T_c``) is a metadata record named ``session``.

Writing a message (encoding it to CDR) costs about 0.1 ms of Python, too much for a 1 ms loop,
so the nodes only queue what to log (:meth:`McapLog.state`, :meth:`McapLog.command`) and the
log is written in the loop's idle time before each sleep (:meth:`McapLog.work`, called by the
:class:`~delaytrack.live.clock.Ticker`) and at the end. The file is written in small
uncompressed chunks (:data:`CHUNK_BYTES`) and flushed at every chunk, so a node that is
killed leaves a file that the ``mcap`` readers decode up to its last chunk (read it as a
stream, ``NonSeekingReader(...).iter_decoded_messages(log_time_order=False)``, which
stops at the cut with ``mcap.exceptions.EndOfFile``, or repair it with ``mcap recover``).
A node that stops normally, or on SIGINT/SIGTERM, finishes the file with its summary and index.
"""

from __future__ import annotations

import csv
import time
from collections import deque
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from delaytrack._io import atomic_path
from delaytrack.live.messages import COMMAND_MSG, COMMAND_TYPE, JOINT_STATE_MSG, JOINT_STATE_TYPE

__all__ = ["CHUNK_BYTES", "McapLog", "write_csv"]

#: Chunk size of the MCAP logs: at most this much is lost when a node is killed.
CHUNK_BYTES = 4096


class McapLog:
    """A ROS 2 MCAP log of one node (module docstring).

    Parameters
    ----------
    path : path
    t0 : float
        Session start on the monotonic clock; session times are written as UNIX nanoseconds
        ``unix_t0 + t`` in log and header stamps.
    metadata : mapping of str to str
    """

    def __init__(self, path: str | Path, t0: float, metadata: Mapping[str, str]) -> None:
        from mcap.writer import CompressionType
        from mcap_ros2.writer import Writer

        self.path = Path(path)
        self._file = open(self.path, "wb")  # noqa: SIM115 - closed in close()
        self._writer = Writer(self._file, chunk_size=CHUNK_BYTES, compression=CompressionType.NONE)
        self._unix_t0 = time.time() - (time.monotonic() - t0)
        self._state = self._writer.register_msgdef(JOINT_STATE_TYPE, JOINT_STATE_MSG)
        self._command = self._writer.register_msgdef(COMMAND_TYPE, COMMAND_MSG)
        self._writer.add_metadata(
            "session", {**metadata, "unix_t0": repr(self._unix_t0), "t0_monotonic": repr(t0)}
        )
        self._size = 0
        self._closed = False
        self._queue: deque[tuple[Any, ...]] = deque()
        self._file.flush()

    def _ns(self, t: float) -> int:
        return int(round((self._unix_t0 + t) * 1e9))

    def _stamp(self, t: float) -> dict[str, Any]:
        ns = self._ns(t)
        return {
            "stamp": {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000},
            "frame_id": "",
        }

    def state(self, *args: Any, **kwargs: Any) -> None:
        """Queue a ``JointState`` (arguments of :meth:`_write_state`; arrays are copied)."""
        self._queue.append((self._write_state, _copied(args), _copied(kwargs)))

    def command(self, *args: Any, **kwargs: Any) -> None:
        """Queue a ``LiveCommand`` (arguments of :meth:`_write_command`)."""
        self._queue.append((self._write_command, _copied(args), _copied(kwargs)))

    def work(self, until: float) -> None:
        """Write queued messages while ``time.monotonic() < until``."""
        queue = self._queue
        while queue and time.monotonic() < until:
            write, args, kwargs = queue.popleft()
            write(*args, **kwargs)

    def _write_state(
        self,
        seq: int,
        sample_time: float,
        log_time: float,
        names: Sequence[str],
        x: np.ndarray,
        effort: np.ndarray | None = None,
        topic: str = "/state",
    ) -> None:
        """A ``JointState`` at model time ``sample_time`` on ``topic``, logged at session time
        ``log_time``."""
        n = len(names)
        self._writer.write_message(
            topic,
            self._state,
            {
                "header": self._stamp(sample_time),
                "name": list(names),
                "position": x[:n].tolist(),
                "velocity": x[n:].tolist(),
                "effort": [] if effort is None else effort.tolist(),
            },
            log_time=self._ns(log_time),
            publish_time=self._ns(sample_time),
            sequence=seq & 0xFFFFFFFF,
        )
        self._flush()

    def _write_command(
        self,
        topic: str,
        *,
        seq: int,
        sample_time: float,
        log_time: float,
        u: np.ndarray,
        send_time: float = float("nan"),
        receive_time: float = float("nan"),
        release_time: float = float("nan"),
        apply_at: float = float("nan"),
        state_time: float = float("nan"),
        flags: int = 0,
    ) -> None:
        """A ``LiveCommand`` on ``topic`` (session-clock seconds; NaN where not known)."""
        self._writer.write_message(
            topic,
            self._command,
            {
                "header": self._stamp(sample_time),
                "seq": int(seq),
                "sample_time": float(sample_time),
                "send_time": float(send_time),
                "receive_time": float(receive_time),
                "release_time": float(release_time),
                "apply_at": float(apply_at),
                "state_time": float(state_time),
                "flags": int(flags),
                "command": u.tolist(),
            },
            log_time=self._ns(log_time),
            publish_time=self._ns(send_time if send_time == send_time else log_time),
            sequence=seq & 0xFFFFFFFF,
        )
        self._flush()

    def _flush(self) -> None:
        # The writer hands a finished chunk to the file; push it to the kernel then, so that a
        # killed process leaves it on disk.
        size = self._file.tell()
        if size != self._size:
            self._file.flush()
            self._size = size

    def close(self) -> None:
        """Finish the file (summary and index) and close it."""
        if self._closed:
            return
        self._closed = True
        try:
            self.work(float("inf"))
            self._writer.finish()
        finally:
            self._file.close()


def _copied(values: Any) -> Any:
    if isinstance(values, dict):
        return {k: v.copy() if isinstance(v, np.ndarray) else v for k, v in values.items()}
    return tuple(v.copy() if isinstance(v, np.ndarray) else v for v in values)


def write_csv(path: str | Path, header: Sequence[str], rows: Iterable[Sequence[Any]]) -> Path:
    """Write a CSV table atomically (numbers as ``repr``, so they read back exactly): a reader,
    or a node killed while writing, leaves the old file or the complete new one."""
    path = Path(path)
    with atomic_path(path) as temporary, open(temporary, "w", newline="", encoding="utf-8") as out:
        writer = csv.writer(out)
        writer.writerow(header)
        for row in rows:
            writer.writerow([repr(v) if isinstance(v, float) else v for v in row])
    return path
