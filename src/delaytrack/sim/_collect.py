"""Collect what the engine wrote for a batch into a :class:`~delaytrack.sim.result.SimResult`,
with the settings that made it."""

from __future__ import annotations

from typing import Any

import numpy as np

from delaytrack.components import call_reference
from delaytrack.sim._execute import Chunks
from delaytrack.sim._plan import Plan
from delaytrack.sim.result import SimResult
from delaytrack.sim.running_metrics import finish_metrics

__all__ = ["collect"]


def collect(chunks: Chunks) -> SimResult:
    """The result of the batch ``chunks`` ran: rows after a run stopped are NaN, rows of the
    reference that run 0 did not record (it stopped before them) are computed from the kernel
    the engine ran."""
    plan, build, records = chunks.build.plan, chunks.build, chunks.records
    status, t_stop = chunks.status, chunks.t_stop
    reference_rows = chunks.settings.reference_record
    times = plan.t0 + (np.arange(plan.records) * plan.every * plan.steps_per_tick) * plan.dt
    for b in np.flatnonzero(status != 0):
        after = times > t_stop[b]
        for array in (
            records.states,
            records.commands,
            records.applied,
            records.delays,
            records.controller_states,
        ):
            array[b, after] = np.nan
    unrecorded = np.flatnonzero(np.isnan(reference_rows).any(axis=(1, 2)))
    if unrecorded.size and build.compiled:
        reference_rows[unrecorded] = np.stack(plan.reference.evaluate(times[unrecorded]), axis=1)
    elif unrecorded.size:
        reference_kernel = build.handles(0, ()).reference
        for row in unrecorded:
            call_reference(
                reference_kernel,
                float(times[row]),
                chunks.settings.reference_params,
                *reference_rows[row],
            )
    first_plant, first_controller = plan.plants[0], plan.controllers[0]
    return SimResult(
        t=times,
        x=records.states,
        reference=reference_rows,
        commands=records.commands,
        applied=records.applied,
        h=records.delays,
        controller_state=records.controller_states,
        controller_state_names=first_controller.state_names,
        reported_state_names=first_controller.reported_state_names,
        status=status,
        t_stop=t_stop,
        metrics=finish_metrics(records.sums, status == 0),
        settings=_provenance(plan, build.compiled),
        coordinate_names=first_plant.coordinate_names,
        coordinate_units=first_plant.coordinate_units,
        input_units=first_plant.input_units,
        input_names=first_plant.input_names,
    )


def _provenance(plan: Plan, compiled: bool) -> dict[str, Any]:
    """The settings of the run, as :attr:`SimResult.settings` records them."""
    plants, controllers, limits = plan.plants, plan.controllers, plan.input_limits
    return {
        "t0": plan.t0,
        "t1": plan.t1,
        "dt": plan.dt,
        "T_c": plan.T_c,
        "record_every": plan.record_every,
        "trajectories": plan.trajectories,
        "metrics_from": plan.t0 + plan.metrics_from_tick * plan.steps_per_tick * plan.dt,
        "divergence_bound": plan.divergence_bound,
        "error_bound": plan.error_bound.tolist(),
        "input_limits": limits[0].tolist() if np.all(limits == limits[0]) else limits.tolist(),
        "measurement_noise": [noise.to_spec() for noise in plan.measurement_noise]
        if plan.noise_given
        else None,
        "packet_loss": [loss.to_spec() for loss in plan.packet_loss] if plan.loss_given else None,
        "compiled": compiled,
        "plant": [p.to_spec() for p in plants]
        if len(set(map(id, plants))) > 1
        else plants[0].to_spec(),
        "controller": controllers[0].to_spec()
        if len(set(map(id, controllers))) == 1
        else [c.to_spec() for c in controllers],
        "model": controllers[0].model.to_spec(),
        "delays": [d.to_spec() for d in plan.delays],
        "reference": plan.reference.to_spec(),
    }
