"""The component protocol: how the engine calls a plant, model, controller or reference kernel.

Every component of a closed loop is a *kernel* (a function with a fixed signature, compiled with
``numba.njit`` or plain Python) plus a parameter vector it reads. The engine is handed each
component's :class:`Kernel` and calls it through one of the functions below:

===============================  ===========================================================
:func:`call_terms`               plant or nominal model: ``terms(t, q, qdot, params, M, N, G)``
:func:`call_command_map`         nominal model: actuator command realising a force ``τ``
:func:`has_identity_mass`        plant: ``M(q) = I`` always (no solve for ``q̈``)
:func:`plant_sizes`              plant: its ``n`` and ``m``, constants when compiled
:func:`has_stepper`              plant: stepped by an integrator of its own
:func:`call_stepper`             such a plant: one step ``stepper(t, x, u, dt, params, first)``
:func:`reduced_size`             plant: ``r`` of a reduced form (:class:`ReducedForm`), else 0
:func:`call_velocity_map`        such a plant: ``velocity_map(q, eta, params, qdot)``
:func:`call_reduced_dynamics`    such a plant: ``dynamics(t, q, eta, u, params, eta_dot)``
:func:`call_step`                controller: one tick (see :mod:`delaytrack.controllers.base`)
:func:`call_reference`           reference: ``q_d, q̇_d, q̈_d`` at ``t``
:func:`call_delay`               delay profile of your own: ``h(t)``
===============================  ===========================================================

The built-in components use this protocol exactly as a user's do; adding one is one file with
its kernel and its class.

In compiled code a :class:`Kernel` has a numba type of its own, named by :attr:`Kernel.key`:
the function's module and name and, for a function outside this package, a hash of its code
(and of the functions and constants it reaches). numba compiles the code that calls a kernel
(its part of the engine) once for each kernel and caches it on disk under this name, so a
user's compiled plant is compiled once, not once per process, and an edit to its code compiles
it again (:mod:`delaytrack._compile.kernel_type`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property, lru_cache
from typing import TYPE_CHECKING, Any

import numpy as np
from numba.extending import overload

from delaytrack._compile.fingerprint import name_with_code
from delaytrack._compile.functions import in_package, is_compiled, qualified_name
from delaytrack._compile.guards import refuse_managed_result
from delaytrack._compile.jit import shared_kernel
from delaytrack._compile.kernel_type import KernelType, known_to_numba, numba_type_of
from delaytrack._compile.native_call import NativeFunctionType, call_native
from delaytrack._compile.stack_arrays import MOST_STACK_ENTRIES
from delaytrack._deprecated import moved_names
from delaytrack._small_linalg import solve_in_place
from delaytrack._validation import is_integer_at_least

if TYPE_CHECKING:
    from numba.core.decorators import _JITOptions

__all__ = [
    "Kernel",
    "ReducedForm",
    "call_command_map",
    "call_delay",
    "call_reduced_dynamics",
    "call_reference",
    "call_step",
    "call_stepper",
    "call_terms",
    "call_velocity_map",
    "compiled_sizes",
    "has_identity_mass",
    "has_stepper",
    "plant_sizes",
    "reduced_size",
    "sizes_on_stack",
    "solve_input_map",
]

#: Fingerprints, guards and the engine's compiled entries belong to the compile machinery now.
__getattr__ = moved_names(
    __name__,
    {
        "evaluate_reference": "delaytrack._compile.native_entries:evaluate_reference",
        "evaluate_step": "delaytrack._compile.native_entries:evaluate_step",
        "code_fingerprint": "delaytrack._compile.fingerprint:code_fingerprint",
        "compiled_functions_reached": "delaytrack._compile.fingerprint:compiled_functions_reached",
        "refuse_changed_globals": "delaytrack._compile.guards:refuse_changed_globals",
        "refuse_random_draws": "delaytrack._compile.guards:refuse_random_draws",
    },
)


@dataclass(frozen=True)
class ReducedForm:
    """A plant's reduced form: its velocities fixed by its positions and ``r`` of them.

    A plant whose ``n`` velocities obey ``n - r`` velocity constraints (a wheeled robot that
    rolls without slipping: ``q̇ = S(q) η`` with ``η`` its ``r`` wheel rates) may declare the
    dynamics of ``(q, η)`` alone. The engine's RK4 then integrates these ``n + r`` numbers
    instead of the ``2n`` of ``(q, q̇)`` and sets the state's velocities from
    ``velocity_map`` after each step: the constraints hold to rounding, and each stage evaluates
    the cheaper reduced dynamics. ``η`` must be the last ``r`` entries of ``q̇``
    (``S(q)``'s last ``r`` rows are the identity).

    Parameters
    ----------
    velocity_map : callable
        ``velocity_map(q, eta, params, qdot)``: write every entry of ``q̇ = S(q) η`` (n,).
        The engine passes ``eta`` as the last ``r`` entries of ``qdot`` itself: read ``eta``
        before writing ``qdot`` (``simulate`` checks this at ``x0``).
    dynamics : callable
        ``dynamics(t, q, eta, u, params, eta_dot)``: write ``η̇`` (r,) of the reduced equations
        of motion with the input ``u`` applied.
    size : int
        ``r`` >= 1, the number of independent velocities.
    """

    velocity_map: Callable[..., Any]
    dynamics: Callable[..., Any]
    size: int

    def __post_init__(self) -> None:
        for name in ("velocity_map", "dynamics"):
            value = getattr(self, name)
            if not callable(value):
                raise TypeError(f"{name} must be callable; got {type(value).__name__}")
        size = self.size
        if not is_integer_at_least(size, 1):
            raise ValueError(f"size must be an integer r >= 1; got {size!r}")
        object.__setattr__(self, "size", int(size))

    @property
    def functions(self) -> tuple[Callable[..., Any], Callable[..., Any]]:
        """``(velocity_map, dynamics)``."""
        return self.velocity_map, self.dynamics

    def as_python(self) -> ReducedForm:
        """The same form with its functions run as plain Python."""
        return ReducedForm(
            getattr(self.velocity_map, "py_func", self.velocity_map),
            getattr(self.dynamics, "py_func", self.dynamics),
            self.size,
        )


@known_to_numba
@dataclass(frozen=True)
class Kernel:
    """A component's kernel as the engine calls it.

    Parameters
    ----------
    function : callable
        The kernel, ``@numba.njit``-compiled or plain Python (then the engine runs as Python).
    command_map : callable, optional
        For a nominal model: ``command_map(q, params, tau, command)`` writing the actuator
        ``command`` (m,) that realises the generalised force ``τ`` (n,); by default
        :func:`solve_input_map`, ``Ĝ(q) command = τ``.
    identity_mass : bool
        For a plant whose terms kernel always fills ``M(q) = I`` (integrated as
        ``q̈ = G(q) u - N(q, q̇)`` without a solve).
    sizes : (int, int), optional
        For a plant: its numbers of coordinates ``n`` and inputs ``m``. The engine's loops
        over them are then compiled for these sizes (unrolled), once per size.
    stepper : callable, optional
        For a plant stepped by an integrator of its own (a MuJoCo model):
        ``stepper(t, x, u, dt, params, first)`` advances the state ``x = [q, q̇]`` in place over
        one step of ``dt`` from ``t`` with the input ``u`` held (``first``: the first step of a
        run, where it resets any state of its own). The engine then calls it once per step
        instead of its RK4 on the terms.
    reduced : ReducedForm, optional
        For a plant with a reduced form (:class:`ReducedForm`; ``sizes`` must then be given):
        the engine's RK4 integrates it instead of the terms.
    """

    function: Callable[..., Any]
    command_map: Callable[..., Any] | None = None
    identity_mass: bool = False
    sizes: tuple[int, int] | None = None
    stepper: Callable[..., Any] | None = None
    reduced: ReducedForm | None = None

    def __post_init__(self) -> None:
        for name in ("function", "command_map", "stepper"):
            value = getattr(self, name)
            if not (callable(value) or (name != "function" and value is None)):
                raise TypeError(f"{name} must be callable; got {type(value).__name__}")
        if self.sizes is not None:
            sizes = tuple(self.sizes)
            if len(sizes) != 2 or not all(
                isinstance(size, int | np.integer) and not isinstance(size, bool) and size >= 1
                for size in sizes
            ):
                raise ValueError(f"sizes must be two integers n, m >= 1; got {self.sizes!r}")
            object.__setattr__(self, "sizes", (int(sizes[0]), int(sizes[1])))
        if self.reduced is not None:
            if not isinstance(self.reduced, ReducedForm):
                raise TypeError(f"reduced must be a ReducedForm; got {type(self.reduced).__name__}")
            if self.stepper is not None:
                raise ValueError(
                    "a plant stepped by an integrator of its own (stepper) cannot also have a "
                    "reduced form: the engine would integrate neither"
                )
            if self.sizes is None or not self.reduced.size <= self.sizes[0]:
                raise ValueError(
                    f"a reduced form of r = {self.reduced.size} velocities needs sizes (n, m) "
                    f"with n >= r; got sizes {self.sizes!r}"
                )

    @property
    def roots(self) -> tuple[Callable[..., Any] | None, ...]:
        """The kernel's functions in a fixed order: its function, command map, stepper and its
        reduced form's velocity map and dynamics (None where it has none)."""
        reduced = (None, None) if self.reduced is None else self.reduced.functions
        return (self.function, self.command_map, self.stepper, *reduced)

    @cached_property
    def key(self) -> str:
        """Name of this kernel's numba type, and of the engine compiled for it on disk."""
        parts = [name_with_code(self.function)]
        if self.command_map is not None:
            parts.append(f"command_map={name_with_code(self.command_map)}")
        if self.identity_mass:
            parts.append("identity_mass")
        if self.sizes is not None:
            parts.append("sizes={}x{}".format(*self.sizes))
        if self.stepper is not None:
            parts.append(f"stepper={name_with_code(self.stepper)}")
        if self.reduced is not None:
            parts.append(
                f"reduced={name_with_code(self.reduced.velocity_map)}"
                f"/{name_with_code(self.reduced.dynamics)}/{self.reduced.size}"
            )
        return ",".join(parts)

    @property
    def callable_names(self) -> tuple[str, ...]:
        """``module:name`` of the kernel's functions (:attr:`roots`) that it has (for
        messages)."""
        return tuple(qualified_name(part) for part in self.roots if part is not None)

    @property
    def built_in(self) -> bool:
        """Whether the kernel is one of this package's (its code is covered by the cache folder,
        :mod:`delaytrack._compile.disk_cache`, not by a fingerprint)."""
        return in_package(self.function)

    @property
    def runs_as_python(self) -> bool:
        """Whether the engine's helpers handed this kernel run as plain Python."""
        return not self.compiled

    @property
    def compiled(self) -> bool:
        """Whether the kernel's functions (:attr:`roots`) are numba-compiled."""
        return _all_compiled(*self.roots)

    @classmethod
    def of(
        cls,
        function: Callable[..., Any],
        command_map: Callable[..., Any] | None = None,
        identity_mass: bool = False,
        sizes: tuple[int, int] | None = None,
        stepper: Callable[..., Any] | None = None,
        reduced: ReducedForm | None = None,
    ) -> Kernel:
        """The Kernel of these functions; for compiled ones made once (its key and numba type
        are then computed once, not at every call of a component's ``engine_kernel``). Python
        kernels are made anew, so that a cache never keeps a user's closures alive."""
        reduced_roots = () if reduced is None else reduced.functions
        if _all_compiled(
            function, command_map, stepper, *reduced_roots
        ):  # a hashable key for the cache; the Kernel checks the sizes themselves
            key = None if sizes is None else tuple(sizes)
            return _kernel_of(
                # mypy takes the __hash__ of Kernel's instances for the class's own (a mypy bug)
                cls,  # type: ignore[arg-type]
                function,
                command_map,
                identity_mass,
                key,
                stepper,
                reduced,
            )
        return cls(function, command_map, identity_mass, sizes, stepper, reduced)

    @cached_property
    def numba_type(self) -> KernelType:
        """This kernel's numba type, made once
        (:func:`~delaytrack._compile.kernel_type.numba_type_of`; the user's compiled functions
        keep their own numba options when the engine compiles them)."""
        return numba_type_of(self)

    def __call__(self, *args: Any) -> Any:
        """Run the kernel from Python (compiled if it is)."""
        return self.function(*args)

    def as_python(self) -> Kernel:
        """The same kernel run as plain Python (its ``py_func``; the helpers it calls and the
        command map stay compiled, but those of this package within
        :func:`~delaytrack._compile.jit.as_python`), for the plain-Python engine."""
        return Kernel(
            getattr(self.function, "py_func", self.function),
            self.command_map,
            self.identity_mass,
            self.sizes,
            getattr(self.stepper, "py_func", self.stepper),
            None if self.reduced is None else self.reduced.as_python(),
        )


def _all_compiled(function: object, *extras: object) -> bool:
    """Whether ``function`` and each of ``extras`` that is given are numba-compiled."""
    return is_compiled(function) and all(extra is None or is_compiled(extra) for extra in extras)


@lru_cache(maxsize=4096)
def _kernel_of(
    cls: type,
    function: Any,
    command_map: Any,
    identity_mass: bool,
    sizes: Any,
    stepper: Any,
    reduced: Any,
) -> Kernel:
    return cls(function, command_map, identity_mass, sizes, stepper, reduced)


# ---- the calls ---------------------------------------------------------------------------------

#: numba options of a call compiled as a function of its own and linked into its callers
#: (without ``inline="always"``): the terms of a plant or a nominal model (in the integrator
#: and in the controllers' steps) and a reduced form's velocity map. No fastmath and NumPy's
#: error model, as every kernel of the package; numba's runtime as the caller has it (numba
#: compiles one copy per caller's setting: the integrator's, without the runtime, counts no
#: references). numba compiles an ``inline="always"`` overload's implementation on its own
#: first, then types and lowers it again inside each caller; linked, it is compiled once per
#: argument types and caller's settings (the robot's first simulation compiled in 11.8-12.0 s
#: instead of 13.0-13.4 s), and LLVM inlines it where it pays (the same run times, the same
#: numbers). The reduced dynamics stay inlined: the robot's, linked, were called, not inlined,
#: and its 60 s run took 13.3 ms instead of 11.4-12.0 ms.
_LINKED: _JITOptions = {"fastmath": False, "error_model": "numpy"}  # as KERNEL_OPTIONS


def call_terms(terms, t, q, qdot, params, mass, nonlinear, input_map):
    """Fill ``M, N, G`` of a plant or nominal model with its :class:`Kernel` ``terms``."""
    terms(t, q, qdot, params, mass, nonlinear, input_map)


@overload(call_terms, jit_options=_LINKED)
def _call_terms_compiled(terms, t, q, qdot, params, mass, nonlinear, input_map):
    if isinstance(terms, KernelType):
        function = terms.kernel().function
        arguments = (t, q, qdot, params, mass, nonlinear, input_map)
        refuse_managed_result(function, arguments, "terms", "nothing")

        def impl(terms, t, q, qdot, params, mass, nonlinear, input_map):
            function(t, q, qdot, params, mass, nonlinear, input_map)

        return impl
    return None


def has_identity_mass(terms):
    """Whether the plant :class:`Kernel` ``terms`` always fills ``M(q) = I``."""
    return terms.identity_mass


@overload(has_identity_mass, inline="always")
def _has_identity_mass_compiled(terms):
    if isinstance(terms, KernelType):
        value = terms.kernel().identity_mass

        def impl(terms):
            return value

        return impl
    return None


def has_stepper(terms):
    """Whether the plant :class:`Kernel` ``terms`` is stepped by an integrator of its own."""
    return terms.stepper is not None


@overload(has_stepper, inline="always")
def _has_stepper_compiled(terms):
    if isinstance(terms, KernelType):
        value = terms.kernel().stepper is not None
        return lambda terms: value
    return None


def call_stepper(terms, t, x, u, dt, params, first):
    """Advance ``x`` over one step with the plant's own integrator (:attr:`Kernel.stepper`)."""
    terms.stepper(t, x, u, dt, params, first)


@overload(call_stepper, inline="always")
def _call_stepper_compiled(terms, t, x, u, dt, params, first):
    if isinstance(terms, KernelType):
        stepper = terms.kernel().stepper
        if stepper is None:
            return lambda terms, t, x, u, dt, params, first: None
        refuse_managed_result(stepper, (t, x, u, dt, params, first), "stepper", "nothing")

        def impl(terms, t, x, u, dt, params, first):
            stepper(t, x, u, dt, params, first)

        return impl
    return None


def reduced_size(terms):
    """``r`` of the plant :class:`Kernel` ``terms``'s reduced form (:class:`ReducedForm`), or 0
    when it has none (a constant in compiled code)."""
    return 0 if terms.reduced is None else terms.reduced.size


@overload(reduced_size, inline="always")
def _reduced_size_compiled(terms):
    if isinstance(terms, KernelType):
        reduced = terms.kernel().reduced
        value = 0 if reduced is None else reduced.size
        return lambda terms: value
    return None


def call_velocity_map(terms, q, eta, params, qdot):
    """``q̇ = S(q) η`` of the plant :class:`Kernel` ``terms``'s reduced form."""
    terms.reduced.velocity_map(q, eta, params, qdot)


@overload(call_velocity_map, jit_options=_LINKED)
def _call_velocity_map_compiled(terms, q, eta, params, qdot):
    if isinstance(terms, KernelType):
        reduced = terms.kernel().reduced
        if reduced is None:
            return lambda terms, q, eta, params, qdot: None
        function = reduced.velocity_map
        refuse_managed_result(function, (q, eta, params, qdot), "velocity map", "nothing")

        def impl(terms, q, eta, params, qdot):
            function(q, eta, params, qdot)

        return impl
    return None


def call_reduced_dynamics(terms, t, q, eta, u, params, eta_dot):
    """``η̇`` of the plant :class:`Kernel` ``terms``'s reduced form."""
    terms.reduced.dynamics(t, q, eta, u, params, eta_dot)


@overload(call_reduced_dynamics, inline="always")
def _call_reduced_dynamics_compiled(terms, t, q, eta, u, params, eta_dot):
    if isinstance(terms, KernelType):
        reduced = terms.kernel().reduced
        if reduced is None:
            return lambda terms, t, q, eta, u, params, eta_dot: None
        function = reduced.dynamics
        arguments = (t, q, eta, u, params, eta_dot)
        refuse_managed_result(function, arguments, "reduced dynamics", "nothing")

        def impl(terms, t, q, eta, u, params, eta_dot):
            function(t, q, eta, u, params, eta_dot)

        return impl
    return None


def plant_sizes(terms, q, u):
    """``(n, m)`` of the plant :class:`Kernel` ``terms``: its :attr:`~Kernel.sizes` when it has
    them (compile-time constants in compiled code), else the lengths of ``q`` and ``u``."""
    if terms.sizes is not None:
        return terms.sizes
    return q.shape[0], u.shape[0]


def compiled_sizes(terms_type: Any) -> tuple[int, int] | None:
    """When compiling: the sizes ``(n, m)`` of the plant :class:`Kernel` whose numba type is
    ``terms_type``, or None (not a kernel, or one without sizes)."""
    return terms_type.kernel().sizes if isinstance(terms_type, KernelType) else None


def sizes_on_stack(terms_type: Any, entries: Callable[[int, int], int]) -> tuple[int, int] | None:
    """When compiling: :func:`compiled_sizes`, if known and if ``entries(n, m)`` float64 fit
    on a compiled function's stack (:data:`~delaytrack._compile.stack_arrays.MOST_STACK_ENTRIES`);
    else None (the caller then works in a workspace on the heap)."""
    sizes = compiled_sizes(terms_type)
    return sizes if sizes is not None and entries(*sizes) <= MOST_STACK_ENTRIES else None


@overload(plant_sizes, inline="always")
def _plant_sizes_compiled(terms, q, u):
    if isinstance(terms, KernelType):
        sizes = compiled_sizes(terms)
        if sizes is None:
            return lambda terms, q, u: (q.shape[0], u.shape[0])
        n, m = sizes

        def impl(terms, q, u):
            return n, m

        return impl
    return None


@shared_kernel
def solve_input_map(input_map, tau, command):
    """The default command map: solve ``G(q) command = τ`` (a fully actuated model).

    ``input_map`` is scratch (the model's ``Ĝ`` of this tick): it is factorised in place, so
    that nothing is allocated.
    """
    for i in range(command.shape[0]):
        command[i] = tau[i]
    if not solve_in_place(input_map, command):  # Ĝ need not be symmetric: partial pivoting
        command[:] = math.nan


def call_command_map(model, q, params, input_map, tau, command):
    """Actuator ``command`` that realises the generalised force ``τ`` on the nominal ``model``
    (``input_map``, the model's ``Ĝ(q)``, may be overwritten).

    The model's own command map when its :class:`Kernel` has one (the wheeled robot's
    ``command = S(q)ᵀ τ``, the paper's Section III), else :func:`solve_input_map`.
    """
    if model.command_map is not None:
        model.command_map(q, params, tau, command)
    else:
        solve_input_map(input_map, tau, command)


@overload(call_command_map)
def _call_command_map_compiled(model, q, params, input_map, tau, command):
    if isinstance(model, KernelType):
        command_map = model.kernel().command_map
        if command_map is None:

            def solve(model, q, params, input_map, tau, command):
                solve_input_map(input_map, tau, command)

            return solve
        refuse_managed_result(command_map, (q, params, tau, command), "command map", "nothing")

        def own(model, q, params, input_map, tau, command):
            command_map(q, params, tau, command)

        return own
    return None


def call_step(
    step, t, q, qdot, qd, qd_dot, qd_ddot, T_c, h, params, state, model, model_params, command, work
):
    """Run one controller tick with the controller's :class:`Kernel` ``step`` (in the compiled
    engine, its :class:`~delaytrack._compile.native_call.NativeFunction`); the other arguments
    are those of the step kernel (:mod:`delaytrack.controllers.base`)."""
    step(t, q, qdot, qd, qd_dot, qd_ddot, T_c, h, params, state, model, model_params, command, work)


@overload(call_step, inline="always")
def _call_step_compiled(
    step, t, q, qdot, qd, qd_dot, qd_ddot, T_c, h, params, state, model, mp, u, work
):
    # Inlined, so that the tick calls the step itself (a call level cost about 0.13 µs a tick;
    # numba's inliner does not take *arguments): through its address (in the compiled engine,
    # delaytrack._compile.native_parts) or linked into the caller (evaluate_step).
    if isinstance(step, NativeFunctionType):  # native_parts.controller_step_part: kernels bound

        def native(
            step, t, q, qdot, qd, qd_dot, qd_ddot, T_c, h, params, state, model, mp, u, work
        ):
            arguments = (t, q, qdot, qd, qd_dot, qd_ddot, T_c, h, params, state, mp, u, work)
            call_native(step, arguments)

        return native
    if isinstance(step, KernelType):
        function = step.kernel().function
        arguments = (t, q, qdot, qd, qd_dot, qd_ddot, T_c, h, params, state, model, mp, u, work)
        refuse_managed_result(function, arguments, "controller step", "nothing")

        def impl(step, t, q, qdot, qd, qd_dot, qd_ddot, T_c, h, params, state, model, mp, u, work):
            function(t, q, qdot, qd, qd_dot, qd_ddot, T_c, h, params, state, model, mp, u, work)

        return impl
    return None


def call_reference(reference, t, params, qd, qd_dot, qd_ddot):
    """Evaluate the reference :class:`Kernel` ``reference``: ``q_d, q̇_d, q̈_d`` at ``t``."""
    reference(t, params, qd, qd_dot, qd_ddot)


@overload(call_reference)
def _call_reference_compiled(reference, t, params, qd, qd_dot, qd_ddot):
    if isinstance(reference, NativeFunctionType):  # evaluate_reference, the kernel bound

        def native(reference, t, params, qd, qd_dot, qd_ddot):
            call_native(reference, (t, params, qd, qd_dot, qd_ddot))

        return native
    if isinstance(reference, KernelType):
        function = reference.kernel().function
        arguments = (t, params, qd, qd_dot, qd_ddot)
        refuse_managed_result(function, arguments, "reference", "nothing")

        def impl(reference, t, params, qd, qd_dot, qd_ddot):
            function(t, params, qd, qd_dot, qd_ddot)

        return impl
    return None


def call_delay(delay, t, params):
    """Evaluate the delay-profile :class:`Kernel` ``delay``: ``h(t)`` in seconds."""
    return delay(t, params)


@overload(call_delay, inline="always")
def _call_delay_compiled(delay, t, params):
    if isinstance(delay, KernelType):
        function = delay.kernel().function
        refuse_managed_result(function, (t, params), "delay profile", "a number")

        def impl(delay, t, params):
            return float(function(t, params))

        return impl
    return None
