"""Golden runs: a short closed loop of each controller on the PIONEER-3 robot, for regression.

Regenerate (from the repository root) — only after reviewing why the numbers changed::

    .venv/bin/python scripts/make_golden.py

It writes ``tests/data/golden_<controller>.npz`` for ``arolc``, ``outer_loop``, ``pcon`` and
``pconf``; ``tests/test_golden.py`` reruns each case through :func:`run_case` (imported from this
file) and compares. Each file holds ``t``, ``x``, ``commands``, ``applied``,
``controller_state``, ``status`` and ``settings`` (a JSON string: the simulator's settings record,
which names plant, payload, controller, model, delay and reference, plus the case's description).

The cases (all on the compiled engine):

* truth: :class:`~delaytrack.plants.robot.PayloadRobot` with random placements from seed 7 on a
  fast schedule (on at 0.5 s for 1 s, off 0.5 s, on again at 2 s), so a 3 s run carries the
  3.5 kg payload twice (the paper's 5 s / 5 s schedule would not place it before 5 s);
* nominal model :class:`~delaytrack.plants.robot.NominalRobot`; reference
  ``paper_reference("consistent")`` started on it (``initial_state``);
* 3 s, ``dt`` = 1 ms, ``T_c`` = 10 ms, one record every 10 controller ticks (0.1 s);
* AROLC: the paper's gains ``K1 = K2 = Q = I``, ``α = 2``, ``ε = 0.1``, ``γ = 0.001``; delay S1;
* OuterLoop: ``K1 = K2 = I``; delay S1;
* PCON: ``κ = 1``, ``k_b = 1``, ``ϑ = 0.5 M̂(q0)⁻¹`` (nominal model at the reference's initial
  pose), history 0.13 s, ``T_c`` = 10 ms; delay S1 (``h_max`` = 0.1 s);
* PCONf: the same gains and ``h̄`` = 0.06 s; delay S3 (60 ms).

These are regression fixtures, not tuned experiments: the gains are fixed here so that any change
in a kernel, the engine or a model shows up as a difference.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

import delaytrack as dt
from delaytrack.controllers import PCON, PCONf
from delaytrack.plants.robot import NominalRobot, PayloadRobot, initial_state, paper_reference

DATA = Path(__file__).resolve().parent.parent / "tests" / "data"
COMMAND = ".venv/bin/python scripts/make_golden.py"

CONTROLLERS = ("arolc", "outer_loop", "pcon", "pconf")
DURATION = 3.0
DT = 1e-3
T_C = 0.01
RECORD_EVERY = 10
PAYLOAD = dict(seed=7, duration=DURATION, first_on=0.5, time_on=1.0, time_off=0.5)
HISTORY = 0.13
H_BAR = 0.06

#: Arrays stored per case (``settings`` is stored beside them as a JSON string).
ARRAYS = ("t", "x", "commands", "applied", "controller_state", "status")


def build_case(name: str) -> dict[str, Any]:
    """Plant, controller, delay, reference and x0 of the golden case ``name``."""
    if name not in CONTROLLERS:
        raise ValueError(f"unknown golden case {name!r}; choose from {list(CONTROLLERS)}")
    reference = paper_reference("consistent")
    x0 = initial_state(reference)
    model = NominalRobot()
    delay = dt.AbsSineDelay.S1()
    if name == "arolc":
        controller = dt.AROLC(model, K1=1.0, K2=1.0, Q=1.0, alpha=2.0, epsilon=0.1, gamma=0.001)
    elif name == "outer_loop":
        controller = dt.OuterLoop(model, K1=1.0, K2=1.0)
    else:
        vartheta = 0.5 * np.linalg.inv(model.mass_matrix(x0[: model.n])[0])
        gains = dict(kappa=1.0, vartheta=vartheta, k_b=1.0, history=HISTORY, T_c=T_C)
        if name == "pcon":
            controller = PCON(model, **gains)
        else:
            controller = PCONf(model, **gains, h_bar=H_BAR)
            delay = dt.ConstantDelay.S3()
    return dict(
        plant=PayloadRobot(**PAYLOAD),
        controller=controller,
        delay=delay,
        reference=reference,
        x0=x0,
    )


def run_case(name: str) -> dict[str, Any]:
    """Run the golden case ``name``; return the stored arrays and the ``settings`` dict."""
    case = build_case(name)
    result = dt.simulate(
        case["plant"],
        case["controller"],
        case["delay"],
        case["x0"],
        reference=case["reference"],
        t1=DURATION,
        dt=DT,
        T_c=T_C,
        record_every=RECORD_EVERY,
    )
    out: dict[str, Any] = {key: np.asarray(getattr(result, key)) for key in ARRAYS}
    # Round-trip through JSON so that the fresh settings compare equal to the stored ones.
    settings = {**result.settings, "case": name, "regenerate": COMMAND}
    out["settings"] = json.loads(json.dumps(settings))
    return out


def path_of(name: str) -> Path:
    return DATA / f"golden_{name}.npz"


def save_case(name: str) -> Path:
    """Run ``name`` and write ``tests/data/golden_<name>.npz``."""
    run = run_case(name)
    if run["status"].tolist() != [0]:
        raise RuntimeError(f"golden case {name!r} did not finish: status {run['status']}")
    arrays = {key: run[key] for key in ARRAYS}
    settings = np.array(json.dumps(run["settings"], sort_keys=True))
    target = path_of(name)
    target.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(target, **arrays, settings=settings)
    return target


def main(argv: list[str] | None = None) -> int:
    names = (argv if argv is not None else sys.argv[1:]) or list(CONTROLLERS)
    for name in names:
        target = save_case(name)
        print(f"wrote {target} ({target.stat().st_size} bytes)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
