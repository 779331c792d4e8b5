"""Working arrays on the stack of a compiled function, and the RK4 and controller-step memory
made of them."""

from __future__ import annotations

import numba
import numpy as np
import pytest
from numba.core.errors import TypingError

from delaytrack._compile.stack_arrays import MOST_STACK_ENTRIES, stack_matrix, stack_vector
from delaytrack.components import Kernel
from delaytrack.controllers.base import step_memory, step_workspace
from delaytrack.plants.robot.kinematics import robot_command_map
from delaytrack.plants.robot.nominal import robot_nominal_terms
from delaytrack.plants.robot.truth import robot_truth_terms
from delaytrack.sim.integrator import rk4_memory, rk4_workspace


@numba.njit
def _fill_and_read(offset):
    """Two stack arrays written through their indices, read back as copies on the heap."""
    matrix = stack_matrix(3, 4)
    vector = stack_vector(5)
    for i in range(3):
        for j in range(4):
            matrix[i, j] = offset + 10 * i + j
    for i in range(5):
        vector[i] = -offset - i
    return (
        matrix.copy(),
        vector.copy(),
        matrix.strides,
        matrix.flags.c_contiguous,
        matrix[1:].shape,
        matrix.ctypes.data != vector.ctypes.data,
    )


def test_stack_arrays_have_their_shape_strides_and_own_memory():
    matrix, vector, strides, contiguous, rows_after_first, distinct = _fill_and_read(7.0)
    np.testing.assert_array_equal(matrix, 7.0 + 10 * np.arange(3)[:, None] + np.arange(4))
    np.testing.assert_array_equal(vector, -7.0 - np.arange(5))
    assert strides == (4 * 8, 8)  # 4 columns of float64
    assert contiguous
    assert rows_after_first == (2, 4)
    assert distinct


@numba.njit
def _in_a_loop(count):
    """A stack array made inside a loop is one array of the frame, not one per iteration."""
    total = 0.0
    for k in range(count):
        values = stack_vector(2)
        values[0] = k
        values[1] = 1.0
        total += values[0] + values[1]
    return total


def test_a_stack_array_made_in_a_loop_does_not_grow_the_stack():
    count = 1_000_000  # 16 MB of stack if each iteration had its own array
    assert _in_a_loop(count) == pytest.approx(count * (count - 1) / 2 + count)


@numba.njit
def _zero_rows():
    return stack_matrix(0, 3).shape


@numba.njit
def _rows_not_constant(rows):
    return stack_matrix(rows, 3).shape


@pytest.mark.parametrize("function, arguments", [(_zero_rows, ()), (_rows_not_constant, (2,))])
def test_an_extent_that_is_not_a_positive_constant_is_refused_when_compiling(function, arguments):
    with pytest.raises(TypingError, match="positive compile-time constant"):
        function(*arguments)


@numba.njit
def _memory_addresses(terms, work):
    memory = rk4_memory(terms, work)
    mass, nonlinear, input_map = memory[4]
    return (
        memory[0].ctypes.data == work[0].ctypes.data,
        memory[1].ctypes.data == work[1].ctypes.data,
        mass.ctypes.data == work[4][0].ctypes.data,
        memory[5].ctypes.data == work[5].ctypes.data,  # the profile's memory lasts: shared
        memory[0].shape,
        mass.shape,
        input_map.shape,
        nonlinear.shape,
        memory[2].shape,
        memory[3].shape,
    )


def test_rk4_memory_is_on_the_stack_for_a_plant_of_known_sizes():
    n, m = 5, 2
    work = rk4_workspace(np.zeros(2 * n), m)
    same_slopes, same_stage, same_mass, same_profile, *shapes = _memory_addresses(
        Kernel(robot_truth_terms, identity_mass=True, sizes=(n, m)), work
    )
    assert (same_slopes, same_stage, same_mass, same_profile) == (False, False, False, True)
    assert shapes == [(4, 2 * n), (n, n), (n, m), (n,), (n,), (n,)]


@pytest.mark.parametrize("sizes", [None, (200, 2)], ids=["sizes unknown", "beyond the bound"])
def test_rk4_memory_is_the_workspace_without_sizes_or_beyond_the_bound(sizes):
    n, m = sizes or (5, 2)
    assert 200 * 200 > MOST_STACK_ENTRIES  # M (200, 200) alone passes the bound
    work = rk4_workspace(np.zeros(2 * n), m)
    same_slopes, same_stage, same_mass, same_profile, *_ = _memory_addresses(
        Kernel(robot_truth_terms, identity_mass=True, sizes=sizes), work
    )
    assert (same_slopes, same_stage, same_mass, same_profile) == (True, True, True, True)


@numba.njit
def _step_memory_of(terms, work):
    mass, nonlinear, input_map, rest = step_memory(terms, work)
    return (
        mass.ctypes.data == work[0].ctypes.data,
        rest.ctypes.data == work[3].ctypes.data,
        (mass.shape, nonlinear.shape, input_map.shape, rest.shape),
        # zeroed, whatever work holds
        mass.sum() + nonlinear.sum() + input_map.sum() + rest.sum(),
    )


def test_a_steps_memory_is_on_the_stack_and_zeroed_for_a_model_of_known_sizes():
    n, m = 5, 2
    work = tuple(np.full_like(array, np.nan) for array in step_workspace(n, m))
    kernel = Kernel(robot_nominal_terms, command_map=robot_command_map, sizes=(n, m))
    same_mass, same_rest, shapes, total = _step_memory_of(kernel, work)
    assert (same_mass, same_rest) == (False, False)
    assert shapes == ((n, n), (n,), (n, m), (4 * n,))
    assert total == 0.0
    # Without sizes (and from Python) it is work's own arrays.
    same_mass, same_rest, shapes, _ = _step_memory_of(
        Kernel(robot_nominal_terms, command_map=robot_command_map), work
    )
    assert (same_mass, same_rest, shapes) == (True, True, ((n, n), (n,), (n, m), (4 * n,)))
    assert step_memory(kernel, work) is work


def test_a_steps_memory_beyond_the_bound_is_the_workspace():
    n, m = 200, 2  # M (200, 200) alone passes the bound
    assert n * n > MOST_STACK_ENTRIES
    work = step_workspace(n, m)
    kernel = Kernel(robot_nominal_terms, command_map=robot_command_map, sizes=(n, m))
    same_mass, same_rest, _, _ = _step_memory_of(kernel, work)
    assert (same_mass, same_rest) == (True, True)
