"""The real-time controller node.

It runs the scenario's controller — built in, or a user's compiled (or Python) step kernel — at
the period ``T_c`` on the monotonic clock, with absolute deadlines ``t0 + t_k + phase``,
``t_k = k·T_c``: a late wake-up does not shift later ticks, and a wake-up past the next deadline
counts the ticks in between as missed and runs the latest one (no burst). At each tick it reads
the newest robot state sampled at or before ``t_k`` (the robot publishes ``x(t_k)`` at
``t0 + t_k``; the sampling ``phase``, default ``min(T_c/2, 1 ms)``, gives it time to arrive),
evaluates the reference at ``t_k``, runs one step of the control law (the same kernel the
simulator runs), and publishes the command stamped with its sequence number ``k`` and sample
time ``t_k``.

The law reads the state as the simulator's controller does: through the scenario's
``measurement_noise`` (encoder quantisation, white noise on ``q`` and ``q̇``), with the
simulator's :func:`~delaytrack.sim.measurement.measure` at the tick index ``k`` of ``t_k``, so
the noise of tick ``k`` is that of the simulation's tick ``k`` whatever the age of the state
received. ``--no-measurement-noise`` reads the true state instead (said in ``controller.json``
and so in the session's summary). The log keeps, at each tick where the law runs, the state
received from the robot on ``/received`` (stamped with its sample time) and the state the law
read on ``/measured`` (stamped ``t_k``), both ``sensor_msgs/msg/JointState`` with the tick
``k`` as the MCAP message's sequence number.

The delay rule counts from ``t_k``, so the sampling phase, the computing time and the transport
are part of the delay the robot sees, as in the paper's experiment, where the delay was
injected "by halting the programme for h(t) amount of time ... between the control input
computation and feeding it to the system" (that halting is the delay node's job here,
:mod:`delaytrack.live.delay`).

Per tick it records the wake-up lateness, the compute time (reference and law), the age
``t_k - s`` of the state used, ticks skipped, and whether it held its command because the
newest state was older than ``--state-timeout`` (safety: the law is not run on a stale state;
``--stale zero`` sends zeros instead).
"""

from __future__ import annotations

import bisect
import threading
import time
from collections import deque
from typing import Any

import numpy as np

from delaytrack.controllers.stepper import entry_point
from delaytrack.live._node import NodeBase, percentile
from delaytrack.live._tables import session_columns
from delaytrack.live.clock import Ticker
from delaytrack.live.log import McapLog, write_csv
from delaytrack.live.messages import HELD_STALE, CommandMessage, StateMessage
from delaytrack.live.transport import declare_stream
from delaytrack.sim.measurement import MeasurementNoise, measure

__all__ = ["ControllerNode"]


class ControllerNode(NodeBase):
    """The controller node (module docstring)."""

    role = "controller"

    def __init__(self, scenario: Any, built: Any, args: Any) -> None:
        super().__init__(scenario, built, args)
        controller, delay = built.controller, built.delay
        self.n, self.m = controller.n, controller.m
        # The law's step with arrays of its own, checked here (check_run at T_c and h_max).
        self._stepper = controller.stepper(T_c=self.T_c, h_max=delay.h_max)
        self.phase = min(self.T_c / 2, 1e-3) if getattr(args, "phase", None) is None else args.phase
        if not self.phase < self.T_c:  # it would wake after the next tick's time: never ticks
            raise ValueError(
                f"--phase must be less than the controller period T_c = {self.T_c:g} s (it is "
                f"how long after each tick time the state is read); got {self.phase:g}"
            )
        self.state_timeout = (
            max(5 * self.T_c, 0.05) if args.state_timeout is None else args.state_timeout
        )
        self.stale_zero = args.stale == "zero"
        reference = built.reference
        self._reference_kernel = reference.reference_kernel
        if not reference.compiled:
            self._reference_kernel = getattr(
                self._reference_kernel, "py_func", self._reference_kernel
            )
        self._reference_params = reference.params
        # What the law reads: the scenario's measurement noise, unless turned off for a session.
        self.measurement_off = bool(getattr(args, "no_measurement_noise", False))
        self.measurement_noise = (
            None if self.measurement_off else scenario.simulated_measurement_noise
        )
        self._measurement = (self.measurement_noise or MeasurementNoise()).params(self.n)
        self.columns = session_columns(built.plant)
        self.names = list(self.columns.names)
        self._needs_delay = controller.needs_delay
        self._delay = delay
        # Warm up (compile) on x0, then start the law again from its initial state.
        # The received q and q̇ are copied into arrays of the node's own and measured into the
        # stepper's inputs, where the reference is written too, so that every argument of the
        # step and of the measurement is one of the node's (types fixed from here on).
        self._q_received, self._qdot_received = np.zeros(self.n), np.zeros(self.n)
        self._q, self._qdot, self._qd, self._qd_dot, self._qd_ddot = self._stepper.inputs
        self._measure = measure
        self._tick(0, built.x0)
        self._measure = entry_point(measure, self._measure_arguments(0))
        self._tick(0, built.x0)
        self._stepper.reset()
        self._states: deque[tuple[StateMessage, float]] = deque(maxlen=64)
        self._lock = threading.Lock()
        self.rows: list[list[Any]] = []
        self._status_row = 0  # the first row after the last status
        self._stale_ticks = 0  # ticks on a stale state up to that row

    def _on_state(self, sample: Any) -> None:
        received = time.monotonic()
        try:
            message = StateMessage.decode(sample.payload.to_bytes(), self.n, self._latest_time())
        except Exception:  # noqa: BLE001 - a malformed payload is ignored
            return
        with self._lock:
            states = self._states
            if states and message.sample_time < states[-1][0].sample_time:
                # Arrived after a newer one (late, or a copy replayed): kept in the order of
                # sample times, so that it is never taken for the newest.
                if len(states) == states.maxlen:
                    states.popleft()
                times = [kept.sample_time for kept, _ in states]
                states.insert(bisect.bisect_right(times, message.sample_time), (message, received))
            else:
                states.append((message, received))

    def declare(self, session: Any, prefix: str) -> None:
        self._publisher = declare_stream(session, f"{prefix}/command")
        self._subscriber = session.declare_subscriber(f"{prefix}/state", self._on_state)
        self.entities += [self._subscriber, self._publisher]

    def _measure_arguments(self, k: int) -> tuple:
        """The arguments of :func:`~delaytrack.sim.measurement.measure` at tick ``k``."""
        return (
            self._q_received,
            self._qdot_received,
            k,
            self._measurement,
            self._q,
            self._qdot,
        )

    def _tick(self, k: int, x: np.ndarray) -> np.ndarray:
        """The command of tick ``k`` computed from the received state ``x``."""
        t_k = k * self.T_c
        self._q_received[:] = x[: self.n]
        self._qdot_received[:] = x[self.n :]
        self._measure(*self._measure_arguments(k))
        self._reference_kernel(t_k, self._reference_params, self._qd, self._qd_dot, self._qd_ddot)
        h = float(self._delay.h(t_k)) if self._needs_delay else 0.0
        return self._stepper.tick(t_k, h).copy()

    def _latest_state(self, t_k: float) -> tuple[StateMessage, float] | None:
        """The state of the latest sample time at or before ``t_k`` among those kept (in the
        order of their sample times: :meth:`_on_state`), None when there is none."""
        with self._lock:
            states = list(self._states)
        tolerance = 1e-9 * self.dt
        for message, received in reversed(states):
            if message.sample_time <= t_k + tolerance:
                return message, received
        return None

    def loop(self, t0: float, stop: Any, handshake: Any) -> None:
        self.log = McapLog(self.out / "controller.mcap", t0, self.metadata())
        ticker = Ticker(
            t0, self.T_c, phase=self.phase, until=self.duration, stop=stop, idle=self.log.work
        )
        self.ticker = ticker
        last_command: np.ndarray | None = None
        last_hello = 0.0
        for wake in ticker:
            t_k = wake.k * self.T_c
            chosen = self._latest_state(t_k)
            if chosen is None:  # nothing from the robot yet: nothing to compute on
                self.rows.append(
                    [
                        wake.k,
                        t_k,
                        wake.lateness * 1e3,
                        np.nan,
                        np.nan,
                        wake.skipped,
                        "no-state",
                        np.nan,
                        *([np.nan] * self.m),
                    ]
                )
                continue
            state, _received = chosen
            age = t_k - state.sample_time
            start = time.perf_counter()
            flags, what = 0, "ok"
            if age > self.state_timeout:
                flags, what = HELD_STALE, "stale-zero" if self.stale_zero else "stale-hold"
                if self.stale_zero or last_command is None:
                    u = np.zeros(self.m)
                else:
                    u = last_command
            else:
                u = self._tick(wake.k, state.x)
            compute = time.perf_counter() - start
            send = ticker.now()
            self._publisher.put(
                CommandMessage(wake.k, t_k, send, state.sample_time, flags, u).encode()
            )
            last_command = u
            self.log.command(
                "/command",
                seq=wake.k,
                sample_time=t_k,
                log_time=send,
                u=u,
                send_time=send,
                state_time=state.sample_time,
                flags=flags,
            )
            if not flags:
                self.log.state(
                    wake.k, state.sample_time, send, self.names, state.x, topic="/received"
                )
                self.log.state(
                    wake.k,
                    t_k,
                    send,
                    self.names,
                    np.concatenate((self._q, self._qdot)),
                    topic="/measured",
                )
            self.rows.append(
                [
                    wake.k,
                    t_k,
                    wake.lateness * 1e3,
                    compute * 1e3,
                    age * 1e3,
                    wake.skipped,
                    what,
                    send,
                    *u.tolist(),
                ]
            )
            if send - last_hello > 0.2:
                handshake.publish()
                last_hello = send
            self.status(send)

    def status_numbers(self, window: float) -> tuple[dict[str, Any], dict[str, Any]]:
        """Ticks run per second, p99 of wake-up lateness and compute time over the ticks since
        the last status; ticks, missed ticks and ticks on a stale state since the start."""
        rows = self.rows[self._status_row :]
        self._status_row = len(self.rows)
        self._stale_ticks += sum(1 for row in rows if row[6].startswith("stale"))
        measured = {
            "tick_rate_hz": len(rows) / window,
            "lateness_ms_p99": percentile([row[2] for row in rows], 99),
            "compute_ms_p99": percentile([row[3] for row in rows], 99),
        }
        totals = {"ticks": len(self.rows), "missed": self.ticker.missed, "stale": self._stale_ticks}
        return measured, totals

    def outputs(self) -> dict[str, Any]:
        header = [
            "k",
            "t_s",
            "lateness_ms",
            "compute_ms",
            "state_age_ms",
            "skipped_before",
            "status",
            "send_s",
            *self.columns.inputs(),
        ]
        write_csv(self.out / "ticks.csv", header, self.rows)
        rows = self.rows
        lateness = [r[2] for r in rows]
        compute = [r[3] for r in rows]
        return {
            "ticks": len(rows),
            "missed": self.ticker.missed if hasattr(self, "ticker") else 0,
            "commands_sent": sum(1 for r in rows if r[6] != "no-state"),
            "no_state": sum(1 for r in rows if r[6] == "no-state"),
            "stale": sum(1 for r in rows if str(r[6]).startswith("stale")),
            "lateness_ms_p50": percentile(lateness, 50),
            "lateness_ms_p99": percentile(lateness, 99),
            "lateness_ms_max": percentile(lateness, 100),
            "compute_ms_p50": percentile(compute, 50),
            "compute_ms_p99": percentile(compute, 99),
            "state_age_ms_p99": percentile([r[4] for r in rows], 99),
            # Ticks computed on a state sampled before t_k (it had not arrived within the
            # phase): the simulator's controller always reads x(t_k).
            "older_state": sum(1 for r in rows if r[4] > 1e-6),
            "phase_ms": self.phase * 1e3,
            # What the law read: the measurement model applied (None: the true state), and
            # whether --no-measurement-noise turned the scenario's off.
            "measurement_noise": None
            if self.measurement_noise is None
            else self.measurement_noise.to_spec(),
            "measurement_noise_off": self.measurement_off,
        }


def main(args: Any) -> int:
    from delaytrack.live._node import run_node

    return run_node(ControllerNode, args)
