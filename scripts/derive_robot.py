"""Symbolic derivation of the wheeled robot's dynamics, checked against the kernels.

Run from the repository root (needs sympy, in the ``test`` extra)::

    .venv/bin/python scripts/derive_robot.py            # rewrite tests/data/robot_derivation.json
    .venv/bin/python scripts/derive_robot.py --check    # exit 1 if the checked-in file differs

What it derives, from positions alone (no hand-written velocity or energy formula):

* Bodies: the platform (mass ``m_c``, yaw inertia ``I_c`` about its centre of mass at body-frame
  ``(c_x, c_y)`` from the axle midpoint A), two wheels (mass ``m_w`` at ``A ∓ L n``, spin inertia
  ``I_w``, yaw inertia ``I_m`` about a diameter) and a point payload ``m_p`` at ``(p_x, p_y)``.
  ``e = (cos φ, sin φ)`` is the heading, ``n = (-sin φ, cos φ)`` points to the robot's left, and the
  coordinates are ``q = (x_c, y_c, φ, θ_r, θ_l)`` with ``(x_c, y_c) = A + d e``.
* ``T`` = sum of ½ m |ṙ|² of every mass (velocities by differentiating positions) plus the
  rotational terms ½ I_c φ̇², ½ I_w θ̇², ½ I_m φ̇²; the unconstrained ``M(q) = ∂²T/∂q̇²`` and
  Coriolis/centrifugal ``c(q, q̇)`` by Christoffel symbols.
* Constraints (velocities of material points): A has no velocity along ``n``; each wheel's contact
  point has no velocity along ``e``: ``ṙ_wheel · e - R θ̇ = 0``. ``Λ(q)`` is their Jacobian in q̇;
  ``S(q)`` solves ``Λ S = 0`` with rows 4–5 the identity (``q̇ = S η``, ``η = (θ̇_r, θ̇_l)``).
* Reduced wheel-space dynamics (d'Alembert: ``Sᵀ Λᵀ = 0`` removes the multipliers)::

      M_r η̇ + n_r = τ - f,   M_r = Sᵀ M S,   n_r = Sᵀ (M Ṡ η + c(q, S η)),
      f_i = b_v θ̇_i + f_c tanh(θ̇_i / v_s)         (wheel friction, truth plant only)

  and the coordinate accelerations on the constraint manifold ``q̈ = S η̇ + Ṡ η``.

The JSON output holds each expression as a sympy string (``sympy.sympify`` reads it back);
``tests/test_robot_derivation.py`` evaluates them at random states and compares with the numba
kernels of :mod:`delaytrack.plants.robot`.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import sympy as sp

OUTPUT = Path(__file__).resolve().parent.parent / "tests" / "data" / "robot_derivation.json"

#: Parameter symbols, in the order the JSON lists them.
PARAMETERS = ("R L d m_c I_c c_x c_y m_w I_w I_m m_p p_x p_y b_v f_c v_s").split()


def _tidy(expression: sp.Expr, phi: sp.Symbol) -> sp.Expr:
    """A fast normal form: expand, reduce powers of sin φ with sin² φ + cos² φ = 1, cancel."""
    if isinstance(expression, sp.MatrixBase):
        return expression.applyfunc(lambda entry: _tidy(entry, phi))
    s, c = sp.symbols("s_ c_")

    def reduce(part: sp.Expr) -> sp.Expr:
        polynomial = sp.expand(part).subs({sp.sin(phi): s, sp.cos(phi): c})
        remainder = sp.rem(polynomial, s**2 + c**2 - 1, s)
        return sp.expand(remainder).subs({s: sp.sin(phi), c: sp.cos(phi)})

    numerator, denominator = sp.fraction(sp.together(sp.expand(expression)))
    return sp.factor_terms(sp.cancel(reduce(numerator) / reduce(denominator)))


def derive() -> dict[str, object]:
    """Return every derived expression as strings (see the module docstring)."""
    t = sp.Symbol("t")
    p = {name: sp.Symbol(name, real=True) for name in PARAMETERS}
    R, L, d = p["R"], p["L"], p["d"]
    coordinates = [sp.Function(name)(t) for name in ("x", "y", "phi", "theta_r", "theta_l")]
    x, y, phi, theta_r, theta_l = coordinates
    q = sp.Matrix(coordinates)
    qdot = q.diff(t)
    # Plain symbols for q and q̇ in the results.
    q_s = sp.symbols("x y phi theta_r theta_l", real=True)
    qd_s = sp.symbols("xdot ydot phidot omega_r omega_l", real=True)
    to_plain = {**dict(zip(qdot, qd_s, strict=True)), **dict(zip(q, q_s, strict=True))}

    e = sp.Matrix([sp.cos(phi), sp.sin(phi)])
    n = sp.Matrix([-sp.sin(phi), sp.cos(phi)])
    point = sp.Matrix([x, y])
    axle = point - d * e
    platform = axle + p["c_x"] * e + p["c_y"] * n
    right = axle - L * n
    left = axle + L * n
    payload = axle + p["p_x"] * e + p["p_y"] * n

    def speed2(position: sp.Matrix) -> sp.Expr:
        velocity = position.diff(t)
        return (velocity.T * velocity)[0, 0]

    phidot = phi.diff(t)
    kinetic = (
        p["m_c"] * speed2(platform) / 2
        + p["I_c"] * phidot**2 / 2
        + p["m_w"] * (speed2(right) + speed2(left)) / 2
        + p["I_w"] * (theta_r.diff(t) ** 2 + theta_l.diff(t) ** 2) / 2
        + p["I_m"] * phidot**2
        + p["m_p"] * speed2(payload) / 2
    )
    kinetic = sp.expand(kinetic.subs(to_plain))
    mass = _tidy(sp.hessian(kinetic, qd_s), q_s[2])
    # c_i = Σ_jk (∂M_ij/∂q_k - ½ ∂M_jk/∂q_i) q̇_j q̇_k
    coriolis = sp.zeros(5, 1)
    for i in range(5):
        term = 0
        for j in range(5):
            for k in range(5):
                term += (
                    (sp.diff(mass[i, j], q_s[k]) - sp.diff(mass[j, k], q_s[i]) / 2)
                    * qd_s[j]
                    * qd_s[k]
                )
        coriolis[i] = _tidy(term, q_s[2])

    # Constraints from material-point velocities.
    constraints = [
        (axle.diff(t).T * n)[0, 0],
        (right.diff(t).T * e)[0, 0] - R * theta_r.diff(t),
        (left.diff(t).T * e)[0, 0] - R * theta_l.diff(t),
    ]
    constraints = [sp.expand(sp.simplify(c.subs(to_plain))) for c in constraints]
    lam = sp.Matrix([[sp.diff(c, v) for v in qd_s] for c in constraints])
    lam = sp.simplify(lam)
    S_top = sp.simplify(-lam[:, :3].inv() * lam[:, 3:])
    S = S_top.col_join(sp.eye(2))
    if sp.simplify(lam * S) != sp.zeros(3, 2):
        raise RuntimeError("the kinematic map does not annihilate the constraints")

    eta = sp.Matrix(qd_s[3:])
    on_manifold = dict(zip(qd_s[:3], list(S_top * eta), strict=True))
    # Ṡ η: S depends on φ only, and φ̇ = (S η)_φ on the manifold.
    S_dot = S.diff(q_s[2]) * (S[2, :] * eta)[0, 0]
    reduced_mass = _tidy(S.T * mass * S, q_s[2])
    reduced_bias = _tidy(S.T * (mass * S_dot * eta + coriolis.subs(on_manifold)), q_s[2])
    if q_s[2] in (reduced_mass.free_symbols | reduced_bias.free_symbols):
        raise RuntimeError("the reduced dynamics should not depend on the heading φ")

    friction = sp.Matrix([p["b_v"] * w + p["f_c"] * sp.tanh(w / p["v_s"]) for w in qd_s[3:]])
    tau = sp.Matrix(sp.symbols("tau_r tau_l", real=True))
    eta_dot = sp.Matrix(sp.symbols("alpha_r alpha_l", real=True))
    qddot = S * eta_dot + S_dot * eta

    def strings(matrix: sp.Matrix) -> list:
        return [[str(matrix[i, j]) for j in range(matrix.shape[1])] for i in range(matrix.shape[0])]

    return {
        "about": (
            "Generated by scripts/derive_robot.py; do not edit. Expressions are sympy strings "
            "in the symbols listed; eta_dot = reduced_mass^-1 (tau - friction - reduced_bias), "
            "qddot = S eta_dot + S_dot_eta (alpha_r, alpha_l stand for eta_dot)."
        ),
        "parameters": list(PARAMETERS),
        "coordinates": [str(s) for s in q_s],
        "velocities": [str(s) for s in qd_s],
        "inputs": [str(s) for s in tau],
        "accelerations": [str(s) for s in eta_dot],
        "kinetic_energy": str(kinetic),
        "mass_matrix": strings(mass),
        "coriolis": strings(coriolis),
        "constraint_matrix": strings(lam),
        "kinematic_map": strings(S),
        "reduced_mass": strings(reduced_mass),
        "reduced_bias": strings(reduced_bias),
        "friction": strings(friction),
        "qddot_on_manifold": strings(_tidy(qddot, q_s[2])),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUTPUT, help="JSON file to write")
    parser.add_argument(
        "--check", action="store_true", help="compare with the file instead of writing it"
    )
    args = parser.parse_args(argv)
    text = json.dumps(derive(), indent=1, ensure_ascii=False) + "\n"
    if args.check:
        current = args.out.read_text() if args.out.exists() else ""
        if current != text:
            print(f"{args.out} is out of date; rerun scripts/derive_robot.py", file=sys.stderr)
            return 1
        print(f"{args.out} is up to date")
        return 0
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
