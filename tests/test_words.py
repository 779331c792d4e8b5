"""Counts in words (``delaytrack._words``)."""

from delaytrack._words import counted


def test_one_is_singular_and_every_other_count_plural():
    assert counted(1, "draw") == "1 draw"
    assert [counted(n, "work unit") for n in (0, 2)] == ["0 work units", "2 work units"]
