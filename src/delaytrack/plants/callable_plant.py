"""An Euler–Lagrange plant from user functions ``M(q)`` and ``N(q, q̇)``."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from delaytrack._result_columns import trajectory_columns
from delaytrack._user_calls import UserFunctionError, raised_by
from delaytrack._validation import as_spd_matrix, coordinate_labels, format_values
from delaytrack.plants.base import ELPlant, check_plant_size

__all__ = ["CallablePlant"]


@dataclass(frozen=True, eq=False)
class CallablePlant(ELPlant):
    """``M(q) q̈ + N(q, q̇) = G(q) u`` from Python callables.

    Parameters
    ----------
    n : int
        Number of coordinates.
    mass_matrix_fn : callable
        ``mass_matrix_fn(q) -> (n, n)`` symmetric positive definite ``M(q)``.
    nonlinear_terms_fn : callable
        ``nonlinear_terms_fn(q, qdot) -> (n,)``: ``N(q, q̇)``, Coriolis, gravity, friction,
        disturbances.
    input_map_fn : callable or array_like, optional
        ``input_map_fn(q) -> (n, m)`` or a constant (n, m) matrix ``G``; the identity by default.
    name : str
        Shown in results and reports.
    coordinate_names : sequence of str, optional
        Names of the coordinates in result tables and figures; ``q1 .. qn`` by default.
        Different identifiers whose result columns differ: ``x`` and ``x_d`` are refused (the
        reference of ``x`` and the position of ``x_d`` would share a column), as is ``run``.
    coordinate_units : sequence of str, optional
        Units of the coordinates (``"m"``, ``"rad"``) for figure axes and table columns.
    input_units : sequence of str, optional
        Units of the inputs (``"N"``, ``"N·m"``), one per input, for figure axes and table
        columns.
    input_names : sequence of str, optional
        Names of the inputs in figures (``"shoulder"``), one per input; ``u1 .. um`` by
        default.

    Notes
    -----
    The functions are checked once at ``q = q̇ = 0`` (shapes, finiteness, symmetry and positive
    definiteness of ``M``), and what they return at every call of a run is checked as there
    (real numbers of the shape given at construction; non-finite values end the run with the
    status ``diverged``): anything else, or anything they raise (a ``SystemExit`` included; a
    ``KeyboardInterrupt`` stays an interruption), ends the run with one line that names the
    function and the time. They run as Python inside the simulator, which is much slower than
    the compiled built-in plants.
    """

    n: int
    mass_matrix_fn: Callable[[np.ndarray], np.ndarray]
    nonlinear_terms_fn: Callable[[np.ndarray, np.ndarray], np.ndarray]
    input_map_fn: Callable[[np.ndarray], np.ndarray] | np.ndarray | None = None
    name: str = "callable"
    coordinate_names: tuple[str, ...] | None = None
    coordinate_units: tuple[str, ...] | None = None
    input_units: tuple[str, ...] | None = None
    input_names: tuple[str, ...] | None = None
    m: int = field(init=False)
    type_name: ClassVar[str] = "callable"

    def __post_init__(self) -> None:
        check_plant_size("n", self.n)
        for label, fn in (
            ("mass_matrix", self.mass_matrix_fn),
            ("nonlinear_terms", self.nonlinear_terms_fn),
        ):
            if not callable(fn):
                raise TypeError(f"{label} must be callable; got {type(fn).__name__}")
        for label in ("coordinate_names", "coordinate_units"):
            if getattr(self, label) is not None:
                labels = coordinate_labels(label, getattr(self, label), self.n)
                object.__setattr__(self, label, labels)
        if self.input_map_fn is not None and not callable(self.input_map_fn):
            constant = np.array(self.input_map_fn, dtype=float)
            if constant.ndim != 2 or constant.shape[0] != self.n:
                raise ValueError(f"input_map must have shape ({self.n}, m); got {constant.shape}")
            object.__setattr__(self, "input_map_fn", constant)
        zero = np.zeros(self.n)
        mass = self._evaluate("mass_matrix", self.mass_matrix_fn, (zero,), (self.n, self.n))
        as_spd_matrix("mass_matrix(0)", mass, self.n)
        self._evaluate("nonlinear_terms", self.nonlinear_terms_fn, (zero, zero), (self.n,))
        object.__setattr__(self, "m", check_plant_size("m", self._input_map(zero).shape[1]))
        for label in ("input_units", "input_names"):
            if getattr(self, label) is not None:
                labels = coordinate_labels(label, getattr(self, label), self.m)
                object.__setattr__(self, label, labels)
        trajectory_columns(
            self.coordinate_names, self.coordinate_units, self.n, self.input_units, self.m
        )

    def _evaluate(
        self, label: str, fn: Callable[..., Any], args: tuple, shape: tuple[int, ...]
    ) -> np.ndarray:
        value = _returned(label, fn(*args), shape, "")
        if not np.all(np.isfinite(value)):
            raise ValueError(
                f"{label} returned non-finite values at q = qdot = 0: {format_values(value)}"
            )
        return value

    def _input_map(self, q: np.ndarray) -> np.ndarray:
        """``G(q)``: the constant, or the function's value checked for its rows (the run checks
        it as :meth:`_called` does, against the ``m`` learnt here at construction)."""
        if self.input_map_fn is None:
            return np.eye(self.n)
        if callable(self.input_map_fn):
            value = np.asarray(self.input_map_fn(q), dtype=float)
            if value.ndim != 2 or value.shape[0] != self.n:
                raise ValueError(f"input_map must return shape ({self.n}, m); got {value.shape}")
            return value
        return self.input_map_fn

    def _called(
        self, label: str, fn: Callable[..., Any], args: tuple, shape: tuple[int, ...], t: float
    ) -> np.ndarray:
        """What ``fn`` (the user's ``label``) returns at time ``t`` of a run, checked as at
        construction; what it raises (a ``KeyboardInterrupt`` aside) named, in one line."""
        try:
            value = fn(*args)
        except KeyboardInterrupt:
            raise
        except BaseException as error:
            raise raised_by(self._described(label, fn), error, t) from error
        if type(value) is np.ndarray and value.shape == shape and value.dtype.kind == "f":
            return value  # what a correct function returns, at the cost of three comparisons
        where = f" at t = {t:.6g} s"
        return _returned(self._described(label, fn), value, shape, where, UserFunctionError)

    def _described(self, label: str, fn: Callable[..., Any]) -> str:
        name = getattr(fn, "__qualname__", type(fn).__name__)
        module = getattr(fn, "__module__", None) or "?"
        return f"your {label}_fn {module}:{name} (CallablePlant {self.name!r})"

    @property
    def params(self) -> np.ndarray:
        return np.zeros(0)

    @property
    def terms_kernel(self):
        def terms(t, q, qdot, params, mass, nonlinear, input_map):
            mass[:, :] = self._called("mass_matrix", self.mass_matrix_fn, (q,), mass.shape, t)
            nonlinear[:] = self._called(
                "nonlinear_terms", self.nonlinear_terms_fn, (q, qdot), nonlinear.shape, t
            )
            if callable(self.input_map_fn):
                input_map[:, :] = self._called(
                    "input_map", self.input_map_fn, (q,), input_map.shape, t
                )
            else:
                input_map[:, :] = self._input_map(q)

        return terms

    def to_spec(self) -> dict[str, Any]:
        return {"type": self.type_name, "name": self.name, "n": int(self.n), "m": int(self.m)}


def _returned(
    label: str,
    value: object,
    shape: tuple[int, ...],
    where: str,
    refusal: type[ValueError] = ValueError,
) -> np.ndarray:
    """``value``, what the user's function ``label`` returned (``where``: at construction, or
    at a time of the run), as real numbers of ``shape``; anything else is refused in one line,
    a ``refusal``."""
    not_numbers = f"{label} must return real numbers of shape {shape}; got {_shown(value)}{where}"
    try:
        array = np.asarray(value)
    except ValueError:  # nested sequences of different lengths
        raise refusal(not_numbers) from None
    if array.dtype.kind == "O" and value is not None:  # Python numbers of several kinds
        try:
            array = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            pass
    if array.dtype.kind not in "iuf":
        raise refusal(not_numbers)
    if array.shape != shape:
        raise refusal(f"{label} must return shape {shape}; got {array.shape}{where}")
    return array.astype(float, copy=False)


def _shown(value: object) -> str:
    """``value`` in a message: None, a short text, or its type."""
    if value is None or (isinstance(value, str | bytes | complex) and len(repr(value)) <= 40):
        return repr(value)
    if isinstance(value, np.ndarray):
        return f"an array of {value.dtype}, shape {value.shape}"
    return f"a {type(value).__name__}"
