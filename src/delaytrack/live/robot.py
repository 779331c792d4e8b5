"""The robot node: in real time, at every step ``dt``, read the robot's state and write its input.

The node wakes at the absolute deadlines ``t0 + j·dt`` and talks to a robot through a
:class:`~delaytrack.live.bridge.RobotBridge`: at the start of step ``j`` (model time
``s = j·dt``) it reads the state ``x(s)`` (:meth:`~delaytrack.live.bridge.RobotBridge.read_state`),
publishes it on the ``state`` key (every ``--state-every`` steps, default every controller
period, at the tick times), picks the command in force — the released command with the latest
``apply_at <= s`` (:mod:`delaytrack.live.delay`) — saturates it to the scenario's
``input_limits`` (docs/decisions.md, D12b) and writes it
(:meth:`~delaytrack.live.bridge.RobotBridge.write_command`), which the robot holds over the
step, as a zero-order hold sampled at ``dt``.

The robot is, by default, the scenario's plant (:class:`SimulatedRobot`): ``M(q) q̈ + N(q, q̇)
= G(q) u`` — any plant of the toolkit whose terms the simulator integrates (analytic, a user's
compiled or Python plant, a MuJoCo model's terms, the P3-DX with its payload schedule) —
advanced by one RK4 step of ``dt`` per write, so that model time stays locked to the session
clock. The step is the simulator's own RK4 sub-step compiled for the plant
(:mod:`delaytrack.live._plant_step`: a few microseconds, against 0.15 ms in Python; compiled
once, announced on stderr, then loaded from numba's disk cache); a plant whose kernel is plain
Python is stepped in Python. With ``--bridge FILE.py:FUNCTION`` the robot is yours
(:mod:`delaytrack.live.bridge`): a real robot's driver, or a simulator with a clock of its own.

A wake-up later than the next deadline has missed the steps in between (counted, ``missed`` in
``steps.csv``, with the input the robot held over them). The simulated plant, whose time
advances one step per write, is read and written at each of them on that wake-up, its states
at the tick times published late; a robot that lives in real time is read and written once, for
the latest step.

Safety: before the first command the node writes the scenario's ``u_init`` (zero unless the
scenario sets it, as the simulator does), and when no released command has arrived for
``--command-timeout`` seconds (default ``max(0.1 s, 10·T_c)``) zero input; those steps are
counted and logged. A bridge call that raises, or a state read that is not
finite or has the wrong shape (the simulated plant's state that is not finite, or a mass
matrix that is not positive definite), stops the node: one line on stderr, the bridge closed,
the log and tables written up to that step, exit code 1.
"""

from __future__ import annotations

import functools
import math
import sys
from typing import Any

import numpy as np

from delaytrack._compile.functions import FEW_POINTS
from delaytrack.live._node import NodeBase, Received, percentile
from delaytrack.live._tables import session_columns
from delaytrack.live.bridge import DRIVER_ERRORS, RobotBridge, check_state, load_bridge
from delaytrack.live.clock import Ticker, steps_until
from delaytrack.live.log import McapLog, write_csv
from delaytrack.live.messages import ReleaseMessage, StateMessage
from delaytrack.live.transport import declare_stream
from delaytrack.sim._kernel_checks import check_reduced_start, velocities_on_constraints

__all__ = ["PlantStepper", "RobotNode", "SimulatedRobot"]


class PlantStepper:
    """One RK4 step of ``dt`` of a plant's terms with a held input: the simulator's own scheme.

    For a compiled plant the step is the engine's RK4 sub-step compiled for the plant's kernel
    (:mod:`delaytrack.live._plant_step`, about a microsecond a step), called on arrays this
    object owns: :attr:`x` (the state, advanced in place) and :attr:`u` (the input held over
    the step). A plant whose kernel is plain Python is stepped by the same scheme in Python
    (:meth:`python_step`). A plant stepped by an integrator of its own (a MuJoCo model with
    ``stepping = "mujoco"``, the robot on contact wheels) takes each step with it, as the
    simulator does: ``dt`` must be the model's timestep, and the first step resets MuJoCo's
    data. The simulator also splits a step where the delayed input switches; here the input
    switches only at step boundaries, so no split is needed.

    Parameters
    ----------
    plant : ELPlant
    dt : float
        The step.
    x0 : array
        The initial state ``[q, q̇]``.
    announce : callable, optional
        Called with a line of text before a first compile (the node's status line).
    """

    def __init__(self, plant: Any, dt: float, x0: Any, announce: Any = None) -> None:
        self.n, self.m, self.dt = plant.n, plant.m, float(dt)
        self.x = np.array(x0, dtype=np.float64).reshape(2 * self.n).copy()
        check_reduced_start([plant], self.x[None])  # as the simulator: never changed silently
        self._plant = plant
        self._kernel = plant.engine_kernel
        self.start_from(self.x)
        self.u = np.zeros(self.m)
        self.compiled = bool(plant.compiled)
        self._terms = plant.terms_kernel
        self._params = np.ascontiguousarray(plant.params, dtype=np.float64).ravel()
        self._M = np.zeros((self.n, self.n))
        self._N = np.zeros(self.n)
        self._G = np.zeros((self.n, self.m))
        self._entry = None
        self._stepper = plant.stepper_kernel
        self._first = True
        if self._stepper is not None:
            plant.check_step(self.dt)
            _compile_stepper(plant, announce)
        elif self.compiled:
            self._entry, self._work = _compiled_step(plant, announce)
        elif self._kernel.reduced is not None:  # the reduced sub-step's kernel and memory, once
            from delaytrack.sim.integrator import rk4_workspace

            workspace = rk4_workspace(np.empty(2 * self.n), self.m)
            self._python_reduced = (self._kernel.as_python(), workspace)

    def start_from(self, x: np.ndarray) -> None:
        """Set :attr:`x` to ``x``, a start: for a plant in its reduced form, the next step first
        maps it onto the constraints, ``q̇ = S(q) η``, as the simulator's first step does (it is
        read as given until then)."""
        self.x[:] = x
        self._mapped = self._kernel.reduced is None

    def step(self, t: float) -> bool:
        """Advance :attr:`x` by one step from ``t`` with :attr:`u` held; False when the new
        state is not finite or a mass matrix met was not positive definite. A plant in its
        reduced form first sets the start's ``q̇ = S(q) η`` (at the first step only)."""
        if not self._mapped:
            self.x[self.n :] = velocities_on_constraints(self._plant, self.x, as_the_engine=True)
            self._mapped = True
        if self._stepper is not None:  # the plant's own integrator (MuJoCo's mj_step)
            self._stepper(t, self.x, self.u, self.dt, self._params, self._first)
            self._first = False
            return bool(np.all(np.isfinite(self.x)))
        if self._entry is None:
            self.x[:] = self.python_step(t, self.x, self.u, self.dt)
            return bool(np.all(np.isfinite(self.x)))
        outside, indefinite_at = self._entry(
            self._kernel, self._params, t, self.x, self.u, self.dt, self._work, math.inf
        )
        return not outside and indefinite_at != indefinite_at  # NaN: none

    def derivative(self, t: float, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        n = self.n
        self._terms(t, x[:n], x[n:], self._params, self._M, self._N, self._G)
        out = np.empty(2 * n)
        out[:n] = x[n:]
        out[n:] = np.linalg.solve(self._M, self._G @ u - self._N)
        return out

    def python_step(self, t: float, x: np.ndarray, u: np.ndarray, dt: float) -> np.ndarray:
        """The same RK4 step in plain Python and NumPy (returns the new state); for a plant
        with a reduced form, the engine's reduced sub-step run as Python, from an ``x`` on the
        plant's constraints (its ``q̇`` is read as ``S(q) η``)."""
        if self._kernel.reduced is not None:
            from delaytrack.sim.integrator import _reduced_rk4_substep

            kernel, work = self._python_reduced
            new = np.array(x, dtype=np.float64)
            _reduced_rk4_substep.py_func(kernel, self._params, t, new, u, dt, work, math.inf)
            return new
        k1 = self.derivative(t, x, u)
        k2 = self.derivative(t + dt / 2, np.ascontiguousarray(x + dt / 2 * k1), u)
        k3 = self.derivative(t + dt / 2, np.ascontiguousarray(x + dt / 2 * k2), u)
        k4 = self.derivative(t + dt, np.ascontiguousarray(x + dt * k3), u)
        return x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


def _compile_stepper(plant: Any, announce: Any) -> None:
    """Compile (or load from numba's disk cache) the integrator of a plant stepped by one of its
    own, ``stepper(t, x, u, dt, params, first)``, for the robot node's arguments, announcing a
    first compile through ``announce``."""
    from numba import typeof, types

    from delaytrack._compile.first_compile import code_ready

    vector = typeof(np.empty(1))
    signature = (types.float64, vector, vector, types.float64, vector, types.boolean)
    stepper = plant.stepper_kernel
    if not code_ready(stepper, signature, signature) and announce is not None:
        announce(
            f"compiling {type(plant).__name__}'s own step for the live robot node (once; "
            "from seconds to a minute, then kept on disk)"
        )
    stepper.compile(signature)


def _compiled_step(plant: Any, announce: Any) -> tuple[Any, Any]:
    """The compiled step's entry point for ``plant`` and its working memory (the first compile
    announced through ``announce``, then kept on disk)."""
    from delaytrack._compile.first_compile import code_ready
    from delaytrack._compile.guards import refuse_changed_globals
    from delaytrack._compile.stale_caches import compile_from_source
    from delaytrack.live._plant_step import entry_point, plant_step_function, step_signature
    from delaytrack.sim.integrator import rk4_workspace

    kernel = plant.engine_kernel
    refuse_changed_globals(kernel)
    signature = step_signature(kernel, plant.n, plant.m)
    step = plant_step_function(kernel)
    if not code_ready(step, signature, signature):
        compile_from_source([kernel])
        if announce is not None:
            announce(
                f"compiling {type(plant).__name__}'s step for the live robot node (once; "
                "from seconds to a minute, then kept on disk)"
            )
    return entry_point(step, signature), rk4_workspace(np.empty(2 * plant.n), plant.m)


class SimulatedRobot(RobotBridge):
    """The scenario's plant as the robot: the robot node's bridge when no ``--bridge`` is given.

    Its time is the node's step count (:attr:`steps_on_write`): :meth:`write_command` holds
    ``u`` over one step ``dt`` from ``t`` and advances the state by one step of
    :class:`PlantStepper`; :meth:`read_state` returns the state reached.

    Parameters
    ----------
    plant : ELPlant
    dt : float
        The step.
    x0 : array
        The initial state ``[q, q̇]``.
    announce : callable, optional
        Called with a line of text before a first compile.
    """

    steps_on_write = True

    def __init__(self, plant: Any, dt: float, x0: Any, announce: Any = None) -> None:
        self.stepper = PlantStepper(plant, dt, x0, announce=announce)
        # Warm up on a throw-away copy of the state (the step advances x in place).
        saved = self.stepper.x.copy()
        self.stepper.step(0.0)
        self.stepper.start_from(saved)

    def read_state(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        x, n = self.stepper.x, self.stepper.n
        return x[:n], x[n:]

    def write_command(self, t: float, u: np.ndarray) -> None:
        self.stepper.u[:] = u
        if not self.stepper.step(t):
            raise SimulatedRobotDiverged(
                f"its state is not finite (or its mass matrix not positive definite) in the "
                f"step from t = {t:g} s"
            )


class SimulatedRobotDiverged(FloatingPointError):
    """The simulated robot's step left the finite numbers: the closed loop diverged (what
    ``simulate`` calls ``diverged``), not a fault of a driver."""


class RobotNode(NodeBase):
    """The robot node (module docstring)."""

    role = "robot"

    def __init__(self, scenario: Any, built: Any, args: Any) -> None:
        super().__init__(scenario, built, args)
        plant = built.plant
        self.n, self.m = plant.n, plant.m
        self.bridge_name = getattr(args, "bridge", None)
        self.diverged = False  # the simulated robot's state left the finite numbers
        self.failed_when_closed = False  # the bridge's close() raised, the loop had not failed
        horizons = [("reference", built.reference.horizon)]
        if self.bridge_name is None:
            plant.check_step(self.dt)
            horizons.insert(0, ("plant", plant.horizon))
        for what, horizon in horizons:
            if self.duration > horizon:
                raise ValueError(
                    f"the {what} is defined up to t = {horizon:g} s; the session lasts "
                    f"{self.duration:g} s (shorten --duration)"
                )
        self.columns = session_columns(plant)
        self.names = list(self.columns.names)
        limits = scenario.simulated_input_limits
        self.limits = np.broadcast_to(np.asarray(limits, dtype=float), (self.m,)).copy()
        self.state_every = (
            self.steps_per_tick if getattr(args, "state_every", None) is None else args.state_every
        )
        self.command_timeout = (
            max(0.1, 10 * self.T_c) if args.command_timeout is None else args.command_timeout
        )
        self.x = np.zeros(2 * self.n)  # the state read last
        self.u = np.zeros(self.m)  # the input written last
        self.releases_out_of_order = 0  # releases older than the command in force, not applied
        # the input before the first command: the scenario's u_init, as the simulator's
        u_init = scenario.simulated_u_init
        self.u_init = np.zeros(self.m) if u_init is None else u_init
        self.steps: list[list[Any]] = []
        self.states: list[list[Any]] = []
        self.applied: list[list[Any]] = []
        # The status (status_numbers): h at the steps where commands came into force (warmed
        # up here, at more points than h evaluates as Python, so that its compiled code is
        # loaded now: at the first status it took 4-8 ms of the loop, and the robot missed
        # steps at t = 1 s), the rows already counted, the commands seen in force and the
        # zero-input steps counted.
        self.delay = built.delay
        self.delay.h(np.zeros(FEW_POINTS + 1))
        self._status_step, self._status_applied = 0, 0
        self._in_force: set[int] = set()
        self._zero_input = 0
        self._stop: Any = None
        self._closed = False
        self.bridge: RobotBridge = (
            SimulatedRobot(plant, self.dt, built.x0, announce=self._announce)
            if self.bridge_name is None
            else load_bridge(self.bridge_name, scenario, self.dt, self.n)
        )

    def declare(self, session: Any, prefix: str) -> None:
        self._received = Received(
            functools.partial(ReleaseMessage.decode, size=self.m, until=self._latest_time())
        )
        self._publisher = declare_stream(session, f"{prefix}/state")
        self._subscriber = session.declare_subscriber(f"{prefix}/release", self._received)
        self.entities += [self._subscriber, self._publisher]

    def loop(self, t0: float, stop: Any, handshake: Any) -> None:
        try:
            self._loop(t0, stop, handshake)
        finally:
            self.close()

    def _loop(self, t0: float, stop: Any, handshake: Any) -> None:
        self.log = McapLog(self.out / "robot.mcap", t0, self.metadata())
        ticker = Ticker(t0, self.dt, until=self.duration, stop=stop, idle=self.log.work)
        self.ticker, self._stop = ticker, stop
        pending: list[tuple[ReleaseMessage, float]] = []
        current: ReleaseMessage | None = None
        last_arrival = -math.inf
        dt = self.dt
        u = self.u
        saturated = np.zeros(self.m)  # the command in force, saturated (computed once)
        status = "no-command"
        j_model = 0  # the next step to read and write
        last_hello = 0.0
        for wake in ticker:
            j = wake.k
            j_model = self._missed(j_model, j, current)
            if self.failure is not None:
                break
            s = j * dt
            now = wake.now
            if not self._read(j, now):
                break
            for message, received in self._received.drain():
                pending.append((message, received - t0))
                last_arrival = max(last_arrival, received - t0)
            if pending:
                pending, taken = self._release_to_apply(pending, current, s)
                if taken is not None:
                    current, arrived = taken
                    saturated = np.minimum(np.maximum(current.u, -self.limits), self.limits)
                    self.applied.append(
                        [
                            current.seq,
                            current.t_k,
                            s,
                            current.apply_at,
                            current.release_time,
                            arrived,
                        ]
                    )
                    self.log.command(
                        "/applied",
                        seq=current.seq,
                        sample_time=current.t_k,
                        log_time=now,
                        u=current.u,
                        send_time=current.command_send_time,
                        receive_time=arrived,
                        release_time=current.release_time,
                        apply_at=s,
                    )
            if current is None:
                u[:], status = self.u_init, "no-command"
            elif now - last_arrival > self.command_timeout:
                u[:], status = 0.0, "timeout-zero"
            else:
                u[:], status = saturated, "ok"
            self.steps.append(
                [
                    j,
                    s,
                    wake.lateness * 1e3,
                    status,
                    -1 if current is None else current.seq,
                    *u.tolist(),
                ]
            )
            j_model = j + 1
            if not self._write(j):
                break
            if now - last_hello > 0.2:
                handshake.publish()
                last_hello = now
            self.status(now)
        # Steps after the last wake-up (it was late and the session ended meanwhile).
        total = steps_until(self.duration, dt)
        if self.failure is None and not stop() and j_model < total:
            j_model = self._missed(j_model, total, current)
        self.end_time = j_model * dt
        if self.failure is None and self._state(j_model):
            self.states.append([j_model, self.end_time, *self.x.tolist()])
            self.log.state(j_model, self.end_time, ticker.now(), self.names, self.x)

    def status_numbers(self, window: float) -> tuple[dict[str, Any], dict[str, Any]]:
        """The p50 and p99 of ``|realised delay - h|`` over the commands that came into force
        for the first time since the last status (the step ``s`` from which command ``k`` is in
        force, minus ``t_k``, minus ``h(s)``: the delay rule makes it at most about one step);
        steps, missed steps, zero-input steps and commands that came into force since the start."""
        statuses = [row[3] for row in self.steps[self._status_step :]]
        self._zero_input += statuses.count("no-command") + statuses.count("timeout-zero")
        self._status_step = len(self.steps)
        first = []
        for row in self.applied[self._status_applied :]:
            if row[0] not in self._in_force:
                self._in_force.add(row[0])
                first.append(row)
        self._status_applied = len(self.applied)
        applied_at = np.array([row[2] for row in first], dtype=float)
        sample_time = np.array([row[1] for row in first], dtype=float)
        error_ms = np.abs(applied_at - sample_time - self.delay.h(applied_at)) * 1e3
        error_ms = error_ms[np.isfinite(error_ms)]
        p50, p99 = np.percentile(error_ms, [50, 99]) if error_ms.size else (math.nan, math.nan)
        measured = {"realised_minus_h_abs_ms_p50": p50, "realised_minus_h_abs_ms_p99": p99}
        totals = {
            "steps": len(self.steps),
            "missed": self.ticker.missed,
            "zero_input": self._zero_input,
            "applied": len(self._in_force),
        }
        return measured, totals

    def _release_to_apply(
        self,
        pending: list[tuple[ReleaseMessage, float]],
        current: ReleaseMessage | None,
        s: float,
    ) -> tuple[list[tuple[ReleaseMessage, float]], tuple[ReleaseMessage, float] | None]:
        """The releases ``pending`` (each with its arrival) still not due at the step of time
        ``s``, and the one to apply from that step with its arrival, or None to keep
        ``current``: the latest due, by the step it applies at, then by arrival. The delay
        node releases in the order of the steps they apply at: one older than ``current`` is a
        copy replayed (counted in ``releases_out_of_order``, not applied), and ``current``
        again is not applied twice."""
        tolerance = 1e-9 * self.dt
        due = [p for p in pending if p[0].apply_at <= s + tolerance]
        if not due:
            return pending, None
        later = [p for p in pending if p[0].apply_at > s + tolerance]
        chosen = max(due, key=lambda p: (p[0].apply_at, p[1]))
        if current is not None and chosen[0].apply_at < current.apply_at:
            self.releases_out_of_order += 1
            return later, None
        if current is not None and (chosen[0].seq, chosen[0].apply_at) == (
            current.seq,
            current.apply_at,
        ):
            return later, None
        return later, chosen

    def _missed(self, j_model: int, j: int, current: Any) -> int:
        """The steps ``j_model .. j - 1`` whose wake-up was missed, each recorded with the input
        held over it. A bridge whose time advances per write (the simulated plant) is read and
        written at each, late (its states at the tick times published and logged as at any
        step); a robot that lives in real time held the input over them and is not called.
        Returns the next step (short of ``j`` when the bridge failed)."""
        dt, u = self.dt, self.u
        replay = self.bridge.steps_on_write
        while j_model < j:
            if replay and not self._read(j_model, self.ticker.now()):
                return j_model
            self.steps.append(
                [
                    j_model,
                    j_model * dt,
                    math.nan,
                    "missed",
                    -1 if current is None else current.seq,
                    *u.tolist(),
                ]
            )
            j_model += 1
            if replay and not self._write(j_model - 1):
                return j_model
        return j_model

    def _state(self, j: int) -> bool:
        """Read the robot's state at step ``j`` into :attr:`x`; False (the node stopped) when
        the bridge raised or the state has the wrong shape or is not finite."""
        try:
            state = self.bridge.read_state(j * self.dt)
        except DRIVER_ERRORS as error:  # the robot's driver: reported, node stops
            self._fail(
                j, f"{type(self.bridge).__name__}.read_state raised {type(error).__name__}: {error}"
            )
            return False
        problem = check_state(state, self.x)
        if problem is not None:
            self._fail(j, f"{type(self.bridge).__name__}.{problem}")
            return False
        return True

    def _read(self, j: int, now: float) -> bool:
        """Read the state at step ``j`` (:meth:`_state`), publish it and log it at the tick
        times (``now``: the session time of the log); False when the node stopped."""
        if not self._state(j):
            return False
        s = j * self.dt
        if j % self.state_every == 0:
            self._publisher.put(StateMessage(j, s, self.ticker.now(), self.x).encode())
        if j % self.steps_per_tick == 0:
            self.states.append([j, s, *self.x.tolist()])
            self.log.state(j, s, now, self.names, self.x, self.u)
        return True

    def _write(self, j: int) -> bool:
        """Write :attr:`u` for step ``j``; False (the node stopped) when the bridge raised."""
        try:
            self.bridge.write_command(j * self.dt, self.u)
        except SimulatedRobotDiverged as error:  # the loop, not a driver
            self.diverged = True
            self._fail(j, str(error))
            return False
        except DRIVER_ERRORS as error:  # the robot's driver: reported, node stops
            self._fail(
                j,
                f"{type(self.bridge).__name__}.write_command raised "
                f"{type(error).__name__}: {error}",
            )
            return False
        return True

    def _fail(self, j: int, what: str) -> None:
        """Stop the node on a failure of the robot at step ``j`` (said on stderr, one line):
        its driver's (``what`` names the call), or the simulated robot's divergence."""
        self.failure = what.replace("\n", " ")
        event = "diverged" if self.diverged else "failed"
        print(
            f"error: the robot {event} at t = {j * self.dt:g} s (step {j}): {self.failure}; "
            "the robot node stops (exit code 1), its log and tables up to there are written",
            file=sys.stderr,
            flush=True,
        )
        self._stop.set()

    def close(self) -> None:
        """Close the bridge (once). A bridge whose ``close`` raises is said on stderr in one line
        and ends the node as a failure (exit code 1), its log and tables written."""
        if self._closed or not hasattr(self, "bridge"):
            return
        self._closed = True
        try:
            self.bridge.close()
        except DRIVER_ERRORS as error:  # the bridge is the user's code
            what = f"{type(self.bridge).__name__}.close() raised {type(error).__name__}: {error}"
            what = what.replace("\n", " ")
            if self.failure is None:
                self.failure, self.failed_when_closed = what, True
            print(
                f"error: {what}; the robot may still hold its last input",
                file=sys.stderr,
                flush=True,
            )

    def _announce(self, text: str) -> None:
        """A first compile is said on stderr even with --quiet (it may take a minute)."""
        print(f"[robot] delaytrack: {text}", file=sys.stderr, flush=True)

    def outputs(self) -> dict[str, Any]:
        write_csv(
            self.out / "steps.csv",
            ["j", "t_s", "lateness_ms", "status", "seq", *self.columns.inputs()],
            self.steps,
        )
        write_csv(self.out / "states.csv", ["j", "t_s", *self.columns.states], self.states)
        write_csv(
            self.out / "applied.csv",
            ["seq", "t_k_s", "applied_s", "apply_at_s", "released_s", "arrived_s"],
            self.applied,
        )
        statuses = [row[3] for row in self.steps]
        return {
            "steps": len(self.steps),
            "missed_steps": self.ticker.missed if hasattr(self, "ticker") else 0,
            "lateness_ms_p50": percentile([r[2] for r in self.steps], 50),
            "lateness_ms_p99": percentile([r[2] for r in self.steps], 99),
            "no_command_steps": statuses.count("no-command"),
            "timeout_zero_steps": statuses.count("timeout-zero"),
            "applications": len(self.applied),
            "late_applications": sum(1 for r in self.applied if r[2] > r[3] + 1e-9 * self.dt),
            "dropped_by_queue": self._received.dropped if hasattr(self, "_received") else 0,
            "releases_out_of_order": self.releases_out_of_order,
            "coordinates": self.names,
            "bridge": self.bridge_name or "simulated",
            "failure": self.failure,
            "diverged": self.diverged,
            "failed_when_closed": self.failed_when_closed,
        }


def main(args: Any) -> int:
    from delaytrack.live._node import run_node

    return run_node(RobotNode, args)
