"""A linear mechanical plant ``M q̈ + D q̇ + K q = G u`` (mass-spring-damper chains, tests)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from delaytrack._compile.jit import kernel
from delaytrack._validation import as_spd_matrix, as_square_matrix, finite_array
from delaytrack.plants.base import MAX_PLANT_SIZE, ELPlant

__all__ = ["MAX_COORDINATES", "LinearPlant", "linear_terms"]

#: Most coordinates of a :class:`LinearPlant`, as of any plant (:data:`MAX_PLANT_SIZE`): it
#: also holds M, D and K as dense n x n matrices in its parameters (24 MB at n = 1000).
MAX_COORDINATES = MAX_PLANT_SIZE


@kernel
def linear_terms(t, q, qdot, params, mass, nonlinear, input_map):
    """Fill ``M``, ``N = D q̇ + K q`` and ``G``; ``params = [M, D, K, G]`` flattened row-major."""
    n = q.shape[0]
    m = input_map.shape[1]
    # Index arithmetic, not reshaped views: a reshape compiles numba's shape checks and its
    # runtime into every caller (about 3 s of the first compile of an integrator).
    for i in range(n):
        for j in range(n):
            mass[i, j] = params[i * n + j]
        for j in range(m):
            input_map[i, j] = params[3 * n * n + i * m + j]
    for i in range(n):  # D q̇ + K q by loops: no temporaries in the right-hand side
        damping_force = 0.0
        stiffness_force = 0.0
        for j in range(n):
            damping_force += params[n * n + i * n + j] * qdot[j]
            stiffness_force += params[2 * n * n + i * n + j] * q[j]
        nonlinear[i] = damping_force + stiffness_force


@dataclass(frozen=True, eq=False)
class LinearPlant(ELPlant):
    """``M q̈ + D q̇ + K q = G u`` with constant matrices.

    Parameters
    ----------
    mass : array_like
        ``M``, symmetric positive definite (n, n); a scalar or 1-D value means a diagonal.
        At most :data:`MAX_COORDINATES` coordinates.
    damping, stiffness : array_like, optional
        ``D`` and ``K`` (n, n); zero by default.
    input_map_matrix : array_like, optional
        ``G`` (n, m); the identity by default.
    """

    mass: np.ndarray
    damping: np.ndarray | None = None
    stiffness: np.ndarray | None = None
    input_map_matrix: np.ndarray | None = None
    n: int = field(init=False)
    m: int = field(init=False)
    _params: np.ndarray = field(init=False, repr=False)
    type_name: ClassVar[str] = "linear"

    def __post_init__(self) -> None:
        mass_array = np.asarray(self.mass, dtype=float)
        n = 1 if mass_array.ndim == 0 else mass_array.shape[0]
        if n > MAX_COORDINATES:
            size = 8 * 3 * n * n / 2**20
            raise ValueError(
                f"mass gives n = {n} coordinates; a LinearPlant holds M, D and K as dense "
                f"n x n matrices ({size:.0f} MB) and works on them in O(n²) at every step, for "
                f"at most n = {MAX_COORDINATES} coordinates"
            )
        mass = as_spd_matrix("mass", self.mass, n)
        damping = (
            np.zeros((n, n))
            if self.damping is None
            else as_square_matrix("damping", self.damping, n)
        )
        stiffness = (
            np.zeros((n, n))
            if self.stiffness is None
            else as_square_matrix("stiffness", self.stiffness, n)
        )
        if self.input_map_matrix is None:
            input_map = np.eye(n)
        else:
            input_map = finite_array("input_map_matrix", self.input_map_matrix)
            input_map = input_map.reshape(n, -1) if input_map.ndim < 2 else input_map
            if input_map.ndim != 2 or input_map.shape[0] != n:
                raise ValueError(
                    f"input_map_matrix must have shape ({n}, m); got {input_map.shape}"
                )
        for name, value in (
            ("mass", mass),
            ("damping", damping),
            ("stiffness", stiffness),
            ("input_map_matrix", input_map),
        ):
            object.__setattr__(self, name, value)
        object.__setattr__(self, "n", n)
        object.__setattr__(self, "m", input_map.shape[1])
        object.__setattr__(
            self,
            "_params",
            np.concatenate([mass.ravel(), damping.ravel(), stiffness.ravel(), input_map.ravel()]),
        )

    @property
    def params(self) -> np.ndarray:
        return self._params

    @property
    def terms_kernel(self):
        return linear_terms

    def to_spec(self) -> dict[str, Any]:
        # Construction replaces a None matrix by its default.
        assert self.damping is not None and self.stiffness is not None
        assert self.input_map_matrix is not None
        return {
            "type": self.type_name,
            "mass": self.mass.tolist(),
            "damping": self.damping.tolist(),
            "stiffness": self.stiffness.tolist(),
            "input_map": self.input_map_matrix.tolist(),
        }
