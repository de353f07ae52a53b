"""The one per-cell CSV table: ``compute``'s CELLS.csv, which ``zones`` writes with a
``zone`` column added, and the number format of every CSV the commands write.

One row per cell with at least ``min_points`` points; numbers at full precision
(the shortest text that reads back to the same float); an empty field where a cell
has no value.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TextIO

import numpy as np

from rough_viewer.grid.roughness import GridRoughness
from rough_viewer.io.output import write_atomic

CSV_COLUMNS = (
    "ix", "iy", "iz", "cx", "cy", "cz", "n_points",
    "theta_odr", "theta_ols", "theta_hybrid", "e_ols",
    "normal_x", "normal_y", "normal_z",
)


def fmt_column(values: np.ndarray) -> list[str]:
    """Shortest round-trip text of each value (full precision); NaN -> empty."""
    values = np.asarray(values)
    if np.issubdtype(values.dtype, np.integer):
        return values.astype(str).tolist()
    text = values.astype(str)
    text[~np.isfinite(values)] = ""
    return text.tolist()


def cells_csv_rows(
    result: GridRoughness, extra: Mapping[str, np.ndarray] | None = None
) -> list[list[str]]:
    """Columns (as text) of the CELLS.csv for cells with at least ``min_points``
    points: :data:`CSV_COLUMNS`, then each ``extra`` (M,) per-cell array."""
    keep = result.n_points >= result.min_points
    cols = [
        result.ijk[keep, 0], result.ijk[keep, 1], result.ijk[keep, 2],
        result.centre[keep, 0], result.centre[keep, 1], result.centre[keep, 2],
        result.n_points[keep],
        result.theta_odr[keep], result.theta_ols[keep], result.theta_hybrid[keep],
        result.e_ols[keep],
        result.normal[keep, 0], result.normal[keep, 1], result.normal[keep, 2],
    ]
    cols += [np.asarray(v)[keep] for v in (extra or {}).values()]
    return [fmt_column(np.asarray(c)) for c in cols]


def write_csv(path: Path, header: Sequence[str], cols: Sequence[list[str]]) -> None:
    """Write text columns under ``header`` atomically (temporary file, then rename)."""

    def write(fh: TextIO) -> None:
        fh.write(",".join(header) + "\n")
        for row in zip(*cols, strict=True):
            fh.write(",".join(row))
            fh.write("\n")

    write_atomic(path, write)  # type: ignore[arg-type]


def write_cells_csv(
    path: Path, result: GridRoughness, extra: Mapping[str, np.ndarray] | None = None
) -> None:
    """Write CELLS.csv (and the ``extra`` columns) atomically."""
    write_csv(path, (*CSV_COLUMNS, *(extra or {})), cells_csv_rows(result, extra))
