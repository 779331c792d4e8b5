"""SimResult for a user at a notebook: plot(), a compact repr, an HTML summary, units."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from matplotlib.figure import Figure

from delaytrack.controllers import AROLC, OuterLoop
from delaytrack.delays import AbsSineDelay
from delaytrack.plants import CallablePlant, LinearPlant, TwoLinkArm
from delaytrack.references import SinusoidalReference
from delaytrack.report import commands_figure, error_figure, tracking_figure
from delaytrack.report.figures import write_run_figures
from delaytrack.sim import simulate

REFERENCE = SinusoidalReference([0.0, 0.0], amplitude=[0.8, 0.5], frequency=[0.5, 0.7])


@pytest.fixture(scope="module")
def arm_result():
    return arm_run([1.0, 2.0], t1=2.0)


def arm_run(gains, **options):
    """The two-link arm under AROLC with ``K1 = K2 = k`` for each ``k`` of ``gains``, and S1."""
    arm = TwoLinkArm()
    controllers = [
        AROLC(arm, K1=k, K2=k, Q=1.0, alpha=2.0, epsilon=0.1, gamma=0.001) for k in gains
    ]
    settings = dict(reference=REFERENCE, dt=0.001, T_c=0.01) | options
    return simulate(arm, controllers, AbsSineDelay.S1(), np.zeros(4), **settings)


def test_plot_labels_every_axis_with_names_and_units(arm_result):
    figure = arm_result.plot(1)
    assert isinstance(figure, Figure)
    labels = [ax.get_ylabel() for ax in figure.axes]
    assert labels[:4] == ["q1 (rad)", "e1 of q1 (rad)", "q2 (rad)", "e1 of q2 (rad)"]
    assert "inputs (N·m)" in labels and "h(t) (ms)" in labels and "ĉ (dimensionless)" in labels
    assert figure.axes[-1].get_xlabel() == "t (s)"
    assert figure._suptitle.get_text() == "run 1 of 2: ok"
    # The lines are the run's data: the second panel is e1 of q1 of run 1.
    error = figure.axes[1].lines[0].get_ydata()
    np.testing.assert_array_equal(error, arm_result.e1[1, :, 0])
    with pytest.raises(ValueError, match=r"run must be 0 \.\. 1; got 2"):
        arm_result.plot(2)


def outer_loop_run(plant):
    """One second of a one-coordinate plant under the outer loop and S1."""
    return simulate(
        plant,
        OuterLoop(plant, K1=1.0, K2=1.0),
        AbsSineDelay.S1(),
        np.zeros(2),
        reference=SinusoidalReference([0.0], amplitude=[0.5], frequency=[0.5]),
        t1=1.0,
        dt=0.001,
        T_c=0.01,
    )


def test_a_user_plant_carries_its_names_and_units_into_the_figure():
    plant = CallablePlant(
        1,
        lambda q: np.eye(1),
        lambda q, qdot: np.zeros(1),
        coordinate_names=["angle"],
        coordinate_units=["rad"],
    )
    result = outer_loop_run(plant)
    assert result.coordinate_names == ("angle",) and result.coordinate_units == ("rad",)
    figure = result.plot()
    assert figure.axes[0].get_ylabel() == "angle (rad)"
    assert "AE angle (rad)" in result._repr_html_()
    # No units given: the labels say only the name, never a made-up unit.
    result = outer_loop_run(LinearPlant(np.eye(1)))
    assert result.plot().axes[0].get_ylabel() == "q1"


def test_the_run_figures_label_each_axis_with_the_plants_own_units_or_none():
    def labels(result):
        return (
            [ax.get_ylabel() for ax in tracking_figure(result).axes],
            [ax.get_ylabel() for ax in error_figure(result).axes],
            [ax.get_ylabel() for ax in commands_figure(result).axes],
        )

    plant = CallablePlant(
        1,
        lambda q: np.eye(1),
        lambda q, qdot: np.zeros(1),
        coordinate_names=["cart"],
        coordinate_units=["m"],
        input_units=["N"],
    )
    assert labels(outer_loop_run(plant)) == (["cart (m)"], ["|e1| of cart (m)"], ["u1 (N)"])
    assert list(outer_loop_run(plant).summary())[2:] == ["AE cart (m)", "TV (N)"]
    # Inputs named by the plant: the commands' panels (the overview's legend too).
    pushed = outer_loop_run(dataclasses.replace(plant, input_names=["push"]))
    assert [ax.get_ylabel() for ax in commands_figure(pushed).axes] == ["push (N)"]
    assert "push sent" in [t.get_text() for ax in pushed.plot().axes if ax.get_legend()
                           for t in ax.get_legend().get_texts()]  # fmt: skip
    # A plant that declares no units gets none, not radians and newton-metres.
    bare = labels(outer_loop_run(LinearPlant(np.eye(1))))
    assert bare == (["q1"], ["|e1| of q1"], ["u1"])
    assert list(outer_loop_run(LinearPlant(np.eye(1))).summary())[2:] == ["AE q1", "TV"]
    # A unit given by the caller labels every panel.
    result = outer_loop_run(LinearPlant(np.eye(1)))
    assert tracking_figure(result, unit="deg").axes[0].get_ylabel() == "q1 (deg)"


@pytest.mark.parametrize(
    "changes, message",
    [
        (dict(coordinate_names=["a", "b"]), r"coordinate_names must be a list of n = 1"),
        (dict(coordinate_names=["1a"]), r"coordinate_names must be a list of n = 1 different"),
        (dict(coordinate_units=[""]), r"coordinate_units must be a list of 1 unit strings"),
        (dict(input_units=["N", "N"]), r"input_units must be .* 1 unit strings, one per input"),
        (dict(input_names=["", "u"]), r"input_names must be a list of 1 different non-empty"),
        (dict(input_names=[" "]), r"input_names must be a list of 1 different non-empty names"),
        (dict(coordinate_units="rad"), r"coordinate_units must be a list .* got 'rad'"),
    ],
)
def test_bad_names_and_units_are_refused(changes, message):
    with pytest.raises(ValueError, match=message):
        CallablePlant(1, lambda q: np.eye(1), lambda q, qdot: np.zeros(1), **changes)


def test_repr_is_one_line_and_html_summarises_each_run(arm_result):
    text = repr(arm_result)
    assert "\n" not in text and len(text) < 400
    assert text.startswith("SimResult(runs=2, ok=2, t = 0 .. 2 s (201 records), n=2 (q1, q2)")
    assert "c_hat, has_previous_s, s_previous_0, s_previous_1" in text
    html = arm_result._repr_html_()
    assert html.count("<tr>") >= 3 and "AE q1 (rad)" in html and "TV (N·m)" in html
    ae = f"{arm_result.metrics['ae'][1, 0]:.4g}"
    assert ae in html


def test_a_metrics_only_result_cannot_be_plotted_and_says_why(arm_result):
    result = arm_run([1.0], t1=0.5, trajectories=False)
    assert arm_result.has_trajectories and "metrics only" in repr(result)
    with pytest.raises(ValueError, match="no recorded trajectories"):
        result.plot()


def test_a_figure_saved_in_two_formats_keeps_its_layout_engine(tmp_path):
    import numpy as np
    from matplotlib.figure import Figure

    from delaytrack.report.figures import save_figure

    figure = Figure(layout="constrained")
    axes = figure.subplots()
    figure.colorbar(axes.imshow(np.eye(3)))
    engine = figure.get_layout_engine()
    paths = save_figure(figure, tmp_path / "eye")
    assert [p.name for p in paths] == ["eye.png", "eye.svg"]
    assert all(p.stat().st_size > 0 for p in paths)
    assert figure.get_layout_engine() is engine  # laid out once for both, then given back


def test_a_legend_too_wide_for_the_layout_is_drawn_without_matplotlibs_warning(tmp_path):
    """A run named with thousands of characters, in a legend beside the axes: constrained layout
    gives up (warnings are errors in this suite; a title alone that wide is clipped without one)
    and the figure is drawn in matplotlib's default positions."""
    from delaytrack.report.figures import png_bytes, save_figure

    figure = Figure(layout="constrained")
    axes = figure.subplots()
    axes.plot([0.0, 1.0], label="x" * 5000)
    axes.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0))
    paths = save_figure(figure, tmp_path / "long")
    assert all(p.stat().st_size > 0 for p in paths)
    assert png_bytes(figure).startswith(b"\x89PNG")


def test_a_figure_saved_in_two_formats_is_laid_out_once(tmp_path, monkeypatch):
    import matplotlib
    from matplotlib.figure import Figure

    from delaytrack.report.figures import save_figure

    # a user's setting that would give a figure without a layout engine one
    monkeypatch.setitem(matplotlib.rcParams, "figure.constrained_layout.use", True)
    figure = Figure(layout="constrained")
    figure.subplots().plot([1.0, 2.0])
    drawn = []
    draw = figure.draw
    monkeypatch.setattr(figure, "draw", lambda renderer: drawn.append(1) or draw(renderer))
    save_figure(figure, tmp_path / "line")
    # the first format: a pass that lays the figure out, then the drawing; the second: only its
    # drawing (a figure with a layout engine is drawn once more before each format)
    assert len(drawn) == 3


def test_a_mistake_in_the_figures_arguments_is_raised_not_taken_for_a_figure_left_out(
    arm_result, tmp_path
):
    with pytest.raises(ValueError, match="expected 2 names; got 3"):
        write_run_figures(arm_result, tmp_path, coordinate_names=["a", "b", "c"])
