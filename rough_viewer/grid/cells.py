"""The one grid: cubic cells of edge ``g``, point-to-cell indexing and per-cell sums.

docs/science.md section 1: origin ``o`` = bounding-box minimum unless given; cell index of
a point ``i = floor((p - o) / g)`` per axis; cell centre ``o + (i + 0.5) g``.

Points are passed as three float64 columns (structure of arrays). Work is done in
chunks of points so no stage allocates several full-length temporaries, and the
per-cell sums are taken in cell-local coordinates (relative to the cell centre) so
that UTM-sized coordinates lose no precision.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from rough_viewer.grid.keys import DENSE_LIMIT, dense_bookkeeping
from rough_viewer.grid.keys import chunk_size as _chunk_size
from rough_viewer.grid.keys import decode_keys as _decode_keys
from rough_viewer.memory import require
from rough_viewer.vocabulary import Engine, InputError

#: Largest total number of grid cells (occupied or not) we can key with int64.
MAX_GRID_CELLS = 2**62
#: Bytes per occupied cell of the result arrays (moments, planes, maps), an estimate
#: used to refuse grids that cannot fit in memory.
BYTES_PER_CELL = 400


@dataclass(frozen=True)
class GridSpec:
    """A regular grid of cubic cells."""

    origin: np.ndarray
    """(3,) grid origin, metres (cell (0, 0, 0) starts here)."""
    cell_size: float
    """Cell edge length, metres."""
    index_min: np.ndarray
    """(3,) int64, smallest cell index that holds points (0 when origin = bbox min)."""
    shape: tuple[int, int, int]
    """Number of cells per axis between ``index_min`` and the largest occupied index."""

    @property
    def n_cells(self) -> int:
        """Total number of cells of the bounding grid (occupied or not)."""
        return int(self.shape[0]) * int(self.shape[1]) * int(self.shape[2])

    def centres(self, ijk: np.ndarray) -> np.ndarray:
        """Cell centres ``o + (ijk + 0.5) g`` of an (M, 3) index array, metres."""
        return self.origin + (np.asarray(ijk, dtype=np.float64) + 0.5) * self.cell_size


#: Largest grid size, as a multiple of the cloud's largest extent, :func:`make_grid`
#: takes: beyond it one cell already holds the whole cloud, and the cell-local
#: moments lose the cloud's variance to round-off (at 1e6 m over a 270 m scan the
#: whole-cloud cell had no ODR plane; 1e300 m overflowed).
MAX_SIZE_OVER_EXTENT = 1000.0


#: The finest fraction of a cell that a point's offset from a given grid origin must
#: resolve (float64 keeps ~16 digits: an origin 1e15 m away resolves only 0.125 m).
ORIGIN_RESOLUTION = 1e-6

def make_grid(
    bounds_min: np.ndarray,
    bounds_max: np.ndarray,
    cell_size: float,
    origin: np.ndarray | None = None,
    *,
    n_points: int | None = None,
) -> GridSpec:
    """The grid of edge ``cell_size`` covering a bounding box.

    Parameters
    ----------
    bounds_min, bounds_max : (3,) array_like
        Bounding box of the points, metres.
    cell_size : float
        Cell edge, metres; must be positive and finite.
    origin : (3,) array_like, optional
        Grid origin, metres. Default: ``bounds_min``.
    n_points : int, optional
        Number of points, to refuse grids whose occupied cells could not fit in
        memory.

    Raises
    ------
    InputError
        If ``cell_size`` is not positive or the grid would need too many cells.
    """
    g = float(cell_size)
    if not np.isfinite(g) or g <= 0:
        raise InputError(f"grid size must be a positive number of metres, got {cell_size}")
    lo_b = np.asarray(bounds_min, dtype=np.float64)
    hi_b = np.asarray(bounds_max, dtype=np.float64)
    o = lo_b.copy() if origin is None else np.asarray(origin, dtype=np.float64).copy()
    span = (hi_b - o) / g
    first = (lo_b - o) / g
    if not (np.all(np.isfinite(span)) and np.all(np.isfinite(first))):
        raise InputError(f"grid size {g:g} m is too small for this cloud's extent")
    if origin is not None:
        # a point's cell is floor((x - o) / g): far from the cloud, x - o keeps too few
        # digits to place points in their cells (at -1e15 m, 541 cells instead of 525)
        far = float(np.max(np.maximum(np.abs(lo_b - o), np.abs(hi_b - o))))
        resolved = float(np.spacing(far))
        if resolved > ORIGIN_RESOLUTION * g:
            raise InputError(
                f"the grid origin is {far:.3g} m from the cloud: offsets there resolve only "
                f"{resolved:.3g} m, more than {ORIGIN_RESOLUTION:g} of the {g:g} m grid, so "
                "points would land in the wrong cells; choose an origin near the cloud")
    index_min = np.floor(first)
    index_max = np.floor(span)
    counts = index_max - index_min + 1
    total = float(counts[0]) * float(counts[1]) * float(counts[2])  # inf, not a warning, on overflow
    if total > MAX_GRID_CELLS or np.any(np.abs(index_max) > 2**53) or np.any(np.abs(index_min) > 2**53):
        raise InputError(
            f"grid size {g:g} m would take {total:.3g} cells over the cloud's extent; "
            "choose a larger grid size"
        )
    if n_points is not None:
        occupied_max = min(total, float(n_points))
        require(occupied_max * BYTES_PER_CELL,
                f"grid size {g:g} m (up to {occupied_max:.3g} occupied cells)",
                hint="choose a larger grid size")
    extent = float(np.max(hi_b - lo_b))
    if extent > 0 and g > MAX_SIZE_OVER_EXTENT * extent:
        # cell-local sums of squares over a cell far larger than the cloud lose the
        # cloud's variance to round-off (and overflow for absurd sizes)
        raise InputError(
            f"grid size {g:g} m is more than {MAX_SIZE_OVER_EXTENT:g} times the cloud's "
            f"extent ({extent:.4g} m); one cell holds the whole cloud at "
            f"{extent:.4g} m already: choose a grid size of at most "
            f"{MAX_SIZE_OVER_EXTENT * extent:.4g} m")
    shape = (int(counts[0]), int(counts[1]), int(counts[2]))
    return GridSpec(origin=o, cell_size=g, index_min=index_min.astype(np.int64), shape=shape)


@dataclass(frozen=True)
class CellIndex:
    """Which cell every point falls in, and the occupied cells."""

    grid: GridSpec
    ijk: np.ndarray
    """(M, 3) int64 cell indices of the occupied cells, sorted by linear key (x fastest)."""
    counts: np.ndarray
    """(M,) int64 number of points per occupied cell."""
    point_cell: np.ndarray
    """(N,) int64 index into ``ijk`` for every point."""

    @property
    def n_cells(self) -> int:
        """Number of occupied cells."""
        return int(self.counts.shape[0])


def _chunks(n: int, size: int):
    for start in range(0, n, size):
        yield slice(start, min(n, start + size))


def _local_chunks(x: np.ndarray, y: np.ndarray, z: np.ndarray, index: CellIndex):
    """Yield ``(point_cell, [lx, ly, lz])`` chunk by chunk: the points' coordinates
    relative to their cell centre, metres. Every pass over the points takes its
    cell-local coordinates from here, so the moments and the distances agree exactly."""
    centre = index.grid.centres(index.ijk)
    centre_cols = [np.ascontiguousarray(centre[:, a]) for a in range(3)]
    for s in _chunks(int(x.shape[0]), _chunk_size(index.n_cells)):
        pc = index.point_cell[s]
        yield pc, [col[s] - c[pc] for col, c in zip((x, y, z), centre_cols, strict=True)]


def index_points(
    x: np.ndarray, y: np.ndarray, z: np.ndarray, grid: GridSpec, *, engine: Engine = "numpy",
    dense_limit: int = DENSE_LIMIT,
) -> CellIndex:
    """Assign every point to its grid cell.

    Parameters
    ----------
    x, y, z : (N,) float64 arrays
        Point coordinates, metres.
    grid : GridSpec
        The grid (from :func:`make_grid` over these points' bounds).
    engine : {"numpy", "numba", "auto"}
        ``numpy``: this module's reference code; ``numba``: the compiled kernels of
        :mod:`rough_viewer.grid.fast` (same keys).
    dense_limit : int
        Dense bookkeeping (two int64 per grid cell) is used up to this many cells of
        the grid or ``4 N``, whichever is larger; beyond, a sort (the same result).

    Returns
    -------
    CellIndex
        Occupied cells (in linear-key order), their point counts and the cell of
        every point.
    """
    from rough_viewer.grid import fast

    compiled = fast.resolve_engine(engine) == "numba"
    n = int(x.shape[0])
    total = grid.n_cells
    dense = dense_bookkeeping(total, n, dense_limit)
    if compiled:
        key = fast.cell_keys(x, y, z, grid.origin, grid.cell_size, grid.index_min, grid.shape)
    else:
        key = _cell_keys(x, y, z, grid)
    if dense:
        counts_dense = fast.dense_counts(key, total) if compiled else np.bincount(key, minlength=total)
        occupied = np.flatnonzero(counts_dense)
        counts = counts_dense[occupied]
        del counts_dense
        lookup = np.full(total, -1, dtype=np.int64)
        lookup[occupied] = np.arange(occupied.shape[0], dtype=np.int64)
        if compiled:
            fast.relabel(key, lookup)
        else:
            for s in _chunks(n, 1 << 21):
                key[s] = lookup[key[s]]
        del lookup
        keys_occ = occupied.astype(np.int64)
        point_cell = key
    else:
        keys_occ, point_cell, counts = np.unique(key, return_inverse=True, return_counts=True)
        del key
    ijk = _decode_keys(keys_occ, grid.shape, grid.index_min)
    return CellIndex(grid=grid, ijk=ijk, counts=counts.astype(np.int64), point_cell=point_cell)


def cell_keys_of(ijk: np.ndarray, grid: GridSpec) -> np.ndarray:
    """(M,) int64 linear keys ``i + nx (j + ny k)`` (relative to ``grid.index_min``) of
    cell indices ``ijk`` ((M, 3) int64; -1 for a cell outside the grid)."""
    rel = np.asarray(ijk, dtype=np.int64) - grid.index_min
    shape = np.asarray(grid.shape, dtype=np.int64)
    inside = np.all((rel >= 0) & (rel < shape), axis=1)
    keys = (rel[:, 2] * shape[1] + rel[:, 1]) * shape[0] + rel[:, 0]
    keys[~inside] = -1
    return keys


def cell_rows(x: np.ndarray, y: np.ndarray, z: np.ndarray, grid: GridSpec,
              cell_keys: np.ndarray) -> np.ndarray:
    """(N,) int64 row, among cells of linear keys ``cell_keys`` ((M,) ascending:
    :func:`cell_keys_of` of a result's ``ijk``), of the cell of every point, -1 where
    the point's cell is not among them (or lies outside the grid). A point's cell is
    ``floor((p - origin) / cell_size)``, the arithmetic of :func:`index_points`, so a
    point of the cloud a result was computed from gets the row of its own cell.

    >>> g = GridSpec(origin=np.zeros(3), cell_size=1.0, index_min=np.zeros(3, np.int64),
    ...              shape=(4, 4, 1))
    >>> keys = cell_keys_of(np.array([[0, 0, 0], [2, 1, 0]]), g)
    >>> cell_rows(np.array([0.5, 2.5, 3.5, -1.0]), np.array([0.5, 1.2, 0.0, 0.0]),
    ...           np.zeros(4), g, keys).tolist()
    [0, 1, -1, -1]
    """
    n = int(np.asarray(x).shape[0])
    out = np.full(n, -1, dtype=np.int64)
    m = int(cell_keys.shape[0])
    if m == 0 or n == 0:
        return out
    for s in _chunks(n, 1 << 20):  # the temporaries: ~40 bytes a point of a chunk
        key = np.zeros(s.stop - s.start, dtype=np.int64)
        inside = np.ones(s.stop - s.start, dtype=bool)
        stride = 1
        for axis, col in enumerate((x, y, z)):
            t = np.asarray(col[s], dtype=np.float64) - grid.origin[axis]
            t /= grid.cell_size
            np.floor(t, out=t)
            t -= grid.index_min[axis]
            size = int(grid.shape[axis])
            ok = (t >= 0) & (t < size)
            inside &= ok
            key += np.where(ok, t, 0).astype(np.int64) * stride
            stride *= size
        pos = np.minimum(np.searchsorted(cell_keys, key), m - 1)
        found = inside & (cell_keys[pos] == key)
        out[s][found] = pos[found]
    return out


def _cell_keys(x: np.ndarray, y: np.ndarray, z: np.ndarray, grid: GridSpec) -> np.ndarray:
    """(N,) int64 linear keys ``i + nx (j + ny k)`` (relative to ``index_min``) of every
    point's cell: the reference computation."""
    n = int(x.shape[0])
    g = grid.cell_size
    nx, ny, _ = grid.shape
    key = np.empty(n, dtype=np.int64)
    tmp = np.empty(min(n, 1 << 21), dtype=np.float64)
    for s in _chunks(n, 1 << 21):
        m = s.stop - s.start
        t = tmp[:m]
        kk = key[s]
        for col, axis, stride in ((z, 2, nx * ny), (y, 1, nx), (x, 0, 1)):
            np.subtract(col[s], grid.origin[axis], out=t)
            np.divide(t, g, out=t)
            np.floor(t, out=t)
            t -= grid.index_min[axis]
            if axis == 2:
                kk[:] = t
                kk *= stride
            else:
                if stride != 1:
                    t *= stride
                kk += t.astype(np.int64)
    return key


@dataclass(frozen=True)
class CellMoments:
    """First and second moment sums per cell, in cell-local coordinates.

    Coordinates are taken relative to each cell's centre (``|local| <= g/2``), so the
    sums keep full precision whatever the magnitude of the file's coordinates.
    """

    counts: np.ndarray
    """(M,) number of points per cell."""
    s1: np.ndarray
    """(M, 3) sums of local x, y, z (metres)."""
    s2: np.ndarray
    """(M, 3, 3) sums of products of local coordinates (square metres)."""

    def mean_local(self) -> np.ndarray:
        """(M, 3) centroid relative to the cell centre, metres."""
        return self.s1 / self.counts[:, None]

    def covariance(self) -> np.ndarray:
        """(M, 3, 3) population covariance of each cell's points, square metres."""
        n = self.counts.astype(np.float64)[:, None, None]
        m = self.s1[:, :, None] / n
        return self.s2 / n - m * np.swapaxes(m, 1, 2)


def cell_moments(
    x: np.ndarray, y: np.ndarray, z: np.ndarray, index: CellIndex, *, engine: Engine = "numpy"
) -> CellMoments:
    """Per-cell moment sums of the points' cell-local coordinates.

    Parameters
    ----------
    x, y, z : (N,) float64 arrays
        Point coordinates, metres.
    index : CellIndex
        Cell membership from :func:`index_points`.
    engine : {"numpy", "numba", "auto"}
        As :func:`index_points`.

    Returns
    -------
    CellMoments
    """
    from rough_viewer.grid import fast

    m_cells = index.n_cells
    if fast.resolve_engine(engine) == "numba":
        s1, s2 = fast.moment_sums(x, y, z, index.point_cell, index.grid.centres(index.ijk),
                                  _chunk_size(m_cells))
        return CellMoments(counts=index.counts, s1=s1, s2=s2)
    s1 = np.zeros((m_cells, 3))
    s2 = np.zeros((m_cells, 3, 3))
    for pc, local in _local_chunks(x, y, z, index):
        for a in range(3):
            s1[:, a] += np.bincount(pc, weights=local[a], minlength=m_cells)
            for b in range(a, 3):
                acc = np.bincount(pc, weights=local[a] * local[b], minlength=m_cells)
                s2[:, a, b] += acc
                if b != a:
                    s2[:, b, a] += acc
    return CellMoments(counts=index.counts, s1=s1, s2=s2)


def distance_sums(
    x: np.ndarray,
    y: np.ndarray,
    z: np.ndarray,
    index: CellIndex,
    vectors: dict[str, tuple[np.ndarray, np.ndarray]],
    *,
    engine: Engine = "numpy",
    lookup: np.ndarray | None = None,
    rows: np.ndarray | None = None,
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per-cell sums of ``|D|`` and ``D^2`` with ``D = v . (p - c)``, per named vector.

    Parameters
    ----------
    x, y, z : (N,) float64 arrays
        Point coordinates, metres.
    index : CellIndex
        Cell membership.
    vectors : dict
        name -> (v, c_local): ``v`` (M, 3) per-cell vector, ``c_local`` (M, 3) the
        reference point relative to the cell centre, metres.
    engine : {"numpy", "numba", "auto"}
        As :func:`index_points`.
    lookup : (K,) int64, optional
        ``index.point_cell`` holds keys (or a finer grid's rows) rather than rows:
        the row of point ``i`` is ``lookup[index.point_cell[i]]``, written to
        ``rows`` on the way (``rows`` may be ``index.point_cell``: in place; the
        compiled engine does it within its pass over the points).

    Returns
    -------
    dict
        name -> (sum of ``|D|``, sum of ``D^2``), each (M,), in units of ``v`` times
        metres (squared).
    """
    from rough_viewer.grid import fast

    m_cells = index.n_cells
    offsets = {
        name: (v, np.einsum("ij,ij->i", v, c_local)) for name, (v, c_local) in vectors.items()
    }
    if fast.resolve_engine(engine) == "numba" and (offsets or lookup is not None):
        names = list(offsets)
        q = len(names)
        sums = fast.distance_sums(
            x, y, z, index.point_cell, index.grid.centres(index.ijk),
            np.stack([offsets[k][0] for k in names]) if q else np.empty((0, m_cells, 3)),
            np.stack([offsets[k][1] for k in names]) if q else np.empty((0, m_cells)),
            _chunk_size(m_cells), lookup=lookup, rows=rows)
        return {k: (sums[q, 0], sums[q, 1]) for q, k in enumerate(names)}
    if lookup is not None:
        target = index.point_cell if rows is None else rows
        for s in _chunks(int(x.shape[0]), 1 << 21):
            target[s] = lookup[index.point_cell[s]]
        index = CellIndex(grid=index.grid, ijk=index.ijk, counts=index.counts,
                          point_cell=target)
    out = {name: (np.zeros(m_cells), np.zeros(m_cells)) for name in vectors}
    for pc, local in _local_chunks(x, y, z, index):
        for name, (v, off) in offsets.items():
            d = local[0] * v[:, 0][pc]
            d += local[1] * v[:, 1][pc]
            d += local[2] * v[:, 2][pc]
            d -= off[pc]
            abs_sum, sq_sum = out[name]
            sq_sum += np.bincount(pc, weights=d * d, minlength=m_cells)
            np.abs(d, out=d)
            abs_sum += np.bincount(pc, weights=d, minlength=m_cells)
    return out


def coarsen(
    index: CellIndex, moments: CellMoments, factor: int, *, gather: bool = True
) -> Any:
    """The cell index and moments of the grid ``factor`` times coarser, from a finer
    grid's, without touching the point coordinates.

    Grids with one origin nest by integer factors: the coarse cell of a point is
    ``floor(i_fine / factor)`` exactly (``floor(t / k) == floor(floor(t) / k)``), so the
    coarse moments are sums of the fine ones, shifted from fine to coarse cell centres.
    Only the per-point cell membership (one gather) is recomputed.

    Parameters
    ----------
    index, moments : CellIndex, CellMoments
        Of the fine grid (edge ``g``).
    factor : int
        Positive integer; the coarse edge is ``factor * g``.
    gather : bool
        Make the coarse ``point_cell`` (one gather over the points). With False it
        is left empty and the fine-to-coarse row map is returned third: the row of
        point ``i`` is ``parent[index.point_cell[i]]`` (for a pass over the points
        to apply on its way, :func:`distance_sums`).

    Returns
    -------
    CellIndex, CellMoments[, parent]
        Of the coarse grid; equal to :func:`index_points` and :func:`cell_moments` on
        ``make_grid(bounds, factor * g, origin)`` up to rounding (the moments are
        regrouped sums: the cells, counts and rows are the same, the sums agree to
        round-off); ``parent`` (M_fine,) int64 with ``gather=False``.
    """
    k = int(factor)
    if k < 1 or k != factor:
        raise InputError(f"factor must be a positive integer, got {factor}")
    fine = index.grid
    g = fine.cell_size * k
    ijk_c = np.floor_divide(index.ijk, k)
    lo = ijk_c.min(axis=0)
    hi = ijk_c.max(axis=0)
    shape = tuple(int(v) for v in (hi - lo + 1))
    key = ((ijk_c[:, 2] - lo[2]) * shape[1] + (ijk_c[:, 1] - lo[1])) * shape[0] + (ijk_c[:, 0] - lo[0])
    total = shape[0] * shape[1] * shape[2]
    if dense_bookkeeping(total, key.shape[0]):  # no sort: one int64 per coarse grid cell
        occupied = np.bincount(key, minlength=total) > 0
        keys_c = np.flatnonzero(occupied)
        lookup = np.cumsum(occupied) - 1
        parent = lookup[key]
        del occupied, lookup
    else:
        keys_c, parent = np.unique(key, return_inverse=True)
    m_c = keys_c.shape[0]
    coarse_ijk = _decode_keys(keys_c, shape, lo)  # type: ignore[arg-type]
    grid = GridSpec(origin=fine.origin.copy(), cell_size=g, index_min=lo.astype(np.int64),
                    shape=shape)  # type: ignore[arg-type]
    counts = np.bincount(parent, weights=index.counts, minlength=m_c).astype(np.int64)
    # shift of each fine cell's centre from its coarse cell's centre, metres
    delta = ((index.ijk + 0.5) - (coarse_ijk[parent] + 0.5) * k) * fine.cell_size
    n = moments.counts.astype(np.float64)
    s1_f = moments.s1
    s1 = np.empty((m_c, 3))
    s2 = np.empty((m_c, 3, 3))
    for a in range(3):
        s1[:, a] = np.bincount(parent, weights=s1_f[:, a] + n * delta[:, a], minlength=m_c)
        for b in range(a, 3):  # symmetric: each pair once
            w = (moments.s2[:, a, b] + s1_f[:, a] * delta[:, b] + delta[:, a] * s1_f[:, b]
                 + n * delta[:, a] * delta[:, b])
            s2[:, a, b] = np.bincount(parent, weights=w, minlength=m_c)
            s2[:, b, a] = s2[:, a, b]
    point_cell = parent[index.point_cell] if gather else np.empty(0, dtype=np.int64)
    out = (CellIndex(grid=grid, ijk=coarse_ijk, counts=counts, point_cell=point_cell),
           CellMoments(counts=counts, s1=s1, s2=s2))
    return out if gather else (*out, parent)


def index_and_moments(x: np.ndarray, y: np.ndarray, z: np.ndarray, grid: GridSpec, *,
                      dense_limit: int = DENSE_LIMIT) -> tuple[CellIndex, CellMoments]:
    """:func:`index_points` and :func:`cell_moments` in two passes of the compiled
    kernels (:func:`rough_viewer.grid.fast.index_and_moments`): the same cells, rows
    and sums as the reference, bit for bit."""
    from rough_viewer.grid import fast

    ijk, counts, point_cell, s1, s2 = fast.index_and_moments(x, y, z, grid,
                                                             dense_limit=dense_limit)
    return (CellIndex(grid=grid, ijk=ijk, counts=counts, point_cell=point_cell),
            CellMoments(counts=counts, s1=s1, s2=s2))
