"""The plain outer loop (computed torque with PD outer loop): AROLC without the switching term."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from delaytrack._compile.jit import tick_kernel
from delaytrack._validation import as_spd_matrix
from delaytrack.components import plant_sizes
from delaytrack.controllers.base import (
    Controller,
    auxiliary_input,
    computed_torque_command,
    step_memory,
    tracking_errors,
)
from delaytrack.plants.base import ELPlant

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

__all__ = ["OuterLoop", "outer_loop_step"]


@tick_kernel
def outer_loop_step(
    t, q, qdot, qd, qd_dot, qd_ddot, T_c, h, params, state, model_terms, model_params, command, work
):
    """``τ = M̂ (q̈_d + K2 ė1 + K1 e1) + N̂``: paper eqs. (input) and (aux) with ``Δu = 0``.

    ``params = [K1, K2]`` flattened row-major; there is no state; ``work`` is
    :func:`~delaytrack.controllers.base.step_workspace` scratch.
    """
    n, m = plant_sizes(model_terms, q, command)
    memory = step_memory(model_terms, work)  # one set of arrays for the whole step
    vectors = memory[3]
    error = vectors[: 2 * n]
    u = vectors[2 * n : 3 * n]
    tracking_errors(q, qdot, qd, qd_dot, error, n)
    auxiliary_input(params, error, qd_ddot, u, n)
    computed_torque_command(model_terms, model_params, t, q, qdot, u, command, memory)


@dataclass(frozen=True, eq=False)
class OuterLoop(Controller):
    """Outer-loop controller ``τ = M̂ û + N̂``, ``û = q̈_d + K2 ė1 + K1 e1`` (the ablation of AROLC).

    Parameters
    ----------
    model : ELPlant
        Nominal plant ``M̂, N̂``.
    K1, K2 : array_like
        Symmetric positive definite (n, n); a scalar means a multiple of I, 1-D a diagonal.
    """

    model: ELPlant
    K1: np.ndarray
    K2: np.ndarray
    _params: np.ndarray = field(init=False, repr=False)
    type_name: ClassVar[str] = "outer-loop"

    if TYPE_CHECKING:
        # The generated __init__ takes any array_like gain; __post_init__ makes it a matrix.
        def __init__(self, model: ELPlant, K1: ArrayLike, K2: ArrayLike) -> None: ...

    def __post_init__(self) -> None:
        self._check_model()
        object.__setattr__(self, "K1", as_spd_matrix("K1", self.K1, self.model.n))
        object.__setattr__(self, "K2", as_spd_matrix("K2", self.K2, self.model.n))
        object.__setattr__(self, "_params", np.concatenate([self.K1.ravel(), self.K2.ravel()]))

    @property
    def params(self) -> np.ndarray:
        return self._params

    @property
    def step_kernel(self):
        return outer_loop_step

    @property
    def state_names(self) -> tuple[str, ...]:
        return ()

    def initial_state(self) -> np.ndarray:
        return np.zeros(0)

    def to_spec(self) -> dict[str, Any]:
        return {"type": self.type_name, "K1": self.K1.tolist(), "K2": self.K2.tolist()}
