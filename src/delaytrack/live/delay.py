"""The delay node: the paper's "halting the programme for h(t)" done as a network element.

The paper injected the input delay "by halting the programme for h(t) amount of time ...
between the control input computation and feeding it to the system". This node sits on the
command path between the controller and the robot and holds each command until the toolkit's
rule lets the robot apply it: at time ``t`` the robot applies the latest command whose sample
time satisfies ``t_k <= t - h(t)`` (docs/decisions.md, D10), for the scenario's delay
profile — any profile of the toolkit (constant, S1–S4, traces, random, a user's compiled
kernel), evaluated by the profile's own ``h``.

It evaluates the rule on the robot's step grid ``s_j = j·dt`` (the robot holds each command
over a step, as a zero-order hold sampled at ``dt``): ``lead`` seconds before the robot's step
``s_j`` it computes ``g = s_j - h(s_j)``, picks the latest command received with ``t_k <= g``
and, when it differs from the one it last released, releases it stamped ``apply_at = s_j``. The
robot applies a released command from its step ``apply_at`` on, never earlier, so the rule
holds by construction; the ``lead`` (default :func:`default_lead`: a quarter of the session's
smallest ``h``, within 2 ms, at least ``min(dt/2, 0.5 ms)``) covers the transport to the
robot. When ``t - h(t)`` runs backwards (``dh/dt > 1``) the rule picks an older command again
and it is released again (docs/decisions.md, D11). A command that reaches this node after its
release time is released at the first step after it arrives; its realised delay is then longer
than ``h``, and the logs show it.

The node does not wake at every step: at most steps the rule picks the command last released
and nothing is sent. It computes ahead, from the commands it holds, the next step where the
pick changes (``h`` evaluated on the coming steps at once) and sleeps until ``lead`` before
that step, or until a command arrives that the rule could pick earlier (the plan is then made
again), or at most :data:`_HORIZON`. At ``T_c`` = 10 ms that is about two wake-ups per command
instead of one per millisecond. A wake-up so late that the step is less than
:func:`release_margin` away (``min(lead/2, dt/2, 0.5 ms)``) evaluates the rule at the first step
still that far ahead: at once when that step's own deadline (``lead`` before it) has passed too,
else at its deadline, with the commands that arrive by then (at leads under ``dt`` plus the
margin, a step can be that far ahead before its deadline).

Packet loss (docs/decisions.md, D12d): with a probability ``p`` and a seed (the scenario's
``packet_loss`` table, or ``--loss P --loss-seed S``), command ``k`` is dropped when the
toolkit's counter-based draw :func:`~delaytrack.sim.packet_loss.packet_lost` says so — the
same commands the simulator loses — and the latest command received stays in force.

It records, per command: receive time, lost or not, first release time and the step it was
released for, and ``h`` there.
"""

from __future__ import annotations

import bisect
import functools
import math
import time
from typing import Any

import numpy as np

from delaytrack.live._node import NodeBase, Received, percentile
from delaytrack.live.clock import steps_until
from delaytrack.live.log import McapLog, write_csv
from delaytrack.live.messages import CommandMessage, ReleaseMessage
from delaytrack.live.transport import declare_stream
from delaytrack.sim.packet_loss import PacketLoss, packet_lost

__all__ = [
    "DelayNode",
    "check_session_delay",
    "default_lead",
    "first_reachable_step",
    "release_margin",
    "session_lead",
]

#: Without commands to release, the node wakes at most this often (seconds) to plan again.
_HORIZON = 0.1


def default_lead(dt: float, h_min: float) -> float:
    """How long before a robot step its release is sent by default: a quarter of the smallest
    delay of the session, within 2 ms, and never less than ``min(dt/2, 0.5 ms)``.

    The release must reach the robot before its step: on loopback under load the transport
    took 0.4 ms median and up to 3 ms (p99), so ``min(dt/2, 0.5 ms)`` alone made about a
    third of the applications one step late. A longer lead costs nothing while every command
    reaches this node more than ``lead`` before its release step, that is while ``h`` exceeds
    the controller's sampling phase, compute and transport time by ``lead``: with
    ``lead <= h_min / 4`` that holds up to ``0.75 h_min``.
    """
    return max(min(dt / 2, 5e-4), min(2e-3, h_min / 4))


def release_margin(lead: float, dt: float) -> float:
    """The least time a release is sent before its step: ``min(lead/2, dt/2, 0.5 ms)``. A
    wake-up planned ``lead`` before a step that comes later than ``lead - margin`` evaluates
    the rule at the first step still ``margin`` ahead instead.

    Half the lead, not all of it: with ``margin = lead`` (as before, for leads of 0.5 ms or
    less), any lateness of the wake-up, tens of microseconds at best, moved every release one
    step later than the rule's.
    """
    return min(lead / 2, dt / 2, 5e-4)


def first_reachable_step(now: float, margin: float, dt: float) -> int:
    """The first step ``j`` (at ``j dt``) still at least ``margin`` after ``now`` (seconds from
    the session's start)."""
    return math.ceil((now + margin) / dt - 1e-9)


def session_lead(lead: float | None, delay: Any, dt: float, duration: float) -> tuple[float, float]:
    """``(lead, h_min)``: the lead of a session (``--lead``, or :func:`default_lead`) and the
    smallest ``h`` over its robot steps; a lead longer than half that ``h`` (or the default's
    floor) is a ValueError naming ``--lead``: a command must reach the delay node more than
    the lead before the step it is due at, so a longer lead makes the delays longer than
    ``h(t)``. The launcher checks it before any node starts, the delay node again."""
    steps = np.arange(steps_until(duration, dt)) * dt
    h_min = float(np.min(delay.h(steps))) if steps.size else 0.0
    chosen = default_lead(dt, h_min) if lead is None else lead
    longest = max(h_min / 2, default_lead(dt, h_min))
    if chosen > longest:
        raise ValueError(
            f"--lead {chosen:g} s is longer than half the session's smallest delay, "
            f"h = {h_min * 1e3:g} ms: a command must reach the delay node more than "
            "--lead before the robot step it is due at, so a longer lead makes the delays "
            f"longer than h(t); give at most {longest:g} s"
        )
    return chosen, h_min


def check_session_delay(delay: Any, duration: float) -> None:
    """Refuse a delay profile whose data do not cover a session of ``duration`` seconds from
    ``t = 0`` (a trace that starts later or ends sooner; raises ValueError)."""
    if duration > delay.horizon:
        raise ValueError(
            f"the delay profile is defined up to t = {delay.horizon:g} s; the session "
            f"lasts {duration:g} s (shorten --duration or hold the profile's last value)"
        )
    if delay.start > 0.0:
        raise ValueError(
            f"the delay profile starts at t = {delay.start:g} s, after the session's start "
            "t = 0 s; give it a sample at or before 0"
        )


class DelayNode(NodeBase):
    """The delay node (module docstring)."""

    role = "delay"

    def __init__(self, scenario: Any, built: Any, args: Any) -> None:
        super().__init__(scenario, built, args)
        self.delay = built.delay
        self.m = built.plant.m  # the inputs of every command
        check_session_delay(self.delay, self.duration)
        self.delay.check_run(0.0, self.dt, math.ceil(self.duration / self.dt))
        loss = scenario.simulated_packet_loss
        if getattr(args, "loss", None) is not None:
            loss = PacketLoss(args.loss, args.loss_seed)
        self.loss = loss or PacketLoss()
        self._loss = np.array(self.loss.params(), dtype=float)
        self.lead, self.h_min = session_lead(
            getattr(args, "lead", None), self.delay, self.dt, self.duration
        )
        self.h_max = float(self.delay.h_max)
        self.h(0.0)  # warm up (compile)
        packet_lost(0, self._loss)
        self._clock = time.monotonic  # the session's clock (a test's own in tests)
        self.commands: dict[int, list[Any]] = {}
        self.releases: list[list[Any]] = []
        self._tolerance = 1e-9 * self.dt
        # The commands that may still be released, sorted by t_k, and their t_k.
        self._held_times: list[float] = []
        self._held: list[CommandMessage] = []
        self.wakes = 0  # returns from sleep
        self.missed_steps = 0  # steps skipped because a wake-up came after the next deadline
        self.lateness_ms: list[float] = []  # of each step where the pick changed
        self.session_s = 0.0
        self.lost_count = 0  # commands received and dropped on purpose (packet loss)
        self.duplicates = 0  # commands received again under a seq already taken, not taken
        self._seq_range: tuple[int, int] | None = None  # the least and greatest seq received

    def h(self, t: float) -> float:
        return float(self.delay.h(t))

    def declare(self, session: Any, prefix: str) -> None:
        self._reach = math.inf
        self._received = Received(
            functools.partial(CommandMessage.decode, size=self.m, until=self._latest_time()),
            wake=lambda message: message.t_k <= self._reach,
        )
        self._publisher = declare_stream(session, f"{prefix}/release")
        self._subscriber = session.declare_subscriber(f"{prefix}/command", self._received)
        self.entities += [self._subscriber, self._publisher]

    def _take(self, t0: float) -> bool:
        """Take in the commands that arrived (lost ones recorded, not held); whether any did."""
        arrived = self._received.drain()
        for message, received in arrived:
            if message.seq in self.commands:  # a copy (replayed, or sent twice): not taken
                self.duplicates += 1
                continue
            lost = bool(packet_lost(message.seq, self._loss))
            self.lost_count += lost
            low, high = self._seq_range or (message.seq, message.seq)
            self._seq_range = (min(low, message.seq), max(high, message.seq))
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
            i = bisect.bisect_right(self._held_times, message.t_k)
            self._held_times.insert(i, message.t_k)
            self._held.insert(i, message)
        return bool(arrived)

    def _next_change(self, start: int, stop_at: int, last_released: int | None) -> tuple:
        """``(j, reach)``: ``j`` the first step in ``[start, stop_at)`` where the rule picks
        another command than ``last_released`` from what is held now (None if none), ``reach``
        the largest ``g = s - h(s)`` of the steps before it (a command with a later ``t_k``
        cannot be picked there). ``h`` is evaluated on the steps at once, with the same
        numbers as one by one."""
        s = np.arange(start, stop_at) * self.dt
        g = s - self.delay.h(s)
        found = np.empty(0, dtype=np.int64)
        if self._held_times:
            index = (
                np.searchsorted(np.asarray(self._held_times), g + self._tolerance, side="right") - 1
            )
            seqs = np.array([m.seq for m in self._held], dtype=np.int64)
            previous = -1 if last_released is None else last_released  # sequence numbers >= 0
            found = np.flatnonzero((index >= 0) & (seqs[np.maximum(index, 0)] != previous))
        if not found.size:
            return None, float(np.max(g)) + self._tolerance
        change = int(found[0])
        reach = float(np.max(g[:change])) + self._tolerance if change else -math.inf
        return start + change, reach

    def loop(self, t0: float, stop: Any, handshake: Any) -> None:
        """Wake only where the rule can change (event-driven: docs/decisions.md, D42).

        The rule is evaluated at the steps ``s_j`` as before, ``lead`` before each, with the
        commands received by then; but at a step where the command it picks is the one last
        released nothing is sent, so the node computes ahead, from what it holds, the next step
        where the pick changes and sleeps until ``lead`` before it, or until a command arrives
        (which may change it: the plan is then made again from the first step still ahead).
        Without commands it wakes at most every ``_HORIZON`` seconds. A wake-up so late that
        the step is less than :func:`release_margin` away evaluates the rule at the first step
        that is still that far ahead instead (the steps in between count as missed), at once
        if that step's deadline has passed too, else at its deadline as planned from it.
        """
        self.log = McapLog(self.out / "delay.mcap", t0, self.metadata())
        dt, lead, tolerance = self.dt, self.lead, self._tolerance
        margin = release_margin(lead, dt)
        end = steps_until(self.duration, dt)  # steps 0 .. end - 1
        horizon = max(1, round(_HORIZON / dt))
        clock = self._clock
        last_released: int | None = None
        last_hello = -math.inf
        j = 0  # the first step not yet dealt with
        plan: tuple[int, bool] | None = None  # (step, whether the pick changes there)
        while not stop():
            self._reach = math.inf  # while planning, any arrival wakes the loop
            arrived = self._take(t0)
            now = clock() - t0
            latest = math.floor((now + lead) / dt + 1e-9)  # the latest step whose deadline passed
            feasible = first_reachable_step(now, margin, dt)
            if arrived and plan is not None and latest < plan[0]:
                plan = None  # plan again with it; a planned step already due is dealt with first
            if plan is None:
                start = max(j, feasible)
                if start >= end:
                    break
                self._forget(start * dt)
                last = min(start + horizon, end)
                change, reach = self._next_change(start, last, last_released)
                plan = (last, False) if change is None else (change, True)
                j = start
            step, changes = plan
            if latest >= step:  # its deadline has passed: deal with it
                if changes:
                    k = min(max(step, feasible), end - 1)
                    self.missed_steps += k - step
                    self.lateness_ms.append((now - (step * dt - lead)) * 1e3)
                    if latest >= k:  # its deadline has passed too: release with what is held
                        s = k * dt
                        h = self.h(s)
                        i = bisect.bisect_right(self._held_times, s - h + tolerance) - 1
                        if i >= 0 and self._held[i].seq != last_released:
                            last_released = self._release(self._held[i], s, h, clock() - t0)
                        j = k + 1
                    else:  # a later step, its deadline ahead: plan it with what comes by then
                        j = k
                else:
                    j = step
                plan = None
                if j >= end:
                    break
            else:
                deadline = t0 + step * dt - lead
                # Work that may wait (writing the log), until shortly before the deadline.
                self.log.work(deadline - min(2e-4, dt / 4))
                remaining = deadline - clock()
                if remaining > 0:
                    # Only a command that the rule could pick before the planned step wakes
                    # the loop earlier; the others are taken in at that step.
                    self._reach = reach
                    # Until the deadline, a command or 50 ms (to see a stop request soon).
                    self._received.wait(min(remaining, 0.05))
                    self.wakes += 1
            if now - last_hello > 0.2:
                handshake.publish()
                last_hello = now
            self.status(now)
        self.session_s = clock() - t0
        # Commands in flight when the session ended: recorded as received, never released
        # (taken in until none has come for 0.2 s, at most for a second).
        self._reach = math.inf
        until = clock() + 1.0
        self._take(t0)
        while clock() < until and self._received.wait(min(0.2, until - clock())):
            self._take(t0)

    def status_numbers(self, window: float) -> tuple[dict[str, Any], dict[str, Any]]:
        """Commands received, lost on purpose, missing from the sequence received (``gaps``:
        sent and not received, or ticks the controller missed) and releases, since the
        start."""
        low, high = self._seq_range or (0, -1)
        totals = {
            "received": len(self.commands),
            "lost": self.lost_count,
            "gaps": high - low + 1 - len(self.commands),
            "releases": len(self.releases),
        }
        return {}, totals

    def _forget(self, s: float) -> None:
        """Drop what can never be picked again from ``s`` on: ``g(t) >= t - h_max``."""
        held_times, held = self._held_times, self._held
        while len(held_times) >= 2 and held_times[1] <= s - self.h_max - self._tolerance:
            del held_times[0], held[0]

    def _release(self, chosen: CommandMessage, s: float, h: float, now: float) -> int:
        """Send ``chosen`` to be applied from the robot's step ``s``; record it."""
        self._publisher.put(
            ReleaseMessage(chosen.seq, chosen.t_k, chosen.send_time, now, s, chosen.u).encode()
        )
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
        return chosen.seq

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
            "duplicates": self.duplicates,
            "missed_steps": self.missed_steps,
            "wakes": self.wakes,
            "session_s": self.session_s,
            "wakes_per_s": self.wakes / self.session_s if self.session_s > 0 else math.nan,
            "release_lateness_ms_p50": percentile(self.lateness_ms, 50),
            "release_lateness_ms_p99": percentile(self.lateness_ms, 99),
            "release_minus_h_ms_p99": percentile(np.abs(early) * 1e3, 99) if early else math.nan,
            "packet_loss": self.loss.to_spec(),
            "lead_ms": self.lead * 1e3,
        }


def main(args: Any) -> int:
    from delaytrack.live._node import run_node

    return run_node(DelayNode, args)
