"""``simulate``: the one verb that runs closed loops (SPEC §5)."""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from typing import Any, TypeVar

import numpy as np
from tqdm.auto import tqdm

from delaytrack._validation import finite_array, integer_multiple, positive_scalar
from delaytrack.controllers.base import Controller
from delaytrack.delays.base import DelayProfile
from delaytrack.plants.base import ELPlant
from delaytrack.reference import SinusoidalReference
from delaytrack.sim.engine import run_batch, run_batch_compiled
from delaytrack.sim.history import history_capacity
from delaytrack.sim.result import SimResult

__all__ = ["simulate"]

_T = TypeVar("_T")


def _as_batch(name: str, value: _T | Sequence[_T], kind: type) -> list[_T]:
    items = list(value) if isinstance(value, list | tuple) else [value]
    if not items:
        raise ValueError(f"{name} must not be empty")
    for i, item in enumerate(items):
        if not isinstance(item, kind):
            raise TypeError(
                f"{name}[{i}] must be an instance of {kind.__name__}; got {type(item).__name__}"
            )
    return items


def _integer_ratio(name: str, value: float, unit: float, what: str, scale: float = 0.0) -> int:
    count = integer_multiple(value, unit, scale=scale)
    if count is None:
        raise ValueError(
            f"{name} must be a positive integer multiple of {what}; "
            f"got ({name})/{what} = {value / unit:.12g}"
        )
    return count


def _physical_memory() -> float:
    """Bytes of physical memory (infinite where the platform does not say)."""
    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, ValueError, OSError):
        return math.inf


def _broadcast(name: str, items: list[_T], batch: int) -> list[_T]:
    if len(items) == batch:
        return items
    if len(items) == 1:
        return items * batch
    raise ValueError(
        f"{name} has {len(items)} entries but the batch has {batch}; give 1 or {batch}"
    )


def _stack_padded(vectors: list[np.ndarray]) -> np.ndarray:
    width = max(1, max(vector.size for vector in vectors))
    out = np.zeros((len(vectors), width))
    for i, vector in enumerate(vectors):
        out[i, : vector.size] = vector
    return out


def simulate(
    plant: ELPlant | Sequence[ELPlant],
    controller: Controller | Sequence[Controller],
    delay: DelayProfile | Sequence[DelayProfile],
    x0: np.ndarray,
    *,
    reference: SinusoidalReference,
    t1: float,
    dt: float,
    T_c: float,
    t0: float = 0.0,
    u_init: np.ndarray | None = None,
    record_every: int = 1,
    divergence_bound: float = 1e6,
    progress: bool = False,
) -> SimResult:
    """Simulate ``M(q) q̈ + N(q, q̇) = G(q) τ(t - h(t))`` under a sampled controller.

    The controller runs every ``T_c`` seconds with zero-order hold; the plant is integrated by RK4
    at ``dt``, with each step split where the delayed input switches (see
    :mod:`delaytrack.sim.engine`). The batch size is the largest of the lengths of ``plant``,
    ``controller``, ``delay`` and the first axis of a 2-D ``x0``; each of them has 1 entry
    (shared) or one per batch element.

    Parameters
    ----------
    plant : ELPlant or sequence of ELPlant
        The true plant(s); all of one kind (same terms kernel).
    controller : Controller or sequence of Controller
        Controller(s) of one kind, each with its nominal model.
    delay : DelayProfile or sequence of DelayProfile
        Input delay ``h(t)`` per batch element.
    x0 : array_like, shape (2n,) or (batch, 2n)
        Initial state ``[q(t0), q̇(t0)]``.
    reference : SinusoidalReference
        Desired trajectory ``q_d(t)``.
    t1, dt, T_c : float
        Final time, plant step and controller period, in seconds. ``T_c`` must be an integer
        multiple of ``dt`` and ``t1 - t0`` an integer multiple of ``T_c``. There is no default
        ``dt``: the choice is yours to justify.
    t0 : float
        Initial time.
    u_init : array_like, shape (m,), optional
        Input applied before the first command arrives (zero by default).
    record_every : int
        Record every ``record_every``-th controller tick.
    divergence_bound : float
        A run whose state leaves ``max |x_i| <= divergence_bound`` (or becomes non-finite) stops
        with status ``diverged``; the rest of the batch goes on.
    progress : bool
        Show a progress bar over the batch.

    Returns
    -------
    SimResult
    """
    plants = _as_batch("plant", plant, ELPlant)
    controllers = _as_batch("controller", controller, Controller)
    delays = _as_batch("delay", delay, DelayProfile)
    dt = positive_scalar("dt", dt)
    T_c = positive_scalar("T_c", T_c)
    t0 = float(finite_array("t0", t0, ndim=0))
    t1 = float(finite_array("t1", t1, ndim=0))
    if t1 <= t0:
        raise ValueError(f"t1 must be later than t0; got t0 = {t0:g}, t1 = {t1:g}")
    steps_per_tick = _integer_ratio("T_c", T_c, dt, "dt")
    n_ticks = _integer_ratio("t1 - t0", t1 - t0, T_c, "T_c", scale=max(abs(t0), abs(t1)))
    if (
        isinstance(record_every, bool)
        or not isinstance(record_every, int | np.integer)
        or record_every < 1
    ):
        raise ValueError(f"record_every must be a positive integer; got {record_every!r}")
    divergence_bound = positive_scalar("divergence_bound", divergence_bound)
    if not isinstance(reference, SinusoidalReference):
        raise TypeError(f"reference must be a SinusoidalReference; got {type(reference).__name__}")

    first_plant, first_controller = plants[0], controllers[0]
    n, m = first_plant.n, first_plant.m
    for i, item in enumerate(plants):
        if type(item) is not type(first_plant) or (item.n, item.m) != (n, m):
            raise ValueError(
                f"plant[{i}] must be a {type(first_plant).__name__} with n = {n}, m = {m}"
            )
    for i, item in enumerate(controllers):
        if item.step_kernel is not first_controller.step_kernel or type(item.model) is not type(
            first_controller.model
        ):
            raise ValueError(
                f"controller[{i}] must be of the same kind as controller[0] "
                "(with the same model type)"
            )
        if (item.n, item.m) != (n, m):
            raise ValueError(
                f"controller[{i}] has n = {item.n}, m = {item.m}; the plant has n = {n}, m = {m}"
            )
    if reference.n != n:
        raise ValueError(f"reference has n = {reference.n} coordinates; the plant has n = {n}")

    states0 = finite_array("x0", x0)
    if states0.ndim == 1:
        states0 = states0[None, :]
    if states0.ndim != 2 or states0.shape[1] != 2 * n:
        raise ValueError(f"x0 must have shape ({2 * n},) or (batch, {2 * n}); got {np.shape(x0)}")
    batch = max(len(plants), len(controllers), len(delays), states0.shape[0])
    plants = _broadcast("plant", plants, batch)
    controllers = _broadcast("controller", controllers, batch)
    delays = _broadcast("delay", delays, batch)
    states0 = np.ascontiguousarray(
        np.broadcast_to(states0, (batch, 2 * n)) if states0.shape[0] == 1 else states0
    )
    if states0.shape[0] != batch:
        raise ValueError(
            f"x0 has {states0.shape[0]} rows but the batch has {batch}; give 1 or {batch}"
        )
    for controller_b, delay_b in zip(controllers, delays, strict=True):
        controller_b.check_run(T_c, delay_b.h_max)
    u_init = np.zeros(m) if u_init is None else finite_array("u_init", u_init, ndim=1)
    if u_init.shape != (m,):
        raise ValueError(f"u_init must have shape ({m},); got {u_init.shape}")

    if np.max(np.abs(states0)) > divergence_bound:
        raise ValueError(
            f"x0 must lie within divergence_bound = {divergence_bound:g}; "
            f"max |x0| = {np.max(np.abs(states0)):g}"
        )

    records = n_ticks // record_every + 1
    state_size = first_controller.state_size
    recorded_state = len(first_controller.state_names)
    size = batch * records * (2 * n + 2 * m + 1 + recorded_state) * 8
    if size > _physical_memory():
        raise ValueError(
            f"recording {batch} run(s) x {records} samples needs {size / 2**30:.3g} GiB, more "
            "than this machine's memory; raise record_every, shorten t1 - t0 or split the batch"
        )
    try:
        states = np.full((batch, records, 2 * n), np.nan)
        commands = np.full((batch, records, m), np.nan)
        applied = np.full((batch, records, m), np.nan)
        delay_records = np.full((batch, records), np.nan)
        controller_states = np.full((batch, records, recorded_state), np.nan)
    except MemoryError:
        raise ValueError(
            f"recording {batch} run(s) x {records} samples needs {size / 2**30:.3g} GiB, more "
            "than is free; raise record_every, shorten t1 - t0 or split the batch"
        ) from None
    status = np.zeros(batch, dtype=np.int64)
    t_stop = np.zeros(batch)

    compiled = first_plant.compiled and first_controller.compiled
    runner = run_batch_compiled if compiled else run_batch

    def handles(b: int) -> tuple:
        """Kernel ids (compiled) or element ``b``'s own callables (plain Python)."""
        plant_b, controller_b = plants[b], controllers[b]
        if compiled:
            return (
                plant_b.kernel_id,
                controller_b.model.kernel_id,
                reference.kernel_id,
                controller_b.kernel_id,
            )
        return (
            plant_b.terms_kernel,
            controller_b.model.kernel_handle,
            reference.kernel,
            controller_b.step_callable,
        )

    runs = (
        _stack_padded([p.params for p in plants]),
        _stack_padded([c.model.params for c in controllers]),
        _stack_padded([c.params for c in controllers]),
        np.array([c.initial_state() for c in controllers]).reshape(batch, state_size),
        np.array([d.kind for d in delays], dtype=np.int64),
        _stack_padded([d.params for d in delays]),
        states0,
        np.array([history_capacity(d.h_max, T_c) for d in delays], dtype=np.int64),
    )
    settings = (
        reference.params,
        u_init,
        t0,
        dt,
        steps_per_tick,
        n_ticks,
        int(record_every),
        divergence_bound,
    )
    outputs = (states, commands, applied, delay_records, controller_states)
    # Compiled kernels are shared by the whole batch; Python callables may differ per element,
    # so the plain-Python engine runs one element at a time.
    if compiled and not progress:
        chunks = [np.arange(batch)]
    else:
        chunks = np.array_split(np.arange(batch), batch if not compiled else min(batch, 100))
    for chunk in tqdm(chunks, desc="simulate", unit="chunk", disable=not progress):
        part = slice(chunk[0], chunk[-1] + 1)
        runner(
            handles(int(chunk[0])),
            tuple(array[part] for array in runs),
            settings,
            tuple(array[part] for array in outputs),
            status[part],
            t_stop[part],
        )

    times = t0 + (np.arange(records) * record_every * steps_per_tick) * dt
    for b in np.flatnonzero(status != 0):
        after = times > t_stop[b]
        for array in (states, commands, applied, delay_records, controller_states):
            array[b, after] = np.nan
    qd, qd_dot, qd_ddot = reference.evaluate(times)
    record: dict[str, Any] = {
        "t0": t0,
        "t1": t1,
        "dt": dt,
        "T_c": T_c,
        "record_every": int(record_every),
        "divergence_bound": divergence_bound,
        "compiled": compiled,
        "plant": [p.to_spec() for p in plants]
        if len(set(map(id, plants))) > 1
        else plants[0].to_spec(),
        "controller": controllers[0].to_spec()
        if len(set(map(id, controllers))) == 1
        else [c.to_spec() for c in controllers],
        "model": controllers[0].model.to_spec(),
        "delays": [d.to_spec() for d in delays],
        "reference": reference.to_spec(),
    }
    return SimResult(
        t=times,
        x=states,
        reference=np.stack([qd, qd_dot, qd_ddot], axis=1),
        commands=commands,
        applied=applied,
        h=delay_records,
        controller_state=controller_states,
        controller_state_names=first_controller.state_names,
        status=status,
        t_stop=t_stop,
        settings=record,
    )
