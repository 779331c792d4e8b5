"""Hand-written baselines of the paper's robot closed loop, for ``make bench``.

``benchmarks/run.py`` times :func:`numpy_loop` and :func:`solve_ivp_loop` against the compiled
engine (:func:`delaytrack.sim.simulate`) on the same case, built once by :func:`robot_case`: the
paper's scenario S1 — :class:`~delaytrack.plants.robot.PayloadRobot` (seed
:data:`~delaytrack.experiments.paper.PAYLOAD_SEED`) under AROLC with the paper's gains and the
nominal robot model, delay ``h(t) = 20 + 80 |sin t|`` ms, ``T_c`` = 10 ms, ``dt`` = 1 ms.

Both baselines are what a user would write without the engine, in plain Python and NumPy:

* the controller runs at the ticks ``t_k = k T_c``: it reads ``x(t_k)`` and ``q_d, q̇_d, q̈_d``
  at ``t_k`` and issues command ``k`` (:class:`PlainAROLC`, AROLC written out in NumPy);
* the plant ``M(q) q̈ + N(q, q̇) = G(q) u`` is evaluated by the plain-Python version of its terms
  kernel (``terms_kernel.py_func``) and ``q̈`` by ``np.linalg.solve``;
* the applied input at time ``t`` is the command of the latest tick ``t_k <= t - h(t)``, and zero
  before the first command arrives.

They differ in the integrator. :func:`numpy_loop` takes classical RK4 steps of ``dt`` and looks
the input up at each stage time, without splitting a step where the delayed input switches (the
engine does split), so it is only first-order accurate across a switch. :func:`solve_ivp_loop`
calls :func:`scipy.integrate.solve_ivp` once per controller period; its error test does not see
the small jumps of the delayed input inside a step either. Both stay within about 1e-4 of the
engine's states until the adaptive law of AROLC takes another branch than in the engine: the
sign of ``sᵀ(s - s_prev)`` is discontinuous in the state, so a difference of 1e-5 can flip
``ĉ' = ±‖s‖`` at a tick where it is near zero, after which ĉ differs by ``2 T_c ‖s‖`` and the
trajectories separate by up to about 1e-2. :func:`agreement` reports the difference before and
after that point; ``python benchmarks/baselines.py [duration]`` prints it with the wall time per
simulated second.

The helpers of the plant's kernel (the truth robot's terms, the payload schedule) and of the
command map ``S(q)ᵀ τ`` are numba functions, which ``py_func`` still calls compiled, through
numba's dispatcher; everything else runs as Python.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable

import numpy as np
from scipy.integrate import solve_ivp

from delaytrack.controllers import AROLC
from delaytrack.delays import AbsSineDelay
from delaytrack.experiments.paper import AROLC_GAINS, DT, DURATION, PAYLOAD_SEED, T_C
from delaytrack.plants.robot import NominalRobot, PayloadRobot, initial_state, paper_reference
from delaytrack.plants.robot.kinematics import robot_command_map
from delaytrack.references import SinusoidalReference
from delaytrack.sim import simulate

__all__ = ["PlainAROLC", "agreement", "numpy_loop", "robot_case", "solve_ivp_loop"]

#: Plant steps per controller period.
STEPS_PER_TICK = round(T_C / DT)
#: Tolerances of :func:`solve_ivp_loop`, what a careful user would pick: eight digits on states
#: of O(1) m and rad (the wheel angles grow to O(100) rad), far below the millimetres that the
#: tracking metrics resolve. Tighter buys little agreement with the engine (rtol 1e-10 with atol
#: 1e-12 takes 2.5 times as long and still differs by 4e-5 after 5 s): the error comes from the
#: input's switches inside the steps, which the error estimate underrates.
RTOL = 1e-8
ATOL = 1e-10

Case = tuple[PayloadRobot, AROLC, AbsSineDelay, SinusoidalReference, np.ndarray]
Advance = Callable[[PayloadRobot, AbsSineDelay, np.ndarray, int, np.ndarray], np.ndarray]


def robot_case(duration: float) -> Case:
    """The paper's robot experiment under S1, as :func:`delaytrack.sim.simulate` receives it.

    Parameters
    ----------
    duration : float
        Seconds to be simulated; the payload schedule covers at least the paper's 60 s, so that
        a shorter run is the start of the paper's run.

    Returns
    -------
    plant : PayloadRobot
        The truth plant with the paper's payload seed.
    controller : AROLC
        AROLC with the paper's gains on the nominal robot model.
    delay : AbsSineDelay
        The paper's S1, ``h(t) = 20 + 80 |sin t|`` ms.
    reference : SinusoidalReference
        The paper's path (``consistent``).
    x0 : ndarray, shape (10,)
        Initial state ``[q, q̇]`` on the reference.
    """
    reference = paper_reference("consistent")
    plant = PayloadRobot(seed=PAYLOAD_SEED, duration=max(duration, DURATION))
    controller = AROLC(NominalRobot(), **AROLC_GAINS)
    return plant, controller, AbsSineDelay.S1(), reference, initial_state(reference)


class PlainAROLC:
    """AROLC written out in NumPy (the law of :func:`delaytrack.controllers.arolc.arolc_step`).

    At each tick, with ``e1 = q_d - q``, ``e = [e1; ė1]`` and ``s = Bᵀ P e`` (``BᵀP`` is the
    last ``n`` rows of ``P``)::

        u   = q̈_d + K2 ė1 + K1 e1 + α ĉ s / max(‖s‖, ε)
        τ   = M̂(q) u + N̂(q, q̇),   command = S(q)ᵀ τ
        ĉ' = γ if ĉ <= γ;  ‖s‖ if sᵀ(s - s_prev) > 0;  -‖s‖ otherwise (also at the first tick)
        ĉ  ← ĉ + T_c ĉ', but not below γ when decreasing

    Parameters
    ----------
    controller : AROLC
        Gains, ``P`` and nominal model (the robot's, whose command map is ``S(q)ᵀ τ``).
    T_c : float
        Controller period, s (the Euler step of ĉ).
    """

    def __init__(self, controller: AROLC, T_c: float) -> None:
        self.controller = controller
        self.T_c = T_c
        self.c_hat = controller.c_hat0
        self.s_previous: np.ndarray | None = None
        n = controller.n
        self._BtP = controller.P[n:, :]
        self._mass = np.empty((n, n))
        self._nonlinear = np.empty(n)
        self._input_map = np.empty((n, controller.m))

    def __call__(
        self, t: float, x: np.ndarray, qd: np.ndarray, qd_dot: np.ndarray, qd_ddot: np.ndarray
    ) -> np.ndarray:
        """Command (m,) at tick ``t`` from the state ``x = [q, q̇]``; advances ``ĉ``."""
        c = self.controller
        model = c.model
        n = c.n
        q, qdot = x[:n], x[n:]
        e1, e1_dot = qd - q, qd_dot - qdot
        s = self._BtP @ np.concatenate([e1, e1_dot])
        norm_s = math.sqrt(s @ s)
        u = qd_ddot + c.K2 @ e1_dot + c.K1 @ e1 + c.alpha * self.c_hat / max(norm_s, c.epsilon) * s
        model.terms_kernel.py_func(
            t, q, qdot, model.params, self._mass, self._nonlinear, self._input_map
        )
        tau = self._mass @ u + self._nonlinear
        command = np.empty(c.m)
        robot_command_map.py_func(q, model.params, tau, command)
        if self.c_hat <= c.gamma:
            rate = c.gamma
        elif self.s_previous is not None and s @ (s - self.s_previous) > 0.0:
            rate = norm_s
        else:
            rate = -norm_s
        c_next = self.c_hat + self.T_c * rate
        self.c_hat = c.gamma if rate < 0.0 and c_next < c.gamma else c_next
        self.s_previous = s
        return command


def _applied_input(delay: AbsSineDelay, commands: np.ndarray, t: float) -> np.ndarray:
    """Command of the latest tick ``t_k <= t - h(t)``; zero before the first one."""
    h = delay.offset + delay.amplitude * abs(math.sin(delay.frequency * t + delay.phase))
    k = math.floor((t - h) / T_C)
    return commands[k] if k >= 0 else np.zeros(commands.shape[1])


def _state_derivative(plant: PayloadRobot, t: float, x: np.ndarray, u: np.ndarray) -> np.ndarray:
    """``[q̇, q̈]`` with ``q̈ = M(q)⁻¹ (G(q) u - N(q, q̇))`` from the plant's Python terms."""
    n, m = plant.n, plant.m
    mass, nonlinear, input_map = np.empty((n, n)), np.empty(n), np.empty((n, m))
    plant.terms_kernel.py_func(t, x[:n], x[n:], plant.params, mass, nonlinear, input_map)
    return np.concatenate([x[n:], np.linalg.solve(mass, input_map @ u - nonlinear)])


def _closed_loop(duration: float, advance: Advance) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Run the sampled loop of :func:`robot_case` for ``duration`` s with the plant integrator
    ``advance(plant, delay, commands, k, x) -> x(t_{k+1})``; return ``(t, x, commands)``."""
    n_ticks = round(duration / T_C)
    if n_ticks < 1 or not math.isclose(n_ticks * T_C, duration):
        raise ValueError(f"duration must be a positive multiple of T_c = {T_C} s; got {duration}")
    plant, controller, delay, reference, x0 = robot_case(duration)
    law = PlainAROLC(controller, T_C)
    t = np.arange(n_ticks + 1) * T_C
    qd, qd_dot, qd_ddot = reference.evaluate(t)
    states = np.empty((n_ticks + 1, x0.size))
    commands = np.empty((n_ticks + 1, controller.m))
    x = x0.copy()
    for k in range(n_ticks + 1):
        states[k] = x
        commands[k] = law(t[k], x, qd[k], qd_dot[k], qd_ddot[k])
        if k < n_ticks:
            x = advance(plant, delay, commands, k, x)
    return t, states, commands


def _rk4_period(
    plant: PayloadRobot, delay: AbsSineDelay, commands: np.ndarray, k: int, x: np.ndarray
) -> np.ndarray:
    """``STEPS_PER_TICK`` classical RK4 steps from tick ``k``, the input looked up per stage."""
    for j in range(STEPS_PER_TICK):
        t = (k * STEPS_PER_TICK + j) * DT
        mid, end = t + 0.5 * DT, t + DT
        k1 = _state_derivative(plant, t, x, _applied_input(delay, commands, t))
        k2 = _state_derivative(plant, mid, x + 0.5 * DT * k1, _applied_input(delay, commands, mid))
        k3 = _state_derivative(plant, mid, x + 0.5 * DT * k2, _applied_input(delay, commands, mid))
        k4 = _state_derivative(plant, end, x + DT * k3, _applied_input(delay, commands, end))
        x = x + DT / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return x


def _solve_ivp_period(
    plant: PayloadRobot, delay: AbsSineDelay, commands: np.ndarray, k: int, x: np.ndarray
) -> np.ndarray:
    """One :func:`~scipy.integrate.solve_ivp` call (RK45, :data:`RTOL`, :data:`ATOL`) from tick
    ``k`` to tick ``k + 1``, the input looked up in the right-hand side."""

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        return _state_derivative(plant, t, y, _applied_input(delay, commands, t))

    solution = solve_ivp(rhs, (k * T_C, (k + 1) * T_C), x, method="RK45", rtol=RTOL, atol=ATOL)
    if not solution.success:
        raise RuntimeError(f"solve_ivp failed after tick {k}: {solution.message}")
    return solution.y[:, -1]


def numpy_loop(duration: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The S1 robot loop (:func:`robot_case`) with a per-step NumPy RK4 loop.

    Classical RK4 at ``dt`` = 1 ms; at each stage time ``t`` the input is the command of the
    latest tick ``<= t - h(t)`` (steps are not split where it switches).

    Parameters
    ----------
    duration : float
        Seconds to simulate, a multiple of ``T_c`` = 10 ms.

    Returns
    -------
    t : ndarray, shape (R,)
        Tick times ``k T_c``, ``R = duration / T_c + 1``.
    x : ndarray, shape (R, 10)
        State ``[q, q̇]`` at the ticks (before the tick's command).
    commands : ndarray, shape (R, 2)
        Wheel torques issued at the ticks.
    """
    return _closed_loop(duration, _rk4_period)


def solve_ivp_loop(duration: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The S1 robot loop (:func:`robot_case`) with :func:`scipy.integrate.solve_ivp`.

    One RK45 call per controller period (``rtol`` = 1e-8, ``atol`` = 1e-10, see :data:`RTOL`);
    the right-hand side looks the input up at ``t - h(t)`` and leaves its switches inside a step
    to the adaptive step control.

    Parameters
    ----------
    duration : float
        Seconds to simulate, a multiple of ``T_c`` = 10 ms.

    Returns
    -------
    t, x, commands : ndarray
        As :func:`numpy_loop` returns them.
    """
    return _closed_loop(duration, _solve_ivp_period)


def _c_hat_steps(
    controller: AROLC, t: np.ndarray, x: np.ndarray, reference: np.ndarray
) -> np.ndarray:
    """``ĉ_{k+1} - ĉ_k`` of AROLC replayed on the recorded states ``x`` (R, 2n) and reference
    rows ``(R, 3, n)``: the law depends on nothing else, so this is the run's own ĉ."""
    law = PlainAROLC(controller, T_C)
    c_hat = np.empty(t.size)
    for k in range(t.size):
        c_hat[k] = law.c_hat
        law(t[k], x[k], *reference[k])
    return np.diff(c_hat)


def agreement(duration: float = 5.0) -> dict[str, dict[str, float]]:
    """Run both baselines and the compiled engine over ``duration`` s and compare them.

    Returns
    -------
    dict
        Per baseline, against :func:`delaytrack.sim.simulate` at the ticks:

        * ``max_abs_dx``, ``max_abs_dcommand``: the largest absolute differences in the states
          and the commands over the whole run;
        * ``split_s``: the first tick at which the adaptive law moved ĉ the other way than in
          the engine (module docstring), ``inf`` if it never did;
        * ``max_abs_dx_before_split``: the largest state difference up to the next tick, before
          that branch can act on the plant;
        * ``wall_s_per_sim_s``: the baseline's wall time per simulated second.
    """
    plant, controller, delay, reference, x0 = robot_case(duration)
    engine = simulate(
        plant, controller, delay, x0, reference=reference, t1=duration, dt=DT, T_c=T_C
    )
    engine_steps = np.diff(engine.controller_state[0, :, 0])
    rows = {}
    for baseline in (numpy_loop, solve_ivp_loop):
        start = time.perf_counter()
        t, x, commands = baseline(duration)
        elapsed = time.perf_counter() - start
        if not np.allclose(t, engine.t, rtol=0.0, atol=1e-12):
            raise AssertionError(f"{baseline.__name__} records other tick times than simulate()")
        dx = np.max(np.abs(x - engine.x[0]), axis=1)
        steps = _c_hat_steps(controller, t, x, engine.reference)
        splits = np.flatnonzero(np.sign(steps) != np.sign(engine_steps))
        split = splits[0] if splits.size else t.size
        rows[baseline.__name__] = {
            "max_abs_dx": float(dx.max()),
            "max_abs_dcommand": float(np.max(np.abs(commands - engine.commands[0]))),
            "split_s": float(t[split]) if splits.size else math.inf,
            "max_abs_dx_before_split": float(dx[: split + 2].max()),
            "wall_s_per_sim_s": elapsed / duration,
        }
    return rows


if __name__ == "__main__":
    seconds = float(sys.argv[1]) if len(sys.argv) > 1 else 5.0
    headers = {
        "max_abs_dx": "max |dx|",
        "max_abs_dcommand": "max |dcmd|",
        "split_s": "split at s",
        "max_abs_dx_before_split": "before split",
        "wall_s_per_sim_s": "wall s / sim s",
    }
    print(f"robot S1 under AROLC, {seconds:g} s, against simulate()")
    print(f"{'baseline':<16}" + "".join(f"{header:>15}" for header in headers.values()))
    for name, row in agreement(seconds).items():
        print(f"{name:<16}" + "".join(f"{row[key]:>15.3g}" for key in headers))
