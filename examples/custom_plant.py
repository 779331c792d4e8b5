"""AROLC on your own Euler-Lagrange plant: a pendulum with gravity and friction, from Python.

The plant is given as two plain functions, M(q) and N(q, q̇), wrapped in ``CallablePlant``. The
controller's nominal model is another ``CallablePlant`` that gets the mass 25 % wrong and knows
no friction. Both run under the paper's S1 delay, h(t) = 20 + 80 |sin t| ms, which neither
controller is told about.

Run it with ``python examples/custom_plant.py [--out DIR]``; it takes a few seconds (a Python
plant is simulated in plain Python, not compiled). With ``--out`` it also writes the figures.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

import delaytrack as dt
from delaytrack.report import error_figure, save_figure

GRAVITY = 9.81


def pendulum(mass: float, length: float, friction: float) -> dt.CallablePlant:
    """A point mass on a massless rod: ``m l² q̈ + m g l sin q + b q̇ = τ``."""

    def mass_matrix(q: np.ndarray) -> np.ndarray:
        return np.array([[mass * length**2]])

    def nonlinear_terms(q: np.ndarray, qdot: np.ndarray) -> np.ndarray:
        return np.array([mass * GRAVITY * length * math.sin(q[0]) + friction * qdot[0]])

    return dt.CallablePlant(
        n=1,
        mass_matrix_fn=mass_matrix,
        nonlinear_terms_fn=nonlinear_terms,
        name="pendulum",
        coordinate_names=("angle",),
        coordinate_units=("rad",),
        input_units=("N·m",),
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=None, help="also write figures to this folder")
    args = parser.parse_args()

    truth = pendulum(mass=1.2, length=0.5, friction=0.4)
    nominal = pendulum(mass=0.9, length=0.5, friction=0.0)

    # Theorem 1: the delay the gains below are certified for (the paper's gains, n = 1).
    bound = dt.razumikhin_bound(K1=1.0, K2=1.0, Q=1.0, beta=1.0, r=1.1)
    print(f"certified delay bound h_m = {1e3 * bound.h_m:.1f} ms")

    gains = dict(K1=1.0, K2=1.0)
    controllers = {
        "AROLC": dt.AROLC(nominal, Q=1.0, alpha=2.0, epsilon=0.1, gamma=0.001, **gains),
        "outer loop": dt.OuterLoop(nominal, **gains),
    }
    reference = dt.SinusoidalReference(offset=[0.3], amplitude=[0.5], frequency=[1.0])
    delay = dt.AbsSineDelay.S1()
    print(f"delay S1: h_max = {1e3 * delay.h_max:.0f} ms")

    results = {}
    for label, controller in controllers.items():
        results[label] = dt.simulate(
            truth, controller, delay, np.zeros(2), reference=reference, t1=20.0, dt=1e-3, T_c=2e-3
        )
        table = dt.metrics_table(results[label], coordinate_names=["angle"], label=label)
        row = table.iloc[0]
        print(
            f"{label:>10}: status {row['status']}, AE {row['ae_angle']:.4f} rad, "
            f"max |e1| {row['max_angle']:.4f} rad, TV {row['tv']:.2f} N·m"
        )

    if args.out is not None:
        figure = error_figure(results, coordinate_names=["angle"], title="Pendulum under S1")
        for path in save_figure(figure, args.out / "pendulum_error"):
            print(f"wrote {path}")


if __name__ == "__main__":
    main()
