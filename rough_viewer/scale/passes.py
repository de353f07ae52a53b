"""The two passes over a chunk of points, as pure functions of the chunk's
coordinates: the per-chunk map of the chunked and Dask paths.

Both reuse the grid's own code (:mod:`rough_viewer.grid.cells`): the chunk is
indexed on a sub-grid of the global grid (same origin and cell size, the chunk's own
extent), whose cell indices ``ijk`` are the global ones; :func:`global_keys` turns
them into keys of the global grid. Moments and distances are then taken by
:func:`~rough_viewer.grid.cells.cell_moments` and
:func:`~rough_viewer.grid.cells.distance_sums` exactly as the in-memory path takes
them, relative to the same cell centres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rough_viewer.grid.cells import (
    CellIndex,
    CellMoments,
    GridSpec,
    cell_moments,
    distance_sums,
    index_points,
    make_grid,
)
from rough_viewer.scale.partials import Partial
from rough_viewer.vocabulary import Engine

#: Value columns of a moments table: count, sums of x, y, z, then of xx, xy, xz, yy,
#: yz, zz (cell-local coordinates, metres and square metres).
MOMENT_COLUMNS = 10
_PAIRS = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))

#: Dense cell bookkeeping of a chunk is allowed up to this many cells of its
#: bounding grid, or 4 per point (beyond: the sort-based path), so a chunk's memory
#: stays proportional to its points.
CHUNK_DENSE_LIMIT = 1 << 20


class OutsideGrid(Exception):
    """A chunk has points outside the grid fixed before the pass (a LAS header whose
    bounding box is wrong): the pass is run again on the measured bounds."""


def global_keys(ijk: np.ndarray, grid: GridSpec) -> np.ndarray:
    """(M,) int64 keys ``i + nx (j + ny k)`` (relative to ``grid.index_min``) of cell
    indices ``ijk`` on the global grid; :class:`OutsideGrid` if any lies outside."""
    rel = ijk - grid.index_min
    shape = np.asarray(grid.shape, dtype=np.int64)
    if rel.size and (rel.min() < 0 or np.any(rel.max(axis=0) >= shape)):
        raise OutsideGrid
    return (rel[:, 2] * shape[1] + rel[:, 1]) * shape[0] + rel[:, 0]


def decode_keys(keys: np.ndarray, grid: GridSpec) -> np.ndarray:
    """(M, 3) cell indices of global keys (inverse of :func:`global_keys`)."""
    nx, ny = int(grid.shape[0]), int(grid.shape[1])
    k = keys // (nx * ny)
    rem = keys - k * (nx * ny)
    j = rem // nx
    return np.stack([rem - j * nx, j, k], axis=1) + grid.index_min


def _chunk_index(x: np.ndarray, y: np.ndarray, z: np.ndarray, grid: GridSpec,
                 engine: Engine, box: tuple[np.ndarray, np.ndarray] | None = None
                 ) -> CellIndex:
    """The chunk's points on the sub-grid of ``grid`` over their box (``box``: the
    box, where known already)."""
    if box is None:
        lo = np.array([x.min(), y.min(), z.min()])
        hi = np.array([x.max(), y.max(), z.max()])
    else:
        lo, hi = box
    sub = make_grid(lo, hi, grid.cell_size, grid.origin)
    return index_points(x, y, z, sub, engine=engine, dense_limit=CHUNK_DENSE_LIMIT)


def chunk_moments(x: np.ndarray, y: np.ndarray, z: np.ndarray, grid: GridSpec,
                  engine: Engine = "auto") -> Partial:
    """Pass 1 on one chunk: count and cell-local moment sums per cell.

    Parameters
    ----------
    x, y, z : (n,) float64
        The chunk's points, metres.
    grid : GridSpec
        The global grid.
    engine : {"auto", "numpy", "numba"}
        Engine of the point passes.

    Returns
    -------
    Partial
        :data:`MOMENT_COLUMNS` columns per cell, with the chunk's bounding box.

    Raises
    ------
    OutsideGrid
        If a point lies outside ``grid``.
    """
    lo = np.array([x.min(), y.min(), z.min()])
    hi = np.array([x.max(), y.max(), z.max()])
    index = _chunk_index(x, y, z, grid, engine, (lo, hi))
    keys = global_keys(index.ijk, grid)
    values = moment_columns(cell_moments(x, y, z, index, engine=engine))
    return Partial(keys=keys, values=values, n_points=int(x.shape[0]), bounds_min=lo,
                   bounds_max=hi)


def moment_columns(mom: CellMoments) -> np.ndarray:
    """(M, :data:`MOMENT_COLUMNS`) the table columns of cells' moments: count, the
    sums of x, y, z, then the six distinct products (inverse of :func:`moments_of`)."""
    values = np.empty((mom.counts.shape[0], MOMENT_COLUMNS))
    values[:, 0] = mom.counts
    values[:, 1:4] = mom.s1
    for c, (a, b) in enumerate(_PAIRS, start=4):
        values[:, c] = mom.s2[:, a, b]
    return values


def moments_of(table: Partial) -> CellMoments:
    """The :class:`~rough_viewer.grid.cells.CellMoments` of a reduced moments table."""
    v = table.values
    s2 = np.empty((table.n_cells, 3, 3))
    for c, (a, b) in enumerate(_PAIRS, start=4):
        s2[:, a, b] = v[:, c]
        s2[:, b, a] = v[:, c]
    return CellMoments(counts=np.rint(v[:, 0]).astype(np.int64), s1=np.ascontiguousarray(v[:, 1:4]),
                       s2=s2)


@dataclass(frozen=True)
class PlaneTable:
    """What pass 2 needs of every cell: its key and the vectors and reference points
    of its distances (one entry per distance kind, e.g. ``odr``, ``ols``)."""

    keys: np.ndarray
    """(M,) int64 global cell keys, sorted."""
    names: tuple[str, ...]
    """Distance kinds, in column order of the distance table."""
    vectors: np.ndarray
    """(Q, M, 3) per-cell vectors."""
    points: np.ndarray
    """(Q, M, 3) per-cell reference points relative to the cell centre, metres."""


def chunk_distances(x: np.ndarray, y: np.ndarray, z: np.ndarray, grid: GridSpec,
                    planes: PlaneTable, engine: Engine = "auto") -> Partial:
    """Pass 2 on one chunk: sums of ``|D|`` and ``D^2`` per cell and distance kind.

    Returns
    -------
    Partial
        Keys = rows of ``planes`` (not cell keys: the cells are known by now);
        ``2 Q`` columns: for each kind ``q``, sum of ``|D|`` then sum of ``D^2``.
    """
    index = _chunk_index(x, y, z, grid, engine)
    rows = np.searchsorted(planes.keys, global_keys(index.ijk, grid))
    vectors = {name: (planes.vectors[q][rows], planes.points[q][rows])
               for q, name in enumerate(planes.names)}
    sums = distance_sums(x, y, z, index, vectors, engine=engine)
    values = np.empty((index.n_cells, 2 * len(planes.names)))
    for q, name in enumerate(planes.names):
        values[:, 2 * q] = sums[name][0]
        values[:, 2 * q + 1] = sums[name][1]
    return Partial(keys=rows.astype(np.int64), values=values, n_points=int(x.shape[0]))
