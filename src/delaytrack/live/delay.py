"""The delay node: the paper's "halting the programme for h(t)" done as a network element.

The paper injected the input delay "by halting the programme for h(t) amount of time ...
between the control input computation and feeding it to the system". This node sits on the
command path between the controller and the robot and holds each command until the toolkit's
rule lets the robot apply it: at time ``t`` the robot applies the latest command whose sample
time satisfies ``t_k <= t - h(t)`` (D10 of the design decisions), for the scenario's delay
profile — any profile of the toolkit (constant, S1–S4, traces, random, a user's compiled
kernel), evaluated by the profile's own ``h``.

It evaluates the rule on the robot's step grid ``s_j = j·dt`` (the robot holds each command
over a step, as a zero-order hold sampled at ``dt``): ``lead`` seconds before the robot's step
``s_j`` it computes ``g = s_j - h(s_j)``, picks the latest command received with ``t_k <= g``
and, when it differs from the one it last released, releases it stamped ``apply_at = s_j``. The
robot applies a released command from its step ``apply_at`` on, never earlier, so the rule
holds by construction; the ``lead`` (default ``min(dt/2, 0.5 ms)``) covers the transport to
the robot. When ``t - h(t)`` runs backwards (``dh/dt > 1``) the rule picks an older command
again and it is released again (D11). A command that reaches this node after its release time
is released at the first step after it arrives; its realised delay is then longer than ``h``,
and the logs show it.

Packet loss (D12d): with a probability ``p`` and a seed (the scenario's ``packet_loss`` table,
or ``--loss P --loss-seed S``), command ``k`` is dropped when the toolkit's counter-based draw
:func:`~delaytrack.sim.packet_loss.packet_lost` says so — the same commands the simulator loses
— and the latest command received stays in force.

It records, per command: receive time, lost or not, first release time and the step it was
released for, and ``h`` there.
"""

from __future__ import annotations

import bisect
import math
import time
from typing import Any

import numpy as np

from delaytrack.live._node import NodeBase, Received, percentile
from delaytrack.live.clock import Ticker
from delaytrack.live.log import McapLog, write_csv
from delaytrack.live.messages import CommandMessage, ReleaseMessage
from delaytrack.sim.packet_loss import PacketLoss, packet_lost

__all__ = ["DelayNode"]


class DelayNode(NodeBase):
    """The delay node (module docstring)."""

    role = "delay"

    def __init__(self, scenario: Any, built: Any, args: Any) -> None:
        super().__init__(scenario, built, args)
        self.delay = built.delay
        if self.duration > self.delay.horizon:
            raise ValueError(
                f"the delay profile is defined up to t = {self.delay.horizon:g} s; the session "
                f"lasts {self.duration:g} s (shorten --duration or hold the profile's last value)"
            )
        self.delay.check_run(0.0, self.dt, math.ceil(self.duration / self.dt))
        loss = scenario.simulated_packet_loss
        if getattr(args, "loss", None) is not None:
            loss = PacketLoss(args.loss, args.loss_seed)
        self.loss = loss or PacketLoss()
        self._loss = np.array(self.loss.params(), dtype=float)
        self.lead = min(self.dt / 2, 5e-4) if getattr(args, "lead", None) is None else args.lead
        self.h_max = float(self.delay.h_max)
        self.h(0.0)  # warm up (compile)
        packet_lost(0, self._loss)
        self.commands: dict[int, list[Any]] = {}
        self.releases: list[list[Any]] = []

    def h(self, t: float) -> float:
        return float(self.delay.h(t))

    def declare(self, session: Any, prefix: str) -> None:
        self._received = Received(CommandMessage.decode)
        self._publisher = session.declare_publisher(f"{prefix}/release", express=True)
        self._subscriber = session.declare_subscriber(f"{prefix}/command", self._received)
        self.entities += [self._subscriber, self._publisher]

    def loop(self, t0: float, stop: Any, handshake: Any) -> None:
        self.log = McapLog(self.out / "delay.mcap", t0, self.metadata())
        ticker = Ticker(
            t0, self.dt, phase=-self.lead, until=self.duration, stop=stop, idle=self.log.work
        )
        self.ticker = ticker
        held_times: list[float] = []  # t_k of the commands that may still be released, sorted
        held: list[CommandMessage] = []
        last_released: int | None = None
        last_hello = 0.0
        tolerance = 1e-9 * self.dt
        for wake in ticker:
            s = wake.k * self.dt
            for message, received in self._received.drain():
                lost = bool(packet_lost(message.seq, self._loss))
                self.commands[message.seq] = [
                    message.seq,
                    message.t_k,
                    message.send_time,
                    received - t0,
                    int(lost),
                    math.nan,
                    math.nan,
                    math.nan,
                ]
                if lost:
                    continue
                i = bisect.bisect_right(held_times, message.t_k)
                held_times.insert(i, message.t_k)
                held.insert(i, message)
            h = self.h(s)
            g = s - h
            i = bisect.bisect_right(held_times, g + tolerance) - 1
            if i >= 0 and held[i].seq != last_released:
                chosen = held[i]
                now = ticker.now()
                self._publisher.put(
                    ReleaseMessage(
                        chosen.seq, chosen.t_k, chosen.send_time, now, s, chosen.u
                    ).encode()
                )
                last_released = chosen.seq
                record = self.commands.get(chosen.seq)
                if record is not None and math.isnan(record[5]):
                    record[5], record[6], record[7] = now, s, h
                self.releases.append([chosen.seq, chosen.t_k, now, s, h])
                self.log.command(
                    "/release",
                    seq=chosen.seq,
                    sample_time=chosen.t_k,
                    log_time=now,
                    u=chosen.u,
                    send_time=chosen.send_time,
                    receive_time=record[3] if record else math.nan,
                    release_time=now,
                    apply_at=s,
                )
            # Forget what can never be picked again: g(t) >= t - h_max for every later t.
            while len(held_times) >= 2 and held_times[1] <= s - self.h_max - tolerance:
                del held_times[0], held[0]
            if wake.now - last_hello > 0.2:
                handshake.publish()
                last_hello = wake.now
                self.status(
                    wake.now,
                    f"received {len(self.commands)}  released {len(self.releases)}  "
                    f"h {h * 1e3:.1f} ms",
                )
        # Commands in flight when the session ended: recorded as received, never released.
        time.sleep(0.1)
        for message, received in self._received.drain():
            self.commands[message.seq] = [
                message.seq,
                message.t_k,
                message.send_time,
                received - t0,
                int(bool(packet_lost(message.seq, self._loss))),
                math.nan,
                math.nan,
                math.nan,
            ]

    def outputs(self) -> dict[str, Any]:
        header = [
            "seq",
            "t_k_s",
            "sent_s",
            "received_s",
            "lost",
            "released_s",
            "apply_at_s",
            "h_at_apply_s",
        ]
        rows = [self.commands[k] for k in sorted(self.commands)]
        write_csv(self.out / "releases.csv", header, rows)
        write_csv(
            self.out / "release_events.csv",
            ["seq", "t_k_s", "released_s", "apply_at_s", "h_s"],
            self.releases,
        )
        early = [(r[6] - r[1]) - r[7] for r in rows if not math.isnan(r[6])]
        return {
            "received": len(rows),
            "lost": sum(r[4] for r in rows),
            "released": len(self.releases),
            "rereleased": len(self.releases) - sum(1 for r in rows if not math.isnan(r[6])),
            "dropped_by_queue": self._received.dropped,
            "missed_steps": self.ticker.missed if hasattr(self, "ticker") else 0,
            "release_minus_h_ms_p99": percentile(np.abs(early) * 1e3, 99) if early else math.nan,
            "packet_loss": self.loss.to_spec(),
            "lead_ms": self.lead * 1e3,
        }


def main(args: Any) -> int:
    from delaytrack.live._node import run_node

    return run_node(DelayNode, args)
