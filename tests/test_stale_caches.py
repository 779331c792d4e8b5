"""A kernel with numba's own disk cache (``cache=True``) whose helper in another file was edited:
numba keeps serving the old code, and the engine must not take it."""

from __future__ import annotations

import importlib
import sys
import uuid

import numpy as np
import pytest

import delaytrack as dt
from delaytrack.components import Kernel, compiled_functions_reached
from delaytrack.controllers import OuterLoop
from delaytrack.delays import ConstantDelay
from delaytrack.references import SinusoidalReference
from delaytrack.sim.stale_caches import compile_from_source

_HELPER = """
import math
import numba


@numba.njit
def swing(q):
    return {gravity} * math.sin(q)
"""

_KERNEL = """
import numba
from {helper} import swing


@numba.njit(cache=True)
def terms(t, q, qdot, params, M, N, G):
    M[0, 0] = params[0] * params[1] ** 2
    N[0] = params[0] * params[1] * swing(q[0]) + params[2] * qdot[0]
    G[0, 0] = 1.0
"""

PARAMS = np.array([1.0, 0.5, 0.1])


@pytest.fixture
def pendulum(tmp_path, monkeypatch):
    """``load(gravity)``: the kernel module (its helper written with ``gravity`` in a file of
    its own), imported afresh under names no other test run has used."""
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(sys, "dont_write_bytecode", True)
    suffix = uuid.uuid4().hex[:12]
    helper, kernel = f"helper_{suffix}", f"pendulum_{suffix}"
    (tmp_path / f"{kernel}.py").write_text(_KERNEL.format(helper=helper))

    def load(gravity: float):
        (tmp_path / f"{helper}.py").write_text(_HELPER.format(gravity=gravity))
        for name in (helper, kernel):
            monkeypatch.delitem(sys.modules, name, raising=False)
        return importlib.import_module(kernel)

    return load


def nonlinear_term(terms) -> float:
    """``N`` at ``q = 1``, ``q̇ = 0``: ``m l g sin(1)``."""
    M, N, G = np.zeros((1, 1)), np.zeros(1), np.zeros((1, 1))
    terms(0.0, np.array([1.0]), np.array([0.0]), PARAMS, M, N, G)
    return float(N[0])


def test_the_functions_reached_are_those_the_fingerprint_walks(pendulum):
    module = pendulum(9.81)
    reached = {function.py_func.__name__ for function in compiled_functions_reached(module.terms)}
    assert reached == {"terms", "swing"}


def hits_and_misses(function) -> tuple[int, int]:
    return sum(function.stats.cache_hits.values()), sum(function.stats.cache_misses.values())


def test_a_disk_cache_is_emptied_and_the_code_loaded_from_it_dropped(pendulum):
    expected = 0.5 * 9.81 * np.sin(1.0)
    assert nonlinear_term(pendulum(9.81).terms) == pytest.approx(expected)  # compiled, saved
    loaded = pendulum(9.81).terms
    assert nonlinear_term(loaded) == pytest.approx(expected)
    assert hits_and_misses(loaded) == (1, 0)  # from the disk cache
    compile_from_source([Kernel(loaded)])
    assert not loaded.overloads and hits_and_misses(loaded) == (0, 0)  # dropped
    compiled_again = pendulum(9.81).terms
    assert nonlinear_term(compiled_again) == pytest.approx(expected)
    assert hits_and_misses(compiled_again) == (0, 1)  # the disk cache was emptied


def test_code_compiled_from_the_source_is_saved_again(pendulum):
    compiled = pendulum(9.81).terms
    nonlinear_term(compiled)
    assert hits_and_misses(compiled) == (0, 1)
    compile_from_source([Kernel(compiled)])
    assert compiled.overloads  # from the source: kept, and saved again for the next process
    later = pendulum(9.81).terms
    nonlinear_term(later)
    assert hits_and_misses(later) == (1, 0)


def test_only_the_users_functions_are_touched(pendulum, monkeypatch):
    from delaytrack.controllers.arolc import arolc_step
    from delaytrack.sim import stale_caches

    touched = []
    monkeypatch.setattr(stale_caches, "_from_source", touched.append)
    terms = pendulum(9.81).terms
    compile_from_source([Kernel(arolc_step), Kernel(terms)])  # ours: the package's cache folder
    assert sorted(function.py_func.__name__ for function in touched) == ["swing", "terms"]


@pytest.mark.slow  # compiles the engine's parts around a new pendulum (about 10 s)
def test_a_helper_edited_in_another_file_reaches_the_simulation(pendulum):
    nonlinear_term(pendulum(9.81).terms)  # numba's disk cache now holds the code with 9.81
    edited = pendulum(1.62).terms
    # numba's own limit: the edit is in another file, and the old code is loaded.
    assert nonlinear_term(edited) == pytest.approx(0.5 * 9.81 * np.sin(1.0))

    def run(engine: str) -> np.ndarray:
        plant = dt.CompiledPlant(1, 1, edited, PARAMS)
        controller = OuterLoop(dt.CompiledPlant(1, 1, edited, PARAMS), K1=4.0, K2=4.0)
        reference = SinusoidalReference(offset=[0.0], amplitude=[0.5], frequency=[1.0])
        settings = {"t1": 1.0, "dt": 1e-3, "T_c": 1e-3, "trajectories": False, "engine": engine}
        return dt.simulate(
            plant, controller, ConstantDelay(0.02), np.zeros(2), reference=reference, **settings
        ).metrics["ae"]

    compiled = run("compiled")
    from_source = run("python")  # the kernels' Python source, as it is now
    np.testing.assert_allclose(compiled, from_source, rtol=1e-9)
    assert nonlinear_term(edited) == pytest.approx(0.5 * 1.62 * np.sin(1.0))  # repaired
