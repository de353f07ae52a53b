"""Per-point values that come from a per-cell table: what the LAS/LAZ and PLY writers
attach to every point (each point gets the value of its grid cell).

Kept as per-cell arrays plus one point -> cell map, never as N-long copies, so a
writer can gather them chunk by chunk and memory stays bounded.

>>> import numpy as np
>>> f = PointFields(
...     fields=(CellField("theta", np.array([0.1, 0.2], np.float32), "roughness (m)",
...                       np.float32(np.nan)),),
...     point_cell=np.array([1, 0, 1]))
>>> [v.tolist() for v in f.gather_rows(np.array([True, False, True, True]), 0)]
[[0.20000000298023224, nan, 0.10000000149011612, 0.20000000298023224]]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rough_viewer.vocabulary import InputError


@dataclass(frozen=True)
class CellField:
    """One per-point value taken from a per-cell array."""

    name: str
    """Dimension / property name (LAS extra bytes: at most 32 characters)."""
    cell_values: np.ndarray
    """(M,) one value per cell, in the output's dtype."""
    description: str
    """What it is, with its unit (LAS extra bytes: at most 32 characters)."""
    fill: np.generic
    """Value for a point that belongs to no cell (a row dropped as non-finite)."""

    @property
    def dtype(self) -> np.dtype:
        """The output type."""
        return self.cell_values.dtype


@dataclass(frozen=True)
class PointFields:
    """Per-point fields of a cloud: per-cell arrays and the cell of every point."""

    fields: tuple[CellField, ...]
    """The fields, in output order."""
    point_cell: np.ndarray
    """(N,) row of the cell arrays for every point of the cloud (the finite rows of
    the input file, in file order)."""

    def __post_init__(self) -> None:
        names = [f.name for f in self.fields]
        if len(set(names)) != len(names):
            raise InputError(f"duplicate point field names: {names}")
        for f in self.fields:
            if len(f.name) > 32 or len(f.description) > 32:
                raise InputError(f"point field {f.name!r}: name and description must have "
                                 "at most 32 characters (LAS extra bytes)")

    @property
    def names(self) -> tuple[str, ...]:
        """Field names in output order."""
        return tuple(f.name for f in self.fields)

    @property
    def n_points(self) -> int:
        """Points of the cloud (N)."""
        return int(self.point_cell.shape[0])

    @property
    def bytes_per_point(self) -> int:
        """Bytes of one point's fields."""
        return int(sum(f.dtype.itemsize for f in self.fields))

    def gather(self, start: int, stop: int) -> list[np.ndarray]:
        """Values of cloud points ``start:stop``, one array per field."""
        cells = self.point_cell[start:stop]
        return [f.cell_values[cells] for f in self.fields]

    def gather_rows(self, kept: np.ndarray, start: int) -> list[np.ndarray]:
        """Values of a block of file rows.

        Parameters
        ----------
        kept : (m,) bool
            Which rows of the block are in the cloud (finite coordinates); the others
            get each field's ``fill``.
        start : int
            Cloud index of the block's first kept row.
        """
        n_kept = int(np.count_nonzero(kept))
        if start + n_kept > self.n_points:
            raise InputError("the input has more finite points than when it was read "
                             "(did the file change?)")
        values = self.gather(start, start + n_kept)
        if n_kept == kept.shape[0]:
            return values
        out = []
        for f, v in zip(self.fields, values, strict=True):
            full = np.full(kept.shape[0], f.fill, dtype=f.dtype)
            full[kept] = v
            out.append(full)
        return out
