"""Large problems: figures stay bounded for many coordinates, dense linear algebra beyond its
bound is refused before anything of its size is computed, and a sweep solves each distinct
controller's Lyapunov equation once.

The numbers behind each bound are measured, not asserted: the tests check structure (panels
drawn, solvers never called, solves counted), never time.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
import scipy.linalg
from hypothesis import given, settings
from hypothesis import strategies as st

from delaytrack.analysis import (
    MAX_COUPLED_JOINTS,
    MAX_JOINTS,
    MAX_SCANNED_JOINTS,
    exact_delay_margin,
    lyapunov_matrix,
    razumikhin,
    razumikhin_bound,
)
from delaytrack.controllers import AROLC
from delaytrack.plants import LinearPlant
from delaytrack.plants.linear import MAX_COORDINATES
from delaytrack.report.figures import (
    MAX_PANELS,
    commands_figure,
    error_figure,
    overview_figure,
    tracking_figure,
)
from delaytrack.scenario import Scenario, ScenarioError
from delaytrack.sim.result import SimResult
from delaytrack.sweeps import SweepSpec

# ---- figures --------------------------------------------------------------------------------


def many_coordinates(n: int, records: int = 5) -> SimResult:
    """One run of ``n`` coordinates whose tracking error (and command) grows with the index
    modulo 7, so that the largest are known: coordinate j has |e1| = |u| = 1 + (j % 7) + j/1e6."""
    t = np.arange(records, dtype=float)
    size = 1.0 + np.arange(n) % 7 + np.arange(n) / 1e6
    reference = np.zeros((records, 3, n))
    x = np.zeros((1, records, 2 * n))
    x[0, :, :n] = -size  # e1 = q_d - q = size
    commands = np.broadcast_to(size, (1, records, n)).copy()
    return SimResult(
        t=t,
        x=x,
        reference=reference,
        commands=commands,
        applied=commands.copy(),
        h=np.full((1, records), 0.01),
        controller_state=np.zeros((1, records, 1)),
        controller_state_names=("c_hat",),
        status=np.array([0]),
        t_stop=np.array([t[-1]]),
    )


def largest(n: int) -> list[int]:
    """The coordinates ``many_coordinates(n)`` should draw, ascending."""
    size = 1.0 + np.arange(n) % 7 + np.arange(n) / 1e6
    return sorted(np.argsort(-size, kind="stable")[:MAX_PANELS].tolist())


def labels(figure) -> list[str]:
    return [ax.get_ylabel() for ax in figure.axes]


def test_a_figure_of_400_coordinates_draws_the_largest_errors_and_says_so():
    result = many_coordinates(400)
    shown = [f"|e1| of q{j + 1}" for j in largest(400)]
    for make in (tracking_figure, error_figure):
        figure = make(result)
        assert len(figure.axes) == MAX_PANELS
        text = figure.get_suptitle()
        assert f"{MAX_PANELS} of 400 coordinates shown" in text
        assert "all 400 are in the trajectories table" in text
    assert labels(error_figure(result)) == shown
    commands = commands_figure(result)
    assert len(commands.axes) == MAX_PANELS
    assert f"{MAX_PANELS} of 400 inputs shown" in commands.get_suptitle()


def test_the_overview_of_400_coordinates_is_bounded_too():
    figure = overview_figure(many_coordinates(400))
    # a q and an e1 panel per drawn coordinate, then inputs, delay and controller state
    assert len(figure.axes) == 2 * MAX_PANELS + 3
    inputs = [ax for ax in figure.axes if ax.get_ylabel() == "inputs"][0]
    assert len(inputs.get_lines()) == 2 * MAX_PANELS
    text = figure.get_suptitle()
    assert f"{MAX_PANELS} of 400 coordinates shown" in text
    assert f"{MAX_PANELS} of 400 inputs shown" in text


@settings(max_examples=25, deadline=None)
@given(n=st.integers(min_value=1, max_value=3 * MAX_PANELS), title=st.sampled_from([None, "T"]))
def test_panels_are_min_of_n_and_the_bound_and_the_title_says_how_many(n, title):
    figure = error_figure(many_coordinates(n), title=title)
    assert len(figure.axes) == min(n, MAX_PANELS)
    assert labels(figure) == [f"|e1| of q{j + 1}" for j in largest(n)]
    text = figure.get_suptitle()
    note = f"{MAX_PANELS} of {n} coordinates shown"
    assert (note in text) == (n > MAX_PANELS)
    if title:
        assert text.startswith(title)
    elif n <= MAX_PANELS:
        assert text == ""


# ---- dense linear algebra -------------------------------------------------------------------


@pytest.fixture
def no_dense_work(monkeypatch):
    """Fail a test that reaches a Lyapunov solver or an eigenvalue routine."""

    def refuse(*arguments, **keywords):
        raise AssertionError("a dense solver ran for a problem that should have been refused")

    monkeypatch.setattr(scipy.linalg, "solve_continuous_lyapunov", refuse)
    monkeypatch.setattr(np.linalg, "eigvalsh", refuse)
    monkeypatch.setattr(np.linalg, "eigvals", refuse)


def test_a_linear_plant_of_2000_coordinates_is_refused_before_any_matrix_is_checked(
    no_dense_work,
):
    with pytest.raises(ValueError, match=rf"^mass gives n = 2000 .* at most n = {MAX_COORDINATES}"):
        LinearPlant(mass=[1.0] * 2000)


def test_the_scenario_of_a_2000_coordinate_linear_plant_names_its_key(no_dense_work):
    n = 2000
    data = {
        "name": "big",
        "duration": 0.02,
        "dt": 0.001,
        "T_c": 0.002,
        "plant": {"type": "linear", "mass": [1.0] * n},
        "model": {"type": "linear", "mass": [1.0] * n},
        "controller": {
            "type": "arolc",
            "K1": 1.0,
            "K2": 1.0,
            "Q": 1.0,
            "alpha": 2.0,
            "epsilon": 0.1,
            "gamma": 0.001,
        },
        "delay": {"type": "constant", "h": 0.01},
        "reference": {"offset": [0.0] * n, "amplitude": [0.1] * n, "frequency": [0.5] * n},
    }
    with pytest.raises(ScenarioError, match=r"^scenario key 'plant.mass' gives n = 2000"):
        Scenario.from_dict(data).build()


@pytest.mark.parametrize(
    ("call", "pattern"),
    [
        (lambda: lyapunov_matrix(1.0, 1.0, 1.0, n=2000), rf"^n gives n = 2000 .*{MAX_JOINTS}"),
        (lambda: razumikhin_bound(1.0, 1.0, 1.0, n=2000), rf"^n gives n = 2000 .*{MAX_JOINTS}"),
        (lambda: exact_delay_margin(1.0, 1.0, n=2000), rf"^n gives n = 2000 .*{MAX_JOINTS}"),
        (
            lambda: lyapunov_matrix(1.0, 1.0, 1.0, n=MAX_COUPLED_JOINTS + 1),
            rf"^K1 is {MAX_COUPLED_JOINTS + 1}x.* GB .* at most n = {MAX_COUPLED_JOINTS} coupled",
        ),
    ],
)
def test_dense_analysis_beyond_its_bound_is_refused_before_any_solver(no_dense_work, call, pattern):
    with pytest.raises(ValueError, match=pattern):
        call()


def test_coupled_gains_beyond_the_bound_are_refused_before_the_lyapunov_solver(monkeypatch):
    def refuse(*arguments, **keywords):
        raise AssertionError("the Lyapunov solver ran")

    monkeypatch.setattr(scipy.linalg, "solve_continuous_lyapunov", refuse)
    n = MAX_COUPLED_JOINTS + 1
    K1 = np.full((n, n), 0.1) + np.eye(n)  # symmetric positive definite, coupled
    with pytest.raises(ValueError, match=r"couple the joints .* one dense"):
        razumikhin_bound(K1, 1.0, 1.0)


def test_a_scan_of_coupled_gains_beyond_its_bound_is_refused_before_any_eigenvalue(
    monkeypatch,
):
    def refuse(*arguments, **keywords):
        raise AssertionError("the scan ran")

    monkeypatch.setattr(np.linalg, "eigvals", refuse)
    n = MAX_SCANNED_JOINTS + 1
    K1 = np.full((n, n), 0.1) + np.eye(n)
    with pytest.raises(ValueError, match=rf"at most n = {MAX_SCANNED_JOINTS} coupled"):
        exact_delay_margin(K1, 1.0)


def test_arolc_beyond_the_coupled_bound_is_refused_before_its_weights_are_checked(request):
    model = LinearPlant(mass=np.ones(MAX_COUPLED_JOINTS + 1))
    request.getfixturevalue("no_dense_work")  # from here on
    with pytest.raises(ValueError, match=r"^K1 is .* for AROLC's P"):
        AROLC(model, 1.0, 1.0, 1.0, alpha=2.0, epsilon=0.1, gamma=0.001)


def test_diagonal_gains_are_still_solved_joint_by_joint_for_many_joints():
    assert razumikhin_bound(1.0, 1.0, 1.0, n=MAX_COUPLED_JOINTS + 1).h_m == pytest.approx(
        0.12487, abs=5e-6
    )


# ---- sweeps ---------------------------------------------------------------------------------


def test_a_sweep_solves_each_distinct_controllers_lyapunov_equation_once(monkeypatch):
    """40 runs over 2 gains: AROLC's P is solved for 2 gain pairs, not 40 times."""
    solved: list[int] = []
    original = scipy.linalg.solve_continuous_lyapunov

    def counting(a, q):
        solved.append(a.shape[0])
        return original(a, q)

    razumikhin._solved_lyapunov.cache_clear()
    monkeypatch.setattr(scipy.linalg, "solve_continuous_lyapunov", counting)
    spec = SweepSpec.from_dict(
        {
            "scenario": "two_link_S1",
            "unit_size": 10,
            "draws": 20,
            "seed": 3,
            "grid": {"controller.K1": [1.5, 2.5]},
            "random": {"plant.fd1": {"dist": "uniform", "low": 1.0, "high": 5.0}},
        }
    )
    assert len(spec.runs) == 40
    # one solve of P and one of its error bound per distinct (K1, K2, Q)
    assert len(solved) == 2 * 2
    again = lyapunov_matrix(1.5, 1.0, 1.0, n=2)
    again[0, 0] = -1.0  # a caller's copy: the remembered solution is not changed
    assert lyapunov_matrix(1.5, 1.0, 1.0, n=2)[0, 0] > 0
    assert re.fullmatch(r"[0-9a-f]{64}", spec.units()[0].hash)
