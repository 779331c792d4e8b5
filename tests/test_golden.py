"""Golden regression: a short closed loop of each controller on the robot against stored runs.

The cases (AROLC, OuterLoop, PCON, PCONf on the PIONEER-3 robot with payload; 3 s, ``dt`` = 1 ms,
``T_c`` = 10 ms) are defined once, in ``scripts/make_golden.py``; this test imports its
:func:`run_case` and compares with ``tests/data/golden_<controller>.npz``, which that script
writes::

    .venv/bin/python scripts/make_golden.py

Tolerance: ``rtol = 0``, ``atol = 1e-9`` on every float array (states, commands, applied commands,
controller state, times). On one machine the runs are deterministic and bitwise equality is
expected; ``1e-9`` leaves room for another BLAS, CPU or compiler reordering floating-point sums,
while any change of a law, a model, the engine or a setting moves the values far more. ``status``
and the settings record must match exactly.

A failure means the numbers changed. Find out why before regenerating: regenerate only once the
change is reviewed and intended.
"""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

SCRIPT = Path(__file__).resolve().parent.parent / "scripts" / "make_golden.py"
ATOL = 1e-9


def _load_script():
    spec = importlib.util.spec_from_file_location("make_golden", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


golden = _load_script()

HINT = (
    "the golden run {name!r} changed ({what}). If the change is intended, review it and only "
    f"then regenerate with `{golden.COMMAND}`; otherwise it is a regression."
)


@pytest.fixture(scope="module", params=golden.CONTROLLERS)
def case(request):
    name = request.param
    path = golden.path_of(name)
    assert path.exists(), f"missing {path}; generate it with `{golden.COMMAND}`"
    with np.load(path) as stored:
        expected = {key: stored[key] for key in stored.files}
    return name, expected, golden.run_case(name)


def test_settings_match(case):
    name, expected, fresh = case
    assert json.loads(str(expected["settings"])) == fresh["settings"], HINT.format(
        name=name, what="settings"
    )


def test_status_matches(case):
    name, expected, fresh = case
    np.testing.assert_array_equal(
        fresh["status"], expected["status"], err_msg=HINT.format(name=name, what="status")
    )
    assert expected["status"].tolist() == [0]


@pytest.mark.parametrize("key", ["t", "x", "commands", "applied", "controller_state"])
def test_arrays_match(case, key):
    name, expected, fresh = case
    assert fresh[key].shape == expected[key].shape, HINT.format(name=name, what=f"{key} shape")
    np.testing.assert_allclose(
        fresh[key], expected[key], rtol=0, atol=ATOL, err_msg=HINT.format(name=name, what=key)
    )
