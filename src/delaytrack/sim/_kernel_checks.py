"""The user's kernels tried before the run, so that a fault is refused naming the kernel instead
of running on silently or crashing compiled code."""

from __future__ import annotations

from typing import Any

import numpy as np

from delaytrack._compile.functions import at_few_points, qualified_name
from delaytrack._validation import as_spd_matrix
from delaytrack.components import Kernel
from delaytrack.controllers.base import Controller
from delaytrack.delays.base import DelayProfile
from delaytrack.kernel_arguments import KERNEL_ARGUMENTS, check_kernel_arguments
from delaytrack.plants.base import ELPlant
from delaytrack.references import Reference
from delaytrack.sim._kernel_errors import numba_cause, raised_during_the_run, raised_in_code_of

__all__ = [
    "check_controller_at_x0",
    "check_kernels_take_their_arguments",
    "check_plant_at_x0",
    "check_reduced_start",
    "checked_before_the_run",
    "refuse_reads_past",
    "velocities_on_constraints",
]


def check_kernels_take_their_arguments(
    plant: ELPlant, controller: Controller, reference: Reference
) -> None:
    """Check that the plant's, the controller's and the reference's kernels take the arguments
    the engine passes them (:mod:`delaytrack.kernel_arguments`), before anything is compiled."""
    for owner, component in (("plant", plant), ("controller's model", controller.model)):
        kernel = component.engine_kernel
        check_kernel_arguments(owner, "terms", kernel.function)
        for kind in ("command_map", "stepper"):
            if getattr(kernel, kind) is not None:
                check_kernel_arguments(owner, kind, getattr(kernel, kind))
        if kernel.reduced is not None:
            check_kernel_arguments(owner, "velocity_map", kernel.reduced.velocity_map)
            check_kernel_arguments(owner, "reduced_dynamics", kernel.reduced.dynamics)
    check_kernel_arguments("controller", "step", controller.step_kernel)
    check_kernel_arguments("reference", "reference", reference.reference_kernel)


def checked_before_the_run(kernel: Kernel, what: str, check: Any) -> Any:
    """``check()``, a call of the user's ``kernel`` before the run (``what`` it checks), with
    what it raises other than a ValueError of ours in one line naming the kernel: an error of
    the kernel itself, or numba's when it cannot compile the check around it."""
    try:
        return check()
    except Exception as error:
        if isinstance(error, ValueError) and not raised_in_code_of(kernel, error):
            raise  # a refusal of ours
        if type(error).__module__.startswith("numba"):
            raise ValueError(
                f"numba could not compile {what} for your kernel {kernel.callable_names[0]}: "
                f"{numba_cause(error)}"
            ) from None
        raise ValueError(
            raised_during_the_run(error, [kernel], when=f"before the run ({what})")
        ) from None


#: How a message names a kernel of each kind (a key of ``KERNEL_ARGUMENTS``).
_KIND_NAMES = {"step": "controller step"}


def refuse_reads_past(kernel: Kernel, kind: str, arguments: tuple, where: str) -> None:
    """Run the plain-Python version of the user's ``kernel`` (a ``kind`` of
    :data:`~delaytrack.kernel_arguments.KERNEL_ARGUMENTS`) once on copies of ``arguments``, the
    arrays the engine passes it, of their sizes: compiled, a read past an array's end runs on
    silently with whatever lies there, and a write past it overwrites other memory (or crashes
    the process); Python raises IndexError, refused here naming the kernel and the arrays'
    sizes. Other errors are left to the compiled kernel, which is what runs (Python may lack
    what numba provides). An index only on another branch, or in a compiled helper the kernel
    calls, is not seen."""
    python = getattr(kernel.function, "py_func", None)
    if kernel.built_in or python is None:
        return
    copies = [value.copy() if isinstance(value, np.ndarray) else value for value in arguments]
    try:
        python(*copies)
    except IndexError as error:
        sizes = ", ".join(
            f"{name} {value.shape[0] if value.ndim == 1 else value.shape}"
            for name, value in zip(KERNEL_ARGUMENTS[kind], arguments, strict=True)
            if isinstance(value, np.ndarray)
        )
        raise ValueError(
            f"your {_KIND_NAMES.get(kind, kind)} kernel {kernel.callable_names[0]} reads or "
            f"writes beyond an array {where} ({error}); the arrays it is given have these "
            f"sizes: {sizes}. Index only within them (compiled, it would read or write other "
            "memory silently, or crash the process)"
        ) from None
    except Exception:  # noqa: BLE001 - only reads past an array's end are checked here
        return


def check_plant_at_x0(plant: ELPlant, x0: np.ndarray, t0: float) -> None:
    """A plant of the user's (solved for ``q̈``) at the run's start: its kernel reads no index
    past an array's end (:func:`refuse_reads_past`) and gives an ``M`` that is symmetric
    positive definite, or it is refused naming the kernel (the run would stop at once)."""
    kernel = plant.engine_kernel
    if kernel.built_in or kernel.stepper is not None or kernel.identity_mass:
        return
    n = plant.n
    terms = (t0, x0[:n], x0[n:], plant.params, np.zeros((n, n)), np.zeros(n))
    refuse_reads_past(kernel, "terms", (*terms, np.zeros((n, plant.m))), "at x0")
    mass = checked_before_the_run(
        kernel, "the check of M at x0", lambda: plant.terms(x0[None, :n], x0[None, n:], t0)[0][0]
    )
    as_spd_matrix(f"the plant's M at x0 (from your kernel {kernel.callable_names[0]})", mass, n)


#: Largest ``|q̇ - S(q) η|`` of a start accepted by a plant with a reduced form, relative to
#: ``1 + |q̇|``: rounding, not a velocity.
REDUCED_START_TOLERANCE = 1e-9


def check_reduced_start(plants: list[ELPlant], states0: np.ndarray) -> None:
    """Refuse starts off the velocity constraints of plants with a reduced form
    (:class:`~delaytrack.components.ReducedForm`): the engine integrates ``(q, η)`` and sets
    ``q̇ = S(q) η``, so a start whose other velocities disagree would be changed at the first
    step instead of run as given. Each row of ``states0`` is checked with its run's plant (a
    single plant or row serves every run); the velocity map must write every entry of ``q̇``
    and read ``η`` before writing ``q̇`` (the engine passes ``η`` as the tail of ``q̇``)."""
    if all(plant.engine_kernel.reduced is None for plant in plants):
        return
    runs = max(len(plants), len(states0))
    checked = set()  # a plant repeated over a batch from one x0 is checked once
    for run in range(runs):
        plant = plants[run if len(plants) > 1 else 0]
        row = run if len(states0) > 1 else 0
        kernel = plant.engine_kernel
        if kernel.reduced is not None and (id(plant), row) not in checked:
            checked.add((id(plant), row))
            where = "" if runs == 1 else f" (run {run})"
            _check_reduced_row(plant, kernel, states0[row], where)


def velocities_on_constraints(
    plant: ELPlant, state: np.ndarray, as_the_engine: bool = False
) -> np.ndarray:
    """``q̇ = S(q) η`` of a plant with a reduced form (:class:`~delaytrack.components.ReducedForm`)
    at ``state = [q, q̇]``, ``η`` the last ``r`` entries of ``q̇``: the velocities on the plant's
    constraints. ``as_the_engine``: the map called as the engine calls it, ``η`` the tail of the
    ``q̇`` it writes (else on copies, into an array of NaN)."""
    reduced = plant.engine_kernel.reduced
    assert reduced is not None
    n, r = plant.n, reduced.size
    params = np.ascontiguousarray(plant.params, dtype=np.float64)

    def at_state(velocity_map):
        x = np.array(state, dtype=np.float64)
        if as_the_engine:
            velocity_map(x[:n], x[2 * n - r :], params, x[n:])
            return x[n:]
        qdot = np.full(n, np.nan)
        velocity_map(x[:n], x[2 * n - r :].copy(), params, qdot)
        return qdot

    # one point of one of the package's maps as Python while it is not compiled
    return at_few_points(reduced.velocity_map, 1, at_state)


def _check_reduced_row(plant: ELPlant, kernel: Kernel, state: np.ndarray, where: str) -> None:
    """:func:`check_reduced_start` for one run's ``plant`` and start ``state``."""
    reduced = kernel.reduced
    assert reduced is not None
    n, r = plant.n, reduced.size
    qdot = np.ascontiguousarray(state[n:])
    found: list[np.ndarray] = []

    def both() -> None:
        found.extend(velocities_on_constraints(plant, state, engine) for engine in (False, True))

    checked_before_the_run(kernel, "the velocity map at x0", both)
    expected, aliased = found
    name = qualified_name(reduced.velocity_map)
    if not np.all(np.isfinite(expected)):
        raise ValueError(
            f"your velocity map {name} gave a non-finite q̇ at x0{where}: "
            f"{np.array2string(expected, precision=6)}; it must write every entry of q̇"
        )
    if not np.array_equal(expected, aliased):
        raise ValueError(
            f"your velocity map {name} gives another q̇ when eta is the tail of qdot, as the "
            "engine passes it: read every entry of eta before writing qdot"
        )
    gap = float(np.max(np.abs(qdot - expected)))
    if not gap <= REDUCED_START_TOLERANCE * (1.0 + float(np.max(np.abs(qdot)))):
        raise ValueError(
            f"x0{where} must satisfy the plant's velocity constraints q̇ = S(q) η, η its "
            f"last {r} velocities: q̇ = {np.array2string(qdot, precision=6)} but "
            f"S(q) η = {np.array2string(expected, precision=6)} (the plant "
            f"{type(plant).__name__} is integrated in its reduced form, which keeps the "
            "constraints exactly); start from velocities that satisfy them (for the wheeled "
            "robot: delaytrack.plants.robot.consistent_state)"
        )


def check_controller_at_x0(
    controller: Controller, x0: np.ndarray, t0: float, T_c: float, delay: DelayProfile
) -> None:
    """A controller's kernels of the user's at the run's first tick: its nominal model's and
    its step's read no index past an array's end (:func:`refuse_reads_past`; the reference
    taken as zeros, the delay as ``h(t0)``)."""
    n, m = controller.n, controller.m
    model = controller.model
    q, qdot = x0[:n], x0[n:]
    terms = (t0, q, qdot, model.params, np.zeros((n, n)), np.zeros(n), np.zeros((n, m)))
    refuse_reads_past(model.engine_kernel, "terms", terms, "at x0")
    step = controller.engine_kernel
    if step.built_in:
        return
    arguments = controller.step_arguments(
        t0,
        q,
        qdot,
        (np.zeros(n), np.zeros(n), np.zeros(n)),
        controller.initial_state(),
        T_c=T_c,
        h=float(delay.h(t0)),
    )
    refuse_reads_past(step, "step", arguments, "at its first tick")
