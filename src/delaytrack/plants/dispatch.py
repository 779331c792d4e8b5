"""Calling a plant's terms kernel from the engine: by id when compiled, as a callable otherwise.

numba keys its disk cache on argument types, and the type of a function passed as an argument
embeds its address, which changes in every process. So the compiled engine receives an integer
*kernel id* for built-in plants and dispatches statically (cacheable); the plain-Python engine
receives the callable itself. :func:`call_terms` is that one call site for both.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import types
from numba.extending import overload

from delaytrack._jit import inline_kernel
from delaytrack._small_linalg import solve_in_place

__all__ = [
    "LINEAR",
    "PythonKernel",
    "IDENTITY_MASS_IDS",
    "ROBOT_COMMAND_MAP_IDS",
    "ROBOT_NOMINAL",
    "ROBOT_PAYLOAD",
    "ROBOT_PRINTED",
    "ROBOT_TRUTH",
    "TWO_LINK_ARM",
    "call_command_map",
    "call_terms",
    "has_identity_mass",
    "python_kernel",
    "solve_input_map",
]

TWO_LINK_ARM = 0
LINEAR = 1
#: The wheeled robot (:mod:`delaytrack.plants.robot`): truth, truth with payload, the nominal
#: Lagrangian model and the paper's printed model.
ROBOT_TRUTH = 2
ROBOT_PAYLOAD = 3
ROBOT_NOMINAL = 4
ROBOT_PRINTED = 5
#: Nominal models whose command map is the robot's ``command = S(q)ᵀ τ``.
ROBOT_COMMAND_MAP_IDS = (ROBOT_NOMINAL, ROBOT_PRINTED)
#: Plants whose terms kernel always fills ``M = I``: the constrained robot, integrated as
#: ``q̈ = a + b τ`` (:mod:`delaytrack.plants.robot.truth`).
IDENTITY_MASS_IDS = (ROBOT_TRUTH, ROBOT_PAYLOAD)


def call_terms(terms, t, q, qdot, params, mass, nonlinear, input_map):
    """Fill ``M, N, G`` with ``terms`` (a callable here; an id or a callable in compiled code)."""
    terms(t, q, qdot, params, mass, nonlinear, input_map)


@overload(call_terms, inline="always")
def _call_terms_compiled(terms, t, q, qdot, params, mass, nonlinear, input_map):
    if isinstance(terms, types.Integer):
        from delaytrack.plants.linear import linear_terms
        from delaytrack.plants.robot.nominal import robot_nominal_terms
        from delaytrack.plants.robot.payload import robot_payload_terms
        from delaytrack.plants.robot.printed import robot_printed_terms
        from delaytrack.plants.robot.truth import robot_truth_terms
        from delaytrack.plants.two_link_arm import two_link_terms

        def by_id(terms, t, q, qdot, params, mass, nonlinear, input_map):
            if terms == TWO_LINK_ARM:
                two_link_terms(t, q, qdot, params, mass, nonlinear, input_map)
            elif terms == LINEAR:
                linear_terms(t, q, qdot, params, mass, nonlinear, input_map)
            elif terms == ROBOT_TRUTH:
                robot_truth_terms(t, q, qdot, params, mass, nonlinear, input_map)
            elif terms == ROBOT_PAYLOAD:
                robot_payload_terms(t, q, qdot, params, mass, nonlinear, input_map)
            elif terms == ROBOT_NOMINAL:
                robot_nominal_terms(t, q, qdot, params, mass, nonlinear, input_map)
            elif terms == ROBOT_PRINTED:
                robot_printed_terms(t, q, qdot, params, mass, nonlinear, input_map)
            else:
                raise ValueError("unknown plant kernel id")

        return by_id

    def by_callable(terms, t, q, qdot, params, mass, nonlinear, input_map):
        terms(t, q, qdot, params, mass, nonlinear, input_map)

    return by_callable


def has_identity_mass(terms):
    """Whether the plant kernel ``terms`` always fills ``M(q) = I``, so that ``q̈`` needs no solve.

    True for the ids in :data:`IDENTITY_MASS_IDS` (in plain Python, for a :class:`PythonKernel`
    carrying one of them); False for any other kernel, which is then solved for ``q̈``.
    """
    return getattr(terms, "kernel_id", None) in IDENTITY_MASS_IDS


@overload(has_identity_mass, inline="always")
def _has_identity_mass_compiled(terms):
    if isinstance(terms, types.Integer):

        def by_id(terms):
            return terms == ROBOT_TRUTH or terms == ROBOT_PAYLOAD

        return by_id

    def other(terms):
        return False

    return other


@inline_kernel
def solve_input_map(input_map, tau, command):
    """The default command map: solve ``G(q) command = τ`` (a fully actuated model)."""
    square = input_map.copy()
    command[:] = tau
    if not solve_in_place(square, command):
        command[:] = np.nan


@dataclass(frozen=True)
class PythonKernel:
    """A plant's terms kernel as plain Python (its ``py_func``), for the reference engine.

    It carries the plant's built-in ``kernel_id`` (None for a user plant), so that
    :func:`call_command_map` picks the same command map as the compiled engine does.
    """

    function: Callable[..., None]
    kernel_id: int | None

    def __call__(self, t, q, qdot, params, mass, nonlinear, input_map) -> None:
        self.function(t, q, qdot, params, mass, nonlinear, input_map)


def python_kernel(plant: Any) -> PythonKernel:
    """``plant``'s terms kernel as plain Python (see :class:`PythonKernel`)."""
    kernel = plant.terms_kernel
    return PythonKernel(getattr(kernel, "py_func", kernel), plant.kernel_id)


def call_command_map(model, q, params, input_map, tau, command):
    """Actuator ``command`` that realises the generalised force ``τ`` on the nominal ``model``.

    Fully actuated models solve ``G(q) command = τ``. A model with constraints supplies its own
    map by kernel id: the wheeled robot's nominal models (:data:`ROBOT_COMMAND_MAP_IDS`) use
    ``command = S(q)ᵀ τ`` (the paper's Section III). Other ids and Python models use the default; a
    :class:`PythonKernel` carries its model's id.
    """
    model = getattr(model, "kernel_id", model)
    if isinstance(model, int | np.integer) and not isinstance(model, bool):
        if int(model) in ROBOT_COMMAND_MAP_IDS:
            from delaytrack.plants.robot.kinematics import robot_command_map

            robot_command_map(q, params, tau, command)
            return
    solve_input_map(input_map, tau, command)


@overload(call_command_map)
def _call_command_map_compiled(model, q, params, input_map, tau, command):
    if isinstance(model, types.Integer):
        from delaytrack.plants.robot.kinematics import robot_command_map

        def by_id(model, q, params, input_map, tau, command):
            if model == ROBOT_NOMINAL or model == ROBOT_PRINTED:
                robot_command_map(q, params, tau, command)
            else:
                solve_input_map(input_map, tau, command)

        return by_id

    def default(model, q, params, input_map, tau, command):
        solve_input_map(input_map, tau, command)

    return default
