"""A two-link planar direct-drive arm with viscous friction (horizontal plane, no gravity).

Model (Dixon et al., *Nonlinear Control of Engineering Systems*, 2003; the same arm is the
simulation example of Sharma, Bhasin, Wang & Dixon, "Predictor-based control for an uncertain
Euler–Lagrange system with input delay", Automatica 47(11), 2011, the paper's PCONf reference):

    M(q) = [[p1 + 2 p3 cos q2,  p2 + p3 cos q2],
            [p2 + p3 cos q2,    p2           ]]
    V(q, q̇) q̇ = [-p3 sin q2 (2 q̇1 q̇2 + q̇2²),  p3 sin q2 q̇1²]
    N(q, q̇) = V(q, q̇) q̇ + F_d q̇,   F_d = diag(fd1, fd2),   G = I

with p1 = 3.473 kg·m², p2 = 0.196 kg·m², p3 = 0.242 kg·m², fd1 = 5.3 N·m·s, fd2 = 1.1 N·m·s.
M(q) is positive definite for all q when p1 p2 - p2² > p3² (true for these values).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from delaytrack._compile.jit import kernel
from delaytrack._validation import positive_scalar
from delaytrack.plants.base import ELPlant

__all__ = ["TwoLinkArm", "two_link_terms"]


@kernel
def two_link_terms(t, q, qdot, params, mass, nonlinear, input_map):
    """Fill ``M``, ``N`` and ``G = I`` of the two-link arm; ``params = [p1, p2, p3, fd1, fd2]``."""
    p1, p2, p3, fd1, fd2 = params[0], params[1], params[2], params[3], params[4]
    c2 = math.cos(q[1])
    s2 = math.sin(q[1])
    mass[0, 0] = p1 + 2.0 * p3 * c2
    mass[0, 1] = p2 + p3 * c2
    mass[1, 0] = p2 + p3 * c2
    mass[1, 1] = p2
    nonlinear[0] = -p3 * s2 * (2.0 * qdot[0] * qdot[1] + qdot[1] * qdot[1]) + fd1 * qdot[0]
    nonlinear[1] = p3 * s2 * qdot[0] * qdot[0] + fd2 * qdot[1]
    input_map[0, 0] = 1.0  # written entry by entry: a slice assignment is a memset call
    input_map[0, 1] = 0.0
    input_map[1, 0] = 0.0
    input_map[1, 1] = 1.0


@dataclass(frozen=True)
class TwoLinkArm(ELPlant):
    """Two-link planar arm; the defaults are the direct-drive arm that
    :mod:`delaytrack.plants.two_link_arm` describes.

    Parameters
    ----------
    p1, p2, p3 : float
        Inertia parameters in kg·m²; ``p1 p2 - p2² > p3²`` keeps ``M(q)`` positive definite.
    fd1, fd2 : float
        Viscous friction at the joints in N·m·s, ``>= 0``.
    """

    p1: float = 3.473
    p2: float = 0.196
    p3: float = 0.242
    fd1: float = 5.3
    fd2: float = 1.1
    n = 2
    m = 2
    type_name: ClassVar[str] = "two-link-arm"
    coordinate_units = ("rad", "rad")
    input_units = ("N·m", "N·m")
    input_names = ("tau1", "tau2")

    def __post_init__(self) -> None:
        for name in ("p1", "p2", "p3"):
            object.__setattr__(self, name, positive_scalar(name, getattr(self, name)))
        for name in ("fd1", "fd2"):
            object.__setattr__(
                self, name, positive_scalar(name, getattr(self, name), strictly=False)
            )
        # Products, not powers: a float's ** raises OverflowError where * gives inf.
        margin = self.p1 * self.p2 - self.p2 * self.p2 - self.p3 * self.p3
        if not (math.isfinite(margin) and margin > 0.0):
            raise ValueError(
                "two-link arm parameters must satisfy p1*p2 - p2**2 > p3**2, a finite margin, "
                "for a positive definite "
                f"mass matrix; got p1={self.p1:g}, p2={self.p2:g}, p3={self.p3:g}"
            )

    @property
    def params(self) -> np.ndarray:
        return np.array([self.p1, self.p2, self.p3, self.fd1, self.fd2])

    @property
    def terms_kernel(self):
        return two_link_terms

    def to_spec(self) -> dict[str, Any]:
        return {
            "type": self.type_name,
            "p1": self.p1,
            "p2": self.p2,
            "p3": self.p3,
            "fd1": self.fd1,
            "fd2": self.fd2,
        }
