"""Benchmarks of the closed loop: ``make bench`` prints a table and writes benchmarks/results.json.

Case: the two-link arm under AROLC with the paper's S1 delay, 10 s simulated, dt = 1 ms,
T_c = 2 ms. The baseline is the same engine source run as plain Python (the path a user plant
given as Python callables takes), measured in the same run. Medians of several repetitions,
after one untimed call that compiles (or loads from numba's disk cache).
"""

from __future__ import annotations

import json
import platform
import statistics
import time
from pathlib import Path

import numpy as np

from delaytrack.controllers import AROLC
from delaytrack.delays import AbsSineDelay
from delaytrack.plants import CallablePlant, TwoLinkArm
from delaytrack.reference import SinusoidalReference
from delaytrack.sim import simulate

DURATION = 10.0
DT = 1e-3
T_C = 2e-3
REPEATS = 5


def python_arm(arm: TwoLinkArm) -> CallablePlant:
    """The same arm as Python callables, so the engine runs uncompiled."""

    def mass(q: np.ndarray) -> np.ndarray:
        return arm.mass_matrix(q)[0]

    def nonlinear(q: np.ndarray, qdot: np.ndarray) -> np.ndarray:
        return arm.nonlinear_terms(q, qdot)[0]

    return CallablePlant(2, mass, nonlinear, name="two-link-arm (Python)")


def median_seconds(run, repeats: int) -> float:
    run()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    arm = TwoLinkArm()
    nominal = TwoLinkArm(p1=0.8 * arm.p1, p2=0.8 * arm.p2, p3=0.8 * arm.p3, fd1=0.0, fd2=0.0)
    controller = AROLC(nominal, K1=1.0, K2=1.0, Q=1.0, alpha=2.0, epsilon=0.1, gamma=0.001)
    reference = SinusoidalReference([0.0, 0.0], amplitude=[0.8, 0.5], frequency=[0.5, 0.7])
    steps = round(DURATION / DT)

    def run(plant, duration: float = DURATION):
        return lambda: simulate(
            plant,
            controller,
            AbsSineDelay.S1(),
            np.zeros(4),
            reference=reference,
            t1=duration,
            dt=DT,
            T_c=T_C,
        )

    compiled = median_seconds(run(arm), REPEATS)
    # The Python path is ~100x slower: time 1 s of it and scale, to keep `make bench` short.
    python = median_seconds(run(python_arm(arm), 1.0), 3) * DURATION
    cases = [
        {
            "case": "two-link S1 AROLC, compiled",
            "median_s": compiled,
            "steps_per_s": steps / compiled,
        },
        {
            "case": "same, plain-Python engine (baseline)",
            "median_s": python,
            "steps_per_s": steps / python,
        },
    ]
    for case in cases:
        case["baseline_s"] = python
        case["ratio_to_baseline"] = python / case["median_s"]
    print(f"{'case':<42} {'median s':>10} {'steps/s':>12} {'speed-up':>9}")
    for case in cases:
        speed = f"{case['steps_per_s']:>12.3g} {case['ratio_to_baseline']:>8.1f}x"
        print(f"{case['case']:<42} {case['median_s']:>10.4f} {speed}")
    output = {
        "machine": {"python": platform.python_version(), "processor": platform.machine()},
        "settings": {"duration_s": DURATION, "dt": DT, "T_c": T_C, "repeats": REPEATS},
        "cases": cases,
    }
    path = Path(__file__).with_name("results.json")
    path.write_text(json.dumps(output, indent=2) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
