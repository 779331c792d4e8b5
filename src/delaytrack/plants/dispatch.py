"""Calling a plant's terms kernel from the engine: by id when compiled, as a callable otherwise.

numba keys its disk cache on argument types, and the type of a function passed as an argument
embeds its address, which changes in every process. So the compiled engine receives an integer
*kernel id* for built-in plants and dispatches statically (cacheable); the plain-Python engine
receives the callable itself. :func:`call_terms` is that one call site for both.
"""

from __future__ import annotations

import numpy as np
from numba import types
from numba.extending import overload, register_jitable

__all__ = ["LINEAR", "TWO_LINK_ARM", "call_command_map", "call_terms", "solve_input_map"]

TWO_LINK_ARM = 0
LINEAR = 1


def call_terms(terms, t, q, qdot, params, mass, nonlinear, input_map):
    """Fill ``M, N, G`` with ``terms`` (a callable here; an id or a callable in compiled code)."""
    terms(t, q, qdot, params, mass, nonlinear, input_map)


@overload(call_terms)
def _call_terms_compiled(terms, t, q, qdot, params, mass, nonlinear, input_map):
    if isinstance(terms, types.Integer):
        from delaytrack.plants.linear import linear_terms
        from delaytrack.plants.two_link_arm import two_link_terms

        def by_id(terms, t, q, qdot, params, mass, nonlinear, input_map):
            if terms == TWO_LINK_ARM:
                two_link_terms(t, q, qdot, params, mass, nonlinear, input_map)
            elif terms == LINEAR:
                linear_terms(t, q, qdot, params, mass, nonlinear, input_map)
            else:
                raise ValueError("unknown plant kernel id")

        return by_id

    def by_callable(terms, t, q, qdot, params, mass, nonlinear, input_map):
        terms(t, q, qdot, params, mass, nonlinear, input_map)

    return by_callable


@register_jitable
def solve_input_map(input_map, tau, command):
    """The default command map: solve ``G(q) command = τ`` (a fully actuated model)."""
    command[:] = np.linalg.solve(input_map, tau)


def call_command_map(model, q, params, input_map, tau, command):
    """Actuator ``command`` that realises the generalised force ``τ`` on the nominal ``model``.

    Fully actuated models solve ``G(q) command = τ``. A model with constraints supplies its own
    map by kernel id (e.g. the wheeled robot's ``command = S(q)ᵀ τ``); a Python model uses the
    default.
    """
    solve_input_map(input_map, tau, command)


@overload(call_command_map)
def _call_command_map_compiled(model, q, params, input_map, tau, command):
    def default(model, q, params, input_map, tau, command):
        solve_input_map(input_map, tau, command)

    return default
