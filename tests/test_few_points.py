"""A few points evaluated from Python run as plain Python until the kernel is compiled: the
robot's terms, kinematic map, velocity map and reduced terms give the compiled numbers bit for
bit, refuse nothing the compiled code takes, and compile nothing."""

import contextlib
import subprocess
import sys
from collections import Counter

import numpy as np

from delaytrack._compile import functions
from delaytrack.plants import LinearPlant, TwoLinkArm
from delaytrack.plants.robot import NominalRobot, PayloadRobot, WheeledRobot
from delaytrack.plants.robot.kinematics import kinematic_map
from delaytrack.sim._kernel_checks import velocities_on_constraints


def _states() -> tuple[np.ndarray, np.ndarray]:
    """Drawn positions and velocities, then angles Python's ``math`` refuses (``cos(inf)``) or
    that overflow, which the compiled code takes."""
    rng = np.random.default_rng(11)
    q = rng.normal(0.0, 4.0, (6, 5))
    qdot = rng.normal(0.0, 3.0, (6, 5))
    q[3, 2], q[4, 2], q[5, 2] = 1e308, np.inf, np.nan
    qdot[4, 3] = 1e200  # η² overflows in the bias
    return q, qdot


def _delays() -> list:
    from delaytrack.delays import (
        AbsSineDelay,
        ConstantDelay,
        PiecewiseConstantDelay,
        RandomDelay,
        TraceDelay,
    )
    from delaytrack.experiments.paper_setup import SCENARIOS

    knots = np.linspace(0.0, 10.0, 6)
    return [
        *SCENARIOS.values(),
        AbsSineDelay(0.02, 0.08, 1.3, 0.2),
        ConstantDelay(0.05),
        PiecewiseConstantDelay(knots, np.linspace(0.01, 0.06, 6)),
        TraceDelay(knots, np.linspace(0.01, 0.06, 6), beyond="hold"),
        RandomDelay(0.01, 0.12, 0.5, 60.0, seed=4, beyond="hold"),
    ]


def _evaluated(monkeypatch, as_python: bool, ran: Counter) -> list[np.ndarray]:
    """Every evaluation, each kernel's evaluations that returned as plain Python counted in
    ``ran``."""
    asked: list[str] = []

    def chosen(function, points):
        asked.append(function.__name__)
        return as_python

    plain = functions.as_python

    @contextlib.contextmanager
    def counted():  # at_few_points asks few_points_as_python, then enters as_python
        name = asked[-1]
        with plain():
            yield
        ran[name] += 1  # the evaluation returned as Python (not through the compiled fallback)

    monkeypatch.setattr(functions, "few_points_as_python", chosen, raising=True)
    monkeypatch.setattr(functions, "as_python", counted, raising=True)
    q, qdot = _states()
    plants = (NominalRobot(), TwoLinkArm(), LinearPlant(np.diag([2.0, 3.0, 1.0, 1.0, 4.0])))
    found = []
    for rows in (slice(0, 3), slice(None)):  # finite rows alone (as Python), then all
        found += [kinematic_map(q[rows], 0.0975, 0.1655, 0.02)]
        for plant in plants:
            n = plant.n
            found += plant.terms(q[rows, :n], qdot[rows, :n])
    times = np.array([0.0, 0.37, 2.5, 9.99, 41.0, 1e12, np.nan])
    for delay in _delays():
        found += [delay.h(times[:5]), delay.h(times), delay.h(0.37)]
    for plant in (WheeledRobot(), PayloadRobot(seed=3, duration=10.0)):
        found += [*plant.reduced_terms(qdot[:3], t=2.0), *plant.reduced_terms(qdot, t=7.0)]
        for row in range(q.shape[0]):
            state = np.concatenate([q[row], qdot[row]])
            found += [velocities_on_constraints(plant, state, engine) for engine in (False, True)]
    return found


def test_a_few_points_as_python_are_the_compiled_numbers(monkeypatch):
    ran: Counter = Counter()
    as_python = _evaluated(monkeypatch, True, ran)
    compiled = _evaluated(monkeypatch, False, Counter())
    # each kernel ran as Python (at the finite points), not only through the compiled fallback
    assert set(ran) >= {
        "kinematic_map_kernel",
        "robot_nominal_terms",
        "two_link_terms",
        "linear_terms",
        "profile_values",
        "reduced_terms_kernel",
        "robot_velocity_map",
    }
    assert len(as_python) == len(compiled)
    for got, want in zip(as_python, compiled, strict=True):
        np.testing.assert_array_equal(got, want)


def test_a_value_python_refuses_is_computed_compiled():
    from delaytrack._compile.jit import kernel

    def ratio(x, out):
        out[0] = 1.0 / x

    # A module of the package, as the package's kernels have: numba keeps the compiled code
    # on disk and a later process (the suite run again on the same cache) loads it, importing
    # that module (a made-up name could not be imported: the load failed).
    ratio.__module__ = functions.__name__
    ratio = kernel(ratio)  # as the package's kernels

    def each(kernel):
        out = np.empty(1)
        kernel(0.0, out)
        return out

    assert functions.at_few_points(ratio, 1, each)[0] == np.inf  # ZeroDivisionError in Python
    assert ratio.signatures  # computed compiled


def test_the_robot_set_up_compiles_nothing():
    code = """
import sys
import numpy as np
from numba.core.dispatcher import Dispatcher
from delaytrack.experiments import tuning
from delaytrack.experiments.paper_setup import SCENARIOS
from delaytrack.plants.robot import WheeledRobot
tuning.vartheta_base("PCON-wheel")
WheeledRobot().reduced_terms(np.ones(5))
SCENARIOS["S1"].h(0.5)
kernels = {
    value for name, module in list(sys.modules.items()) if name.startswith("delaytrack")
    for value in vars(module).values() if isinstance(value, Dispatcher)
}
print(sorted(kernel.__name__ for kernel in kernels))
print(sorted(kernel.__name__ for kernel in kernels if kernel.signatures))
"""
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=True
    )
    seen, compiled = done.stdout.splitlines()
    # the kernels the set-up calls were looked at: those of the calls above and the paper's circle
    for name in ("kinematic_map_kernel", "robot_nominal_terms", "reduced_terms_kernel"):
        assert f"'{name}'" in seen
    for name in ("profile_values", "sinusoidal_reference_values"):
        assert f"'{name}'" in seen
    assert compiled == "[]"  # none compiled or loaded from the disk cache
