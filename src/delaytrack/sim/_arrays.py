"""The arrays the engine takes for a :class:`~delaytrack.sim._plan.Plan`, by name
(:mod:`delaytrack.sim.engine`)."""

from __future__ import annotations

import numpy as np

from delaytrack._validation import real_array
from delaytrack.sim._broadcast import stack_padded
from delaytrack.sim._plan import Plan
from delaytrack.sim.engine import Records, Run, Settings
from delaytrack.sim.running_metrics import accumulator_size

__all__ = ["records", "runs", "settings"]


def records(plan: Plan) -> tuple[Records, np.ndarray]:
    """What the runs write, filled with NaN (the metrics' sums with zeros), and the reference's
    record ``(R, 3, n)``; a recording that does not fit in free memory is refused."""
    batch, rows, n, m = plan.batch, plan.records, plan.n, plan.m
    recorded_state = len(plan.controllers[0].state_names)
    try:
        written = Records(
            states=np.full((batch, rows, 2 * n), np.nan),
            commands=np.full((batch, rows, m), np.nan),
            applied=np.full((batch, rows, m), np.nan),
            delays=np.full((batch, rows), np.nan),
            controller_states=np.full((batch, rows, recorded_state), np.nan),
            sums=np.zeros((batch, accumulator_size(n))),
        )
        reference_record = np.full((rows, 3, n), np.nan)  # q_d, q̇_d, q̈_d, by run 0
    except MemoryError:
        raise plan.too_big("is free") from None
    return written, reference_record


def runs(plan: Plan) -> Run:
    """Every run's arrays, with a leading batch axis."""
    plants, controllers = plan.plants, plan.controllers
    return Run(
        plant_params=stack_padded([p.params for p in plants]),
        model_params=stack_padded([c.model.params for c in controllers]),
        controller_params=stack_padded([c.params for c in controllers]),
        # float64, as the compiled parts take them (a user's class may give integers)
        controller_state=real_array(
            "the controllers' initial states", [c.initial_state() for c in controllers]
        ).reshape(plan.batch, controllers[0].state_size),
        delay_kind=np.array([d.kind for d in plan.delays], dtype=np.int64),
        delay_params=stack_padded([d.params for d in plan.delays]),
        x0=plan.x0,
        capacity=plan.capacities,
        input_limits=plan.input_limits,
        measurement=np.array([noise.params(plan.n) for noise in plan.measurement_noise]),
        loss=np.array([loss.params() for loss in plan.packet_loss]),
        records_reference=np.arange(plan.batch) == 0,  # the run that records the reference
    )


def settings(plan: Plan, reference_record: np.ndarray) -> Settings:
    """What every run shares; the run that records the reference writes ``reference_record``."""
    return Settings(
        reference_params=real_array("reference.params", plan.reference.params, ndim=1),
        u_init=plan.u_init,
        t0=plan.t0,
        dt=plan.dt,
        steps_per_tick=plan.steps_per_tick,
        n_ticks=plan.n_ticks,
        record_every=plan.every if plan.trajectories else 0,
        divergence_bound=plan.divergence_bound,
        error_bound=plan.error_bound,
        metrics_from=plan.metrics_from_tick,
        reference_record=reference_record,
    )
