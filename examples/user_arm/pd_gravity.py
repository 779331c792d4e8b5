"""A controller of your own at compiled speed: PD with gravity compensation.

    τ = K_P e1 + K_D ė1 + N̂(q, 0),   e1 = q_d - q,

where ``N̂(q, 0)`` is the nominal model's gravity (and friction at rest) at the measured ``q``
(Takegaki & Arimoto, "A new feedback method for dynamic control of manipulators", ASME J. Dyn.
Syst. Meas. Control 103, 1981). It needs no model of the inertia, only of gravity, and knows
nothing of the delay: a classic, simple rival of AROLC on a robot arm.

The step kernel has the signature every controller's has (:mod:`delaytrack.controllers.base`)
and calls the nominal model through :func:`delaytrack.components.call_terms`, so it runs with
any plant, built-in or your own, compiled into the simulator's loop. :func:`make_pd_gravity` is
the factory a scenario file names: ``type = "python:pd_gravity.py:make_pd_gravity"``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numba
import numpy as np

from delaytrack.components import call_command_map, call_terms
from delaytrack.controllers import Controller
from delaytrack.controllers.base import terms_views, tracking_errors
from delaytrack.plants import ELPlant


@numba.njit(cache=True, error_model="numpy")
def pd_gravity_step(
    t, q, qdot, qd, qd_dot, qd_ddot, T_c, h, params, state, model, model_params, command, work
):
    n = q.shape[0]
    mass, nonlinear, input_map, rest = terms_views(work, n, command.shape[0])
    error = rest[: 2 * n]
    tracking_errors(q, qdot, qd, qd_dot, error)
    at_rest = rest[2 * n : 3 * n]
    at_rest[:] = 0.0
    call_terms(model, t, q, at_rest, model_params, mass, nonlinear, input_map)  # N̂(q, 0)
    tau = rest[3 * n : 4 * n]
    for i in range(n):
        tau[i] = nonlinear[i]
        for j in range(n):
            tau[i] += params[i * n + j] * error[j] + params[n * n + i * n + j] * error[n + j]
    call_command_map(model, q, model_params, input_map, tau, command)


@dataclass(frozen=True, eq=False)
class PDGravity(Controller):
    """PD with gravity compensation around the nominal ``model`` (module docstring)."""

    model: ELPlant
    K_P: np.ndarray
    K_D: np.ndarray
    type_name: ClassVar[str] = "pd-gravity"

    def __post_init__(self) -> None:
        self._check_model()
        for name in ("K_P", "K_D"):
            gain = np.array(getattr(self, name), dtype=float)
            gain = gain * np.eye(self.n) if gain.ndim == 0 else gain
            gain = np.diag(gain) if gain.ndim == 1 else gain
            if gain.shape != (self.n, self.n) or not np.all(np.linalg.eigvalsh(gain) > 0):
                raise ValueError(f"{name} must be a positive definite {self.n}x{self.n} gain")
            object.__setattr__(self, name, gain)

    @property
    def params(self) -> np.ndarray:
        return np.concatenate([self.K_P.ravel(), self.K_D.ravel()])

    @property
    def step_kernel(self):
        return pd_gravity_step

    @property
    def state_names(self) -> tuple[str, ...]:
        return ()

    def initial_state(self) -> np.ndarray:
        return np.zeros(0)

    def to_spec(self) -> dict[str, Any]:
        return {"type": self.type_name, "K_P": self.K_P.tolist(), "K_D": self.K_D.tolist()}


def make_pd_gravity(model: ELPlant, K_P: Any, K_D: Any) -> PDGravity:
    """The factory of a scenario's ``[controller]`` table (gains as numbers, lists or matrices)."""
    return PDGravity(model, K_P, K_D)
