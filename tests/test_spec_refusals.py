"""A constructor's refusal of a table's value names the key: from the argument the error
carries (``ArgumentError.argument``), not from the wording of its message."""

from __future__ import annotations

import pytest

from delaytrack._spec import SpecError, TypeSpec, build_from_table, number, string
from delaytrack._validation import ArgumentError
from delaytrack.controllers import controller_from_spec
from delaytrack.delays import delay_from_spec
from delaytrack.plants import TwoLinkArm
from delaytrack.references import reference_from_spec

_RANDOM = {"type": "random", "h_low": 0.1, "max_rate": 1.0, "duration": 1.0, "seed": 0}
_PREDICTOR = {"kappa": 1.0, "vartheta": 1.0, "k_b": 1.0, "history": 1.0, "T_c": 0.002}


@pytest.mark.parametrize(
    ("build", "table", "key", "problem"),
    [
        (delay_from_spec, {"type": "constant", "h": -1.0}, "delay.h", "must be >= 0; got -1"),
        (
            delay_from_spec,
            {**_RANDOM, "h_high": 0.05},
            "delay.h_high",
            "must be >= h_low; got h_low = 0.1, h_high = 0.05",
        ),
        (
            delay_from_spec,
            {"type": "piecewise-constant", "times": [1.0, 0.0], "values": [0.1, 0.2]},
            "delay.times",
            "must be strictly increasing; times[0] = 1 is followed by times[1] = 0",
        ),
        (
            delay_from_spec,
            {"type": "trace", "times": [0.0, 1.0], "values": [0.1]},
            "delay.values",
            "must have one entry per time; got 1 values for 2 times",
        ),
        (
            delay_from_spec,
            {"type": "trace", "times": [0.0, 1.0], "values": [0.1, 0.2], "time_column": "t"},
            "delay.time_column",
            "reads a CSV file; it needs 'path' (not 'times' and 'values')",
        ),
        (
            reference_from_spec,
            {"type": "spline", "times": [0.0, 1.0], "values": [0.0, 1.0], "boundary": "free"},
            "reference.boundary",
            "must be one of ['clamped', 'natural', 'not-a-knot']; got 'free'",
        ),
        (
            reference_from_spec,
            {"offset": [0.0, 0.0], "slope": [1.0]},
            "reference.slope",
            "must have length n = 2; got 1",
        ),
        (
            lambda table: controller_from_spec(table, TwoLinkArm()),
            {"type": "pcon", **_PREDICTOR, "space": "joint"},
            "controller.space",
            "must be one of ('generalised', 'actuator'); got 'joint'",
        ),
    ],
)
def test_a_constructors_refusal_carries_the_key(build, table, key, problem):
    with pytest.raises(SpecError) as refused:
        build(table)
    assert (refused.value.key, refused.value.problem) == (key, problem)
    assert str(refused.value) == f"scenario key {key!r} {problem}"


def _refusing(error: Exception):
    def build(**arguments: object) -> object:
        raise error

    return build


def _built(error: Exception) -> SpecError:
    """The refusal of a table whose constructor raises ``error``; the table's key ``h`` sets the
    argument ``value`` and its key ``floor`` the argument ``low``."""
    keys = {"h": ("value", number), "floor": ("low", number), "mode": ("mode", string)}
    with pytest.raises(SpecError) as refused:
        build_from_table(
            "demo", {"type": "kind", "h": 1.0}, {"kind": TypeSpec(_refusing(error), keys)}
        )
    return refused.value


def test_the_key_is_found_by_the_argument_and_named_as_the_table_does():
    refused = _built(ArgumentError("value", "must exceed $low = 2", ("low",)))
    assert str(refused) == "scenario key 'demo.h' must exceed floor = 2"
    assert (refused.key, refused.problem) == ("demo.h", "must exceed floor = 2")


def test_an_argument_that_is_no_key_is_blamed_on_the_table():
    refused = _built(ArgumentError("n", "mode must be 1"))
    assert str(refused) == "scenario table [demo]: n mode must be 1" and refused.key is None


def test_a_plain_error_of_a_shared_check_still_names_its_key():
    refused = _built(ValueError("mode must be one of ['a', 'b']; got 'c'"))
    assert (refused.key, refused.problem) == ("demo.mode", "must be one of ['a', 'b']; got 'c'")
    refused = _built(ValueError("the file is empty"))
    assert str(refused) == "scenario table [demo]: the file is empty" and refused.key is None
