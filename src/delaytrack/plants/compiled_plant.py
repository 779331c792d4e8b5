"""A user plant at compiled speed: its terms kernel written with ``numba.njit``."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from delaytrack._compile.functions import is_compiled
from delaytrack._compile.guards import refuse_random_draws
from delaytrack._result_columns import trajectory_columns
from delaytrack._validation import (
    as_spd_matrix,
    coordinate_labels,
    finite_array,
    format_values,
)
from delaytrack.components import Kernel, ReducedForm
from delaytrack.kernel_arguments import check_kernel_arguments
from delaytrack.plants.base import ELPlant, check_plant_size

__all__ = ["CompiledPlant"]


@dataclass(frozen=True, eq=False)
class CompiledPlant(ELPlant):
    """``M(q) q̈ + N(q, q̇) = G(q) u`` from a numba-compiled terms kernel.

    Parameters
    ----------
    n, m : int
        Number of coordinates and of inputs.
    kernel : numba-compiled function
        ``kernel(t, q, qdot, params, M, N, G)`` filling ``M`` (n, n), ``N`` (n,) and ``G``
        (n, m) in place (see :mod:`delaytrack.plants.base`), decorated with ``@numba.njit``.
        It is compiled into the simulator's loop, so the plant runs as fast as a built-in one.
    parameters : array_like
        1-D float parameter vector passed to ``kernel`` as ``params`` (may be empty).
    name : str
        Shown in results and reports.
    coordinate_names : sequence of str, optional
        Names of the coordinates in result tables (``ae_<name>``); ``q1 .. qn`` by default.
        Different identifiers whose result columns differ: ``x`` and ``x_d`` are refused (the
        reference of ``x`` and the position of ``x_d`` would share a column), as is ``run``.
    coordinate_units : sequence of str, optional
        Units of the coordinates (``"m"``, ``"rad"``) for figure axes and table columns.
    input_units : sequence of str, optional
        Units of the inputs (``"N"``, ``"N·m"``), one per input, for figure axes and table
        columns.
    reduced : ReducedForm, optional
        For a plant whose velocities obey constraints: its reduced form
        (:class:`~delaytrack.components.ReducedForm`, both functions compiled with
        ``numba.njit``), which the simulator integrates instead of the terms; ``kernel`` still
        gives ``M, N, G`` to the Python methods. ``simulate`` then refuses a start off the
        constraints.
    input_names : sequence of str, optional
        Names of the inputs in figures (``"shoulder"``), one per input; ``u1 .. um`` by
        default.

    Notes
    -----
    The kernel is checked once at ``q = q̇ = 0``, ``t = 0`` (its arguments, finite values, ``M``
    symmetric positive definite, every entry of ``M, N, G`` written, zeros included, and, run
    as Python, no read past the end of ``parameters``: compiled code would read on silently; a
    read only on another branch is not seen), and ``simulate`` checks ``M`` and the reads
    again at the run's ``x0``. A run whose ``M`` stops being positive definite ends with the
    status ``mass matrix not positive definite`` at that time. The
    simulator's loop is compiled for your kernel on the first ``simulate`` call and kept on
    disk, keyed by a hash of the kernel's code (and of the functions and constants it uses):
    later processes load it, and an edit to the kernel compiles it again. Compile the kernel
    with ``numba.njit(error_model="numpy")`` to have a division by zero end only that run (as
    ``diverged``) instead of raising. A plant given as plain Python callables
    (:class:`CallablePlant`) needs no compilation but runs about 100x
    slower.
    """

    n: int
    m: int
    kernel: Callable[..., None]
    parameters: np.ndarray = field(default_factory=lambda: np.zeros(0))
    name: str = "compiled"
    coordinate_names: tuple[str, ...] | None = None
    coordinate_units: tuple[str, ...] | None = None
    input_units: tuple[str, ...] | None = None
    reduced: ReducedForm | None = None
    input_names: tuple[str, ...] | None = None
    type_name: ClassVar[str] = "compiled"

    def __post_init__(self) -> None:
        for label in ("n", "m"):
            check_plant_size(label, getattr(self, label))
        if not is_compiled(self.kernel):
            raise TypeError(
                "kernel must be a numba-compiled function (decorate it with @numba.njit); got "
                f"{type(self.kernel).__name__}. For plain Python functions use CallablePlant."
            )
        check_kernel_arguments("CompiledPlant", "terms", self.kernel)
        if self.reduced is not None:
            self.engine_kernel  # noqa: B018 - the Kernel checks the form: its type, its size
            for label in ("velocity_map", "dynamics"):
                if not is_compiled(getattr(self.reduced, label)):
                    raise TypeError(f"reduced.{label} must be numba-compiled (@numba.njit)")
        for label in ("coordinate_names", "coordinate_units"):
            if getattr(self, label) is not None:
                labels = coordinate_labels(label, getattr(self, label), self.n)
                object.__setattr__(self, label, labels)
        for label in ("input_units", "input_names"):
            if getattr(self, label) is not None:
                labels = coordinate_labels(label, getattr(self, label), self.m)
                object.__setattr__(self, label, labels)
        trajectory_columns(
            self.coordinate_names, self.coordinate_units, self.n, self.input_units, self.m
        )
        parameters = finite_array("parameters", self.parameters, ndim=1)
        object.__setattr__(self, "parameters", np.ascontiguousarray(parameters))
        self._check_reads()
        # before the entries' check: a kernel that draws random numbers writes other entries
        # at each call, which that check would report as entries it does not write
        refuse_random_draws(self.engine_kernel)
        self._check_every_entry_written()
        mass, nonlinear, input_map = self.terms(np.zeros(self.n), np.zeros(self.n))
        for label, value in (("M", mass), ("N", nonlinear), ("G", input_map)):
            if not np.all(np.isfinite(value)):
                raise ValueError(
                    f"kernel gave a non-finite {label} at q = qdot = 0: {format_values(value)}"
                )
        as_spd_matrix("the kernel's M(0)", mass[0], self.n)

    def _check_every_entry_written(self) -> None:
        """Call the kernel at ``q = q̇ = 0``, ``t = 0`` on ``M, N, G`` filled with NaN, then with
        zeros, and refuse it, naming the entries, when they differ: an entry the kernel leaves
        unwritten (or reads before writing it) would hold whatever the array held, which in the
        simulator is the solve's factors of an earlier stage (the solve for ``q̈`` works in
        ``M``), so results would depend on what ran before. Zeros are not assumed."""
        n, m = self.n, self.m
        zero = np.zeros(n)
        outputs = []
        for fill in (np.nan, 0.0):
            arrays = (np.full((n, n), fill), np.full(n, fill), np.full((n, m), fill))
            self.kernel(0.0, zero, zero.copy(), self.parameters.copy(), *arrays)
            outputs.append(arrays)
        unwritten = []
        for label, with_nan, with_zeros in zip("MNG", *outputs, strict=True):
            same = (with_nan == with_zeros) | (np.isnan(with_nan) & np.isnan(with_zeros))
            unwritten += [f"{label}[{', '.join(map(str, index))}]" for index in np.argwhere(~same)]
        if unwritten:
            shown = ", ".join(unwritten[:6])
            if len(unwritten) > 6:
                shown += f" and {len(unwritten) - 6} more entries"
            raise ValueError(
                f"kernel {Kernel.of(self.kernel).callable_names[0]} does not write {shown} at "
                "q = qdot = 0 (or reads them before writing them): write every entry of M, N "
                "and G, zeros included (the simulator reuses these arrays from step to step)"
            )

    def _check_reads(self) -> None:
        """Run the kernel's Python version once at ``q = q̇ = 0``, ``t = 0``: compiled code reads
        past the end of ``params`` (or of another array) without a word and runs on with
        whatever lies there; Python raises IndexError. Other errors are left to the compiled
        kernel, which is what runs (Python may lack what numba provides)."""
        n, m = self.n, self.m
        zero = np.zeros(n)
        try:
            self.kernel.py_func(  # type: ignore[attr-defined]  # a numba dispatcher's attribute
                0.0,
                zero,
                zero.copy(),
                self.parameters.copy(),
                np.zeros((n, n)),
                np.zeros(n),
                np.zeros((n, m)),
            )
        except IndexError as error:
            raise ValueError(
                f"kernel reads beyond an array at q = qdot = 0 ({error}); parameters has "
                f"{self.parameters.size} entries and n = {n}, m = {m}: give the parameters "
                "the kernel reads, and M (n, n), N (n,), G (n, m) as it fills them"
            ) from None
        except Exception:  # noqa: BLE001 - only reads past an array's end are checked here
            return

    @property
    def params(self) -> np.ndarray:
        return self.parameters

    @property
    def terms_kernel(self) -> Callable[..., None]:
        return self.kernel

    @property
    def reduced_form(self) -> ReducedForm | None:
        return self.reduced

    def to_spec(self) -> dict[str, Any]:
        return {"type": self.type_name, "name": self.name, "n": int(self.n), "m": int(self.m)}
