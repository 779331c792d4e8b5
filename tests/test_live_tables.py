"""A session folder's tables read column by column: the rows a mapping by index would keep,
numbers as the cells give them, memory of the order of the file's text, bounded reads."""

from __future__ import annotations

import csv
import math
import os
import tracemalloc

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from delaytrack.live._tables import RowsByIndex, number, read_table, values_at


@given(
    st.lists(st.integers(0, 30), max_size=60),
    st.lists(st.integers(-2, 35), max_size=20),
    st.booleans(),
)
def test_rows_by_index_keep_the_row_a_mapping_would(indices, wanted, first):
    kept: dict[int, int] = {}
    for row, index in enumerate(indices):
        if first:
            kept.setdefault(index, row)
        else:
            kept[index] = row
    by_index = RowsByIndex(np.array(indices, dtype=np.int64), first=first)
    assert by_index.indices.tolist() == sorted(kept)
    assert by_index.rows.tolist() == [kept[index] for index in sorted(kept)]
    assert by_index.find(wanted).tolist() == [kept.get(index, -1) for index in wanted]
    values = np.arange(len(indices), dtype=float) * 0.5
    expected = [values[kept[index]] if index in kept else math.nan for index in wanted]
    np.testing.assert_array_equal(values_at(values, by_index.find(wanted)), expected)


def _write(path, header, rows):
    with open(path, "w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(header)
        writer.writerows(rows)


def test_cells_are_read_as_the_session_readers_read_them(tmp_path):
    path = tmp_path / "ticks.csv"
    rows = [
        ["0", "0.5", "ok", "1e-3"],
        ["1", "", "no-state", "x"],
        [],  # a blank line: no row
        [" 2 ", "inf", "ok"],  # its last cell missing: empty
    ]
    _write(path, ["k", "t_s", "status", "u1"], rows)
    table = read_table(path, None, indices=("k",), texts=("status",))
    assert table.rows == 3 and table.header == ["k", "t_s", "status", "u1"]
    assert table["k"].tolist() == [0, 1, 2]
    expected = {"t_s": ["0.5", "", "inf"], "u1": ["1e-3", "x", ""]}
    for column, cells in expected.items():
        np.testing.assert_array_equal(table[column], [number(cell) for cell in cells])
    assert table["status"].tolist() == ["ok", "no-state", "ok"]
    assert table["status"][0] is table["status"][2]  # one object for each distinct text
    np.testing.assert_array_equal(
        table.at(["u1", "t_s"], [2, -1, 0]), [[np.nan, np.inf], [np.nan, np.nan], [1e-3, 0.5]]
    )
    with pytest.raises(ValueError, match=r"ticks.csv: no column 'u2' \(it has"):
        table.at(["u1", "u2"])
    with pytest.raises(ValueError, match=r"ticks.csv: no column 'lateness_ms'"):
        read_table(path, ("lateness_ms",))


def test_a_cell_that_is_no_index_is_refused_naming_the_line(tmp_path):
    path = tmp_path / "states.csv"
    _write(path, ["j", "q1"], [["0", "1.0"], ["1", "2.0"], ["-2", "3.0"]])
    with pytest.raises(
        ValueError, match=r"states.csv, line 4: column 'j' holds '-2', not an index"
    ):
        read_table(path, None, indices=("j",))


def test_a_missing_table_has_no_rows_and_a_required_one_is_refused(tmp_path):
    table = read_table(tmp_path / "steps.csv", ("lateness_ms",), indices=("j",))
    assert table.rows == 0 and table["lateness_ms"].size == 0 and table["j"].dtype == np.int64
    with pytest.raises(ValueError, match=r"steps.csv is missing or has no rows"):
        table.required()


def _read_with_peak(path):
    """The states table ``path`` and the peak of the memory Python allocated reading it."""
    tracemalloc.start()
    try:
        return read_table(path, None, indices=("j",)), tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_a_table_takes_memory_of_the_order_of_its_text(tmp_path):
    # Rows of Python objects (a dict of texts a row) took about thirty times the file's size.
    path = tmp_path / "states.csv"
    count = 50_000
    columns = ["j", "t_s", *(f"q{i}" for i in range(8))]
    _write(
        path,
        columns,
        (
            [str(j), repr(j * 1e-3), *(repr(0.1 * i + j * 1e-7) for i in range(8))]
            for j in range(count)
        ),
    )
    table, peak = _read_with_peak(path)
    assert table.rows == count
    cells = count * len(columns)
    assert peak < 1.5 * 8 * cells < os.path.getsize(path)


def test_a_file_that_gives_more_than_its_size_is_refused(tmp_path):
    pagemap = "/proc/self/pagemap"  # a regular file of size 0 that gives without end
    if not os.path.isfile(pagemap) or os.path.getsize(pagemap) != 0:
        pytest.skip("no /proc/self/pagemap of size 0 here")
    (tmp_path / "ticks.csv").symlink_to(pagemap)
    with pytest.raises(ValueError, match=r"ticks.csv' gives more bytes than its size"):
        read_table(tmp_path / "ticks.csv", ("t_s",))


def test_a_name_given_twice_is_read_from_its_last_column(tmp_path):
    # As rows read into a mapping by name kept it; the names in the order they first come.
    path = tmp_path / "states.csv"
    _write(path, ["j", "q1", "q2", "q1"], [["0", "1.0", "2.0", "3.0"]])
    table = read_table(path, None, indices=("j",))
    assert table.header == ["j", "q1", "q2"]
    assert table["q1"].tolist() == [3.0] and table["q2"].tolist() == [2.0]


def test_an_index_beyond_18_digits_is_refused_naming_the_line(tmp_path):
    path = tmp_path / "applied.csv"
    _write(path, ["seq", "applied_s"], [["1", "0.5"], ["9" * 25, "0.6"]])
    with pytest.raises(ValueError, match=r"applied.csv, line 3: column 'seq' holds '9{20}'"):
        read_table(path, ("applied_s",), indices=("seq",))


def test_rows_of_many_columns_take_memory_of_the_order_of_their_cells(tmp_path):
    # A chunk of rows is held as texts until converted: bounded by its cells, not its rows.
    path = tmp_path / "states.csv"
    width, count = 5000, 200
    header = ["j", *(f"q{i}" for i in range(width))]
    rows = ([str(j), *(repr(j + 1e-3 * i) for i in range(width))] for j in range(count))
    _write(path, header, rows)
    table, peak = _read_with_peak(path)
    assert table.rows == count and table["q4999"][-1] == 199 + 4.999
    assert peak < 2 * 8 * count * (width + 1)  # the texts of all rows: several times as much
