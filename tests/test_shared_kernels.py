"""The package's compiled kernels keep their own settings whichever compile reaches them first:
numba would otherwise give a function first compiled inside another compile that compile's
runtime and fastmath settings, and keep them on disk."""

import os
import subprocess
import sys

import pytest

_FASTMATH_FIRST = """
import numba, numpy as np
from delaytrack.components import solve_input_map

@numba.njit(fastmath=True)
def yours(G, tau, command):
    solve_input_map(G, tau, command)

@numba.njit
def plain(G, tau, command):
    solve_input_map(G, tau, command)

G = np.array([[np.inf, 0.0], [0.0, 1.0]])
command = np.zeros(2)
if "{first}" == "fastmath":
    yours(G, np.array([1.0, 2.0]), np.zeros(2))
plain(G, np.array([1.0, 2.0]), command)
print(*command)
"""

#: A kernel of the package's kind that needs numba's runtime: a reshaped view (as
#: ``LinearPlant``'s terms were written before they read their matrices in place).
_NEEDS_THE_RUNTIME = """
from delaytrack._compile.jit import kernel

@kernel
def reshaping_terms(t, q, qdot, params, mass, nonlinear, input_map):
    n = q.shape[0]
    mass[:, :] = params[: n * n].reshape((n, n))
    stiffness = params[n * n : 2 * n * n].reshape((n, n))
    for i in range(n):
        total = 0.0
        for j in range(n):
            total += stiffness[i, j] * q[j]
        nonlinear[i] = total
"""

_WITHOUT_THE_RUNTIME_FIRST = """
import numba, numpy as np
from reshaping import reshaping_terms

@numba.njit(_nrt=False)  # as the engine's integrator
def terms_in_a_loop_without_the_runtime(q, params, M, N, G):
    for _ in range(3):
        reshaping_terms(0.0, q, q, params, M, N, G)

params = np.concatenate([np.eye(2).ravel(), 2.0 * np.eye(2).ravel()])
M, N, G = np.zeros((2, 2)), np.zeros(2), np.zeros((2, 1))
terms_in_a_loop_without_the_runtime(np.ones(2), params, M, N, G)
print(*M.ravel(), *N)
"""


def _run(code: str, cache, folder=None) -> list[str]:
    """``code`` run by a new Python in ``folder`` (whose modules it can import: ``-c`` puts the
    working folder first on the module search path), with numba's cache in ``cache``."""
    environment = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    done = subprocess.run(
        [sys.executable, "-c", code],
        cwd=folder,
        env=environment,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout.split()


@pytest.mark.parametrize("later", ["same process", "new process"])
def test_a_fastmath_caller_first_leaves_the_package_kernel_as_it_is(tmp_path, later):
    code = _FASTMATH_FIRST.format(first="fastmath")
    if later == "new process":
        _run(code, tmp_path)  # the fastmath caller compiles the package's kernel first, on disk
        code = _FASTMATH_FIRST.format(first="none")
    # G's infinity: the solve gives NaN without fastmath (with it, [0, 2])
    assert _run(code, tmp_path) == ["nan", "nan"]


def test_a_kernel_that_needs_the_runtime_compiles_first_inside_one_without_it(tmp_path):
    (tmp_path / "reshaping.py").write_text(_NEEDS_THE_RUNTIME)
    # M = I, N = K q = 2 q
    printed = _run(_WITHOUT_THE_RUNTIME_FIRST, tmp_path / "cache", tmp_path)
    assert printed == ["1.0", "0.0", "0.0", "1.0", "2.0", "2.0"]
