"""The Euler–Lagrange plant interface ``M(q) q̈ + N(q, q̇) = G(q) u``.

A plant is defined once, by a *terms kernel* ``terms(t, q, qdot, params, M, N, G)`` that fills the
mass matrix ``M`` (n, n), the nonlinear terms ``N`` (n,) — Coriolis, gravity, friction, anything
not proportional to q̈ — and the input map ``G`` (n, m), at time ``t`` (a time-varying plant, such
as one carrying a payload on a schedule, reads it). The simulator integrates the state
``x = [q, q̇]`` (2n,) with the right-hand side :func:`el_rhs`; the controllers use the same
kernel of a *nominal* plant as their model ``M̂, N̂``. Kernels are numba-compiled for the built-in
plants and plain Python for :class:`~delaytrack.plants.CallablePlant`.
"""

from __future__ import annotations

import contextlib
import math
from abc import ABC, abstractmethod
from collections.abc import Callable
from functools import cached_property
from typing import Any, ClassVar

import numpy as np

from delaytrack._compile.functions import at_few_points
from delaytrack._compile.jit import hot_inline_kernel, inline_kernel
from delaytrack._small_linalg import solve_mass_in_place
from delaytrack._validation import is_integer_at_least
from delaytrack.components import (
    Kernel,
    ReducedForm,
    call_terms,
    has_identity_mass,
    plant_sizes,
)

__all__ = ["MAX_PLANT_SIZE", "ELPlant", "check_plant_size", "el_rhs", "rhs_scratch"]

#: Most coordinates, and most inputs, of a plant: every run holds ``M`` (n x n) and ``G``
#: (n x m) dense and solves ``M q̈ = f`` in O(n³) at every RK4 stage (8 MB for ``M`` at
#: n = 1000, about 10⁹ operations a stage).
MAX_PLANT_SIZE = 1000


def check_plant_size(label: str, value: object) -> int:
    """``value`` (``n`` or ``m``, named ``label``) as an int from 1 to :data:`MAX_PLANT_SIZE`,
    or a ValueError naming it."""
    if not is_integer_at_least(value, 1):
        raise ValueError(f"{label} must be a positive integer; got {value!r}")
    if value > MAX_PLANT_SIZE:
        raise ValueError(
            f"{label} = {value} is more than a plant may have: at most {MAX_PLANT_SIZE} (every "
            "run holds M (n x n) and G (n x m) dense and solves M q̈ = f in O(n³) at every "
            "RK4 stage)"
        )
    return int(value)


@inline_kernel
def rhs_scratch(n, m):
    """Working arrays ``(M (n, n), N (n,), G (n, m))`` of :func:`el_rhs`, allocated once a run,
    zeroed: an entry a kernel leaves unwritten holds the same number in every run."""
    return np.zeros((n, n)), np.zeros(n), np.zeros((n, m))


@hot_inline_kernel
def el_rhs(terms, t, q, qdot, u, params, qddot, scratch):
    """Acceleration of ``M(q) q̈ + N(q, q̇) = G(q) u``: ``q̈ = M(q)^{-1} (G(q) u - N(q, q̇))``.

    The paper's eq. (sys new) with the applied, delayed input ``u = τ(t - h(t))``; the state
    derivative is ``[q̇, q̈]``. ``scratch`` is :func:`rhs_scratch` ``(n, m)``: nothing is
    allocated, so the compiled inner loop stays cheap. ``terms`` is the plant's
    :class:`~delaytrack.components.Kernel`; one that always has ``M = I``
    (:attr:`ELPlant.identity_mass`) skips the solve. Returns False when the solve shows that
    ``M`` is not symmetric positive definite
    (:func:`~delaytrack._small_linalg.solve_mass_in_place`).
    """
    mass, nonlinear, input_map = scratch
    call_terms(terms, t, q, qdot, params, mass, nonlinear, input_map)
    n, m = plant_sizes(terms, q, u)
    for i in range(n):
        force = -nonlinear[i]
        for j in range(m):
            force += input_map[i, j] * u[j]
        qddot[i] = force
    # A singular M is reported through q̈ (the simulator then stops the run with a status)
    # instead of raising and ending the whole batch; a non-finite force gives a non-finite q̈,
    # and the state that the simulator checks after each step becomes non-finite with it.
    if has_identity_mass(terms):
        return True
    solved, definite = solve_mass_in_place(mass, qddot)
    if not solved:
        qddot[:] = np.nan
    return definite


class ELPlant(ABC):
    """An Euler–Lagrange plant with ``n`` coordinates and ``m`` inputs.

    Subclasses provide :attr:`terms_kernel` and :attr:`params`. Any control-affine second-order
    system fits this form (a constrained one with ``M = I``, ``N = -a(q, q̇)``, ``G = b(q)``).
    The Python
    methods below evaluate the same kernel with a leading batch axis: ``q (batch, n)``.
    """

    # The sizes, names and units below are set by a plant's class body when they are fixed (a
    # plain assignment, so that a dataclass does not take them for fields) and by its
    # constructor when they depend on the instance (a model file's joints).

    #: Number of generalised coordinates.
    n: int
    #: Number of actuator inputs.
    m: int
    #: Names of the coordinates in result tables (``ae_<name>``); None means ``q1 .. qn``.
    coordinate_names: tuple[str, ...] | None = None
    #: Units of the coordinates (``"m"``, ``"rad"``) for figure axes and table columns; None
    #: when the plant does not say.
    coordinate_units: tuple[str, ...] | None = None
    #: Units of the actuator inputs (``"N·m"``); None when the plant does not say.
    input_units: tuple[str, ...] | None = None
    #: Names of the actuator inputs in figures (``tau1``, a MuJoCo actuator's name); None
    #: means ``u1 .. um``.
    input_names: tuple[str, ...] | None = None
    #: True for a plant whose terms kernel always fills ``M(q) = I`` (a constrained robot
    #: integrated as ``q̈ = a + b τ``): the simulator then skips the solve for ``q̈``.
    identity_mass: ClassVar[bool] = False
    #: False for a plant whose kernel writes memory of its own (a MuJoCo model's ``mjData``):
    #: the simulator then gives each thread of a batch its own copy (:meth:`for_worker`).
    thread_safe: ClassVar[bool] = True

    @property
    @abstractmethod
    def params(self) -> np.ndarray:
        """Parameter vector passed to the kernels (float64, 1-D)."""

    @property
    @abstractmethod
    def terms_kernel(self) -> Callable[..., None]:
        """``terms(t, q, qdot, params, M, N, G)``: fill ``M`` (n, n), ``N`` (n,), ``G`` (n, m)."""

    @abstractmethod
    def to_spec(self) -> dict[str, Any]:
        """Plain-data description (type name and parameters) for scenario files and reports."""

    def for_worker(self, index: int) -> ELPlant:
        """The plant whose kernel the batch's chunk ``index`` (> 0) runs: the plant itself
        unless it writes memory of its own (:attr:`thread_safe`), then a copy of its own."""
        return self

    def while_running(self) -> contextlib.AbstractContextManager[None]:
        """What the simulator holds while its runs evaluate this plant or model: nothing,
        unless a plant needs a setting of the library it runs in (a MuJoCo model stops MuJoCo's
        profiling clock, :mod:`delaytrack.plants.mujoco.timer`)."""
        return contextlib.nullcontext()

    @property
    def run_identity(self) -> np.ndarray:
        """What the engine computes with, as numbers, for a sweep unit's hash: the parameter
        vector, unless it holds numbers that change between processes (addresses)."""
        return self.params

    @property
    def horizon(self) -> float:
        """Last time (s) up to which the plant's data define it (``inf``: always).

        A plant built from time-limited data (a payload schedule) states where that data ends;
        :func:`~delaytrack.sim.simulate` refuses a run beyond it unless the plant was told to
        hold its last state.
        """
        return math.inf

    @property
    def command_map_kernel(self) -> Callable[..., None] | None:
        """As a nominal model: ``command_map(q, params, tau, command)``, the actuator command
        realising a generalised force ``τ`` when the model maps it to its ``m < n`` actuators
        itself (the wheeled robot's ``S(q)ᵀ τ``); None solves ``Ĝ(q) command = τ``."""
        return None

    @property
    def has_command_map(self) -> bool:
        """Whether the model maps ``τ`` to its actuators itself (:attr:`command_map_kernel`)."""
        return self.command_map_kernel is not None

    @cached_property
    def engine_kernel(self) -> Kernel:
        """The :class:`~delaytrack.components.Kernel` the simulator calls for this plant (made
        once: a plant does not change)."""
        return Kernel.of(
            self.terms_kernel,
            self.command_map_kernel,
            self.identity_mass,
            (self.n, self.m),
            self.stepper_kernel,
            self.reduced_form,
        )

    @property
    def reduced_form(self) -> ReducedForm | None:
        """The plant's reduced form (:class:`~delaytrack.components.ReducedForm`), which the
        simulator integrates instead of the terms, or None (the default): a plant whose
        velocities obey constraints may declare one."""
        return None

    @property
    def stepper_kernel(self) -> Callable[..., None] | None:
        """For a plant stepped by an integrator of its own (a MuJoCo model stepped by MuJoCo):
        ``stepper(t, x, u, dt, params, first)`` (:class:`~delaytrack.components.Kernel`);
        None: the simulator integrates the terms with RK4."""
        return None

    def check_step(self, dt: float) -> None:  # noqa: B027 - a default
        """Refuse a plant step ``dt`` this plant cannot take (its own integrator's fixed
        step); every step is fine for the simulator's RK4."""

    @property
    def compiled(self) -> bool:
        """Whether the plant's kernels (terms, and command map, stepper or reduced form when it
        has them) are numba-compiled (else the simulator runs as Python)."""
        return self.engine_kernel.compiled

    def terms(
        self, q: np.ndarray, qdot: np.ndarray, t: float = 0.0
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``M (batch, n, n)``, ``N (batch, n)``, ``G (batch, n, m)`` at ``q, qdot (batch, n)``."""
        q = self._batch("q", q)
        qdot = self._batch("qdot", qdot)
        if q.shape[0] != qdot.shape[0]:
            raise ValueError(
                f"q and qdot must have the same batch size; got {q.shape[0]} and {qdot.shape[0]}"
            )
        batch = q.shape[0]
        params = self.params

        def each_point(terms_kernel):
            mass = np.zeros((batch, self.n, self.n))
            nonlinear = np.zeros((batch, self.n))
            input_map = np.zeros((batch, self.n, self.m))
            for b in range(batch):
                terms_kernel(float(t), q[b], qdot[b], params, mass[b], nonlinear[b], input_map[b])
            return mass, nonlinear, input_map

        # a few points of one of the package's kernels as Python while it is not compiled
        return at_few_points(self.terms_kernel, batch, each_point)

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """``M(q)``, shape (batch, n, n)."""
        q = self._batch("q", q)
        return self.terms(q, np.zeros_like(q))[0]

    def nonlinear_terms(self, q: np.ndarray, qdot: np.ndarray) -> np.ndarray:
        """``N(q, q̇)``, shape (batch, n)."""
        return self.terms(q, qdot)[1]

    def input_map(self, q: np.ndarray) -> np.ndarray:
        """``G(q)``, shape (batch, n, m)."""
        q = self._batch("q", q)
        return self.terms(q, np.zeros_like(q))[2]

    def state_derivative(self, x: np.ndarray, u: np.ndarray, t: float = 0.0) -> np.ndarray:
        """``dx/dt`` at states ``x (batch, 2n)`` with inputs ``u (batch, m)``."""
        x = np.atleast_2d(np.asarray(x, dtype=float))
        u = np.atleast_2d(np.asarray(u, dtype=float))
        if x.shape[1] != 2 * self.n or u.shape[1] != self.m:
            raise ValueError(
                f"x must have shape (batch, {2 * self.n}) and u (batch, {self.m}); "
                f"got {x.shape} and {u.shape}"
            )
        if u.shape[0] not in (1, x.shape[0]):
            raise ValueError(
                f"u must have batch 1 or {x.shape[0]} (the batch of x); got {u.shape[0]}"
            )
        dx = np.empty_like(x)
        dx[:, : self.n] = x[:, self.n :]
        scratch = rhs_scratch(self.n, self.m)
        kernel = self.engine_kernel
        for b in range(x.shape[0]):
            q, qdot = x[b, : self.n], x[b, self.n :]
            el_rhs(
                kernel,
                float(t),
                q,
                qdot,
                u[b % u.shape[0]],
                self.params,
                dx[b, self.n :],
                scratch,
            )
        return dx

    def _batch(self, name: str, value: np.ndarray) -> np.ndarray:
        array = np.atleast_2d(np.asarray(value, dtype=float))
        if array.ndim != 2 or array.shape[1] != self.n:
            raise ValueError(
                f"{name} must have shape (batch, {self.n}) or ({self.n},); got {np.shape(value)}"
            )
        return np.ascontiguousarray(array)
