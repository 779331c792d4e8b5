"""Sinusoidal references: set-points, ramps and the paper's circle.

:class:`SinusoidalReference` is

    q_d,i(t) = offset_i + slope_i t + Σ_k amplitude_ik sin(frequency_ik t + phase_ik)
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from delaytrack._compile.functions import at_few_points
from delaytrack._compile.jit import kernel, tick_kernel
from delaytrack._validation import ArgumentError, check_phase, finite_array
from delaytrack.references.base import Reference, by_time

__all__ = [
    "SinusoidalReference",
    "sinusoidal_reference",
    "sinusoidal_reference_values",
]


@tick_kernel
def sinusoidal_reference(t, params, qd, qd_dot, qd_ddot):
    """Fill ``q_d(t)``, ``q̇_d(t)``, ``q̈_d(t)``; ``params = [n, K, offset, slope, A, ω, φ]``."""
    n = int(params[0])
    harmonics = int(params[1])
    base = 2 + 2 * n
    size = n * harmonics
    for i in range(n):
        qd[i] = params[2 + i] + params[2 + n + i] * t
        qd_dot[i] = params[2 + n + i]
        qd_ddot[i] = 0.0
        for k in range(harmonics):
            j = i * harmonics + k
            amplitude = params[base + j]
            omega = params[base + size + j]
            angle = omega * t + params[base + 2 * size + j]
            qd[i] += amplitude * math.sin(angle)
            qd_dot[i] += amplitude * omega * math.cos(angle)
            qd_ddot[i] -= amplitude * omega * omega * math.sin(angle)


@kernel
def sinusoidal_reference_values(times, params, out):
    """:func:`sinusoidal_reference` at each of ``times`` (1-D) into ``out (3, times.size, n)``."""
    for i in range(times.shape[0]):
        sinusoidal_reference(times[i], params, out[0, i], out[1, i], out[2, i])


@dataclass(frozen=True, eq=False)
class SinusoidalReference(Reference):
    """``q_d(t) = offset + slope t + Σ_k amplitude[:, k] sin(frequency[:, k] t + phase[:, k])``.

    Parameters
    ----------
    offset : array_like, shape (n,)
    slope : array_like, shape (n,), optional
    amplitude, frequency, phase : array_like, shape (n,) or (n, K), optional
        One column per harmonic; frequencies in rad/s.
    """

    offset: np.ndarray
    slope: np.ndarray | None = None
    amplitude: np.ndarray | None = None
    frequency: np.ndarray | None = None
    phase: np.ndarray | None = None
    _params: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        offset = finite_array("offset", self.offset, ndim=1)
        n = offset.size
        if n == 0:
            raise ArgumentError("offset", "must have one value per coordinate; got an empty list")
        slope = np.zeros(n) if self.slope is None else finite_array("slope", self.slope, ndim=1)
        if slope.size != n:
            raise ArgumentError("slope", f"must have length n = {n}; got {slope.size}")
        given = [
            name for name in ("amplitude", "frequency", "phase") if getattr(self, name) is not None
        ]
        if given and not {"amplitude", "frequency"} <= set(given):
            raise ValueError(
                f"a harmonic needs both amplitude and frequency; got only {' and '.join(given)} "
                "(the other would default to zeros: an amplitude at frequency 0 is a constant "
                "amplitude sin(phase), a frequency or phase without amplitude draws nothing)"
            )
        harmonic = {}
        for name in ("amplitude", "frequency", "phase"):
            value = getattr(self, name)
            array = np.zeros((n, 0)) if value is None else finite_array(name, value)
            array = array.reshape(n, -1) if array.ndim == 1 and array.size == n else array
            if array.ndim != 2 or array.shape[0] != n:
                raise ArgumentError(
                    name, f"must have shape (n,) or (n, K) with n = {n}; got {array.shape}"
                )
            harmonic[name] = array
        widths = {
            name: array.shape[1]
            for name, array in harmonic.items()
            if getattr(self, name) is not None
        }
        count = max(widths.values(), default=0)
        for name in harmonic:
            if getattr(self, name) is None:
                harmonic[name] = np.zeros((n, count))
            elif harmonic[name].shape[1] != count:
                raise ValueError(
                    f"amplitude, frequency and phase must have the same shape; got {widths}"
                )
        _check_derivatives_finite(harmonic["amplitude"], harmonic["frequency"])
        check_phase("phase", harmonic["phase"])
        object.__setattr__(self, "offset", offset)
        object.__setattr__(self, "slope", slope)
        for name, array in harmonic.items():
            object.__setattr__(self, name, array)
        packed = [np.array([float(n), float(count)]), offset, slope]
        packed += [harmonic[name].ravel() for name in ("amplitude", "frequency", "phase")]
        object.__setattr__(self, "_params", np.concatenate(packed))

    @classmethod
    def from_spec(cls, spec: dict[str, Any]) -> SinusoidalReference:
        """Build from ``{"offset": [...], "slope": [...], "amplitude": ..., ...}``."""
        accepted = {"offset", "slope", "amplitude", "frequency", "phase"}
        unknown = sorted(set(spec) - accepted)
        if unknown:
            raise ValueError(
                f"unknown key(s) {unknown} in reference; valid keys are {sorted(accepted)}"
            )
        if "offset" not in spec:
            raise ValueError("reference needs 'offset' (one value per coordinate)")
        return cls(**spec)

    @property
    def n(self) -> int:
        return self.offset.size

    @property
    def params(self) -> np.ndarray:
        return self._params

    @property
    def reference_kernel(self):
        return sinusoidal_reference

    def evaluate(self, t: float | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``q_d, q̇_d, q̈_d`` at times ``t``, each of shape ``(*t.shape, n)``."""
        times = np.asarray(t, dtype=float)
        # contiguous and writable, as compile_ahead compiles it
        flat = np.require(times.ravel(), requirements=("C", "W"))
        function, arguments = self.compiled_values(flat)

        def values(kernel: Callable[..., None]) -> np.ndarray:
            kernel(*arguments)
            return arguments[2]

        # a few times as Python while the kernel is not compiled (Reference.evaluate)
        return by_time(at_few_points(function, times.size, values), times.shape)

    def compiled_values(self, times: np.ndarray) -> tuple[Any, tuple]:
        """:func:`sinusoidal_reference_values` and its arguments for ``times`` (1-D,
        contiguous), its output array among them (:meth:`Reference.compiled_values`)."""
        return sinusoidal_reference_values, (times, self._params, np.empty((3, times.size, self.n)))

    def to_spec(self) -> dict[str, Any]:
        """The parameters (the table of the default reference type, ``"sinusoidal"``)."""
        # Construction replaces a None parameter by its default.
        assert self.slope is not None and self.amplitude is not None
        assert self.frequency is not None and self.phase is not None
        return {
            "offset": self.offset.tolist(),
            "slope": self.slope.tolist(),
            "amplitude": self.amplitude.tolist(),
            "frequency": self.frequency.tolist(),
            "phase": self.phase.tolist(),
        }


def _check_derivatives_finite(amplitude: np.ndarray, frequency: np.ndarray) -> None:
    """Refuse harmonics whose bound on ``q_d``, ``q̇_d`` or ``q̈_d`` (``Σ |A|``, ``Σ |A ω|``,
    ``Σ |A| ω²`` over a coordinate's harmonics) is beyond the largest double: the reference
    would be infinite or NaN at some time, and every run on it diverged without saying why."""
    size, rate = np.abs(amplitude), np.abs(frequency)
    with np.errstate(over="ignore", invalid="ignore"):
        # In the kernel's order, (A ω) ω: a harmonic of zero amplitude stays zero.
        bounds = {
            "position (Σ |A|)": np.sum(size, axis=1),
            "velocity (Σ |A ω|)": np.sum(size * rate, axis=1),
            "acceleration (Σ |A| ω²)": np.sum(size * rate * rate, axis=1),
        }
    for what, bound in bounds.items():
        if not np.all(np.isfinite(bound)):
            worst = int(np.flatnonzero(~np.isfinite(bound))[0])
            raise ArgumentError(
                "amplitude" if what.startswith("position") else "frequency",
                f"gives coordinate {worst + 1} a bound on its {what} beyond the largest double: "
                f"amplitude {amplitude[worst].tolist()}, frequency {frequency[worst].tolist()} "
                "(rad/s)",
            )
