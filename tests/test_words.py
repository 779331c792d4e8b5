"""Counts and quantities in words (``delaytrack._words``)."""

import math

import pytest

from delaytrack._words import counted, quantity_text, scaled_unit, with_scaled


def test_one_is_singular_and_every_other_count_plural():
    assert counted(1, "draw") == "1 draw"
    assert [counted(n, "work unit") for n in (0, 2)] == ["0 work units", "2 work units"]


@pytest.mark.parametrize(
    ("value", "unit", "shown"),
    [
        (0.00951, "m", "9.51 mm"),
        (2.5, "m", "2.5 m"),
        (0.12487, "s", "125 ms"),
        (3e-7, "s", "300 ns"),
        (4.2e-5, "s", "42 µs"),
        (1e-12, "s", "0.001 ns"),  # below the smallest unit: in it, not as 0
        (0.0, "s", "0 s"),
        (math.inf, "s", "inf s"),
        (0.3, "rad", "0.3 rad"),  # no smaller unit of its own
        (0.3, None, "0.3"),
        (0.9996, "m", "1 m"),  # the unit of the rounded value: not "1e+03 mm"
        (0.0009996, "s", "1 ms"),  # not "1e+03 µs"
        (0.0009995, "s", "0.999 ms"),  # 999.5 µs would round to "1e+03 µs"
    ],
)
def test_a_quantity_below_one_unit_is_shown_in_a_smaller_one(value, unit, shown):
    assert quantity_text(value, unit) == shown


def test_the_unit_is_picked_from_the_value_rounded_to_the_digits_shown():
    assert scaled_unit("s", 0.0009996, 3) == (1e-3, "ms")
    assert scaled_unit("s", 0.0009996, 5) == (1e-6, "µs")


def test_values_of_one_sentence_share_the_unit_of_the_largest():
    assert quantity_text(0.0003, "m", largest=0.0098) == "0.3 mm"
    assert quantity_text(1.5, "m", largest=1.5) == "1.5 m"


def test_the_bound_is_given_in_seconds_and_where_below_a_second_in_a_smaller_unit():
    assert with_scaled(0.12487, "s") == "0.12487 s (124.9 ms)"
    assert with_scaled(9.99997e-10, "s") == "9.99997e-10 s (1 ns)"  # not "1e-06 ms"
    assert with_scaled(2.5, "s") == "2.5 s"
    assert with_scaled(0.99999995, "s") == "1 s"  # not "1 s (1000 ms)"
    assert with_scaled(1e-18, "s") == "1e-18 s"  # not "(1e-09 ns)": it would add nothing
