"""The controller's step and the reference as the compiled engine calls them: each compiled on
its own for the components it serves and called through its address
(:mod:`delaytrack._compile.native_parts`)."""

from __future__ import annotations

from delaytrack._compile.jit import tick_kernel
from delaytrack.components import call_reference, call_step

__all__ = ["evaluate_reference", "evaluate_step"]


@tick_kernel
def evaluate_step(
    step, t, q, qdot, qd, qd_dot, qd_ddot, T_c, h, params, state, model, model_params, command, work
):
    """``call_step`` (:func:`delaytrack.components.call_step`), compiled on its own for each
    controller step and nominal model: the compiled engine calls it through its address
    (:mod:`delaytrack._compile.native_parts`)."""
    call_step(
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
    )


@tick_kernel
def evaluate_reference(reference, t, params, qd, qd_dot, qd_ddot):
    """``call_reference`` (:func:`delaytrack.components.call_reference`), compiled on its own for
    each reference kernel: the compiled engine calls it through its address
    (:mod:`delaytrack._compile.native_parts`)."""
    call_reference(reference, t, params, qd, qd_dot, qd_ddot)
