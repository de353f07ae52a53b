"""The one cell-table writer: CSV (the compute contract) and Parquet."""

from __future__ import annotations

import csv
import sys

import numpy as np
import pytest

from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.grid.table import CELL_COLUMNS, cell_columns, table_metadata
from rough_viewer.io.table import check_table_output, table_format, write_table
from rough_viewer.vocabulary import InputError
from tests.helpers import rough_surface


@pytest.fixture(scope="module")
def result():
    return grid_roughness(rough_surface(6000, seed=4, size=3.0), 0.12, min_points=4)


def test_csv_round_trip_is_exact(tmp_path, result):
    path = tmp_path / "cells.csv"
    write_table(path, cell_columns(result))
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    assert tuple(rows[0]) == CELL_COLUMNS
    keep = result.n_points >= 4
    assert len(rows) - 1 == keep.sum() and keep.sum() < result.n_cells
    for k, name in enumerate(CELL_COLUMNS):
        want = cell_columns(result)[name]
        got = [r[k] for r in rows[1:]]
        for text, value in zip(got, want, strict=True):
            if value is np.ma.masked or np.isnan(value):  # masked: an unknown whole number
                assert text == ""
            else:
                assert type(value.item())(text) == value  # int stays int, float is exact


def test_csv_in_blocks(tmp_path, monkeypatch):
    import rough_viewer.io.table as table

    monkeypatch.setattr(table, "CSV_BLOCK_ROWS", 7)
    cols = {"a": np.arange(30), "b": np.linspace(0, 1, 30)}
    write_table(tmp_path / "t.csv", cols)
    lines = (tmp_path / "t.csv").read_text().splitlines()
    assert lines[0] == "a,b" and len(lines) == 31
    assert [float(line.split(",")[1]) for line in lines[1:]] == cols["b"].tolist()


def test_parquet_round_trip(tmp_path, result):
    pq = pytest.importorskip("pyarrow.parquet")
    path = tmp_path / "cells.parquet"
    cols = cell_columns(result)
    write_table(path, cols, metadata=table_metadata(result, "scan.laz"))
    table = pq.read_table(path)
    assert tuple(table.column_names) == CELL_COLUMNS
    for name in CELL_COLUMNS:
        want = cols[name]
        if isinstance(want, np.ma.MaskedArray):  # scanner columns without positions: null
            assert table.column(name).null_count == int(np.ma.count_masked(want))
            continue
        got = table.column(name).to_numpy(zero_copy_only=False)
        assert got.dtype == want.dtype or np.issubdtype(want.dtype, np.floating)
        np.testing.assert_array_equal(np.asarray(got, dtype=want.dtype), want)
        if np.issubdtype(want.dtype, np.floating):
            assert table.column(name).null_count == int(np.isnan(want).sum())
    meta = table.schema.metadata
    assert meta[b"rough_viewer.grid_size_m"] == b"0.12" and meta[b"rough_viewer.input"] == b"scan.laz"


def test_parquet_without_pyarrow_is_one_line(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "pyarrow", None)
    with pytest.raises(InputError, match=r"needs the optional package pyarrow: pip install"):
        check_table_output(tmp_path / "cells.parquet")
    check_table_output(tmp_path / "cells.csv")
    assert table_format("x.PARQUET") == "parquet" and table_format("x.txt") == "csv"


def test_ragged_columns_refused(tmp_path):
    with pytest.raises(InputError, match="shape"):
        write_table(tmp_path / "t.csv", {"a": np.arange(3), "b": np.arange(4)})
    assert not (tmp_path / "t.csv").exists()


def test_csv_floats_are_the_shortest_text_that_reads_back():
    """Full precision in the fewest digits (numpy's own float text), NaN and inf empty."""
    from rough_viewer.io.table import format_column

    rng = np.random.default_rng(3)
    values = np.concatenate([rng.normal(size=5_000) * 10.0 ** rng.integers(-30, 30, 5_000),
                             [0.0, -0.0, 1e16, 1e-5, 5e-324, 0.1, 512_000.125, np.nan, -np.inf]])
    text = format_column(values)
    ok = np.isfinite(values)
    assert [t for t, f in zip(text, ok, strict=True) if not f] == ["", ""]
    np.testing.assert_array_equal(np.array([float(t) for t in np.array(text)[ok]]), values[ok])
    assert [t for t, f in zip(text, ok, strict=True) if f] == values[ok].astype(str).tolist()
