"""Hostile kernels of the user's end in a one-line error naming the kernel, or a documented status.

Each fault class of the campaign: entries of ``M, N, G`` left unwritten (results must not depend
on what a buffer held), a module global changed after numba compiled it in, a delay kernel that
raises or returns an array, a mass matrix that stops being positive definite, and reads past the
end of a parameter vector. One plant kernel, driven by its parameters, serves every plant case,
so that the tests compile it once.
"""

from __future__ import annotations

import re

import numba
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import delaytrack as dt

#: Read by :func:`switchable_terms` as a module global: numba compiles its value in.
DAMPING_SCALE = 1.0

#: ``switchable_terms``' parameters: ``M[0, 0] = a - b t``, damping, a mask per entry of ``M``
#: and of ``G`` (1: written, 0: never, 2: written only while ``t < 0.05``), and the index of a
#: parameter read when ``q[0] != 0`` (its own index: in range).
A, B, DAMPING, M_MASK, G_MASK, READ = 0, 1, 2, slice(3, 7), slice(7, 11), 11


@numba.njit
def switchable_terms(t, q, qdot, params, M, N, G):
    values = ((params[A] - params[B] * t, 0.2), (0.2, 1.0))
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


def parameters(m_mask=(1, 1, 1, 1), g_mask=(1, 1, 1, 1), a=2.0, b=0.0, read=READ) -> list:
    return [a, b, 0.5, *m_mask, *g_mask, read]


def plant(**changes) -> dt.CompiledPlant:
    return dt.CompiledPlant(2, 2, switchable_terms, parameters(**changes), name="switchable")


def run(truth: dt.ELPlant, delay: dt.DelayProfile | None = None, **changes) -> dt.SimResult:
    """A short run under the outer loop on a built-in model (compiled already)."""
    model = dt.LinearPlant(mass=np.diag([2.0, 1.0]))
    settings_ = {"reference": dt.SinusoidalReference([0.0, 0.0]), "t1": 0.2, **changes}
    return dt.simulate(
        truth,
        dt.OuterLoop(model, K1=4.0, K2=4.0),
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
            r"^your delay kernel test_hostile_kernels:faulty_delay reads beyond an array at t0 "
            r"\(index 500 is out of bounds for axis 0 with size 3\).*params 3",
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


@pytest.mark.parametrize("mass", [[[1.0, 2.0], [2.0, 1.0]], [[-1.0, 0.0], [0.0, -2.0]]])
def test_the_solve_tells_a_mass_matrix_that_is_not_positive_definite(mass):
    from delaytrack._small_linalg import solve_in_place

    matrix = np.array(mass)
    solution = np.array([1.0, 1.0])
    solved, definite = solve_in_place(matrix.copy(), solution)
    assert solved and not definite
    np.testing.assert_allclose(solution, np.linalg.solve(matrix, [1.0, 1.0]))
    spd = np.array([[1.0, 2.0], [2.0, 5.0]])  # a row exchange on a positive definite matrix
    assert solve_in_place(spd, np.ones(2)) == (True, True)


def test_a_mass_matrix_not_positive_definite_at_x0_is_refused_before_the_run():
    with pytest.raises(ValueError, match=r"the plant's M at x0 \(from your kernel .*switchable"):
        run(plant(a=1.0, b=10.0), t0=0.2, t1=0.4)


# ---- 5. reads past the end of an array -----------------------------------------------------------


def test_a_plant_kernel_reading_past_its_parameters_at_x0_is_refused():
    truth = plant(read=1000)  # read only where q[0] != 0: not at the construction's q = 0
    with pytest.raises(
        ValueError,
        match=r"your terms kernel .*switchable_terms reads beyond an array at x0 \(index 1000 "
        r"is out of bounds for axis 0 with size 12\).*params 12",
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
    with pytest.raises(ValueError, match=r"your reference kernel .*far_reference reads beyond"):
        run(dt.LinearPlant(mass=np.diag([2.0, 1.0])), reference=FarReference())
