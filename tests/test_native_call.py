"""Calling a compiled function through its address: the engine compiled once per plant."""

from __future__ import annotations

import sys
from pathlib import Path

import numba
import numpy as np
import pytest
from numba.core.errors import TypingError

from delaytrack._compile.native_call import NativeFunction, call_native
from delaytrack.components import Kernel
from delaytrack.controllers import AROLC, OuterLoop
from delaytrack.delays import AbsSineDelay, CompiledDelay
from delaytrack.plants import LinearPlant, TwoLinkArm
from delaytrack.references import SinusoidalReference, SplineReference
from delaytrack.sim import simulate
from delaytrack.sim.engine import run_batch_compiled


@numba.njit
def add_to_first(values, amount):
    values[0] += amount


@numba.njit
def call_add(function, values, amount):
    call_native(function, (values, amount))


@numba.njit
def add_and_double(kernel, values, amount):
    values[0] += amount
    return 2.0 * values[0]


@numba.njit
def call_and_return(function, values, amount):
    return call_native(function, (values, amount))


VECTOR = numba.typeof(np.zeros(1))
#: The shipped example of a user's arm and controller.
USER_ARM = Path(__file__).resolve().parents[1] / "examples" / "user_arm"
#: An argument with no run-time data: a component's kernel, whose numba type names its code.
OPAQUE = Kernel.of(add_to_first).numba_type


def test_a_native_function_is_called_through_its_address() -> None:
    native = NativeFunction.of(add_to_first, (VECTOR, numba.float64))
    assert native.address != 0
    values = np.zeros(3)
    call_add(native, values, 2.5)
    call_add(native, values, 1.0)
    np.testing.assert_array_equal(values, [3.5, 0.0, 0.0])
    call_native(native, (values, 1.0))  # from Python: the function itself
    assert values[0] == 4.5


def test_a_native_function_called_with_other_types_is_refused_when_compiling() -> None:
    native = NativeFunction.of(add_to_first, (VECTOR, numba.float64))
    with pytest.raises(TypingError, match="compiled for"):
        call_add(native, np.zeros(3, dtype=np.int64), 1)


def test_a_bound_argument_is_filled_in_and_the_result_returned() -> None:
    native = NativeFunction.of(
        add_and_double, (OPAQUE, VECTOR, numba.float64), bound=(0,), returns=numba.float64
    )
    values = np.zeros(2)
    assert call_and_return(native, values, 1.5) == 3.0
    assert call_native(native, (values, 1.0)) == 5.0  # from Python: the function itself
    np.testing.assert_array_equal(values, [2.5, 0.0])
    # Its numba type names only what the caller passes: another kernel in the bound position
    # is the same type, so one caller serves both.
    other = Kernel.of(add_and_double).numba_type
    assert other != OPAQUE
    again = NativeFunction.of(
        add_and_double, (other, VECTOR, numba.float64), bound=(0,), returns=numba.float64
    )
    assert again.numba_type == native.numba_type and again.address != native.address


def test_binding_an_argument_with_data_or_a_wrong_result_type_is_refused() -> None:
    with pytest.raises(TypeError, match="may carry data"):
        NativeFunction.of(add_to_first, (VECTOR, numba.float64), bound=(0,))
    with pytest.raises(TypeError, match="may carry data"):  # a pointer's null would be passed
        NativeFunction.of(add_to_first, (numba.types.voidptr, numba.float64), bound=(0,))
    with pytest.raises(ValueError, match="outside the 2 arguments"):
        NativeFunction.of(add_to_first, (VECTOR, numba.float64), bound=(2,))
    with pytest.raises(TypeError, match="returns float64, not none"):
        NativeFunction.of(add_and_double, (OPAQUE, VECTOR, numba.float64), bound=(0,))


def test_an_object_mode_function_is_refused() -> None:
    @numba.jit(forceobj=True)
    def in_object_mode(values, amount):
        values[0] += amount

    with pytest.raises(TypeError, match="object mode"):
        NativeFunction.of(in_object_mode, (VECTOR, numba.float64))


def test_another_controller_on_the_same_plant_reuses_the_compiled_engine() -> None:
    # The engine calls this package's controller steps through their address: a second
    # controller type compiles its step alone, never the engine again.
    arm = TwoLinkArm()
    reference = SinusoidalReference([0.0, 0.0], amplitude=[[0.8], [0.5]], frequency=[[1.0], [1.7]])
    settings = dict(reference=reference, t1=0.1, dt=1e-3, T_c=1e-2, trajectories=False)
    arolc = AROLC(TwoLinkArm(), K1=1.0, K2=1.0, Q=1.0, alpha=2.0, epsilon=0.1, gamma=1e-3)
    simulate(arm, arolc, AbsSineDelay.S1(), np.zeros(4), **settings)
    engines = len(run_batch_compiled.overloads)
    outer = simulate(
        arm, OuterLoop(TwoLinkArm(), 1.0, 1.0), AbsSineDelay.S1(), np.zeros(4), **settings
    )
    assert len(run_batch_compiled.overloads) == engines
    assert outer.status.tolist() == [0]


def test_another_plant_and_reference_reuse_the_compiled_engine() -> None:
    # The plant's integrator and the reference are called through their address too: a new
    # plant or reference compiles its own part, never the engine again.
    settings = dict(t1=0.1, dt=1e-3, T_c=1e-2, trajectories=False)
    arm_reference = SinusoidalReference(
        [0.0, 0.0], amplitude=[[0.8], [0.5]], frequency=[[1.0], [1.7]]
    )
    arolc = AROLC(TwoLinkArm(), K1=1.0, K2=1.0, Q=1.0, alpha=2.0, epsilon=0.1, gamma=1e-3)
    simulate(
        TwoLinkArm(), arolc, AbsSineDelay.S1(), np.zeros(4), reference=arm_reference, **settings
    )
    engines = len(run_batch_compiled.overloads)
    times = np.linspace(0.0, 1.0, 5)
    spline = SplineReference(times, np.sin(times)[:, None])
    line = LinearPlant(1.0, 0.5, 2.0)
    linear = simulate(
        line,
        OuterLoop(LinearPlant(1.0), 1.0, 1.0),
        AbsSineDelay.S1(),
        np.zeros(2),
        reference=spline,
        **settings,
    )
    assert len(run_batch_compiled.overloads) == engines
    assert linear.status.tolist() == [0]


@numba.njit
def slow_rise(t, params):
    return params[0] + 0.01 * np.tanh(t)


def test_controllers_and_delay_kernels_of_the_users_reuse_the_compiled_engine() -> None:
    # A user's step and delay kernel are compiled into parts of their own, keyed by their code;
    # the engine has one variant for the user's steps, whatever the step, model, plant or delay.
    sys.path.insert(0, str(USER_ARM))
    try:
        from pd_gravity import PDGravity
    finally:
        sys.path.remove(str(USER_ARM))
    settings = dict(t1=0.1, dt=1e-3, T_c=1e-2, trajectories=False)
    line = LinearPlant(1.0, 0.5, 2.0)
    simulate(
        line,
        PDGravity(LinearPlant(1.0), 2.0, 1.0),
        AbsSineDelay.S1(),
        np.zeros(2),
        reference=SinusoidalReference([0.0], amplitude=[[0.5]], frequency=[[1.0]]),
        **settings,
    )
    engines = len(run_batch_compiled.overloads)
    arm_reference = SinusoidalReference(
        [0.0, 0.0], amplitude=[[0.8], [0.5]], frequency=[[1.0], [1.7]]
    )
    own = simulate(
        TwoLinkArm(),
        PDGravity(TwoLinkArm(), 2.0, 1.0),
        CompiledDelay(slow_rise, [0.02], h_max=0.05, name="slow rise"),
        np.zeros(4),
        reference=arm_reference,
        **settings,
    )
    assert len(run_batch_compiled.overloads) == engines
    assert own.status.tolist() == [0]
