"""A kernel that reaches a function with numba's own disk cache (``cache=True``) whose helper in
another file was edited: numba keeps serving the old code, and the engine must not take it."""

from __future__ import annotations

import importlib
import sys
import uuid

import numpy as np
import pytest
from numba.core.errors import TypingError

import delaytrack as dt
from delaytrack._compile.fingerprint import compiled_functions_reached
from delaytrack._compile.stale_caches import compile_from_source
from delaytrack.components import Kernel
from delaytrack.controllers import OuterLoop
from delaytrack.delays import ConstantDelay
from delaytrack.references import SinusoidalReference

_HELPER = """
import math
import numba


@numba.njit
def swing(q):
    return {gravity} * math.sin(q)
"""

_SIGNATURE = (
    '"void(float64, float64[::1], float64[::1], float64[::1], float64[:, ::1], float64[::1], '
    'float64[:, ::1])", '
)

_KERNEL = """
import numba
from {helper} import swing


@numba.njit({signature}cache=True)
def terms(t, q, qdot, params, M, N, G):
    M[0, 0] = params[0] * params[1] ** 2
    N[0] = params[0] * params[1] * swing(q[0]) + params[2] * qdot[0]
    G[0, 0] = 1.0
"""

#: A kernel without a cache of its own, calling a cached function in another file, which calls
#: the helper in a third.
_MIDDLE = """
import numba
from {helper} import swing


@numba.njit(cache=True)
def middle(q):
    return swing(q)
"""

_OUTER = """
import numba
from {middle} import middle


@numba.njit
def terms(t, q, qdot, params, M, N, G):
    M[0, 0] = params[0] * params[1] ** 2
    N[0] = params[0] * params[1] * middle(q[0]) + params[2] * qdot[0]
    G[0, 0] = 1.0
"""

PARAMS = np.array([1.0, 0.5, 0.1])


@pytest.fixture
def pendulum(tmp_path, monkeypatch):
    """``load(gravity, layout="cached kernel")``: the pendulum's kernel module, its helper written
    with ``gravity``, all imported afresh under names no other test run has used. Layouts:
    ``"cached kernel"`` (the kernel has a cache and calls the helper), ``"explicit signature"``
    (the same, compiled when decorated), ``"cached middle"`` (a kernel without a cache calls a
    cached function in another file, which calls the helper)."""
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(sys, "dont_write_bytecode", True)
    suffix = uuid.uuid4().hex[:12]
    helper, middle, kernel = (f"{name}_{suffix}" for name in ("helper", "middle", "pendulum"))

    def load(gravity: float, layout: str = "cached kernel"):
        (tmp_path / f"{helper}.py").write_text(_HELPER.format(gravity=gravity))
        (tmp_path / f"{middle}.py").write_text(_MIDDLE.format(helper=helper))
        text = {
            "cached kernel": _KERNEL.format(helper=helper, signature=""),
            "explicit signature": _KERNEL.format(helper=helper, signature=_SIGNATURE),
            "cached middle": _OUTER.format(middle=middle),
        }[layout]
        (tmp_path / f"{kernel}.py").write_text(text)
        for name in (helper, middle, kernel):
            monkeypatch.delitem(sys.modules, name, raising=False)
        return importlib.import_module(kernel)

    return load


def nonlinear_term(terms) -> float:
    """``N`` at ``q = 1``, ``q̇ = 0``: ``m l g sin(1)``."""
    M, N, G = np.zeros((1, 1)), np.zeros(1), np.zeros((1, 1))
    terms(0.0, np.array([1.0]), np.array([0.0]), PARAMS, M, N, G)
    return float(N[0])


def expected(gravity: float) -> float:
    """:func:`nonlinear_term` for ``g = gravity``: ``m l g sin(1)`` with PARAMS' ``m = 1``,
    ``l = 0.5``."""
    return pytest.approx(0.5 * gravity * np.sin(1.0))


def hits_and_misses(function) -> tuple[int, int]:
    return sum(function.stats.cache_hits.values()), sum(function.stats.cache_misses.values())


def test_the_functions_reached_are_the_users_that_the_fingerprint_walks(pendulum):
    terms = pendulum(9.81, "cached middle").terms
    reached = {function.py_func.__name__ for function in compiled_functions_reached(terms)}
    assert reached == {"terms", "middle", "swing"}
    from delaytrack.references.sinusoidal import sinusoidal_reference_values

    assert compiled_functions_reached(sinusoidal_reference_values) == ()  # this package's


def test_the_cache_is_emptied_and_what_was_loaded_compiled_from_the_source(pendulum):
    assert nonlinear_term(pendulum(9.81).terms) == expected(9.81)  # compiled, saved
    loaded = pendulum(9.81).terms
    assert nonlinear_term(loaded) == expected(9.81)
    assert hits_and_misses(loaded) == (1, 0)  # from the disk cache
    compile_from_source([Kernel(loaded)])
    assert hits_and_misses(loaded) == (0, 1)  # compiled again: the disk cache was emptied
    assert nonlinear_term(loaded) == expected(9.81)
    later = pendulum(9.81).terms
    nonlinear_term(later)
    assert hits_and_misses(later) == (1, 0)  # and filled again by that compile


def test_code_compiled_in_this_process_is_compiled_again_once(pendulum):
    terms = pendulum(9.81, "cached middle").terms
    nonlinear_term(terms)  # compiled from the source, but linking the middle function's code
    [signature] = terms.overloads
    first = terms.overloads[signature]
    compile_from_source([Kernel(terms)])
    again = terms.overloads[signature]
    assert again is not first  # it may have held another file's old code
    compile_from_source([Kernel(terms)])
    assert terms.overloads[signature] is again  # compiled since from the source: kept


def test_a_kernel_with_explicit_signatures_is_compiled_again_at_once(pendulum):
    nonlinear_term(pendulum(9.81, "explicit signature").terms)
    loaded = pendulum(9.81, "explicit signature").terms
    compile_from_source([Kernel(loaded)])
    assert loaded.overloads and not loaded._can_compile  # as it was decorated
    assert nonlinear_term(loaded) == expected(9.81)


def test_a_call_numba_refused_is_not_compiled_again(pendulum):
    # numba counts a signature it could not compile as a cache miss; only the code it holds
    # is compiled again.
    terms = pendulum(9.81).terms
    with pytest.raises(TypingError):
        terms("not a time", 1, 2, 3, 4, 5, 6)
    nonlinear_term(terms)
    compile_from_source([Kernel(terms)])  # no TypingError
    assert len(terms.overloads) == 1
    assert nonlinear_term(terms) == expected(9.81)


def test_this_packages_functions_are_left_alone():
    from delaytrack.references.sinusoidal import sinusoidal_reference_values

    reference = SinusoidalReference(offset=[0.0], amplitude=[0.5], frequency=[1.0])
    reference.evaluate(np.zeros(2))  # compiled or loaded
    before = dict(sinusoidal_reference_values.overloads)
    compile_from_source([Kernel(sinusoidal_reference_values)])
    assert dict(sinusoidal_reference_values.overloads) == before


@pytest.mark.slow  # compiles the engine's parts around a new pendulum (about 10 s)
@pytest.mark.parametrize("layout", ["cached kernel", "cached middle"])
def test_a_helper_edited_in_another_file_reaches_the_simulation(pendulum, layout):
    nonlinear_term(pendulum(9.81, layout).terms)  # numba's disk cache now holds g = 9.81
    edited = pendulum(1.62, layout).terms
    # numba's own limit: the edit is in another file, and the old code is loaded.
    assert nonlinear_term(edited) == expected(9.81)

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
    assert nonlinear_term(edited) == expected(1.62)  # the user's own call, repaired


def test_a_cache_that_cannot_be_emptied_is_no_longer_read(pendulum, monkeypatch):
    terms = pendulum(9.81).terms
    nonlinear_term(terms)

    def gone() -> None:
        raise FileNotFoundError("the cache folder was removed")

    monkeypatch.setattr(terms._cache, "flush", gone)
    compile_from_source([Kernel(terms)])  # no error
    assert not terms._cache._enabled
    assert hits_and_misses(terms) == (0, 1)  # compiled again from the source
    assert nonlinear_term(terms) == expected(9.81)


_DELAY_HELPER = """
import numba


@numba.njit(cache=True)
def base(t):
    return {base}
"""

_DELAY = """
import numba
from {helper} import base


@numba.njit(cache=True)
def delay(t, params):
    return base(t) + params[0]
"""


@pytest.mark.slow  # compiles the engine's parts for a new delay kernel (a few seconds)
def test_a_delay_kernels_helper_edited_in_another_file_reaches_h_and_the_simulation(
    tmp_path, monkeypatch
):
    from delaytrack.delays import CompiledDelay
    from delaytrack.plants import TwoLinkArm

    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(sys, "dont_write_bytecode", True)
    suffix = uuid.uuid4().hex[:12]
    helper, module = f"delay_helper_{suffix}", f"delay_{suffix}"

    def load(base: float):
        (tmp_path / f"{helper}.py").write_text(_DELAY_HELPER.format(base=base))
        (tmp_path / f"{module}.py").write_text(_DELAY.format(helper=helper))
        for name in (helper, module):
            monkeypatch.delitem(sys.modules, name, raising=False)
        return importlib.import_module(module).delay

    first = CompiledDelay(load(0.02), [0.001], h_max=0.2)
    assert first.h(0.3) == 0.02 + 0.001  # numba's disk cache now holds base = 0.02
    edited = CompiledDelay(load(0.05), [0.001], h_max=0.2)
    # many points: the profile's code compiled for the edited kernel, before any simulation
    np.testing.assert_array_equal(edited.h(np.full(100, 0.3)), 0.05 + 0.001)
    assert edited.h(0.3) == 0.05 + 0.001
    # edited back, imported again: the same code as the first, and numba's cache holds 0.05
    back = CompiledDelay(load(0.02), [0.001], h_max=0.2)
    assert back.h(0.3) == 0.02 + 0.001
    np.testing.assert_array_equal(back.h(np.full(100, 0.3)), 0.02 + 0.001)

    arm, controller = TwoLinkArm(), OuterLoop(TwoLinkArm(), K1=4.0, K2=4.0)
    reference = SinusoidalReference(offset=[0.0, 0.0], amplitude=[0.5, 0.3], frequency=[1.0, 0.7])
    settings = {"reference": reference, "t1": 0.5, "dt": 1e-3, "T_c": 5e-3, "trajectories": False}

    def run(engine: str) -> np.ndarray:
        result = dt.simulate(arm, controller, edited, np.zeros(4), engine=engine, **settings)
        return result.metrics["ae"]

    np.testing.assert_allclose(run("compiled"), run("python"), rtol=1e-9)
