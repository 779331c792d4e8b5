"""A short first run of a combination not compiled yet runs as plain Python, while that costs
less than compiling it (:mod:`delaytrack._compile.interpret_first`); the rest of the suite
compiles at once (``DELAYTRACK_INTERPRET_FIRST=0``, set in ``conftest.py``)."""

from __future__ import annotations

import uuid
from types import SimpleNamespace

import numpy as np
import pytest

import delaytrack as dt
from delaytrack._compile import interpret_first
from delaytrack._spec import module_from_file

#: A pendulum of the user's, ``m l² q̈ + m g l sin q + c q̇ + a exp(b q̇²) = u``; ``a = b = 0``
#: for a good plant, ``a = 1, b = 10⁵`` for one whose ``exp`` overflows once ``|q̇| > 0.084``:
#: compiled that is ``inf``, and the run diverges; as Python ``math.exp`` raises OverflowError.
_PENDULUM = """
import math
import numba


@numba.njit
def pendulum_terms(t, q, qdot, params, M, N, G):
    M[0, 0] = params[0] * params[1] ** 2 + 0.0 * {token}
    N[0] = (
        params[0] * 9.81 * params[1] * math.sin(q[0])
        + params[2] * qdot[0]
        + params[3] * math.exp(params[4] * qdot[0] * qdot[0])
    )
    G[0, 0] = 1.0
"""


@pytest.fixture
def interpreting(monkeypatch):
    """Interpreting first turned on, with no time spent on any combination yet."""
    monkeypatch.delenv(interpret_first.ENVIRONMENT, raising=False)
    monkeypatch.setattr(interpret_first, "_SPENT", {})


def _pendulum(tmp_path, overflow: bool = False) -> tuple:
    """A new pendulum (new code: nothing compiled) under AROLC on a model of itself."""
    token = uuid.uuid4().int % 10**12
    path = tmp_path / f"pendulum_{token}.py"
    path.write_text(_PENDULUM.format(token=token))
    terms = module_from_file(path).pendulum_terms
    truth = dt.CompiledPlant(1, 1, terms, [1.2, 0.5, 0.4, *((1.0, 1e5) if overflow else (0, 0))])
    model = dt.CompiledPlant(1, 1, terms, [0.9, 0.5, 0.0, 0.0, 0.0])
    controller = dt.AROLC(model, K1=1.0, K2=1.0, Q=1.0, alpha=2.0, epsilon=0.1, gamma=0.001)
    return truth, controller


def _run(truth, controller, t1: float = 0.2, **options) -> dt.SimResult:
    reference = dt.SinusoidalReference(offset=[0.3], amplitude=[0.5], frequency=[1.0])
    return dt.simulate(
        truth,
        controller,
        dt.AbsSineDelay(0.01, 0.005, 1.0),
        np.zeros(2),
        reference=reference,
        t1=t1,
        dt=1e-3,
        T_c=2e-3,
        **options,
    )


def test_a_short_first_run_is_interpreted_says_so_and_gives_the_python_engines_numbers(
    interpreting, tmp_path, capsys
):
    truth, controller = _pendulum(tmp_path)
    first = _run(truth, controller)
    notice = capsys.readouterr().err
    assert "not compiled yet: running as plain Python (200 plant steps" in notice
    assert "delaytrack: compiling" not in notice
    assert first.settings["compiled"] is False
    python = _run(truth, controller, engine="python")
    for name in ("x", "commands", "applied", "h", "controller_state"):
        np.testing.assert_array_equal(getattr(first, name), getattr(python, name), err_msg=name)
    again = _run(truth, controller)  # still cheaper than compiling: interpreted, said once
    assert again.settings["compiled"] is False and capsys.readouterr().err == ""


def test_the_environment_and_compile_ahead_compile_at_once(interpreting, monkeypatch):
    """With ``DELAYTRACK_INTERPRET_FIRST=0``, or inside ``compile_ahead`` (compiling asked for),
    a run that would be interpreted is compiled; the kernels' guards run either way."""
    guarded = []
    monkeypatch.setattr(interpret_first, "refuse_changed_kernels", guarded.append)
    monkeypatch.setattr(interpret_first, "compile_cost", lambda build, chunk: ("c", 10.0))
    plan = SimpleNamespace(batch=2, n_ticks=50, steps_per_tick=2)
    build = SimpleNamespace(plan=plan)
    assert interpret_first.interpret(build, None) == interpret_first.Interpreting("c", 200)
    monkeypatch.setattr(interpret_first, "parts_ahead", lambda: (("a step", None),))
    assert interpret_first.interpret(build, None) is None
    monkeypatch.undo()
    monkeypatch.setattr(interpret_first, "refuse_changed_kernels", guarded.append)
    monkeypatch.setattr(interpret_first, "compile_cost", lambda build, chunk: ("c", 10.0))
    monkeypatch.setattr(interpret_first, "_SPENT", {})
    monkeypatch.setenv(interpret_first.ENVIRONMENT, "0")
    assert interpret_first.interpret(build, None) is None
    assert guarded == [build] * 3


def test_an_interpreted_run_that_raises_is_run_compiled_and_gives_its_outcome(
    interpreting, tmp_path, capsys
):
    """Python raises where compiled code gives ``inf`` (an overflow): the run is computed again
    compiled, whose outcome (here the run diverging) is the result."""
    truth, controller = _pendulum(tmp_path, overflow=True)
    result = _run(truth, controller)
    assert "delaytrack: compiling" in capsys.readouterr().err
    assert result.settings["compiled"] is True
    assert result.status_names == ["diverged"]


def test_the_rule_interprets_until_the_time_spent_would_pass_the_compile(
    interpreting, monkeypatch, capsys
):
    monkeypatch.setattr(interpret_first, "available_cores", lambda: 2)
    choose, per_step = interpret_first.choose, interpret_first.SECONDS_PER_STEP
    # Nothing to compile: compiled. A run estimated beyond half the compile (two cores): compiled.
    assert choose("a", 1000, 0.0) is None
    assert choose("a", int(6.0 / per_step), 10.0) is None
    assert capsys.readouterr().err == ""
    first = choose("a", int(2.0 / per_step), 10.0)
    assert first is not None and "not compiled yet" in capsys.readouterr().err
    first.done(3.0)  # it took 3 s: its pace is now 1.5 times the guess
    second = choose("a", int(1.0 / per_step), 10.0)  # 3 s spent + 1.5 s estimated <= 5 s
    assert second is not None and capsys.readouterr().err == ""
    second.done(1.5)
    assert choose("a", int(0.5 / per_step), 10.0) is None  # 4.5 + 0.75 > 5: compile now
    assert choose("b", int(0.5 / per_step), 10.0) is not None  # another combination: its own
