"""The columns of a run's results, named after the plant's coordinates and units: never shared.

A coordinate ``c`` with unit ``U`` gives four columns (``c_U``, ``c_dot_U_per_s``, ``c_d_U``,
``e1_c_U``; :mod:`delaytrack.units`), next to the table's own ``run``, ``t_s``, ``h_s``, the
inputs' ``uj_sent``, ``uj_applied`` and the controller's reported state. Names such as ``x`` and
``x_d`` (``x``'s reference and ``x_d``'s position are both ``x_d_m``) or ``run`` would make two
columns of one name, and the later would silently replace the earlier in the table.
:func:`trajectory_columns` lists the columns and refuses such names, naming them and the
column; plants call it where they accept their names, :func:`~delaytrack.sim.simulate` before
it runs (with the controller's state) and :meth:`~delaytrack.sim.SimResult.to_frame` where it
builds the table.

The same names and units make a sweep's summary columns ``<metric>_<statistic>_<unit>``
(``ae_x_median_m``; :func:`summary_columns`): :func:`trajectory_columns` refuses names and units
whose summary columns would be shared too, so that a plant that can run can also be swept. A
unit is therefore plain unit text (:func:`plain_unit`): with ``_`` in units, coordinates ``x``
in ``max_m`` and ``x_mean`` in ``m`` would both give ``ae_x_mean_max_m``. Columns are compared
as Python compares identifiers, after Unicode normalisation (NFKC): ``é`` written as one
character or as ``e`` and a combining accent is one name.
"""

from __future__ import annotations

import functools
import unicodedata
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from delaytrack.metrics import COORDINATE_METRICS
from delaytrack.units import default_names, with_unit

__all__ = [
    "FIXED_COLUMNS",
    "SUMMARY_STATISTICS",
    "UNIT_SYMBOLS",
    "input_column",
    "metric_columns_with_units",
    "metric_units",
    "plain_unit",
    "shared_unit",
    "state_columns",
    "summary_columns",
    "trajectory_columns",
]

#: The columns of every trajectory table, whatever the plant: run index, time and true delay.
FIXED_COLUMNS = ("run", "t_s", "h_s")

_FIXED_MEANING = ("the run index", "the time", "the delay")
_COORDINATE_MEANING = ("position", "velocity", "reference", "tracking error")

#: The statistics of a sweep's summary, each a column ``<metric>_<statistic>[_<unit>]``.
SUMMARY_STATISTICS = ("mean", "median", "p95", "max")

#: What a unit may hold besides letters (``µ``, ``Ω``) and digits (``²``): ``N·m``, ``m/s^2``,
#: ``kg*m``, ``m^-1``, ``N.m``, ``%``, ``°``. Never ``_`` (it separates the parts of a column
#: name) nor spaces.
UNIT_SYMBOLS = "·/^*-.%°"


def plain_unit(unit: object, label: str) -> str:
    """``unit`` when it is plain unit text: letters, digits and :data:`UNIT_SYMBOLS`, starting
    with a letter, a digit or ``%``/``°``. ``label`` names it for the message (``coordinate_units
    ['m', 'max_m']``).

    Raises
    ------
    ValueError
        Naming ``label``, the unit and what is valid.
    """
    if not (
        isinstance(unit, str)
        and bool(unit)
        and all(c.isalnum() or c in UNIT_SYMBOLS for c in unit)
        and (unit[0].isalnum() or unit[0] in "%°")
    ):
        raise ValueError(
            f"{label} holds the unit {unit!r}, which is not plain unit text: a unit is letters "
            f"and digits with {' '.join(UNIT_SYMBOLS)} (such as 'm', 'rad', 'N·m', 'm/s^2'), "
            "without '_' or spaces, which would make the result columns named after it ambiguous"
        )
    return unit


def _key(column: str) -> str:
    """A column as compared: NFKC-normalised, as Python compares identifiers."""
    return unicodedata.normalize("NFKC", column)


def _first_duplicate(
    described: Iterable[tuple[str, str]],
) -> tuple[tuple[str, str], tuple[str, str]] | None:
    """The first two ``(column, meaning)`` whose columns are one name (:func:`_key`), or None."""
    seen: dict[str, tuple[str, str]] = {}
    for column, meaning in described:
        if _key(column) in seen:
            return seen[_key(column)], (column, meaning)
        seen[_key(column)] = (column, meaning)
    return None


def _columns_text(first: str, second: str) -> str:
    """``'x_d_m'``, or both spellings when they are one name only after normalisation."""
    if first == second:
        return repr(first)
    return f"{ascii(first)} and {ascii(second)} (one name after Unicode normalisation, NFKC)"


def metric_units(
    coordinate_names: Sequence[str] | None,
    coordinate_units: Sequence[str | None] | None,
    n: int,
    input_units: Sequence[str | None] | None,
) -> dict[str, str | None]:
    """Each metric of a run (``ae_c``, ``rms_c``, ``max_c`` per coordinate, then ``tv`` and
    ``tv_applied``) and its unit: the coordinate's, and for the TVs the inputs' when they share
    one (else None)."""
    names = default_names(coordinate_names, n)
    units = tuple(coordinate_units) if coordinate_units is not None else (None,) * n
    out: dict[str, str | None] = {}
    for prefix in COORDINATE_METRICS:
        out.update({f"{prefix}_{name}": unit for name, unit in zip(names, units, strict=True)})
    out["tv"] = out["tv_applied"] = shared_unit(input_units or ())
    return out


def shared_unit(units: Sequence[str | None]) -> str | None:
    """The one unit all of ``units`` share (None when they differ, or there are none)."""
    distinct = set(units)
    return distinct.pop() if len(distinct) == 1 else None


def summary_columns(units: Mapping[str, str | None]) -> dict[str, str]:
    """A sweep summary's statistic columns: for each metric of ``units`` (metric -> unit or
    None) and statistic of :data:`SUMMARY_STATISTICS`, ``<metric>_<statistic>`` -> the column as
    written, ``<metric>_<statistic>_<unit>``.

    Raises
    ------
    ValueError
        When two of them would be one column, naming the column, both metrics and their units.
    """
    described = [
        (
            f"{metric}_{statistic}",
            with_unit(f"{metric}_{statistic}", unit),
            f"the {statistic} of {metric}" + (f" in {unit!r}" if unit else ""),
        )
        for metric, unit in units.items()
        for statistic in SUMMARY_STATISTICS
    ]
    duplicate = _first_duplicate((written, meaning) for _, written, meaning in described)
    if duplicate is not None:
        (first, first_meaning), (second, second_meaning) = duplicate
        raise ValueError(
            f"a sweep's summary would have two columns {_columns_text(first, second)} "
            f"({first_meaning} and {second_meaning}; a summary column is "
            "<metric>_<statistic>_<unit>)"
        )
    return {plain: written for plain, written, _ in described}


def metric_columns_with_units(result: Any) -> dict[str, str]:
    """The columns of :func:`delaytrack.metrics.metrics_table` of ``result`` (a
    :class:`~delaytrack.sim.SimResult`) renamed with their units, for the tables a user reads:
    ``ae_x`` -> ``ae_x_m``, ``tv`` -> ``tv_Nm`` (when the inputs share a unit), ``t_stop`` ->
    ``t_stop_s``; a metric whose unit the plant does not declare keeps its name."""
    units = metric_units(
        result.coordinate_names, result.coordinate_units, result.n, result.input_units
    )
    return {metric: with_unit(metric, unit) for metric, unit in units.items()} | {
        "t_stop": "t_stop_s"
    }


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
    return input_column(index, unit, "sent"), input_column(index, unit, "applied")


def input_column(index: int, unit: str | None, role: str = "") -> str:
    """The column of input ``index`` (from 0): ``u1_Nm``, or with a ``role`` ``u1_sent_Nm``."""
    return with_unit(f"u{index + 1}_{role}" if role else f"u{index + 1}", unit)


def state_columns(names: Sequence[str], units: Sequence[str | None]) -> list[str]:
    """The position columns of the coordinates ``names`` in their ``units``, then their
    velocity columns (``x_m, .., x_dot_m_per_s, ..``): a live session's ``states.csv``."""
    pairs = [_coordinate_columns(name, unit)[:2] for name, unit in zip(names, units, strict=True)]
    return [position for position, _ in pairs] + [velocity for _, velocity in pairs]


def trajectory_columns(
    coordinate_names: Sequence[str] | None,
    coordinate_units: Sequence[str | None] | None,
    n: int,
    input_units: Sequence[str | None] | None,
    m: int,
    state_names: Sequence[str] = (),
) -> list[str]:
    """Every column of the trajectory table, in its order.

    The columns of names and units met before are remembered (every
    :func:`~delaytrack.sim.simulate` call asks for them); names refused are checked again at
    each call.

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
        When two columns would have one name, here or in a sweep's summary (naming the names,
        the column and what is valid), for a unit that is not plain unit text
        (:func:`plain_unit`), or for names or units that are not one per coordinate or input.
    """
    arguments = (
        _frozen(coordinate_names),
        _frozen(coordinate_units),
        n,
        _frozen(input_units),
        m,
        tuple(state_names),
    )
    try:
        hash(arguments)
    except TypeError:  # names or units of a kind that cannot be remembered: checked each time
        return list(_columns.__wrapped__(*arguments))
    return list(_columns(*arguments))


def _frozen(values: Sequence | None) -> tuple | None:
    return None if values is None else tuple(values)


@functools.lru_cache(maxsize=256)
def _columns(
    coordinate_names: tuple[str, ...] | None,
    coordinate_units: tuple[str | None, ...] | None,
    n: int,
    input_units: tuple[str | None, ...] | None,
    m: int,
    state_names: tuple[str, ...],
) -> tuple[str, ...]:
    """:func:`trajectory_columns` of arguments made tuples (so that they can be remembered)."""
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
        if label.endswith("units"):
            for unit in given:
                if unit is not None:
                    plain_unit(unit, f"{label} {list(given)}")
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
    duplicate = _first_duplicate(described)
    if duplicate is not None:
        raise ValueError(_clash(*duplicate, names, coordinate_units))
    try:
        summary_columns(metric_units(names, units, n, inputs))
    except ValueError as error:
        raise ValueError(
            f"{_given(names, coordinate_units)}: {error}; rename the coordinate or change its unit"
        ) from None
    return tuple(column for column, _ in described)


def _given(names: tuple[str, ...], units: Sequence[str | None] | None) -> str:
    """``coordinate_names [...] with coordinate_units [...]``; names that NFKC changes are shown
    with escapes, so that two spellings of one name are told apart."""
    shown = ascii(list(names)) if any(_key(name) != name for name in names) else list(names)
    return f"coordinate_names {shown}" + (
        f" with coordinate_units {list(units)}" if units is not None else ""
    )


def _clash(
    first: tuple[str, str],
    second: tuple[str, str],
    names: tuple[str, ...],
    units: Sequence[str | None] | None,
) -> str:
    (column, first_meaning), (other, second_meaning) = first, second
    if "coordinate" not in first_meaning + second_meaning:
        return (
            f"the controller's state names repeat {_columns_text(column, other)}; each state "
            "entry needs a name of its own (a column of the results)"
        )
    return (
        f"{_given(names, units)} would give the results two columns "
        f"{_columns_text(column, other)} ({first_meaning} and {second_meaning}); a coordinate c "
        "has the columns c, c_dot, c_d and e1_c (each with c's unit, as in x_m), which must "
        f"differ from every other coordinate's and from {', '.join(FIXED_COLUMNS)}, the inputs' "
        "uj_sent and uj_applied and the controller's state: rename the coordinate"
    )
