"""The columns of a run's trajectory table, named after the plant's coordinates: never shared.

A coordinate ``c`` with unit ``U`` gives four columns (``c_U``, ``c_dot_U_per_s``, ``c_d_U``,
``e1_c_U``; :mod:`delaytrack.units`), next to the table's own ``run``, ``t_s``, ``h_s``, the
inputs' ``uj_sent``, ``uj_applied`` and the controller's reported state. Names such as ``x`` and
``x_d`` (``x``'s reference and ``x_d``'s position are both ``x_d_m``) or ``run`` would make two
columns of one name, and the later would silently replace the earlier in the table.
:func:`trajectory_columns` lists the columns and refuses such names, naming them and the
column; plants call it where they accept their names, :func:`~delaytrack.sim.simulate` before
it runs (with the controller's state) and :meth:`~delaytrack.sim.SimResult.to_frame` where it
builds the table.
"""

from __future__ import annotations

from collections.abc import Sequence

from delaytrack.units import default_names, with_unit

__all__ = ["FIXED_COLUMNS", "trajectory_columns"]

#: The columns of every trajectory table, whatever the plant: run index, time and true delay.
FIXED_COLUMNS = ("run", "t_s", "h_s")

_FIXED_MEANING = ("the run index", "the time", "the delay")
_COORDINATE_MEANING = ("position", "velocity", "reference", "tracking error")


def _coordinate_columns(name: str, unit: str | None) -> tuple[str, str, str, str]:
    """Position, velocity, reference and tracking error columns of coordinate ``name``."""
    rate = f"{unit}/s" if unit else None
    return (
        with_unit(name, unit),
        with_unit(f"{name}_dot", rate),
        with_unit(f"{name}_d", unit),
        with_unit(f"e1_{name}", unit),
    )


def _input_columns(index: int, unit: str | None) -> tuple[str, str]:
    """Sent and applied columns of input ``index`` (from 0; named ``u1 .. um``)."""
    return with_unit(f"u{index + 1}_sent", unit), with_unit(f"u{index + 1}_applied", unit)


def trajectory_columns(
    coordinate_names: Sequence[str] | None,
    coordinate_units: Sequence[str | None] | None,
    n: int,
    input_units: Sequence[str | None] | None,
    m: int,
    state_names: Sequence[str] = (),
) -> list[str]:
    """Every column of the trajectory table, in its order.

    Parameters
    ----------
    coordinate_names, coordinate_units : sequence of str, optional
        The plant's (None: ``q1 .. qn``, no unit).
    n, m : int
        Numbers of coordinates and inputs.
    input_units : sequence of str, optional
        The plant's units of its inputs (None: no unit).
    state_names : sequence of str
        The controller's reported state entries (columns of their own).

    Raises
    ------
    ValueError
        When two columns would have one name (naming the names, the column and what is valid),
        or for names or units that are not one per coordinate or input.
    """
    names = default_names(coordinate_names, n)
    units = tuple(coordinate_units) if coordinate_units is not None else (None,) * n
    inputs = tuple(input_units) if input_units is not None else (None,) * m
    for label, given, size in (
        ("coordinate_names", names, n),
        ("coordinate_units", units, n),
        ("input_units", inputs, m),
    ):
        if len(given) != size:
            raise ValueError(f"{label} must have {size} entries, one each; got {list(given)}")
    described: list[tuple[str, str]] = list(zip(FIXED_COLUMNS, _FIXED_MEANING, strict=True))
    for name, unit in zip(names, units, strict=True):
        columns = _coordinate_columns(name, unit)
        described += [
            (column, f"the {meaning} of coordinate {name!r}")
            for column, meaning in zip(columns, _COORDINATE_MEANING, strict=True)
        ]
    for j, unit in enumerate(inputs):
        sent, applied = _input_columns(j, unit)
        described += [(sent, f"input u{j + 1} as sent"), (applied, f"input u{j + 1} as applied")]
    described += [(name, f"the controller's state {name!r}") for name in state_names]
    seen: dict[str, str] = {}
    for column, meaning in described:
        if column in seen:
            raise ValueError(_clash(column, seen[column], meaning, names, coordinate_units))
        seen[column] = meaning
    return [column for column, _ in described]


def _clash(
    column: str,
    first: str,
    second: str,
    names: tuple[str, ...],
    units: Sequence[str | None] | None,
) -> str:
    if "coordinate" not in first + second:
        return (
            f"the controller's state names repeat {column!r}; each state entry needs a name of "
            "its own (a column of the results)"
        )
    given = f"coordinate_names {list(names)}" + (
        f" with coordinate_units {list(units)}" if units is not None else ""
    )
    return (
        f"{given} would give the results two columns {column!r} ({first} and {second}); a "
        "coordinate c has the columns c, c_dot, c_d and e1_c (each with c's unit, as in x_m), "
        f"which must differ from every other coordinate's and from {', '.join(FIXED_COLUMNS)}, "
        "the inputs' uj_sent and uj_applied and the controller's state: rename the coordinate"
    )
