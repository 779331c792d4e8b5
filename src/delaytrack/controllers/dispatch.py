"""Calling a controller's step from the engine: by id when compiled, as a callable otherwise.

See :mod:`delaytrack.plants.dispatch` for why compiled code dispatches on integer ids.
"""

from __future__ import annotations

from numba import types
from numba.extending import overload

__all__ = ["AROLC_STEP", "OUTER_LOOP_STEP", "PCON_STEP", "call_step"]

OUTER_LOOP_STEP = 0
AROLC_STEP = 1
#: PCON and PCONf share one kernel (a flag in their parameters selects the window).
PCON_STEP = 2


def call_step(
    step, t, q, qdot, qd, qd_dot, qd_ddot, T_c, h, params, state, model, model_params, command, work
):
    """Run one controller tick with ``step`` (see :mod:`delaytrack.controllers.base`)."""
    step(t, q, qdot, qd, qd_dot, qd_ddot, T_c, h, params, state, model, model_params, command, work)


@overload(call_step)
def _call_step_compiled(
    step, t, q, qdot, qd, qd_dot, qd_ddot, T_c, h, params, state, model, model_params, command, work
):
    if isinstance(step, types.Integer):
        from delaytrack.controllers.arolc import arolc_step
        from delaytrack.controllers.outer_loop import outer_loop_step
        from delaytrack.controllers.pcon import pcon_step

        def by_id(
            step,
            t,
            q,
            qdot,
            qd,
            qd_dot,
            qd_ddot,
            T_c,
            h,
            params,
            state,
            model,
            model_params,
            command,
            work,
        ):
            if step == OUTER_LOOP_STEP:
                outer_loop_step(
                    t,
                    q,
                    qdot,
                    qd,
                    qd_dot,
                    qd_ddot,
                    T_c,
                    h,
                    params,
                    state,
                    model,
                    model_params,
                    command,
                    work,
                )
            elif step == AROLC_STEP:
                arolc_step(
                    t,
                    q,
                    qdot,
                    qd,
                    qd_dot,
                    qd_ddot,
                    T_c,
                    h,
                    params,
                    state,
                    model,
                    model_params,
                    command,
                    work,
                )
            elif step == PCON_STEP:
                pcon_step(
                    t,
                    q,
                    qdot,
                    qd,
                    qd_dot,
                    qd_ddot,
                    T_c,
                    h,
                    params,
                    state,
                    model,
                    model_params,
                    command,
                    work,
                )
            else:
                raise ValueError("unknown controller kernel id")

        return by_id

    def by_callable(
        step,
        t,
        q,
        qdot,
        qd,
        qd_dot,
        qd_ddot,
        T_c,
        h,
        params,
        state,
        model,
        model_params,
        command,
        work,
    ):
        step(
            t,
            q,
            qdot,
            qd,
            qd_dot,
            qd_ddot,
            T_c,
            h,
            params,
            state,
            model,
            model_params,
            command,
            work,
        )

    return by_callable
