"""The component protocol: kernels named by their code, and a user's engine cached on disk."""

from __future__ import annotations

import importlib.machinery
import importlib.util
import json
import os
import shutil
import subprocess
import sys
import textwrap

import numba
import numpy as np
import pytest

from delaytrack._compile.fingerprint import code_fingerprint
from delaytrack._compile.helper_process import spare_core
from delaytrack._compile.native_entries import evaluate_reference
from delaytrack.components import Kernel
from delaytrack.controllers.arolc import arolc_step
from delaytrack.plants import TwoLinkArm

USER_MODULE = """
import math
import numba

GRAVITY = {gravity}


@numba.njit
def swing(q):
    return GRAVITY * math.sin(q)


@numba.njit
def pendulum_terms(t, q, qdot, params, M, N, G):
    M[0, 0] = params[0] * params[1] ** 2
    N[0] = params[0] * params[1] * swing(q[0]) + params[2] * qdot[0]
    G[0, 0] = 1.0
"""


def load(tmp_path, name, gravity=9.81, extra=""):
    path = tmp_path / f"{name}.py"
    path.write_text(USER_MODULE.format(gravity=gravity) + extra)
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    writes, sys.dont_write_bytecode = sys.dont_write_bytecode, True  # no .pyc of the same size
    try:  # and second to load instead of an edit
        spec.loader.exec_module(module)
    finally:
        sys.dont_write_bytecode = writes
    return module


def test_builtin_kernels_are_named_by_module_and_function():
    assert Kernel(arolc_step).key == "delaytrack.controllers.arolc:arolc_step"
    assert TwoLinkArm().engine_kernel == TwoLinkArm(p1=4.0).engine_kernel  # parameters are data


def test_a_user_kernel_is_named_by_its_code_and_what_it_reaches(tmp_path):
    first = load(tmp_path, "user_a").pendulum_terms
    again = load(tmp_path, "user_a").pendulum_terms  # the same text loaded twice
    assert code_fingerprint(first) == code_fingerprint(again)
    assert Kernel(first).key.startswith("user_a:pendulum_terms#")
    assert Kernel(first).key == Kernel(again).key
    # A constant read by a helper it calls, or the helper's text, changes the name.
    assert code_fingerprint(load(tmp_path, "user_a", gravity=1.62).pendulum_terms) != (
        code_fingerprint(first)
    )
    edited = load(tmp_path, "user_a", extra="\n# an edit elsewhere in the file\n")
    assert code_fingerprint(edited.pendulum_terms) == code_fingerprint(first)  # its code only


def test_a_constant_read_from_a_module_of_yours_is_part_of_the_name(tmp_path, monkeypatch):
    # numba compiles the value of ``settings.GAIN`` into the kernel, so a new value is new code.
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(sys, "dont_write_bytecode", True)  # no .pyc of the same size and second
    law = "import user_settings\n\n\ndef law(x):\n    return user_settings.GAIN * x\n"
    (tmp_path / "user_law.py").write_text(law)

    def fingerprint(gain: float, name: str = "arm") -> str:
        (tmp_path / "user_settings.py").write_text(f"GAIN = {gain}\nNAME = {name!r}\n")
        for module in ("user_settings", "user_law"):
            monkeypatch.delitem(sys.modules, module, raising=False)
        return code_fingerprint(importlib.import_module("user_law").law)

    assert fingerprint(2.0) == fingerprint(2.0)
    assert fingerprint(3.0) != fingerprint(2.0)
    assert fingerprint(2.0, name="another arm") == fingerprint(2.0)  # a constant it does not read


def _scaled(t, params):
    return params[0] * t


def test_a_kernels_numba_options_are_part_of_its_name():
    # The same code compiled with other options is other machine code: never loaded for it.
    plain = code_fingerprint(numba.njit(_scaled))
    assert code_fingerprint(numba.njit(_scaled)) == plain
    assert code_fingerprint(numba.njit(fastmath=True)(_scaled)) != plain
    assert code_fingerprint(numba.njit(error_model="numpy")(_scaled)) != plain
    flags = code_fingerprint(numba.njit(fastmath={"nnan", "ninf"})(_scaled))
    assert code_fingerprint(numba.njit(fastmath={"ninf", "nnan"})(_scaled)) == flags


def test_numbas_own_defaults_written_out_are_the_same_name():
    plain = code_fingerprint(numba.njit(_scaled))
    defaults = numba.njit(error_model="python", fastmath=False, _nrt=True)(_scaled)
    assert code_fingerprint(defaults) == plain


def _reference_dividing(t, params, qd, qd_dot, qd_ddot):
    qd[0] = 1 // int(params[0])  # numba's default error model: raises ZeroDivisionError


def _divide(value):
    return 1 // value


def _calling(helper):
    """A reference kernel that divides by zero in ``helper``."""

    def reference(t, params, qd, qd_dot, qd_ddot):
        qd[0] = helper(int(params[0]))

    return reference


def _reference_at_zero(reference):
    """``q_d`` of ``reference`` at t = 0 through the engine's compiled call (its own part, compiled
    with error_model="numpy"), or the exception it raises."""
    params, qd = np.zeros(1), np.full(1, np.nan)
    try:
        evaluate_reference(Kernel.of(reference), 0.0, params, qd, np.zeros(1), np.zeros(1))
    except ZeroDivisionError as error:
        return error
    return qd[0]


@pytest.mark.parametrize("in_a_helper", [False, True])
@pytest.mark.parametrize("options", [{}, {"error_model": "numpy"}])
def test_a_kernel_of_yours_keeps_its_own_error_model_inside_the_engine(in_a_helper, options):
    # First compiled inside a part of the engine (compiled with error_model="numpy"), numba
    # would compile the kernel with the part's options: the division would give 0 instead of
    # raising. A helper it calls follows the kernel's options, as when you call it yourself.
    from delaytrack._compile.fingerprint import _walk

    # A new helper each time: numba keeps the first compile of a function for all its callers.
    helper = numba.njit(_divide)  # no options: it takes them from the kernel that calls it
    function = _calling(helper) if in_a_helper else _reference_dividing
    reference = numba.njit(**options)(function)
    _walk.cache_clear()
    name = code_fingerprint(reference)
    outcome = _reference_at_zero(reference)
    if options:
        assert outcome == 0.0  # numpy's model: an integer division by zero gives 0
    else:
        assert isinstance(outcome, ZeroDivisionError)
    _walk.cache_clear()
    assert code_fingerprint(reference) == name  # the defaults it was given change no name
    assert "error_model" not in helper.targetoptions


def _reference_with_scratch(t, params, qd, qd_dot, qd_ddot):
    scratch = np.full(qd.shape[0], params[0] * t)  # an array of its own, freed by numba
    for i in range(qd.shape[0]):
        qd[i] = scratch[i]
        qd_dot[i] = params[0]
        qd_ddot[i] = 0.0


def test_a_kernel_of_yours_may_make_arrays_inside_the_engine():
    # The engine's parts run without numba's runtime; a kernel first compiled inside one would
    # take that and be refused (numba: "Only accept returning of array passed into the
    # function as argument").
    reference = numba.njit(_reference_with_scratch)
    qd, qd_dot, qd_ddot = np.zeros(2), np.zeros(2), np.zeros(2)
    evaluate_reference(Kernel.of(reference), 2.0, np.array([0.5]), qd, qd_dot, qd_ddot)
    assert qd.tolist() == [1.0, 1.0] and qd_dot.tolist() == [0.5, 0.5]  # 0.5 × t, t = 2


def _reference_returning_an_array(t, params, qd, qd_dot, qd_ddot):
    qd[0] = t
    return np.zeros(1000)  # compiled with numba's runtime: the engine would never free it


def _reference_returning_an_argument(t, params, qd, qd_dot, qd_ddot):
    qd[0] = t
    return qd


def _reference_returning_an_argument_of_any_layout(t, params, qd, qd_dot, qd_ddot):
    qd[0] = t
    return qd


#: Its signature, given in advance for arrays of any layout: numba converts the engine's
#: contiguous arrays to it, so no overload is compiled for them.
_ANY_LAYOUT = "float64[:](float64, float64[:], float64[:], float64[:], float64[:])"


@pytest.mark.parametrize(
    "compiled",
    [
        lambda: numba.njit(_reference_returning_an_array),
        lambda: numba.njit(_reference_returning_an_argument),
        lambda: numba.njit(_ANY_LAYOUT)(_reference_returning_an_argument_of_any_layout),
    ],
    ids=["new array", "argument", "signature given in advance"],
)
def test_a_kernel_that_returns_an_array_is_refused_naming_it(compiled):
    from numba.core.errors import TypingError

    zeros = [np.zeros(1) for _ in range(4)]
    with pytest.raises(TypingError, match=r"the reference kernel \S+ returns array\(float64"):
        evaluate_reference(Kernel.of(compiled()), 0.5, *zeros)


def test_only_the_kernel_is_given_numbas_defaults():
    decorator = numba.njit()
    kernel = decorator(_reference_dividing)
    sibling = decorator(_scaled)  # made by the same decorator: numba shares their options
    Kernel.of(kernel).numba_type  # noqa: B018
    assert kernel.targetoptions["error_model"] == "python"
    assert "error_model" not in sibling.targetoptions


def test_the_name_does_not_depend_on_where_or_how_the_code_was_loaded(tmp_path):
    """The same code moved down its file, or read from a .pyc, keeps its name: the name hashes
    what the code does, not its line numbers nor the bytes marshal gives for it."""
    import py_compile

    fresh = load(tmp_path, "user_b")
    moved = tmp_path / "user_c.py"
    moved.write_text(
        "# a comment above moves every line down\n\n" + USER_MODULE.format(gravity=9.81)
    )
    spec = importlib.util.spec_from_file_location("user_b", moved)
    shifted = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(shifted)
    compiled = py_compile.compile(str(tmp_path / "user_b.py"), cfile=str(tmp_path / "b.pyc"))
    loader = importlib.machinery.SourcelessFileLoader("user_b", compiled)
    from_pyc = importlib.util.module_from_spec(importlib.util.spec_from_loader("user_b", loader))
    loader.exec_module(from_pyc)
    expected = code_fingerprint(fresh.pendulum_terms.py_func)
    assert code_fingerprint(shifted.pendulum_terms.py_func) == expected
    assert code_fingerprint(from_pyc.pendulum_terms.py_func) == expected


def test_python_kernels_are_not_kept_by_the_kernel_cache():
    import gc
    import weakref

    from delaytrack.components import _kernel_of

    plant = dt_callable_plant()
    alive = weakref.ref(plant)
    before = _kernel_of.cache_info().currsize
    for _ in range(50):
        assert not plant.compiled  # its kernel is plain Python
    assert _kernel_of.cache_info().currsize == before
    del plant
    gc.collect()
    assert alive() is None
    assert Kernel.of(arolc_step) is Kernel.of(arolc_step)  # compiled ones are made once


def dt_callable_plant():
    from delaytrack.plants import CallablePlant

    return CallablePlant(1, lambda q: np.array([[1.0]]), lambda q, qdot: np.array([0.0]))


def test_flags_are_part_of_the_name():
    plain = Kernel(arolc_step)
    assert Kernel(arolc_step, identity_mass=True).key != plain.key
    assert Kernel(arolc_step, command_map=arolc_step).key != plain.key
    assert Kernel(arolc_step, stepper=arolc_step).key != plain.key
    with pytest.raises(TypeError, match="function must be callable"):
        Kernel(3.0)
    with pytest.raises(TypeError, match="stepper must be callable"):
        Kernel(arolc_step, stepper=3.0)


def test_a_plants_sizes_are_part_of_its_name_and_checked():
    assert TwoLinkArm().engine_kernel.sizes == (2, 2)
    assert Kernel(arolc_step, sizes=(2, 1)).key != Kernel(arolc_step, sizes=(3, 1)).key
    assert Kernel(arolc_step, sizes=(np.int64(2), 1)).sizes == (2, 1)
    for bad in [(0, 1), (2,), (2.0, 1), (True, 1), "21"]:
        with pytest.raises(ValueError, match="sizes must be two integers n, m >= 1"):
            Kernel(arolc_step, sizes=bad)


RUN = """
import json, sys, time
start = time.perf_counter()
import numpy as np
import delaytrack as dt
sys.path.insert(0, sys.argv[1])
from user_plant import pendulum_terms
from delaytrack.sim.engine import run_batch_compiled
from delaytrack.sim.integrator import integrate_tick

# With a helper, the integrator is left to it (this process never claims it; otherwise
# whichever process is free first takes it), so that the test knows who compiled it.
from delaytrack._compile import helper_process, stage
left = []
def start_helper(jobs, ahead=lambda: None):
    left[:] = [i for i, job in enumerate(jobs) if job.function is integrate_tick]
    return helper_process.start(jobs, ahead)
stage.start_helper = start_helper
claim = helper_process.Helper.claim
helper_process.Helper.claim = lambda self, position: position not in left and claim(self, position)

truth = dt.CompiledPlant(1, 1, pendulum_terms, [1.2, 0.5, 0.4])
model = dt.CompiledPlant(1, 1, pendulum_terms, [0.9, 0.5, 0.0])
controller = dt.AROLC(model, K1=1.0, K2=1.0, Q=1.0, alpha=2.0, epsilon=0.1, gamma=0.001)
result = dt.simulate(truth, controller, dt.ConstantDelay(0.01), np.zeros(2),
                     reference=dt.SinusoidalReference(offset=[0.3], amplitude=[0.5],
                                                      frequency=[1.0]),
                     t1=1.0, dt=1e-3, T_c=2e-3, trajectories=False)
engine, plant = run_batch_compiled.stats, integrate_tick.stats
print(json.dumps({"hits": sum(plant.cache_hits.values()),
                  "misses": sum(plant.cache_misses.values()),
                  "engine_hits": sum(engine.cache_hits.values()),
                  "engine_misses": sum(engine.cache_misses.values()),
                  "ae": float(dt.mean_absolute_error(result)[0, 0]),
                  "seconds": time.perf_counter() - start}))
"""


@pytest.mark.slow
def test_a_user_compiled_plant_is_compiled_once_then_loaded_from_disk(tmp_path, monkeypatch):
    (tmp_path / "user_plant.py").write_text(USER_MODULE.format(gravity=9.81))
    script = tmp_path / "run.py"
    script.write_text(textwrap.dedent(RUN))
    # a compile helper whatever the load (the test suite's other workers keep the cores busy)
    monkeypatch.setenv("DELAYTRACK_COMPILE_HELPER", "1")
    helper = spare_core()  # two cores or more
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}

    def run(**settings: str) -> dict:
        done = subprocess.run(
            [sys.executable, str(script), str(tmp_path)],
            env={**env, **settings},
            capture_output=True,
            text=True,
            timeout=900,
            check=True,
        )
        return json.loads(done.stdout.strip().splitlines()[-1])

    # The plant's integrator (the engine's code that runs the plant's kernel) is compiled by the
    # first process and loaded by the second. The first process shares its compiles with a
    # helper process: the engine, the longest for this small plant, is compiled here, the
    # plant's integrator by the helper (RUN leaves it to the helper), loaded here from the
    # cache it wrote.
    first, second = run(), run()
    if helper:
        assert first["misses"] == 0 and first["hits"] == 1
    else:  # one core
        assert first["misses"] == 1 and first["hits"] == 0
    assert first["engine_misses"] == 1
    assert second["misses"] == 0 and second["hits"] == 1 and second["engine_misses"] == 0
    assert second["ae"] == first["ae"] and np.isfinite(first["ae"])
    # Compiled in one process, from a cache that holds everything but the integrator (the
    # engine, which the first process compiled itself, and the other parts, wherever they were
    # compiled): the integrator the helper compiled, compiled here instead, gives the same
    # result, bit for bit. (The other parts the helper compiled are not compiled again here.)
    without_integrator = tmp_path / "without_integrator"
    shutil.copytree(tmp_path / "cache", without_integrator)
    integrator = [
        entry
        for entry in without_integrator.rglob("*.nb[ic]")
        if entry.name.startswith("integrator.integrate_tick")
    ]
    assert integrator  # its index and data
    for entry in integrator:
        entry.unlink()
    alone = run(NUMBA_CACHE_DIR=str(without_integrator), DELAYTRACK_COMPILE_HELPER="0")
    assert alone["engine_misses"] == 0 and alone["engine_hits"] == 1
    assert alone["misses"] == 1 and alone["ae"] == first["ae"]
    # An edit to the kernel's code is compiled again, not loaded stale; the engine around it,
    # which does not contain the plant's code, is loaded (its parts compiled in this process).
    (tmp_path / "user_plant.py").write_text(USER_MODULE.format(gravity=1.62))
    third = run(DELAYTRACK_COMPILE_HELPER="0")
    assert third["misses"] == 1 and third["ae"] != first["ae"]
    assert third["engine_misses"] == 0
