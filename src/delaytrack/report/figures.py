"""Figures of simulation results, as matplotlib :class:`~matplotlib.figure.Figure` objects.

No pyplot: figures are created directly (``Figure(...)``), so nothing here touches matplotlib's
global backend or opens a window, and it runs the same on a head-less machine and in tests.

Every plotting function takes *runs*: a mapping ``label -> SimResult`` where each result holds one
run (batch of one; select one with ``result[i]``), or a single result, which is then plotted for
every batch element with labels ``run 0, run 1, ...``.

A figure draws at most :data:`MAX_PANELS` coordinates (and inputs): with more, those with the
largest tracking error (largest command), in their order, and its title says how many of how
many it shows; every coordinate is in the result's table (:meth:`SimResult.to_frame`, the
results folder's ``trajectories.parquet``). Drawing time and file size so stay bounded
whatever the plant's size.
"""

from __future__ import annotations

import contextlib
import io
import traceback
import warnings
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from delaytrack.report.settings import import_matplotlib

matplotlib = import_matplotlib()  # first: no settings from the working folder (settings)

from matplotlib.figure import Figure  # noqa: E402

from delaytrack._io import atomic_path  # noqa: E402
from delaytrack._words import quantity_text  # noqa: E402
from delaytrack.units import default_names, labelled  # noqa: E402
from delaytrack.warning import DelaytrackWarning  # noqa: E402

if TYPE_CHECKING:
    from matplotlib.typing import HashableList

    from delaytrack.sim.result import SimResult

__all__ = [
    "MAX_PANELS",
    "FigureNotDrawnWarning",
    "c_hat_figure",
    "commands_figure",
    "delay_figure",
    "error_figure",
    "margins_figure",
    "overview_figure",
    "png_bytes",
    "save_figure",
    "tracking_figure",
    "write_run_figures",
]

_ROW_HEIGHT = 2.1
_WIDTH = 8.0
_DPI = 110

#: Most coordinates (or inputs) a figure draws, one panel each (one line each in the inputs
#: panel of :func:`overview_figure`). One panel per coordinate had drawn one of a simulation's
#: ten figure files of a plant of 400 coordinates after nine minutes of CPU; with twelve, all
#: ten take about five seconds.
MAX_PANELS = 12


def _runs(runs: Mapping[str, SimResult] | SimResult) -> dict[str, SimResult]:
    """Normalise to ``label -> single-run result``."""
    if isinstance(runs, Mapping):
        out = {}
        for label, result in runs.items():
            if result.batch_size != 1:
                raise ValueError(
                    f"run {label!r} has a batch of {result.batch_size}; pass one run per label "
                    "(select one with result[i])"
                )
            out[str(label)] = result
        return out
    if runs.batch_size == 1:
        return {"run": runs}
    return {f"run {i}": runs[i] for i in range(runs.batch_size)}


def _names(count: int, names: Sequence[str] | None, prefix: str) -> list[str]:
    if names is not None and len(names) != count:
        raise ValueError(f"expected {count} names; got {len(names)}: {list(names)}")
    return list(default_names(names, count, prefix))


def _units(count: int, declared: Sequence[str] | None, unit: str | None) -> list[str | None]:
    """The axis unit of each of ``count`` panels: ``unit`` for all when given, else the units
    the plant declared, else none."""
    if unit is not None:
        return [unit] * count
    return list(declared) if declared else [None] * count


def _largest(values: np.ndarray) -> np.ndarray:
    """Indices of the columns to draw, ascending: every column up to :data:`MAX_PANELS`, else
    the :data:`MAX_PANELS` whose largest magnitude (NaN left out: rows after a run stopped) is
    largest, the first on a tie. ``values`` has the columns on its last axis."""
    count = values.shape[-1]
    if count <= MAX_PANELS:
        return np.arange(count)
    magnitudes = np.abs(values.reshape(-1, count))
    finite = np.where(np.isnan(magnitudes), -np.inf, magnitudes)
    peaks = finite.max(axis=0, initial=-np.inf)
    return np.sort(np.argsort(-peaks, kind="stable")[:MAX_PANELS])


def _title(title: str | None, shown: int, total: int, what: str, by: str) -> str | None:
    """``title``, and when not every one of ``total`` panels is drawn, which are."""
    if shown == total:
        return title
    note = (
        f"{shown} of {total} {what} shown: those with the largest {by}; all {total} are in "
        "the trajectories table"
    )
    return note if not title else f"{title}\n{note}"


#: What the coordinates and inputs are and how the drawn ones are chosen, for :func:`_title`.
_BY_ERROR = ("coordinates", "|e1|")
_BY_COMMAND = ("inputs", "|command|")


def _largest_errors(runs: dict[str, SimResult]) -> np.ndarray:
    """The coordinates to draw: those whose ``|e1|`` is largest in any of the runs."""
    return _largest(np.concatenate([result.e1[0] for result in runs.values()]))


def _stacked(rows: int, title: str | None) -> tuple[Figure, list]:
    figure = Figure(figsize=(_WIDTH, _ROW_HEIGHT * rows + 0.9), dpi=_DPI, layout="constrained")
    axes = figure.subplots(rows, 1, sharex=True, squeeze=False)[:, 0]
    if title:
        figure.suptitle(title)
    for ax in axes:
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("t (s)")
    return figure, list(axes)


def _legend(ax, columns: int) -> None:
    """Legend above the top panel, outside the data."""
    ax.legend(
        loc="lower left", bbox_to_anchor=(0.0, 1.0), fontsize="small", ncols=columns, frameon=False
    )


def tracking_figure(
    runs: Mapping[str, SimResult] | SimResult,
    *,
    coordinate_names: Sequence[str] | None = None,
    unit: str | None = None,
    title: str | None = None,
) -> Figure:
    """``q_j(t)`` of each run against the reference ``q_d,j(t)``, one panel per coordinate (at
    most :data:`MAX_PANELS`: those with the largest ``|e1|``, as in :func:`error_figure`).

    ``unit`` labels every axis; by default each coordinate's unit as the plant gives it
    (:attr:`SimResult.coordinate_units`), or none."""
    runs = _runs(runs)
    first = next(iter(runs.values()))
    names = _names(
        first.n, first.coordinate_names if coordinate_names is None else coordinate_names, "q"
    )
    units = _units(first.n, first.coordinate_units, unit)
    shown = _largest_errors(runs)
    figure, axes = _stacked(shown.size, _title(title, shown.size, first.n, *_BY_ERROR))
    for j, ax in zip(shown, axes, strict=True):
        ax.plot(first.t, first.reference[:, 0, j], color="black", lw=1.2, ls="--", label="q_d")
        for label, result in runs.items():
            ax.plot(result.t, result.q[0, :, j], lw=1.0, label=label)
        ax.set_ylabel(labelled(names[j], units[j]))
    _legend(axes[0], len(runs) + 1)
    return figure


def error_figure(
    runs: Mapping[str, SimResult] | SimResult,
    *,
    coordinate_names: Sequence[str] | None = None,
    unit: str | None = None,
    title: str | None = None,
) -> Figure:
    """Absolute tracking error ``|e1_j(t)| = |q_d,j - q_j|`` of each run, a panel per coordinate
    (at most :data:`MAX_PANELS`: those whose ``|e1|`` reaches the largest value in any run).

    ``unit`` as in :func:`tracking_figure`."""
    runs = _runs(runs)
    first = next(iter(runs.values()))
    names = _names(
        first.n, first.coordinate_names if coordinate_names is None else coordinate_names, "q"
    )
    units = _units(first.n, first.coordinate_units, unit)
    shown = _largest_errors(runs)
    figure, axes = _stacked(shown.size, _title(title, shown.size, first.n, *_BY_ERROR))
    for j, ax in zip(shown, axes, strict=True):
        for label, result in runs.items():
            ax.plot(result.t, np.abs(result.e1[0, :, j]), lw=1.0, label=label)
        ax.set_ylabel(labelled(f"|e1| of {names[j]}", units[j]))
        ax.set_ylim(bottom=0.0)
    _legend(axes[0], len(runs))
    return figure


def commands_figure(
    runs: Mapping[str, SimResult] | SimResult,
    *,
    input_names: Sequence[str] | None = None,
    unit: str | None = None,
    title: str | None = None,
) -> Figure:
    """Commanded ``τ_j(t)`` (solid) and applied, delayed ``τ_j(t - h(t))`` (dashed) inputs, a
    panel per input (at most :data:`MAX_PANELS`: those with the largest commands).

    ``input_names`` name the panels; by default the plant's (:attr:`SimResult.input_names`),
    or ``u1 .. um``.

    ``unit`` labels every axis; by default each input's unit as the plant gives it
    (:attr:`SimResult.input_units`), or none."""
    runs = _runs(runs)
    first = next(iter(runs.values()))
    m = first.commands.shape[2]
    names = _names(m, first.input_names if input_names is None else input_names, "u")
    units = _units(m, first.input_units, unit)
    shown = _largest(np.concatenate([result.commands[0] for result in runs.values()]))
    figure, axes = _stacked(shown.size, _title(title, shown.size, m, *_BY_COMMAND))
    for j, ax in zip(shown, axes, strict=True):
        for k, (label, result) in enumerate(runs.items()):
            color = f"C{k}"
            ax.plot(
                result.t, result.commands[0, :, j], lw=1.0, color=color, label=f"{label} commanded"
            )
            ax.plot(
                result.t,
                result.applied[0, :, j],
                lw=1.0,
                color=color,
                ls="--",
                alpha=0.8,
                label=f"{label} applied",
            )
        ax.set_ylabel(labelled(names[j], units[j]))
    _legend(axes[0], 2 * len(runs))
    return figure


def delay_figure(
    runs: Mapping[str, SimResult] | SimResult,
    *,
    h_m: float | None = None,
    title: str | None = None,
) -> Figure:
    """The true input delay ``h(t)`` of each run in ms, and the certified bound ``h_m`` if given."""
    runs = _runs(runs)
    figure, axes = _stacked(1, title)
    ax = axes[0]
    for label, result in runs.items():
        ax.plot(result.t, 1e3 * result.h[0], lw=1.2, label=label)
    if h_m is not None:
        ax.axhline(
            1e3 * h_m,
            color="black",
            ls=":",
            lw=1.2,
            label=f"certified h_m = {quantity_text(h_m, 's', 4)}",
        )
    ax.set_ylabel("h(t) (ms)")
    highest = max([np.nanmax(1e3 * r.h[0]) for r in runs.values()] + [1e3 * (h_m or 0.0)])
    ax.set_ylim(0.0, 1.1 * highest if highest > 0 else 1.0)
    _legend(ax, len(runs) + (h_m is not None))
    return figure


def c_hat_figure(
    runs: Mapping[str, SimResult] | SimResult,
    *,
    title: str | None = None,
) -> Figure:
    """The adaptive gain ``ĉ(t)`` of AROLC for each run that has one (state named ``c_hat``)."""
    runs = _runs(runs)
    figure, axes = _stacked(1, title)
    ax = axes[0]
    plotted = 0
    for label, result in runs.items():
        if "c_hat" not in result.controller_state_names:
            continue
        column = result.controller_state_names.index("c_hat")
        ax.plot(result.t, result.controller_state[0, :, column], lw=1.2, label=label)
        plotted += 1
    if plotted == 0:
        raise ValueError(
            "none of the runs has a controller state 'c_hat' (is the controller AROLC?)"
        )
    ax.set_ylabel("ĉ(t) (dimensionless)")
    _legend(ax, plotted)
    return figure


def margins_figure(
    margins: Mapping[str, Sequence[float]],
    groups: Sequence[str],
    *,
    xlabel: str,
    title: str | None = None,
    at_least: Mapping[str, float] | None = None,
) -> Figure:
    """Delay margins side by side per group (e.g. per gain pair), on a log scale.

    Parameters
    ----------
    margins : mapping of str to sequence of float
        ``label -> margin (s) per group``; NaN where a margin is unknown (not drawn).
    groups : sequence of str
        Name of each group, on the horizontal axis.
    xlabel : str
        What the groups are (the horizontal axis's label, with units).
    title : str, optional
    at_least : mapping of str to float, optional
        ``label -> search limit (s)`` of the margins searched empirically: a NaN margin of
        such a series is drawn as a hatched, unfilled bar up to its limit (no failure found
        below it: the margin is at least that), not left out as if it were small or zero. A
        NaN of another series is not drawn.
    """
    figure = Figure(figsize=(_WIDTH + 2.0, 4.2), dpi=_DPI, layout="constrained")
    ax = figure.add_subplot()
    width = 0.8 / len(margins)
    positions = np.arange(len(groups))
    unknown = False  # whether a bar was drawn hatched, to the search limit
    for k, (label, values) in enumerate(margins.items()):
        heights = np.asarray(values, dtype=float)
        at = positions + (k - (len(margins) - 1) / 2) * width
        bars = ax.bar(at, heights, width, label=label)
        missing = np.isnan(heights)
        limit = (at_least or {}).get(label)
        if limit is not None and missing.any():
            color = bars.patches[0].get_facecolor()
            ax.bar(at[missing], limit, width, fill=False, hatch="///", edgecolor=color)
            unknown = True
    if unknown:  # the hatch's meaning, once, in the legend
        ax.bar(
            np.nan,
            np.nan,
            fill=False,
            hatch="///",
            edgecolor="grey",
            label="hatched: no failure up to the search limit (at least that)",
        )
    ax.set_yscale("log")
    ax.set_xticks(positions, groups, rotation=30, ha="right", fontsize="small")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("delay margin (s)")
    ax.grid(axis="y", which="both", alpha=0.3)
    ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.0, 1.0))
    if title:
        ax.set_title(title)
    return figure


@contextlib.contextmanager
def _layout_given_up_quietly() -> Iterator[None]:
    """Without matplotlib's warning that its constrained layout gave up: a legend or labels
    larger than the figure (a run named with thousands of characters, dozens of series) leave
    no room for the axes, and matplotlib then draws the figure in its default positions, with
    a warning about its own settings that a user of this toolkit cannot act on. The figure is
    the same with or without the warning."""
    with warnings.catch_warnings():
        warnings.filterwarnings(
            "ignore", message="constrained_layout not applied", category=UserWarning
        )
        yield


def png_bytes(figure: Figure) -> bytes:
    """The figure rendered as PNG."""
    buffer = io.BytesIO()
    with _layout_given_up_quietly():
        figure.savefig(buffer, format="png", dpi=_DPI)
    return buffer.getvalue()


def save_figure(
    figure: Figure, stem: str | Path, formats: Sequence[str] = ("png", "svg")
) -> list[Path]:
    """Write ``stem.<format>`` for each format, atomically; return the paths.

    The figure's layout (by its layout engine, such as matplotlib's constrained layout) is
    computed when the first format is drawn and kept for the other formats, which do not lay out
    every label again (that took about half the time of writing a figure in two formats), nor
    draw the figure once more before their own drawing, as matplotlib does for a figure with a
    layout engine (a sixth of the time); the figure's layout engine is given back afterwards.
    """
    paths = []
    engine = figure.get_layout_engine()
    try:
        for fmt in formats:
            path = Path(stem).with_suffix(f".{fmt}")
            with atomic_path(path) as temporary, _layout_given_up_quietly():
                # SVG embeds a date by default; drop it so identical runs give identical files.
                metadata = {"Date": None} if fmt == "svg" else None
                figure.savefig(temporary, format=fmt, dpi=_DPI, metadata=metadata)
            # no layout engine (not even one the settings would give a figure without one)
            with matplotlib.rc_context(
                {"figure.autolayout": False, "figure.constrained_layout.use": False}
            ):
                figure.set_layout_engine(None)
            paths.append(path)
    finally:
        if engine is not None:
            figure.set_layout_engine(engine)
    return paths


def _raised_in_matplotlib(error: BaseException) -> bool:
    """Whether ``error`` was raised within matplotlib's code (laying out or drawing a figure)."""
    frames = traceback.walk_tb(error.__traceback__)
    return any(frame.f_globals.get("__name__", "").startswith("matplotlib.") for frame, _ in frames)


class FigureNotDrawnWarning(DelaytrackWarning):
    """A run's figure left out because its values are beyond what matplotlib can draw."""


def write_run_figures(
    result: SimResult,
    folder: str | Path,
    *,
    coordinate_names: Sequence[str] | None = None,
    formats: Sequence[str] = ("png", "svg"),
    label: str | None = None,
) -> list[Path]:
    """The standard figures of one simulation, written to ``folder``.

    ``tracking`` (q vs q_d), ``error`` (|e1| over time), ``commands`` (commanded vs applied),
    ``delay`` (h(t)) and, when the controller has a ``c_hat`` state (AROLC), ``c_hat``. A batched
    result is drawn with one line per batch element (``run 0``, ``run 1``, ...); a single run is
    named ``label`` in the legends (``run`` without it).
    """
    folder = Path(folder)
    runs = {label: result} if label is not None and result.batch_size == 1 else result
    figures = {
        "tracking": lambda: tracking_figure(runs, coordinate_names=coordinate_names),
        "error": lambda: error_figure(runs, coordinate_names=coordinate_names),
        "commands": lambda: commands_figure(runs),
        "delay": lambda: delay_figure(runs),
    }
    if "c_hat" in result.controller_state_names:
        figures["c_hat"] = lambda: c_hat_figure(runs)
    paths: list[Path] = []
    for name, draw in figures.items():
        try:
            # Overflow on the way (seconds to ms of a delay of 1e306 s) is the error below.
            with np.errstate(over="ignore", invalid="ignore"), warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                paths += save_figure(draw(), folder / name, formats)
        except (ValueError, OverflowError) as error:
            if not _raised_in_matplotlib(error):  # a mistake of the caller's, or ours
                raise
            # Values beyond what matplotlib can lay out (a delay of 1e306 s in ms, an axis
            # spanning 1e308): the run's tables are written; this figure is left out, whole.
            for fmt in formats:
                (folder / f"{name}.{fmt}").unlink(missing_ok=True)
            warnings.warn(
                f"figure {name!r} not drawn: its values are beyond what matplotlib can draw "
                f"({type(error).__name__}: {error})",
                FigureNotDrawnWarning,
                stacklevel=2,
            )
    return paths


def overview_figure(result: SimResult, run: int = 0) -> Figure:
    """One run at a glance: each coordinate against its reference (left) and its tracking error
    ``e1 = q_d − q`` (right), the commanded and applied inputs, the delay ``h(t)`` and the
    controller's state, with the plant's coordinate names and units where it gives them. At
    most :data:`MAX_PANELS` coordinates (those with the largest ``|e1|``) and inputs (the
    largest commands) are drawn; the title then says how many of how many."""
    if not result.has_trajectories:
        raise ValueError(
            "this result has no recorded trajectories (simulate(..., trajectories=False)); "
            "simulate again with trajectories=True to plot it"
        )
    if not -result.batch_size <= run < result.batch_size:
        raise ValueError(f"run must be 0 .. {result.batch_size - 1}; got {run!r}")
    n, m = result.n, result.commands.shape[2]
    names = _names(n, result.coordinate_names, "q")
    units = _units(n, result.coordinate_units, None)
    inputs = _names(m, result.input_names, "u")
    input_units = _units(m, result.input_units, None)
    states = list(result.controller_state_names)
    shown = ["c_hat"] if "c_hat" in states else states[:4]
    coordinates = _largest(result.e1[run])
    drawn_inputs = _largest(result.commands[run])
    rows: list[HashableList[str]] = [[f"q{j}", f"e{j}"] for j in coordinates]
    rows += [["u", "u"], ["h", "h"]]
    if shown:
        rows.append(["state", "state"])
    figure = Figure(figsize=(10.0, 1.9 * len(rows) + 1.0), dpi=_DPI, layout="constrained")
    axes = figure.subplot_mosaic(rows, sharex=True)
    t = result.t
    for j in coordinates:
        ax = axes[f"q{j}"]
        ax.plot(t, result.reference[:, 0, j], color="black", ls="--", lw=1.0)
        ax.plot(t, result.q[run, :, j], lw=1.0)
        ax.set_ylabel(labelled(names[j], units[j]))
        ax = axes[f"e{j}"]
        ax.plot(t, result.e1[run, :, j], lw=1.0, color="C3")
        ax.set_ylabel(labelled(f"e1 of {names[j]}", units[j]))
    axes[f"q{coordinates[0]}"].set_title("plant (solid) and reference (dashed)")
    axes[f"e{coordinates[0]}"].set_title("tracking error e1 = q_d − q")
    ax = axes["u"]
    for j in drawn_inputs:
        ax.plot(t, result.commands[run, :, j], lw=1.0, color=f"C{j}", label=f"{inputs[j]} sent")
        ax.plot(
            t,
            result.applied[run, :, j],
            lw=1.0,
            color=f"C{j}",
            ls="--",
            alpha=0.8,
            label=f"{inputs[j]} applied",
        )
    same = len(set(input_units)) == 1
    ax.set_ylabel(labelled("inputs", input_units[0] if same else None))
    _legend(ax, min(2 * drawn_inputs.size, 6))
    ax = axes["h"]
    ax.plot(t, 1e3 * result.h[run], lw=1.0, color="black")
    ax.set_ylabel("h(t) (ms)")
    ax.set_ylim(bottom=0.0)
    if shown:
        ax = axes["state"]
        for name in shown:
            ax.plot(t, result.controller_state[run, :, states.index(name)], lw=1.0, label=name)
        ax.set_ylabel("ĉ (dimensionless)" if shown == ["c_hat"] else "controller state")
        if len(shown) > 1:
            _legend(ax, len(shown))
    for ax in axes.values():
        ax.grid(True, alpha=0.3)
    bottom = axes["state" if shown else "h"]
    bottom.set_xlabel("t (s)")
    status = result.status_names[run]
    stop = f" at t = {result.t_stop[run]:g} s" if status != "ok" else ""
    heading = f"run {run % result.batch_size} of {result.batch_size}: {status}{stop}"
    notes = [
        _title(None, coordinates.size, n, *_BY_ERROR),
        _title(None, drawn_inputs.size, m, *_BY_COMMAND),
    ]
    figure.suptitle("\n".join([heading, *(note for note in notes if note)]))
    return figure
