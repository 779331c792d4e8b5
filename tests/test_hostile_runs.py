"""Hostile runs: what goes wrong while a closed loop runs ends in one clear line, promptly.

A plant given as Python functions that raises or returns the wrong thing partway through a run,
a compiled delay kernel that raises, Ctrl-C during a compiled run, many coordinates, a reader
that closes the pipe. Plain-Python plants compile nothing; the few compiled cases use the
built-in two-link arm (its engine is in the disk cache of the other tests) or one small kernel.
"""

from __future__ import annotations

import math
import signal
import subprocess
import sys
import threading
import time
import warnings
from pathlib import Path

import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from arm_closed_form import arm_mass, arm_nonlinear
from delaytrack._user_calls import UserFunctionError
from delaytrack.cli import main
from delaytrack.cli._main import EXIT_BROKEN_PIPE
from delaytrack.controllers import AROLC
from delaytrack.delays import CompiledDelay, ConstantDelay
from delaytrack.plants import CallablePlant, TwoLinkArm
from delaytrack.references import Reference, SinusoidalReference
from delaytrack.scenario import dumps_toml
from delaytrack.sim import SimResult, simulate
from delaytrack.sim.fallback import PythonFallbackWarning
from delaytrack.sim.interruptible import (
    every_run_interruptible,
    run_interruptibly,
    work_left_running,
)
from test_hostile_inputs import one_line_error
from test_scenario import base_dict

DELAYTRACK = str(Path(sys.executable).with_name("delaytrack"))
#: Runs the command after it with SIGINT handled by default, as from a terminal: a process
#: started from a background job (``make test &``, some CI runners) inherits SIGINT ignored, and
#: Python then keeps it so, which would leave the Ctrl-C tests below waiting out their timeouts.
WITH_CTRL_C = [
    sys.executable,
    "-c",
    "import os, signal, sys; signal.signal(signal.SIGINT, signal.SIG_DFL); "
    "os.execv(sys.argv[1], sys.argv[1:])",
]
X0 = np.array([0.1, -0.1, 0.0, 0.0])
#: Calls of M before a hostile function turns: about 0.06 s into the run.
TURN = 100


def _plant(mass_fn) -> CallablePlant:
    return CallablePlant(2, mass_fn, arm_nonlinear)


def _turning(value_or_error):
    """``M(q)`` of the arm for the first ``TURN`` calls, then ``value_or_error`` (returned, or
    raised when it is an exception, or called when it is a function)."""
    calls = [0]

    def mass(q):
        calls[0] += 1
        if calls[0] <= TURN:
            return arm_mass(q)
        if isinstance(value_or_error, BaseException):
            raise value_or_error
        if callable(value_or_error):
            return value_or_error(q)
        return value_or_error

    return mass


def _arolc() -> AROLC:
    gains = {"K1": np.diag([2.0, 3.0]), "K2": np.array([1.0, 2.0]), "Q": np.eye(4)}
    return AROLC(TwoLinkArm(), **gains, alpha=2.0, epsilon=0.1, gamma=0.001)


def _arm_reference() -> SinusoidalReference:
    return SinusoidalReference([0.0, 0.0], amplitude=[0.3, 0.2], frequency=[0.5, 0.7])


def _run(plant, reference=None, t1: float = 0.2) -> SimResult:
    controller = _arolc()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PythonFallbackWarning)
        return simulate(
            plant,
            controller,
            ConstantDelay(0.01),
            X0,
            reference=reference or _arm_reference(),
            t1=t1,
            dt=0.001,
            T_c=0.002,
        )


def _recurse(q):
    return _recurse(q)


# ---- a plant of Python functions: what it raises, named --------------------------------------


@pytest.mark.parametrize(
    ("fault", "told"),
    [
        (SystemExit(0), "raised SystemExit(0) at t = "),
        (_recurse, "raised RecursionError at t = "),
        (ZeroDivisionError("float division by zero"), "raised ZeroDivisionError at t = "),
        (ValueError("lost the encoder"), "raised ValueError at t = "),
    ],
)
def test_a_python_plant_that_raises_mid_run_is_named(fault, told):
    with pytest.raises(UserFunctionError) as refused:
        _run(_plant(_turning(fault)))
    message = str(refused.value)
    assert "\n" not in message and len(message) < 400, message
    assert "your mass_matrix_fn test_hostile_runs:_turning.<locals>.mass" in message, message
    assert told in message, message
    t = float(message.split("at t = ")[1].split(" s")[0])
    assert 0.0 < t < 0.2  # partway, as it turned


def test_ctrl_c_in_a_python_plant_stays_an_interruption():
    with pytest.raises(KeyboardInterrupt):
        _run(_plant(_turning(KeyboardInterrupt())))


@pytest.mark.parametrize(
    ("value", "told"),
    [
        (None, "must return real numbers of shape (2, 2); got None at t = "),
        (1.0, "must return shape (2, 2); got () at t = "),
        (np.eye(3), "must return shape (2, 2); got (3, 3) at t = "),
        ("M", "must return real numbers of shape (2, 2); got 'M' at t = "),
        (np.eye(2) * (1 + 1j), "must return real numbers of shape (2, 2); got an array of complex"),
        ([[1.0, 0.0], [0.0]], "must return real numbers of shape (2, 2); got a list at t = "),
    ],
)
def test_a_python_plant_returning_the_wrong_value_mid_run_is_refused(value, told):
    """Refused as at construction (None was NaN, a status 'diverged'; 1.0 was spread over M)."""
    with pytest.raises(UserFunctionError, match="your mass_matrix_fn") as refused:
        _run(_plant(_turning(value)))
    assert told in str(refused.value), str(refused.value)


def test_values_taken_at_construction_are_taken_mid_run_with_the_same_result():
    as_floats = _run(_plant(arm_mass), t1=0.1)
    as_lists = _run(_plant(_turning(lambda q: arm_mass(q).tolist())), t1=0.1)
    assert as_lists.status_names == as_floats.status_names == ["ok"]
    np.testing.assert_array_equal(as_lists.x, as_floats.x)
    integers = _run(_plant(_turning(lambda q: np.eye(2, dtype=int))), t1=0.1)
    identity = _run(_plant(_turning(lambda q: np.eye(2))), t1=0.1)
    np.testing.assert_array_equal(integers.x, identity.x)


@settings(max_examples=60, deadline=None)
@given(
    value=st.one_of(
        st.none(),
        st.floats(),
        st.text(max_size=3),
        st.complex_numbers(allow_nan=False, allow_infinity=False),
        st.lists(st.floats(-10, 10), max_size=5),
        st.lists(st.lists(st.floats(-10, 10), min_size=1, max_size=3), max_size=3),
        st.lists(st.lists(st.integers(-5, 5), min_size=2, max_size=2), min_size=2, max_size=2),
    ),
    t=st.floats(0.0, 1e3),
)
def test_a_python_plant_takes_real_numbers_of_its_shape_and_refuses_the_rest(value, t):
    """Whatever the mass function returns during a run: M filled with it, exactly (real numbers
    of shape (2, 2)), or one line that names the function and the time."""
    plant = CallablePlant(2, _turning(value), lambda q, qd: np.zeros(2))
    terms = plant.terms_kernel
    mass, nonlinear, input_map = np.zeros((2, 2)), np.zeros(2), np.zeros((2, 2))
    for _ in range(TURN - 1):  # construction made the first call
        terms(0.0, np.zeros(2), np.zeros(2), plant.params, mass, nonlinear, input_map)
    array = np.asarray(value) if not isinstance(value, list) or _even(value) else None
    accepted = array is not None and array.dtype.kind in "iuf" and array.shape == (2, 2)
    try:
        terms(t, np.zeros(2), np.zeros(2), plant.params, mass, nonlinear, input_map)
    except UserFunctionError as error:
        message = str(error)
        assert not accepted, (value, message)
        assert "\n" not in message and "your mass_matrix_fn" in message, message
        assert f"at t = {t:.6g} s" in message, message
    else:
        assert accepted, value
        np.testing.assert_array_equal(mass, np.asarray(value, dtype=float))


def _even(rows: list) -> bool:
    """Whether nested lists have rows of one length (NumPy refuses the others)."""
    return all(not isinstance(row, list) for row in rows) or len({len(row) for row in rows}) == 1


def test_the_command_line_names_a_python_plant_that_exits_mid_run(tmp_path, capsys):
    (tmp_path / "hostile_plant.py").write_text(
        "import numpy as np\nimport delaytrack as dt\ncalls = [0]\n\n"
        "def make():\n"
        "    def mass(q):\n"
        "        calls[0] += 1\n"
        "        if calls[0] > 50:\n"
        "            raise SystemExit(0)\n"
        "        return np.eye(2)\n"
        "    return dt.CallablePlant(2, mass, lambda q, qdot: np.zeros(2))\n"
    )
    scenario = tmp_path / "exits.toml"
    plant = {"type": "python:hostile_plant.py:make"}
    scenario.write_text(dumps_toml({**base_dict(), "duration": 0.1, "plant": plant}))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PythonFallbackWarning)
        code = main(["simulate", str(scenario), "--out", str(tmp_path / "out"), "--quiet"])
    assert code == 2
    one_line_error(capsys, "your mass_matrix_fn hostile_plant:make.<locals>.mass", "SystemExit(0)")


class _PythonReference(Reference):
    """A reference of the user's with a Python kernel that raises after 0.05 s."""

    n = 2
    params = np.zeros(1)

    @property
    def reference_kernel(self):
        def reference(t, params, qd, qd_dot, qd_ddot):
            if t > 0.05:
                raise TypeError("unsupported operand")
            qd[:] = 0.0
            qd_dot[:] = 0.0
            qd_ddot[:] = 0.0

        return reference

    def to_spec(self):
        return {"type": "python-reference"}


def test_a_python_kernel_that_raises_mid_run_is_named_as_a_compiled_one_is():
    with pytest.raises(UserFunctionError) as refused:
        _run(_plant(arm_mass), reference=_PythonReference())
    message = str(refused.value)
    assert message.startswith("your kernel test_hostile_runs:_PythonReference."), message
    assert "raised TypeError at t = 0.052 s: unsupported operand" in message, message


# ---- a compiled delay kernel that raises -------------------------------------------------------


@numba.njit(cache=True)
def _exploding_delay(t, params):
    if t > 0.05:
        raise ValueError("delay exploded")
    return params[0]


def test_a_compiled_delay_kernel_that_raises_is_named():
    """Its ValueError was taken for a refusal of the simulator's and shown bare."""
    delay = CompiledDelay(_exploding_delay, [0.01], h_max=0.05)
    arm, reference = TwoLinkArm(), _arm_reference()
    with pytest.raises(ValueError) as refused:
        simulate(arm, _arolc(), delay, X0, reference=reference, t1=0.1, dt=0.001, T_c=0.002)
    message = str(refused.value)
    assert message.startswith("your kernel test_hostile_runs:_exploding_delay raised ValueError")
    assert message.endswith("delay exploded") and "\n" not in message


# ---- Ctrl-C during a compiled run ------------------------------------------------------------


def test_ctrl_c_interrupts_the_wait_for_work_that_never_returns():
    code = (
        "import os, signal, threading\n"
        "from delaytrack.sim.interruptible import run_interruptibly, work_left_running\n"
        "threading.Timer(0.5, os.kill, (os.getpid(), signal.SIGINT)).start()\n"
        "try:\n"
        "    run_interruptibly(threading.Event().wait, size=10**9)\n"
        "except KeyboardInterrupt:\n"
        "    print('interrupted', work_left_running(), flush=True)\n"
        "os._exit(0)\n"
    )
    done = subprocess.run(
        [*WITH_CTRL_C, sys.executable, "-c", code], capture_output=True, text=True, timeout=60
    )
    assert done.stdout == "interrupted True\n", done.stderr


def test_short_work_runs_here_unless_every_run_must_be_interruptible():
    assert run_interruptibly(threading.current_thread, size=10) is threading.main_thread()
    with every_run_interruptible():
        assert run_interruptibly(threading.current_thread, size=10) is not threading.main_thread()
    with pytest.raises(ZeroDivisionError):  # what the work raises, raised here
        run_interruptibly(lambda: 1 / 0, size=math.inf)
    assert not work_left_running()


def test_ctrl_c_ends_a_long_compiled_run_on_the_command_line(tmp_path):
    """1e8 steps of the arm: minutes of computing; Ctrl-C ends it at once, in one line."""
    scenario = tmp_path / "long.toml"
    long = {"duration": 1e5, "record_every": 10**5, "delay": {"type": "constant", "h": 0.01}}
    scenario.write_text(dumps_toml({**base_dict(), **long}))
    with subprocess.Popen(
        [*WITH_CTRL_C, DELAYTRACK, "simulate", str(scenario), "--out", str(tmp_path / "out")],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    ) as process:
        try:
            seen = ""
            while "simulate:" not in seen:  # the progress bar: compiled, the run under way
                character = process.stderr.read(1)
                assert character, seen
                seen += character
            time.sleep(1.0)
            process.send_signal(signal.SIGINT)
            start = time.perf_counter()
            code = process.wait(timeout=60)
            assert time.perf_counter() - start < 30
            rest = process.stderr.read()
        finally:
            process.kill()
    assert code == 130
    assert rest.rstrip().split("\n")[-1] == "interrupted" and "Traceback" not in rest, rest


# ---- many coordinates; a closed pipe ---------------------------------------------------------


def test_a_summary_of_many_coordinates_warns_of_nothing():
    n, batch = 400, 2
    result = SimResult(
        t=np.zeros(1),
        x=np.zeros((batch, 1, 2 * n)),
        reference=np.zeros((1, 3, n)),
        commands=np.zeros((batch, 1, n)),
        applied=np.zeros((batch, 1, n)),
        h=np.zeros((batch, 1)),
        controller_state=np.zeros((batch, 1, 0)),
        controller_state_names=(),
        status=np.zeros(batch, dtype=np.int64),
        t_stop=np.zeros(batch),
        metrics={"ae": np.ones((batch, n)), "tv": np.ones(batch)},
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # pandas: "DataFrame is highly fragmented", per column
        summary = result.summary()
    assert summary.shape == (batch, n + 3)
    assert list(summary.columns[:3]) == ["status", "t_stop (s)", "AE q1"]


def test_a_reader_that_closes_the_pipe_ends_the_command_quietly():
    """``delaytrack ... | head -1``: no 'error: [Errno 32] Broken pipe', 128 + SIGPIPE."""
    with subprocess.Popen(
        [DELAYTRACK, "bound", "--k1", "2", "--k2", "1"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    ) as process:
        process.stdout.close()  # before the command writes anything
        rest = process.stderr.read()
        assert process.wait(timeout=120) == EXIT_BROKEN_PIPE == 141
    assert rest == ""
