"""A short first run of a combination not compiled yet runs as plain Python, while that costs
less than compiling it (:mod:`delaytrack._compile.interpret_first`). The suite runs so too,
except the modules of ``conftest.COMPILED``, whose subject is compiling."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import time
import uuid
from types import SimpleNamespace

import numba
import numpy as np
import pytest

import delaytrack as dt
from delaytrack._compile import interpret_first
from delaytrack._spec import module_from_file
from delaytrack.components import Kernel
from delaytrack.sim.fallback import OutOfTime, stepped_until

#: A pendulum of the user's, ``m l² q̈ + m g l sin q + c q̇ + a exp(b q̇²) = u``; ``a = b = 0``
#: for a good plant, ``a = 1, b = 10⁵`` for one whose ``exp`` overflows once ``|q̇| > 0.084``:
#: compiled that is ``inf``, and the run diverges; as Python ``math.exp`` raises OverflowError.
_PENDULUM = """
import math
import numba


@numba.njit({options})
def pendulum_terms(t, q, qdot, params, M, N, G):
    M[0, 0] = params[0] * params[1] ** 2 + 0.0 * {token}
    N[0] = (
        params[0] * 9.81 * params[1] * math.sin(q[0])
        + params[2] * qdot[0]
        + params[3] * math.exp(params[4] * qdot[0] * qdot[0])
    )
    G[0, 0] = 1.0
"""


def _new_terms(folder, options: str = "") -> object:
    """A new pendulum terms kernel (new code: nothing compiled for it yet)."""
    token = uuid.uuid4().int % 10**12
    path = folder / f"pendulum_{token}.py"
    path.write_text(_PENDULUM.format(token=token, options=options))
    return module_from_file(path).pendulum_terms


@pytest.fixture(scope="module")
def shared_terms(tmp_path_factory):
    """One new pendulum for the tests that compile it (compiled once for the module)."""
    return _new_terms(tmp_path_factory.mktemp("pendulum"))


@pytest.fixture
def interpreting(monkeypatch, tmp_path):
    """Interpreting first turned on, with no time spent on any combination yet (the records of
    time spent in ``tmp_path``)."""
    monkeypatch.delenv(interpret_first.INTERPRETING, raising=False)
    monkeypatch.setattr(interpret_first, "_SPENT", {})
    monkeypatch.setattr(interpret_first, "_record", lambda combination: tmp_path / combination)


def _loop(terms, overflow: bool = False) -> tuple:
    """The pendulum under AROLC on a model of itself."""
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


def _same_numbers(first: dt.SimResult, second: dt.SimResult) -> None:
    for name in ("x", "reference", "commands", "applied", "h", "controller_state", "t_stop"):
        np.testing.assert_array_equal(getattr(first, name), getattr(second, name), err_msg=name)
    assert first.metrics.keys() == second.metrics.keys()
    for name, values in first.metrics.items():
        np.testing.assert_array_equal(values, second.metrics[name], err_msg=name)


def test_a_short_first_run_is_interpreted_says_so_and_gives_the_python_engines_numbers(
    interpreting, tmp_path, capsys
):
    truth, controller = _loop(_new_terms(tmp_path))
    first = _run(truth, controller)
    notice = capsys.readouterr().err
    assert "is not ready: running it as plain Python (the same numbers)" in notice
    assert "delaytrack: compiling" not in notice
    assert first.settings["compiled"] is False
    _same_numbers(first, _run(truth, controller, engine="python"))
    again = _run(truth, controller)  # still cheaper than compiling: interpreted, said once
    assert again.settings["compiled"] is False and capsys.readouterr().err == ""
    (record,) = tmp_path.glob("[0-9a-f]" * 24)  # the time spent, for the next process
    assert float(record.read_text()) > 0.0


#: A first run of a new pendulum in a new process; prints the modules of the functions numba
#: compiled (the plant's start-up check compiles the user's kernel) and which engine ran.
_FIRST_RUN = """
import json, sys
from numba.core import event
compiled = []

class Compiles(event.Listener):
    def on_start(self, e):
        pass

    def on_end(self, e):
        compiled.append(e.data["dispatcher"].py_func.__module__)

event.register("numba:compile", Compiles())
import numpy as np
import delaytrack as dt
from delaytrack._spec import module_from_file
from pathlib import Path
terms = module_from_file(Path(sys.argv[1])).pendulum_terms
truth = dt.CompiledPlant(1, 1, terms, [1.2, 0.5, 0.4, 0.0, 0.0])
model = dt.CompiledPlant(1, 1, terms, [0.9, 0.5, 0.0, 0.0, 0.0])
if sys.argv[2] == "AROLC":  # with an |sin| delay, a sinusoid, noise and lost packets
    controller = dt.AROLC(model, K1=1.0, K2=1.0, Q=1.0, alpha=2.0, epsilon=0.1, gamma=0.001)
    delay = dt.AbsSineDelay(0.01, 0.005, 1.0)
    reference = dt.SinusoidalReference(offset=[0.3], amplitude=[0.5], frequency=[1.0])
    options = dict(measurement_noise=dt.MeasurementNoise(position=1e-4, quantization=1e-3,
                   seed=1), packet_loss=dt.PacketLoss(0.1, seed=2))
else:  # PCON with a piece-wise constant delay, a spline and input limits
    from delaytrack.controllers import PCON
    controller = PCON(model, kappa=2.0, vartheta=1.0, k_b=1.0, history=0.05, T_c=2e-3)
    delay = dt.PiecewiseConstantDelay([0.0, 0.1], [0.01, 0.02])
    times = np.linspace(0.0, 0.3, 7)
    reference = dt.SplineReference(times, 0.3 * np.sin(times)[:, None])
    options = dict(input_limits=[5.0])
result = dt.simulate(
    truth, controller, delay, np.zeros(2), reference=reference, t1=0.2, dt=1e-3, T_c=2e-3,
    progress=False, **options,
)
print(json.dumps({"compiled": compiled, "engine_compiled": result.settings["compiled"]}))
"""


@pytest.mark.parametrize("law", ["AROLC", "PCON"])
def test_a_first_run_interpreted_from_an_empty_cache_compiles_nothing_of_the_package(tmp_path, law):
    """Interpreted, every function of this package runs as plain Python, so numba compiles none
    of them (called compiled, a dozen small ones took about 2 s of a first result)."""
    _new_terms(tmp_path)
    (module,) = tmp_path.glob("pendulum_*.py")
    environment = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    environment.pop(interpret_first.INTERPRETING, None)
    environment["DELAYTRACK_COMPILE_HELPER"] = "0"
    done = subprocess.run(
        [sys.executable, "-c", _FIRST_RUN, str(module), law],
        env=environment,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    printed = json.loads(done.stdout.strip().splitlines()[-1])
    assert printed["engine_compiled"] is False
    assert [name for name in printed["compiled"] if name.startswith("delaytrack")] == []
    assert printed["compiled"]  # the user's kernel, checked at rest: the spy sees compiles


def _cheap_compile(monkeypatch, seconds: float, pace: float | None = None) -> None:
    """Make the compile look ``seconds`` long on one core (the run's real parts), and the pace
    of interpreting ``pace`` seconds a step."""
    real = interpret_first.compile_cost
    monkeypatch.setattr(
        interpret_first, "compile_cost", lambda build, chunk: (real(build, chunk)[0], seconds)
    )
    monkeypatch.setattr(interpret_first, "available_cores", lambda: 2)
    if pace is not None:
        spent = interpret_first._spent

        def slow_to_guess(combination):
            found = spent(combination)
            found.pace = pace
            return found

        monkeypatch.setattr(interpret_first, "_spent", slow_to_guess)


def test_a_run_that_outlasts_the_compile_is_abandoned_and_compiled(
    interpreting, shared_terms, monkeypatch, capsys
):
    """Guessed quick enough but slower than the compile (here made to look 0.1 s long, 0.05 s
    on two cores): interpreted until the compile's time is spent, then compiled."""
    _cheap_compile(monkeypatch, 0.1, pace=1e-9)
    truth, controller = _loop(shared_terms)
    result = _run(truth, controller, t1=2.0)
    err = capsys.readouterr().err
    assert "running it as plain Python" in err and "delaytrack: compiling" in err
    # the compile shows its progress: each part as it is done (here, or by the helper)
    done = re.findall(r"^delaytrack: compiled (.+) \(\d+\.\d s into the compile\)$", err, re.M)
    assert done, err
    assert result.settings["compiled"] is True
    (spent,) = interpret_first._SPENT.values()
    assert spent.seconds >= 0.05 and spent.pace == 1e-9  # the abandoned run sets no pace
    _same_numbers(result, _run(truth, controller, t1=2.0, engine="compiled"))


def test_an_interpreted_run_that_raises_is_run_compiled_and_gives_its_outcome(
    interpreting, shared_terms, monkeypatch
):
    """Python raises where compiled code gives ``inf`` (an overflow): the run is computed again
    compiled, whose outcome (here the run diverging) is the result."""
    _cheap_compile(monkeypatch, 20.0)  # interpreted, even if the module compiled it already
    truth, controller = _loop(shared_terms, overflow=True)
    result = _run(truth, controller)
    assert result.settings["compiled"] is True
    assert result.status_names == ["diverged"]


def _fake_build(steps: int, kernels: tuple = ()) -> SimpleNamespace:
    plan = SimpleNamespace(batch=1, n_ticks=steps, steps_per_tick=1)
    return SimpleNamespace(plan=plan, kernels=lambda b: kernels)


@pytest.fixture
def fake_compile(interpreting, monkeypatch):
    """``interpret`` on a fake build whose compile costs 10 s on one core (5 s on two)."""
    guarded = []
    monkeypatch.setattr(interpret_first, "refuse_changed_kernels", guarded.append)
    monkeypatch.setattr(interpret_first, "compile_cost", lambda build, chunk: ((), 10.0))
    monkeypatch.setattr(interpret_first, "_combination", lambda parts: "c")
    monkeypatch.setattr(interpret_first, "available_cores", lambda: 2)
    return guarded


def test_the_rule_interprets_within_the_compiles_time_over_runs_and_processes(
    fake_compile, monkeypatch, capsys
):
    per_step = interpret_first.SECONDS_PER_STEP
    interpret = interpret_first.interpret
    assert interpret(_fake_build(int(6.0 / per_step)), None) is None  # guessed past 5 s
    assert capsys.readouterr().err == "" and fake_compile == []
    first = interpret(_fake_build(int(2.0 / per_step)), None)
    assert first is not None and first.seconds == 5.0 and fake_compile
    assert "for up to about 5 s that compiling would take" in capsys.readouterr().err
    # 3.5 s, of which 0.5 s numba compiling the Python engine's helpers: the pace is 1.5 times
    # the guess
    first.done(3.5, 0.5, int(2.0 / per_step))
    second = interpret(_fake_build(int(1.0 / per_step)), None)  # 3.5 s spent + 1.5 s <= 5 s
    assert second is not None and second.seconds == 1.5 and capsys.readouterr().err == ""
    assert interpret(_fake_build(int(2.0 / per_step)), None) is None  # 3.5 + 3 > 5: compile
    # Another process reads the time spent from the record: 3.5 s, whatever its own guess; and
    # what two processes spend adds up.
    monkeypatch.setattr(interpret_first, "_SPENT", {})
    again = interpret(_fake_build(10), None)
    assert again is not None and again.seconds == 1.5
    assert "up to about 2 s more of the 5 s" in capsys.readouterr().err
    monkeypatch.setattr(interpret_first, "_SPENT", {})
    other = interpret(_fake_build(10), None)
    again.done(1.0, 0.0, None)  # abandoned, say
    other.done(1.0, 0.0, 10)
    monkeypatch.setattr(interpret_first, "_SPENT", {})
    assert interpret(_fake_build(1), None) is None  # 5.5 s spent: the budget is gone


def test_the_environment_compile_ahead_fastmath_and_arrays_compile_at_once(
    fake_compile, monkeypatch, tmp_path
):
    monkeypatch.setattr(interpret_first, "parts_ahead", lambda: (("a step", None),))
    assert interpret_first.interpret(_fake_build(10), None) is None
    monkeypatch.setattr(interpret_first, "parts_ahead", lambda: ())
    monkeypatch.setenv(interpret_first.INTERPRETING, "0")
    assert interpret_first.interpret(_fake_build(10), None) is None
    monkeypatch.setenv(interpret_first.INTERPRETING, "off")
    with pytest.raises(ValueError, match="DELAYTRACK_INTERPRET_FIRST is 'off'; it must be 0"):
        interpret_first.interpret(_fake_build(10), None)
    monkeypatch.setenv(interpret_first.INTERPRETING, "1")
    fast = Kernel(_new_terms(tmp_path, "fastmath=True"))
    assert interpret_first.interpret(_fake_build(10, (fast,)), None) is None
    # A kernel that returned an array where it was called (the compiled engine refuses it).
    terms = _new_terms(tmp_path)
    returning = numba.njit(lambda q: q * 2.0)
    returning(np.zeros(2))
    assert interpret_first.interpret(_fake_build(10, (Kernel(returning),)), None) is None
    plain = Kernel(terms)
    assert interpret_first.interpret(_fake_build(10, (plain,)), None) is not None


def test_a_deadline_stops_a_plant_step_and_a_controller_tick_not_a_run_before_it():
    calls = []
    kernel = Kernel(lambda *arguments: calls.append(arguments))
    later = stepped_until(kernel, time.perf_counter() + 60.0)
    later.function(1, 2)
    assert calls == [(1, 2)]
    past = stepped_until(kernel, time.perf_counter() - 1.0)
    with pytest.raises(OutOfTime):
        past.function(3)
    assert calls == [(1, 2)] and past.stepper is None and past.reduced is None


def test_durations_read_as_a_notice_says_them():
    seconds = (9e-5, 0.04, 0.4, 3.2, 119.4, 150.0)
    texts = [interpret_first.seconds_text(s) for s in seconds]
    assert texts == ["under 0.01 s", "0.04 s", "0.4 s", "3 s", "119 s", "2.5 min"]
