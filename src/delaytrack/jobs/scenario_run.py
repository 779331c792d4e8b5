"""One scenario run to its results folder, what ``delaytrack simulate`` does: the scenario as run,
its metrics, trajectories and figures (drawn by :mod:`delaytrack.report`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from delaytrack._io import write_frame, write_text
from delaytrack._output import check_output_folder, claim_output_folder, record_outputs
from delaytrack.scenario.scenario import BuiltScenario, Scenario, ScenarioError, simulate_built
from delaytrack.sim import SimResult
from delaytrack.sim.simulate import physical_memory

__all__ = ["TRAJECTORY_FORMATS", "RunOutput", "run_to_folder"]

#: The trajectory file formats :func:`run_to_folder` writes.
TRAJECTORY_FORMATS = ("parquet", "csv")
#: Peak memory of writing a results folder over the recorded arrays alone (measured: the frame,
#: its Parquet/CSV writers and the figures hold copies).
_WRITE_OVERHEAD = 10


@dataclass(frozen=True)
class RunOutput:
    """What :func:`run_to_folder` produced: the scenario as run and its built objects, the
    result and the files written."""

    scenario: Scenario
    result: SimResult
    folder: Path
    files: tuple[Path, ...]
    built: BuiltScenario


def _figure_formats(formats: Sequence[str]) -> tuple[str, ...]:
    """``figure_formats`` checked before the run: format names matplotlib writes (a text such as
    ``"png"`` is refused, not read letter by letter); matplotlib is asked only for formats
    other than the default ones."""
    if isinstance(formats, str) or not all(isinstance(name, str) for name in formats):
        raise TypeError(
            f"figure_formats must be a sequence of format names such as ('png', 'svg'); "
            f"got {formats!r}"
        )
    formats = tuple(formats)
    if {name.lower() for name in formats} - {"png", "svg"}:
        from matplotlib.backend_bases import FigureCanvasBase

        known = FigureCanvasBase.get_supported_filetypes()
        unknown = [name for name in formats if name.lower() not in known]  # as savefig reads
        if unknown:
            raise ValueError(
                f"figure_formats {unknown} are not formats matplotlib writes; give some of "
                f"{sorted(known)}"
            )
    return formats


def run_to_folder(
    scenario: Scenario,
    folder: str | Path,
    *,
    formats: Sequence[str] = ("parquet",),
    figure_formats: Sequence[str] = ("png", "svg"),
    progress: bool = False,
) -> RunOutput:
    """Run a scenario and write its results folder.

    Files (each written atomically):

    - ``scenario.toml``: the scenario as run (:meth:`Scenario.resolved`; loads back unchanged);
    - ``metrics.csv``: :func:`delaytrack.metrics.metrics_table` (AE, RMS, max error, TV, and
      with input limits the TV received), each metric's unit in its column name (``ae_x_m``,
      ``tv_Nm``, ``tv_applied_Nm``);
    - ``trajectories.parquet`` and/or ``trajectories.csv``: :meth:`SimResult.to_frame`;
    - ``figures/{tracking,error,commands,delay[,c_hat]}.{png,svg}``.

    Parameters
    ----------
    scenario : Scenario
    folder : path
        Created if missing. It must be new, empty or a results folder of an earlier run (whose
        files are replaced; those this run does not write again are removed), and it is checked
        before anything is computed.
    formats : sequence of {"parquet", "csv"}
        Trajectory file formats.
    figure_formats : sequence of str
        Figure file formats (matplotlib names).
    progress : bool
        Show the simulator's progress bar.
    """
    # Imported here: the first result (metrics.csv) is written before matplotlib is needed.
    from delaytrack._result_columns import metric_columns_with_units
    from delaytrack.metrics import metrics_table
    from delaytrack.report.figures import write_run_figures

    if not isinstance(scenario, Scenario):
        raise TypeError(
            f"scenario must be a Scenario (Scenario.from_toml(path) reads a file, "
            f"load_builtin(name) a shipped one); got {type(scenario).__name__} {scenario!r:.80}"
        )
    unknown = sorted(set(formats) - set(TRAJECTORY_FORMATS))
    if unknown or not formats or isinstance(formats, str):
        raise ValueError(
            f"formats must be a non-empty subset of {list(TRAJECTORY_FORMATS)}; got {formats!r}"
        )
    figure_formats = _figure_formats(figure_formats)
    folder = check_output_folder(folder)
    resolved, built = scenario.resolved_and_built()
    records = int(resolved.duration / resolved.T_c) // resolved.record_every + 1
    columns = 4 * built.plant.n + 2 * built.plant.m + 3 + built.controller.state_size
    needed = _WRITE_OVERHEAD * records * columns * 8
    if needed > physical_memory():
        raise ScenarioError(
            f"scenario {resolved.name!r}: writing {records} records of every tick needs about "
            f"{needed / 2**30:.3g} GiB while its tables and figures are built, more than this "
            "machine's memory; raise 'record_every' or shorten 'duration'"
        )
    text = resolved.to_toml()
    try:
        text.encode("utf-8")
    except UnicodeEncodeError as error:
        raise ScenarioError(
            f"scenario {resolved.name!r} names a file whose path is not UTF-8 text "
            f"({error.object[max(0, error.start - 40) : error.end + 10]!r}); scenario.toml, which "
            "records the scenario as run, could not hold it: rename the folder or file"
        ) from None
    result = simulate_built(resolved, built, built.delay, progress=progress)
    claim_output_folder(folder)  # first: a run interrupted while writing leaves a folder of ours
    files = [folder / "scenario.toml"]
    write_text(files[0], text)
    # The metrics first: they are the result a user waits for; trajectories and figures follow.
    # TV received beside TV where the summary printed shows it: with input limits.
    table = metrics_table(result, label=resolved.name, tv_applied=result.input_limited)
    files.append(
        write_frame(table.rename(columns=metric_columns_with_units(result)), folder / "metrics.csv")
    )
    frame = result.to_frame()
    for fmt in formats:
        files.append(write_frame(frame, folder / f"trajectories.{fmt}"))
    files += write_run_figures(
        result, folder / "figures", formats=figure_formats, label=resolved.name
    )
    record_outputs(folder, files)
    return RunOutput(resolved, result, folder, tuple(files), built)
