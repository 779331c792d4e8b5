"""Hostile kernels of the user's end in a one-line error naming the kernel, or a documented status.

Each fault class of the campaign: entries of ``M, N, G`` left unwritten (results must not depend
on what a buffer held), a module global changed after numba compiled it in, a delay kernel that
raises or returns an array, a mass matrix that stops being symmetric positive definite, reads and
writes past the end of an array (a plant's, a reference's, a delay's or a controller step's
kernel), and kernels that draw random numbers. One plant kernel, driven by its parameters,
serves every plant case, so that the tests compile it once; the controller and random-number
cases are refused before anything is compiled.
"""

from __future__ import annotations

import random
import re
from dataclasses import dataclass
from typing import ClassVar

import numba
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import delaytrack as dt
from delaytrack._small_linalg import solve_in_place, solve_mass_in_place

#: Read by :func:`switchable_terms` as a module global: numba compiles its value in.
DAMPING_SCALE = 1.0

#: ``switchable_terms``' parameters: ``M[0, 0] = a - b t``, damping, a mask per entry of ``M``
#: and of ``G`` (1: written, 0: never, 2: written only while ``t < 0.05``), the index of a
#: parameter read when ``q[0] != 0`` (its own index: in range), and what is added to ``M[0, 1]``
#: (not to ``M[1, 0]``) after ``t = 0.1``.
A, B, DAMPING, M_MASK, G_MASK, READ, SKEW = 0, 1, 2, slice(3, 7), slice(7, 11), 11, 12


@numba.njit
def switchable_terms(t, q, qdot, params, M, N, G):
    skew = params[SKEW] if t > 0.1 else 0.0
    values = ((params[A] - params[B] * t, 0.2 + skew), (0.2, 1.0))
    for i in range(2):
        for j in range(2):
            mask = params[3 + 2 * i + j]
            if mask == 1.0 or (mask == 2.0 and t < 0.05):
                M[i, j] = values[i][j]
            mask = params[7 + 2 * i + j]
            if mask == 1.0 or (mask == 2.0 and t < 0.05):
                G[i, j] = 1.0 if i == j else 0.0
        N[i] = DAMPING_SCALE * params[DAMPING] * qdot[i]
    if q[0] != 0.0:
        N[0] += 0.0 * params[int(params[READ])]


def parameters(m_mask=(1, 1, 1, 1), g_mask=(1, 1, 1, 1), a=2.0, b=0.0, read=READ, skew=0.0) -> list:
    return [a, b, 0.5, *m_mask, *g_mask, read, skew]


def plant(**changes) -> dt.CompiledPlant:
    return dt.CompiledPlant(2, 2, switchable_terms, parameters(**changes), name="switchable")


def run(
    truth: dt.ELPlant,
    delay: dt.DelayProfile | None = None,
    controller: dt.Controller | None = None,
    **changes,
) -> dt.SimResult:
    """A short run under the outer loop on a built-in model (compiled already)."""
    model = dt.LinearPlant(mass=np.diag([2.0, 1.0]))
    settings_ = {"reference": dt.SinusoidalReference([0.0, 0.0]), "t1": 0.2, **changes}
    return dt.simulate(
        truth,
        controller or dt.OuterLoop(model, K1=4.0, K2=4.0),
        delay or dt.ConstantDelay(0.01),
        [0.1, -0.1, 0.0, 0.0],
        dt=1e-3,
        T_c=0.01,
        **settings_,
    )


def entries(label: str, mask) -> list[str]:
    return [f"{label}[{i // 2}, {i % 2}]" for i, value in enumerate(mask) if value == 0]


# ---- 1. entries left unwritten -------------------------------------------------------------------


def test_a_kernel_that_writes_only_the_diagonal_is_refused_naming_the_entries():
    with pytest.raises(ValueError) as refusal:
        plant(m_mask=(1, 0, 0, 1), g_mask=(1, 0, 0, 1))
    message = str(refusal.value)
    assert "test_hostile_kernels:switchable_terms does not write" in message
    for entry in ("M[0, 1]", "M[1, 0]", "G[0, 1]", "G[1, 0]"):
        assert entry in message
    assert "zeros included" in message and "\n" not in message
    assert "e-310" not in message  # no uninitialised memory shown


def test_an_unwritten_entry_of_a_large_plant_is_named_not_printed_as_memory():
    @numba.njit
    def diagonal_only(t, q, qdot, params, M, N, G):
        for i in range(M.shape[0]):
            M[i, i] = 1.0
            N[i] = 0.0
            G[i, 0] = 1.0

    with pytest.raises(ValueError, match=r"does not write M\[0, 1\], .* and \d+ more entries"):
        dt.CompiledPlant(400, 1, diagonal_only)


def test_results_do_not_depend_on_what_the_buffers_held():
    """The off-diagonal entries are written only while t < 0.05: afterwards they hold what the
    arrays held, the same in every run (they are zeroed where they are made)."""
    truth = plant(m_mask=(1, 2, 2, 1))
    first = run(truth)
    assert first.status_names == ["ok"]
    for other in range(5):
        run(plant(a=3.0 + other))  # other runs in between, leaving other numbers behind
        again = run(truth)
        np.testing.assert_array_equal(again.x, first.x)
    batch = run([truth, plant(a=3.0), truth])
    np.testing.assert_array_equal(batch.x[0], first.x[0])
    np.testing.assert_array_equal(batch.x[2], first.x[0])


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    m_mask=st.tuples(*[st.sampled_from([0, 1, 2])] * 4),
    g_mask=st.tuples(*[st.sampled_from([0, 1, 2])] * 4),
)
def test_unwritten_entries_are_refused_by_name_or_runs_repeat_bit_for_bit(m_mask, g_mask):
    unwritten = entries("M", m_mask) + entries("G", g_mask)
    if unwritten:
        with pytest.raises(ValueError) as refusal:
            plant(m_mask=m_mask, g_mask=g_mask)
        message = str(refusal.value)
        assert re.findall(r"[MG]\[\d, \d\]", message) == unwritten[:6]  # the first six named
        assert (f"and {len(unwritten) - 6} more entries" in message) == (len(unwritten) > 6)
        return
    truth = plant(m_mask=m_mask, g_mask=g_mask)
    first = run(truth)
    run(plant(a=5.0))
    np.testing.assert_array_equal(run(truth).x, first.x)


# ---- 2. a module global changed after the kernel was compiled ------------------------------------


def test_a_changed_module_global_is_refused_naming_kernel_and_global(monkeypatch):
    before = run(plant())
    assert before.status_names == ["ok"]
    monkeypatch.setattr(f"{__name__}.DAMPING_SCALE", 3.0)  # what a factory's keyword might do
    with pytest.raises(ValueError) as refusal:
        run(plant())
    message = str(refusal.value)
    assert "switchable_terms reads the module global DAMPING_SCALE" in message
    assert "parameter vector" in message and "\n" not in message
    monkeypatch.setattr(f"{__name__}.DAMPING_SCALE", 1.0)
    np.testing.assert_array_equal(run(plant()).x, before.x)  # the value it was compiled with


# ---- 3. a delay kernel that raises or returns an array -------------------------------------------


@numba.njit
def faulty_delay(t, params):
    if params[1] > 0.0:
        return params[0] / (t - t)  # numba's default error model: raises ZeroDivisionError
    return params[int(params[2])]


@numba.njit
def array_delay(t, params):
    return params * 1.0


@pytest.mark.parametrize(
    ("delay", "message"),
    [
        (
            dt.CompiledDelay(faulty_delay, [0.01, 1.0, 0.0], h_max=0.05),
            r"^your kernel test_hostile_kernels:faulty_delay raised ZeroDivisionError before "
            r"the run",
        ),
        (
            dt.CompiledDelay(array_delay, [0.01], h_max=0.05),
            r"^numba could not compile .* for your kernel test_hostile_kernels:array_delay: .*"
            r"returns array\(float64, 1d, C\); it must return a number",
        ),
        (
            dt.CompiledDelay(faulty_delay, [0.01, 0.0, 500.0], h_max=0.05),
            r"^your delay kernel test_hostile_kernels:faulty_delay reads or writes beyond an "
            r"array at t0 \(index 500 is out of bounds for axis 0 with size 3\).*params 3",
        ),
    ],
    ids=["divides by zero", "returns an array", "reads past its parameters"],
)
def test_a_faulty_delay_kernel_is_a_one_line_error_naming_it(delay, message):
    with pytest.raises(ValueError, match=message) as refusal:
        run(dt.LinearPlant(mass=np.diag([2.0, 1.0])), delay)
    assert "\n" not in str(refusal.value)


# ---- 4. a mass matrix that is not positive definite ----------------------------------------------


def test_a_mass_matrix_that_turns_indefinite_ends_the_run_with_its_status():
    # det M = 1.0433 - 10 t - 0.04 passes zero at t = 0.10033 s, between two RK4 stages (one
    # on the zero would give a huge acceleration instead: a divergence).
    result = run([plant(a=1.0433, b=10.0), plant()])
    assert result.status_names == ["mass matrix not positive definite", "ok"]
    assert 0.10033 < result.t_stop[0] <= 0.101
    assert np.isnan(result.metrics["ae"][0]).all()
    np.testing.assert_array_equal(result.x[1], run(plant()).x[0])  # the batch goes on
    python = run(plant(a=1.0433, b=10.0), engine="python")  # the reference path agrees
    assert python.status_names == [result.status_names[0]] and python.t_stop[0] == result.t_stop[0]


def test_a_mass_matrix_that_turns_non_symmetric_ends_the_run_with_its_status():
    result = run([plant(skew=0.3), plant()])  # M[0, 1] = 0.5, M[1, 0] = 0.2 after t = 0.1
    assert result.status_names == ["mass matrix not positive definite", "ok"]
    assert 0.1 < result.t_stop[0] <= 0.101


@pytest.mark.parametrize(
    "mass",
    [
        [[1.0, 2.0], [2.0, 1.0]],
        [[-1.0, 0.0], [0.0, -2.0]],
        [[1.0, 2.0, 2.0], [2.0, 1.0, 2.0], [2.0, 2.0, 1.0]],  # eigenvalues 5, -1, -1; det > 0
        [[1.0, 0.3, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],  # not symmetric
    ],
    ids=["indefinite", "negative definite", "indefinite 3x3, positive diagonal", "not symmetric"],
)
def test_the_solve_tells_a_mass_matrix_that_is_not_symmetric_positive_definite(mass):
    matrix = np.array(mass)
    solution = np.ones(len(matrix))
    solved, definite = solve_mass_in_place(matrix.copy(), solution)
    assert solved and not definite
    np.testing.assert_allclose(solution, np.linalg.solve(matrix, np.ones(len(matrix))))


def test_the_mass_solve_is_partial_pivoting_bit_for_bit_where_that_exchanges_no_rows():
    arm = dt.TwoLinkArm()
    for angle in np.linspace(-np.pi, np.pi, 25):  # the arm's M: a dominant diagonal
        mass = arm.mass_matrix(np.array([[0.3, angle]]))[0]
        pivoted, symmetric = np.array([0.7, -1.3]), np.array([0.7, -1.3])
        assert solve_in_place(mass.copy(), pivoted)
        assert solve_mass_in_place(mass.copy(), symmetric) == (True, True)
        np.testing.assert_array_equal(symmetric, pivoted)
    exchanged = np.array([[1.0, 2.0], [2.0, 5.0]])  # positive definite; pivoting exchanges rows
    assert solve_mass_in_place(exchanged, np.ones(2)) == (True, True)


@settings(max_examples=200, deadline=None)
@given(
    roots=st.lists(st.floats(-1.0, 1.0), min_size=9, max_size=9),
    eigenvalues=st.lists(st.floats(-2.0, 4.0), min_size=3, max_size=3),
    skew=st.sampled_from([0.0, 1e-6, 0.5]),
)
def test_the_mass_solve_is_definite_exactly_for_symmetric_positive_definite_matrices(
    roots, eigenvalues, skew
):
    basis, _ = np.linalg.qr(np.array(roots).reshape(3, 3) + 3.0 * np.eye(3))
    smallest = min(eigenvalues, key=abs)
    if abs(smallest) < 1e-3:  # rounding decides so close to singular
        return
    mass = basis @ np.diag(eigenvalues) @ basis.T
    mass = 0.5 * (mass + mass.T)
    mass[0, 2] += skew
    solution = np.array([1.0, -2.0, 0.5])
    solved, definite = solve_mass_in_place(mass.copy(), solution)
    assert definite == (skew == 0.0 and min(eigenvalues) > 0.0)
    if solved:
        expected = np.linalg.solve(mass, [1.0, -2.0, 0.5])
        np.testing.assert_allclose(solution, expected, rtol=1e-6, atol=1e-6 * abs(expected).max())


def test_a_mass_matrix_not_positive_definite_at_x0_is_refused_before_the_run():
    with pytest.raises(ValueError, match=r"the plant's M at x0 \(from your kernel .*switchable"):
        run(plant(a=1.0, b=10.0), t0=0.2, t1=0.4)


# ---- 5. reads past the end of an array -----------------------------------------------------------


def test_a_plant_kernel_reading_past_its_parameters_at_x0_is_refused():
    truth = plant(read=1000)  # read only where q[0] != 0: not at the construction's q = 0
    with pytest.raises(
        ValueError,
        match=r"your terms kernel .*switchable_terms reads or writes beyond an array at x0 "
        r"\(index 1000 is out of bounds for axis 0 with size 13\).*params 13",
    ):
        run(truth)


@numba.njit
def far_reference(t, params, qd, qd_dot, qd_ddot):
    for i in range(qd.shape[0]):
        qd[i] = params[500]
        qd_dot[i] = 0.0
        qd_ddot[i] = 0.0


class FarReference(dt.Reference):
    n = 2

    @property
    def params(self):
        return np.array([0.1])

    @property
    def reference_kernel(self):
        return far_reference

    def to_spec(self):
        return {"type": "far"}


def test_a_reference_kernel_reading_past_its_parameters_is_refused():
    with pytest.raises(
        ValueError, match=r"your reference kernel .*far_reference reads or writes beyond"
    ):
        run(dt.LinearPlant(mass=np.diag([2.0, 1.0])), reference=FarReference())


@numba.njit
def indexing_step(
    t, q, qdot, qd, qd_dot, qd_ddot, T_c, h, params, state, model, model_params, command, work
):
    for i in range(command.shape[0]):
        command[i] = 0.0 * params[int(params[0])]  # params = [read, written]
    state[int(params[1])] = t


@dataclass(frozen=True, eq=False)
class IndexingController(dt.Controller):
    """A step kernel that reads ``params[read]`` and writes ``state[written]`` (no state)."""

    model: dt.ELPlant
    read: int = 0
    written: int = 0
    type_name: ClassVar[str] = "indexing"

    @property
    def params(self):
        return np.array([self.read, self.written], dtype=float)

    @property
    def step_kernel(self):
        return indexing_step

    @property
    def state_names(self):
        return ()

    def initial_state(self):
        return np.zeros(0)

    def to_spec(self):
        return {"type": self.type_name}


@pytest.mark.parametrize(
    ("indices", "message"),
    [
        ({"read": 12}, r"index 12 is out of bounds for axis 0 with size 2\).*params 2, state 0"),
        ({"written": 50}, r"index 50 is out of bounds for axis 0 with size 0\).*params 2, state 0"),
    ],
    ids=["reads past its parameters", "writes past its state"],
)
def test_a_controller_step_kernel_indexing_past_its_arrays_is_refused(indices, message):
    """Compiled, the write past the (empty) state crashed the process now and then."""
    controller = IndexingController(dt.LinearPlant(mass=np.diag([2.0, 1.0])), **indices)
    with pytest.raises(ValueError) as refusal:
        run(dt.LinearPlant(mass=np.diag([2.0, 1.0])), controller=controller)
    text = str(refusal.value)
    assert re.match(
        r"your controller step kernel test_hostile_kernels:indexing_step reads or writes beyond "
        r"an array at its first tick \(",
        text,
    )
    assert re.search(message, text) and "\n" not in text


# ---- 6. kernels that draw random numbers ---------------------------------------------------------


@numba.njit
def random_delay(t, params):
    return params[0] + 0.01 * np.random.random()  # noqa: NPY002 - the fault under test


@numba.njit
def jitter(scale):
    return scale * random.gauss(0.0, 1.0)


@numba.njit
def helper_random_delay(t, params):
    return params[0] + abs(jitter(0.001))


@pytest.mark.parametrize(
    ("kernel", "source"),
    [(random_delay, "numpy.random"), (helper_random_delay, r"random \(in .*:jitter\)")],
    ids=["numpy.random", "random, in a helper"],
)
def test_a_kernel_that_draws_random_numbers_is_refused(kernel, source):
    name = kernel.py_func.__qualname__
    delay = dt.CompiledDelay(kernel, [0.02], h_max=0.05)
    with pytest.raises(ValueError) as refusal:
        run(dt.LinearPlant(mass=np.diag([2.0, 1.0])), delay)
    text = str(refusal.value)
    assert re.match(
        rf"your kernel test_hostile_kernels:{name} draws random numbers: it reads {source}", text
    )
    assert "seeded generator" in text and "parameter vector" in text and "\n" not in text


@numba.njit
def noisy_terms(t, q, qdot, params, M, N, G):
    M[0, 0] = 1.0
    N[0] = np.random.randn()  # noqa: NPY002 - the fault under test
    G[0, 0] = 1.0


def test_a_plant_kernel_that_draws_random_numbers_is_refused_as_such_when_made():
    """Not as one that "does not write N[0]": it writes it, with another number at each call,
    which the check of unwritten entries (two calls compared) would report."""
    with pytest.raises(ValueError) as refusal:
        dt.CompiledPlant(1, 1, noisy_terms, [0.0])
    assert re.match(
        r"your kernel test_hostile_kernels:noisy_terms draws random numbers: it reads "
        r"numpy.random",
        str(refusal.value),
    )
