"""The keys of a scenario file: which there are, which are required, and the check of each value.

A check ("phrase") takes a value and returns None when it is valid, otherwise the end of the
sentence that refuses it (``"must be a number > 0 ..."``), which :func:`delaytrack._spec.fail`
completes with the key's name and the value.
"""

from __future__ import annotations

import re
import sys
from collections.abc import Callable
from types import MappingProxyType

from delaytrack._spec import integer, number, string, vector
from delaytrack.controllers import CONTROLLER_SPECS
from delaytrack.delays import DELAY_SPECS
from delaytrack.plants import PLANT_SPECS
from delaytrack.references import REFERENCE_SPECS
from delaytrack.sim import MeasurementNoise, PacketLoss

#: ``x0 = "reference"``: the run starts on the reference, on the plant's constraints.
ON_REFERENCE = "reference"


def x0_phrase(value: object) -> str | None:
    """Check an ``x0``: a list of numbers, or ``"reference"``."""
    if value == ON_REFERENCE:
        return None
    if isinstance(value, str):
        return f'must be a list of 2n numbers or "{ON_REFERENCE}"'
    return vector(value)


def error_bound_phrase(value: object) -> str | None:
    """Check an ``error_bound``: a number or a list of numbers, each > 0 (``inf`` allowed)."""
    values = value if isinstance(value, list) else [value]
    valid = values and all(
        isinstance(v, int | float)
        and not isinstance(v, bool)
        and v > 0
        and (isinstance(v, float) or v <= sys.float_info.max)  # an int that becomes a float
        for v in values
    )
    if valid:
        return None
    return (
        "must be a number > 0 or a list of them, one per coordinate (inf: no bound for that "
        "coordinate)"
    )


def input_limits_phrase(value: object) -> str | None:
    """Check ``input_limits``: a number or a list of numbers, each > 0 (``inf`` allowed)."""
    if error_bound_phrase(value) is None:
        return None
    return "must be a number > 0 or a list of them, one per input (inf: no limit for that input)"


_NOISE_KEYS = ("quantization", "position", "velocity", "seed")


def _without_value(error: Exception) -> str:
    """``error``'s message without its closing ``; got ...``: the key's message gives the whole
    table after it."""
    return str(error).rpartition("; got ")[0] or str(error)


def measurement_noise_phrase(value: object) -> str | None:
    """Check ``measurement_noise``: a table of :class:`MeasurementNoise`'s keys."""
    if isinstance(value, dict) and set(value) <= set(_NOISE_KEYS):
        try:
            MeasurementNoise(**value)
        except (TypeError, ValueError) as error:
            return f"is refused: {_without_value(error)}"
        return None
    return f"must be a table with keys among {list(_NOISE_KEYS)}"


def packet_loss_phrase(value: object) -> str | None:
    """Check ``packet_loss``: a table of :class:`PacketLoss`'s keys."""
    if isinstance(value, dict) and set(value) <= {"probability", "seed"}:
        if "probability" not in value:
            return (
                "is refused: it gives a seed without a probability, which loses nothing (the "
                "probability is 0 unless given); give probability = p in [0, 1)"
            )
        try:
            PacketLoss(**value)
        except (TypeError, ValueError) as error:
            return f"is refused: {_without_value(error)}"
        return None
    return "must be a table with keys among ['probability', 'seed']"


_TOP_LEVEL_SCALARS: dict[str, Callable[[object], str | None]] = {
    "name": string,
    "duration": number,
    "dt": number,
    "T_c": number,
    "seed": integer,
    "x0": x0_phrase,
    "record_every": integer,
    "error_bound": error_bound_phrase,
    "input_limits": input_limits_phrase,
    "measurement_noise": measurement_noise_phrase,
    "packet_loss": packet_loss_phrase,
    "u_init": vector,
}
#: The tables of a scenario, each of a ``type`` of its own.
TABLES = ("plant", "model", "controller", "delay", "reference")
REQUIRED = ("name", "duration", "dt", "T_c", *TABLES)
TOP_LEVEL_KEYS = (*_TOP_LEVEL_SCALARS, *TABLES)
#: The top-level keys of a sweep file (:mod:`delaytrack.sweeps.spec`): here, so that a sweep
#: file given as a scenario is told apart from a scenario file given as a sweep.
SWEEP_KEYS = ("scenario", "unit_size", "draws", "seed", "metrics", "grid", "random")
#: The types each table may name, and the keys of each.
TABLE_TYPES = MappingProxyType(
    {
        "plant": PLANT_SPECS,
        "model": PLANT_SPECS,
        "controller": CONTROLLER_SPECS,
        "delay": DELAY_SPECS,
        "reference": REFERENCE_SPECS,
    }
)
#: What each table describes, for the message naming a missing one.
TABLE_PURPOSE = MappingProxyType(
    {
        "plant": "the true plant",
        "model": "the nominal plant the controller uses; copy [plant] for a perfect model",
        "controller": "the controller and its gains",
        "delay": "the input delay profile",
        "reference": "the desired trajectory q_d(t)",
    }
)
#: A scenario's ``name``: it names the results folder.
NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]*")
