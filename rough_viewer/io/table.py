"""Tables out: one writer for every per-cell (or per-zone) table, as CSV or Parquet.

CSV is the ``compute`` contract: a header line, then one row per record; numbers at
full precision (the shortest text that reads back to the same float64), an empty
field where a value is NaN (or masked, in an integer column given as a masked array). Parquet (``.parquet``, needs the optional package
pyarrow: ``pip install 'rough_viewer[parquet]'``) keeps the column types, with null
where a float is NaN. Both are written atomically (:mod:`rough_viewer.io.output`).

>>> import numpy as np
>>> format_column(np.array([0.1, np.nan, 1e-300]))
['0.1', '', '1e-300']
"""

from __future__ import annotations

import importlib.util
import os
from collections.abc import Mapping
from pathlib import Path
from typing import IO, Any, Literal

import numpy as np

from rough_viewer.io.output import write_atomic, write_path_atomic
from rough_viewer.memory import require
from rough_viewer.vocabulary import UNIT_METRES, InputError

TableFormat = Literal["csv", "parquet"]

#: Rows formatted at a time when writing CSV (bounds the memory of the text).
CSV_BLOCK_ROWS = 100_000

#: Last column of every written table: metres per unit of its lengths (1 for m, 0.001
#: for mm, 0.3048 for ft, 1200/3937 for US ft), a number so that readers of an
#: all-numeric table (``numpy.loadtxt``) still read it.
UNIT_COLUMN = "unit_m"

PARQUET_HINT = "pip install 'rough_viewer[parquet]' (or pip install pyarrow)"


def table_format(path: str | os.PathLike[str]) -> TableFormat:
    """The format chosen by the file name: ``.parquet`` -> Parquet, anything else CSV."""
    return "parquet" if Path(path).suffix.lower() in (".parquet", ".pq") else "csv"


def check_table_output(path: str | os.PathLike[str]) -> None:
    """Raise InputError (one line) when ``path`` asks for Parquet and pyarrow is
    missing; call with the other output checks, before any work."""
    if table_format(path) == "parquet" and importlib.util.find_spec("pyarrow") is None:
        raise InputError(f"Parquet output ({path}) needs the optional package pyarrow: "
                         f"{PARQUET_HINT}")


def format_column(values: np.ndarray) -> list[str]:
    """Text of each value: integers as they are, floats as the shortest text that
    reads back to the same float64 (full precision), NaN or infinite -> ``""``; the
    masked entries of a masked array (an integer column with unknown values) -> ``""``.

    >>> format_column(np.ma.masked_array([2, 0, 1], mask=[False, True, False]))
    ['2', '', '1']
    """
    if isinstance(values, np.ma.MaskedArray):
        masked = np.array(format_column(np.ma.getdata(values)), dtype=object)
        masked[np.ma.getmaskarray(values)] = ""
        return masked.tolist()
    if np.issubdtype(values.dtype, np.integer) or values.dtype == np.bool_:
        return values.astype(np.int64).astype(str).tolist()
    # Python's repr is the shortest round-trip text, as numpy's str, at twice its speed
    text = list(map(repr, values.astype(np.float64).tolist()))
    for i in np.flatnonzero(~np.isfinite(values)).tolist():
        text[i] = ""
    return text


def _columns(columns: Mapping[str, np.ndarray]) -> tuple[list[str], list[np.ndarray], int]:
    names = list(columns)
    if not names:
        raise InputError("a table needs at least one column")
    arrays = [np.asanyarray(columns[n]) for n in names]  # masked arrays stay masked
    n = int(arrays[0].shape[0])
    for name, a in zip(names, arrays, strict=True):
        if a.ndim != 1 or a.shape[0] != n:
            raise InputError(f"table column {name!r} has shape {a.shape}, expected ({n},)")
        if "," in name or "\n" in name:
            raise InputError(f"table column name {name!r} cannot be written as CSV")
    return names, arrays, n


def write_table(
    path: str | os.PathLike[str],
    columns: Mapping[str, np.ndarray],
    *,
    metadata: Mapping[str, str] | None = None,
    unit: str | None = None,
) -> None:
    """Write a table atomically, CSV or Parquet by the file's suffix.

    Every table the commands and the app write states its unit: with ``unit`` (the
    lengths' unit code, ``m``, ``mm``, ``ft``, ``us-ft``) a last column
    :data:`UNIT_COLUMN` holds the metres per unit on every row (a CSV has nowhere
    else to say it; columns read by name or position are unaffected) and a Parquet
    file's schema has ``rough_viewer.unit`` (the code) too.

    Parameters
    ----------
    path : path-like
        Output file; ``.parquet`` writes Parquet, any other suffix CSV.
    columns : mapping
        Column name -> (R,) array, in output order, all of one length R.
    metadata : mapping, optional
        Key-value notes stored in a Parquet file's schema (e.g. units); CSV has none.
    """
    if unit is not None:
        first = next(iter(columns.values()), None)
        rows = 0 if first is None else int(np.shape(first)[0])
        if unit not in UNIT_METRES:
            raise InputError(f"unknown unit {unit!r}; expected one of {', '.join(UNIT_METRES)}")
        columns = {**columns, UNIT_COLUMN: np.full(rows, float(UNIT_METRES[unit]))}
        metadata = {**(metadata or {}), "rough_viewer.unit": str(unit)}
    names, arrays, n = _columns(columns)
    if table_format(path) == "parquet":
        check_table_output(path)
        _write_parquet(Path(path), names, arrays, dict(metadata or {}))
        return
    # text of one block: about 25 characters per field as numpy text and Python str
    require(min(n, CSV_BLOCK_ROWS) * len(names) * 200.0, f"writing the table {path}")

    def write(fh: IO[Any]) -> None:
        fh.write(",".join(names) + "\n")
        for start in range(0, n, CSV_BLOCK_ROWS):
            block = [format_column(a[start:start + CSV_BLOCK_ROWS]) for a in arrays]
            fh.write("".join(",".join(row) + "\n" for row in zip(*block, strict=True)))

    write_atomic(path, write)


def _write_parquet(path: Path, names: list[str], arrays: list[np.ndarray],
                   metadata: dict[str, str]) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    require(sum(a.nbytes for a in arrays) * 3.0, f"writing the table {path}")
    fields = []
    for a in arrays:
        if isinstance(a, np.ma.MaskedArray):
            fields.append(pa.array(np.ma.getdata(a), mask=np.ma.getmaskarray(a)))
        elif np.issubdtype(a.dtype, np.floating):
            fields.append(pa.array(a, mask=~np.isfinite(a)))
        else:
            fields.append(pa.array(a))
    table = pa.Table.from_arrays(fields, names=names)
    if metadata:
        table = table.replace_schema_metadata({k: str(v) for k, v in metadata.items()})
    write_path_atomic(path, lambda tmp: pq.write_table(table, tmp))
