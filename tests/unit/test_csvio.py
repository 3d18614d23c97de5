"""CSV tables per ICD §1: what is kept, what is dropped and counted, what is refused."""

from __future__ import annotations

import time

import numpy as np
import pytest

from gcs_core.errors import InputError
from gcs_core.io.csvio import read_table, write_table

MAG = ("t", "bx", "by", "bz")


def write(tmp_path, text, name="TAM1.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


def refused(path, **kw) -> str:
    with pytest.raises(InputError) as info:
        read_table(path, **kw)
    message = str(info.value)
    assert "\n" not in message
    assert str(path) in message
    return message


def test_reads_comments_header_extra_columns(tmp_path):
    path = write(
        tmp_path,
        "# produced by a simulator\n# second comment\n"
        "t,bx,by,bz,temp\n0,1,2,3,20\n1,4,5,6,21\n\n# late comment\n2,7,8,9,22\n",
    )
    table = read_table(path, required=MAG)
    assert len(table) == 3
    assert list(table.columns) == ["t", "bx", "by", "bz", "temp"]
    np.testing.assert_array_equal(table.t, [0, 1, 2])
    np.testing.assert_array_equal(table.columns["temp"], [20, 21, 22])
    np.testing.assert_array_equal(table.lines, [4, 5, 8])
    assert table.stack(["bx", "bz"]).shape == (3, 2)
    assert table.dropped_nan == 0 and table.dropped_duplicates == 0


def test_whitespace_crlf_and_bom_are_accepted(tmp_path):
    path = tmp_path / "x.csv"
    path.write_bytes("\ufeff t , bx\r\n0 , 1.5\r\n1,  -2e3 \r\n".encode())
    table = read_table(path, required=("t", "bx"))
    np.testing.assert_array_equal(table.columns["bx"], [1.5, -2000.0])


def test_empty_field_and_nan_drop_the_row_and_are_counted(tmp_path):
    path = write(tmp_path, "t,bx,by,bz\n0,1,2,3\n1,,2,3\n2,nan,2,3\n3,1,NaN,3\n4,1,2, \n5,1,2,3\n")
    table = read_table(path, required=MAG)
    np.testing.assert_array_equal(table.t, [0, 5])
    np.testing.assert_array_equal(table.lines, [2, 7])
    assert table.dropped_nan == 4


def test_exact_duplicate_rows_are_dropped_and_counted(tmp_path):
    path = write(tmp_path, "t,bx,by,bz\n0,1,2,3\n1,4,5,6\n1,4,5,6\n1,4.0,5,6\n2,7,8,9\n")
    table = read_table(path, required=MAG)
    np.testing.assert_array_equal(table.t, [0, 1, 2])
    assert table.dropped_duplicates == 2


def test_same_time_different_rows_refused(tmp_path):
    path = write(tmp_path, "t,bx,by,bz\n0,1,2,3\n1,4,5,6\n1,4,5,7\n")
    message = refused(path, required=MAG)
    assert f"{path}:4:4:" in message
    assert "lines 3 and 4" in message and "'bz'" in message


def test_unsorted_times_refused(tmp_path):
    path = write(tmp_path, "t,bx,by,bz\n0,1,2,3\n2,4,5,6\n1,4,5,7\n")
    message = refused(path, required=MAG)
    assert f"{path}:4:1:" in message and "sorted" in message and "'t'" in message


def test_missing_required_column_refused(tmp_path):
    path = write(tmp_path, "# c\nt,bx,by\n0,1,2\n")
    message = refused(path, required=MAG, what="magnetometer telemetry")
    assert f"{path}:2" in message and "column 'bz'" in message and "missing" in message


def test_text_in_a_number_refused_with_line_and_column(tmp_path):
    path = write(tmp_path, "t,bx,by,bz\n0,1,2,3\n1,4,abc,6\n")
    message = refused(path, required=MAG)
    assert f"{path}:3:3:" in message and "'abc'" in message and "'by'" in message


def test_inf_refused(tmp_path):
    path = write(tmp_path, "t,bx,by,bz\n0,1,2,3\n1,4,5,-inf\n")
    message = refused(path, required=MAG)
    assert f"{path}:3:4:" in message and "infinite" in message


@pytest.mark.parametrize("row,column", [("1,4,5", 4), ("1,4,5,6,7", 5)])
def test_wrong_number_of_fields_refused(tmp_path, row, column):
    path = write(tmp_path, f"t,bx,by,bz\n0,1,2,3\n{row}\n")
    message = refused(path, required=MAG)
    assert f"{path}:3:{column}:" in message and "fields" in message


@pytest.mark.parametrize(
    "text,needle",
    [
        ("", "empty file"),
        ("# only a comment\n", "empty file"),
        ("0,1,2,3\n1,2,3,4\n", "no header line"),
        ("t,bx,bx,bz\n0,1,2,3\n", "appears twice"),
        ("t,,by,bz\n0,1,2,3\n", "empty column name"),
    ],
)
def test_bad_headers_refused(tmp_path, text, needle):
    assert needle in refused(write(tmp_path, text), required=MAG)


def test_not_utf8_and_missing_file_refused(tmp_path):
    path = tmp_path / "bin.csv"
    path.write_bytes(b"t,bx\n0,1\n1,\xff\n")
    assert f"{path}:3:2:" in refused(path)
    assert "not found" in refused(tmp_path / "absent.csv")


def test_header_only_gives_an_empty_table(tmp_path):
    table = read_table(write(tmp_path, "t,bx,by,bz\n"), required=MAG)
    assert len(table) == 0 and table.stack(["bx"]).shape == (0, 1)


def test_write_then_read_round_trips_exactly(tmp_path):
    rng = np.random.default_rng(7)
    cols = {"t": np.arange(50.0), "bx": rng.normal(size=50) * 1e4, "tiny": rng.normal(size=50) * 1e-12}
    path = write_table(tmp_path / "rt.csv", cols, comments=["written by a test"])
    table = read_table(path, required=("t", "bx"))
    for name, values in cols.items():
        np.testing.assert_array_equal(table.columns[name], values)
    assert not list(tmp_path.glob(".*.tmp"))


def test_600k_rows_read_fast(tmp_path):
    """ICD §1 files of 600 000 rows (a week of 1 Hz data) must read in a few seconds."""
    n = 600_000
    rng = np.random.default_rng(1)
    lines = np.column_stack([np.arange(n, dtype=float), rng.integers(-40000, 40000, (n, 3))])
    path = tmp_path / "big.csv"
    with open(path, "w") as fh:
        fh.write("t,bx,by,bz\n")
        np.savetxt(fh, lines, fmt="%.3f", delimiter=",")
    start = time.perf_counter()
    table = read_table(path, required=MAG)
    elapsed = time.perf_counter() - start
    assert len(table) == n
    assert elapsed < 6.0, f"600k rows took {elapsed:.1f} s"
