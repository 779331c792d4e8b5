"""The result of a (batched) closed-loop simulation."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from delaytrack._result_columns import shared_unit, trajectory_columns
from delaytrack.sim.engine import STATUS_NAMES
from delaytrack.units import default_names, labelled

if TYPE_CHECKING:
    import pandas as pd
    from matplotlib.figure import Figure

__all__ = ["SimResult"]


@dataclass(frozen=True, eq=False)
class SimResult:
    """Recorded trajectories of ``batch`` closed loops, sampled at controller ticks.

    Attributes
    ----------
    t : ndarray, shape (R,)
        Record times ``t0 + k T_c`` for every ``record_every``-th tick ``k``.
    x : ndarray, shape (batch, R, 2n)
        Plant state ``[q, q̇]`` at the record times (before the tick's command).
    reference : ndarray, shape (R, 3, n)
        ``q_d, q̇_d, q̈_d`` at the record times, as the controller read them.
    commands : ndarray, shape (batch, R, m)
        Command issued by the controller at each record time.
    applied : ndarray, shape (batch, R, m)
        Input the plant received just after the record time (over the first sub-step of the
        plant step that starts there): the delayed command, saturated to the input limits.
    h : ndarray, shape (batch, R)
        True delay ``h(t)`` (known to the simulator only).
    controller_state : ndarray, shape (batch, R, n_state)
        Controller state used at each record time (for AROLC ``ĉ`` is column 0).
    controller_state_names : tuple of str
    status : ndarray of int, shape (batch,)
        0 ok, 1 diverged, 2 delay beyond the history buffer, 3 left the path (a tracking
        error beyond ``error_bound``), 4 mass matrix not positive definite (the plant's
        ``M(q)`` met in the solve for ``q̈`` at ``t_stop``: a fault of its kernel);
        see :attr:`status_names`.
    t_stop : ndarray, shape (batch,)
        Time at which each run ended; rows recorded after it are NaN.
    metrics : dict of str to ndarray
        Running metrics over every controller tick from ``settings["metrics_from"]``
        (:mod:`delaytrack.sim.running_metrics`): ``"ae"``, ``"rms"``, ``"max"`` (batch, n),
        ``"tv"`` (batch,; of the commands) and ``"tv_applied"`` (batch,; of the input the plant
        received); NaN for runs that are not ok. They are there even when no trajectory
        was recorded (``simulate(..., trajectories=False)``).
    settings : dict
        Everything needed to rerun: plant, controller, delays, reference, ``dt``, ``T_c``, ...
    coordinate_names : tuple of str, optional
        The plant's names of its coordinates (``x, y, phi, ...`` for the robot), used by
        :func:`~delaytrack.metrics.metrics_table` and the figures; None means ``q1 .. qn``.
    coordinate_units, input_units : tuple of str, optional
        The plant's units of its coordinates and inputs (``m``, ``rad``, ``N·m``), for figure
        axes and table columns; None when the plant does not say.
    reported_state_names : tuple of str, optional
        The controller state entries that :meth:`to_frame` writes (the controller's
        bookkeeping left out); None means all of ``controller_state_names``.
    input_names : tuple of str, optional
        The plant's names of its inputs, for the figures; None means ``u1 .. um``.
    """

    t: np.ndarray
    x: np.ndarray
    reference: np.ndarray
    commands: np.ndarray
    applied: np.ndarray
    h: np.ndarray
    controller_state: np.ndarray
    controller_state_names: tuple[str, ...]
    status: np.ndarray
    t_stop: np.ndarray
    metrics: dict[str, np.ndarray] = field(default_factory=dict)
    settings: dict[str, Any] = field(default_factory=dict)
    coordinate_names: tuple[str, ...] | None = None
    coordinate_units: tuple[str, ...] | None = None
    input_units: tuple[str, ...] | None = None
    reported_state_names: tuple[str, ...] | None = None
    input_names: tuple[str, ...] | None = None

    @property
    def has_trajectories(self) -> bool:
        """Whether trajectories were recorded (``simulate(..., trajectories=True)``)."""
        return self.t.size > 0

    @property
    def batch_size(self) -> int:
        return self.x.shape[0]

    @property
    def n(self) -> int:
        return self.x.shape[2] // 2

    @property
    def input_limited(self) -> bool:
        """Whether the run had input limits (``simulate(input_limits=...)`` with a finite
        entry)."""
        limits = self.settings.get("input_limits")
        return limits is not None and bool(np.isfinite(np.asarray(limits, dtype=float)).any())

    @property
    def q(self) -> np.ndarray:
        """Coordinates, shape (batch, R, n)."""
        return self.x[:, :, : self.n]

    @property
    def qdot(self) -> np.ndarray:
        """Velocities, shape (batch, R, n)."""
        return self.x[:, :, self.n :]

    @property
    def e1(self) -> np.ndarray:
        """Tracking error ``e1 = q_d - q``, shape (batch, R, n)."""
        return self.reference[None, :, 0, :] - self.q

    @property
    def status_names(self) -> list[str]:
        """Status of each run in words."""
        return [STATUS_NAMES[int(code)] for code in self.status]

    @property
    def ok(self) -> np.ndarray:
        """Boolean mask of the runs that reached the final time."""
        return self.status == 0

    def __getitem__(self, index: int | slice | np.ndarray) -> SimResult:
        """The sub-batch ``index`` (an int keeps a batch axis of length 1)."""
        select = np.atleast_1d(np.arange(self.batch_size)[index])
        settings = dict(self.settings)
        if "delays" in settings:
            settings["delays"] = [settings["delays"][i] for i in select]
        return SimResult(
            t=self.t,
            x=self.x[select],
            reference=self.reference,
            commands=self.commands[select],
            applied=self.applied[select],
            h=self.h[select],
            controller_state=self.controller_state[select],
            controller_state_names=self.controller_state_names,
            status=self.status[select],
            t_stop=self.t_stop[select],
            metrics={name: values[select] for name, values in self.metrics.items()},
            settings=settings,
            coordinate_names=self.coordinate_names,
            coordinate_units=self.coordinate_units,
            input_units=self.input_units,
            reported_state_names=self.reported_state_names,
            input_names=self.input_names,
        )

    def plot(self, run: int = 0) -> Figure:
        """One run at a glance (:func:`~delaytrack.report.figures.overview_figure`): each
        coordinate against its reference and its tracking error, the commanded and applied
        inputs, the delay ``h(t)`` and the controller state, with the plant's coordinate names
        and units. Returns a matplotlib Figure (shown inline in a notebook; save it with
        ``figure.savefig(path)``)."""
        from delaytrack.report.figures import overview_figure

        return overview_figure(self, run)

    def summary(self) -> pd.DataFrame:
        """Status, stop time, AE per coordinate (in its unit) and TV per run (in the inputs'
        unit when they share one); with input limits (:attr:`input_limited`), also "TV
        received", the TV of the input the plant received
        (:func:`~delaytrack.metrics.total_variation` of ``applied``)."""
        import pandas as pd  # imported when a table is made: `import delaytrack` stays light

        names = default_names(self.coordinate_names, self.n)
        units = self.coordinate_units or (None,) * self.n
        columns: dict[str, Any] = {"status": self.status_names, "t_stop (s)": self.t_stop}
        if "ae" in self.metrics:  # built whole: a frame grown column by column fragments
            for j, (name, unit) in enumerate(zip(names, units, strict=True)):
                columns[labelled(f"AE {name}", unit)] = self.metrics["ae"][:, j]
        input_unit = shared_unit(self.input_units or ())
        if "tv" in self.metrics:
            columns[labelled("TV", input_unit)] = self.metrics["tv"]
        if self.input_limited and "tv_applied" in self.metrics:
            columns[labelled("TV received", input_unit)] = self.metrics["tv_applied"]
        frame = pd.DataFrame(columns)
        frame.index.name = "run"
        return frame

    def __repr__(self) -> str:
        names = default_names(self.coordinate_names, self.n)
        span = (
            f"t = {self.t[0]:g} .. {self.t[-1]:g} s ({self.t.size} records)"
            if self.has_trajectories
            else "metrics only (no trajectories)"
        )
        return (
            f"SimResult(runs={self.batch_size}, ok={int(self.ok.sum())}, {span}, "
            f"n={self.n} ({', '.join(names)}), m={self.commands.shape[2]}, "
            f"controller state=({_shortened(self.controller_state_names)}), "
            f"metrics=({', '.join(self.metrics)}))"
        )

    def _repr_html_(self) -> str:
        head = repr(self).replace("&", "&amp;").replace("<", "&lt;")
        return f"<p><code>{head}</code></p>" + self.summary().to_html(
            float_format=lambda v: f"{v:.4g}", max_rows=20
        )

    def to_frame(self) -> pd.DataFrame:
        """Long table, one row per (run, record time), with units in the column names
        (:mod:`delaytrack.units`).

        Columns: ``run``, ``t_s``, ``h_s`` (the true delay); per coordinate ``c`` with unit
        ``U``: ``c_U`` (position), ``c_dot_U_per_s``, ``c_d_U`` (the reference ``q_d``),
        ``e1_c_U`` (``q_d − q``); per input ``uj`` with unit ``V``: ``uj_sent_V`` and
        ``uj_applied_V``; then the controller's reported state by name (for AROLC ``c_hat``).
        A unit the plant does not declare is left out of the name. Two columns never share a
        name: coordinate names that would give them one are refused (a ValueError naming them
        and the column), as plants and :func:`~delaytrack.sim.simulate` refuse them before.
        """
        import pandas as pd  # imported when a table is made: `import delaytrack` stays light

        batch, records = self.batch_size, self.t.size
        inputs = self.commands.shape[2]
        reported = self.reported_state_names
        states = [
            (j, name)
            for j, name in enumerate(self.controller_state_names)
            if reported is None or name in reported
        ]
        names = trajectory_columns(
            self.coordinate_names,
            self.coordinate_units,
            self.n,
            self.input_units,
            inputs,
            [name for _, name in states],
        )
        values = [np.repeat(np.arange(batch), records), np.tile(self.t, batch), self.h.ravel()]
        for i in range(self.n):
            values += [
                self.q[:, :, i].ravel(),
                self.qdot[:, :, i].ravel(),
                np.tile(self.reference[:, 0, i], batch),
                self.e1[:, :, i].ravel(),
            ]
        for j in range(inputs):
            values += [self.commands[:, :, j].ravel(), self.applied[:, :, j].ravel()]
        values += [self.controller_state[:, :, j].ravel() for j, _ in states]
        columns = dict(zip(names, values, strict=True))
        return pd.DataFrame(columns)


def _shortened(names: tuple[str, ...], shown: int = 4) -> str:
    """The first ``shown`` names, then how many more."""
    more = len(names) - shown
    return ", ".join(names[:shown]) + (f", … {more} more" if more > 0 else "")
