"""Fracture and rubble zones: connected groups of rough cells (2011 paper, Fig. 2).

The 2011 paper maps fractures and rubble with the binary transform: cells whose
normalised roughness is at or above a threshold (0.05). A zone is a connected group
of such cells:

- rough cell: normalised roughness (min-max over the cells of one map, default ODR;
  :func:`rough_viewer.grid.summary.normalise`) ``>= threshold``;
- connected: two rough cells touch by a face (``face``, 6 neighbours), a face or an
  edge (``edge``, 18) or a face, edge or corner (``vertex``, 26; default);
- groups of fewer than ``min_cells`` cells (default 3) are dropped;
- zone ids 1..Z by cell count, largest first (ties: the zone holding the cell that
  comes first in grid order); 0 = in no zone.

Per zone (:class:`Zones`; conventions of :mod:`rough_viewer.grid.orientation`):

- ``cells``, ``points``;
- ``area_m2``: the area on the face: the zone's cells projected on the whole-cloud
  ODR plane, each as its ODR plane clipped to the cell (a polygon), the union
  measured in pixels of half a cell (:class:`FaceCoverage`). For a planar face this
  is the face area the cells hold at any orientation (``g^2`` per cell of a face
  parallel to a grid plane);
- ``length_m``, ``width_m``: extent of the cell centres along the zone's long axis
  and across it, plus one cell ``g``. Long axis: the principal axis of the cell
  centres (largest variance). Across: within the zone's surface, ``mean normal x
  long axis``; where the long axis is within 30 degrees of the mean normal, the
  second principal axis;
- ``trace_azimuth_deg``, ``trace_plunge_deg``: trend and plunge of the long axis;
- ``dip_deg``, ``dip_direction_deg``: of the mean ODR normal of the zone's cells,
  each weighted by its points (the principal axis of the orientation tensor
  ``sum n_points n n^T``, so opposite normals do not cancel), oriented upward;
- ``mean_theta``, ``max_theta``: of the chosen map over the zone's cells, metres;
- ``cx, cy, cz``: centroid of the zone's points, metres.

Labelling works on cells only. :class:`ZoneLabeller` is built once per
:class:`~rough_viewer.grid.roughness.GridRoughness` (cell neighbour pairs, per-cell
face areas); after that :meth:`ZoneLabeller.label` costs two gathers over the
neighbour pairs and one connected-components pass over the rough cells, so a
threshold slider can re-label live.

>>> import numpy as np
>>> from rough_viewer.grid.roughness import grid_roughness
>>> rng = np.random.default_rng(0)
>>> x, z = rng.uniform(0, 4, 40_000), rng.uniform(0, 2, 40_000)
>>> y = np.where(np.abs(x - 2.0) < 0.25, 0.05, 0.002) * rng.standard_normal(40_000)
>>> res = grid_roughness(np.column_stack([x, y, z]), 0.25)   # a wall with one rough band
>>> zones = ZoneLabeller.build(res).zones(0.5)
>>> zones.n_zones, int(zones.cells[0]), round(float(zones.trace_plunge_deg[0]))
(1, 16, 90)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rough_viewer.grid.orientation import (
    dip_and_direction,
    line_vectors,
    orient_normals,
    trend_and_plunge,
)
from rough_viewer.grid.outliers import analysed_values
from rough_viewer.grid.roughness import GridRoughness
from rough_viewer.grid.summary import normalise
from rough_viewer.memory import require
from rough_viewer.vocabulary import (
    CONNECTIVITIES,
    DEFAULT_MIN_CELLS,
    MAPS,
    Connectivity,
    InputError,
    MapName,
)

#: Columns of the zone table, in order (the ``rough-viewer zones`` ZONES.csv contract).
ZONE_COLUMNS: tuple[str, ...] = (
    "zone", "cells", "points", "area_m2", "length_m", "width_m",
    "trace_azimuth_deg", "trace_plunge_deg", "dip_deg", "dip_direction_deg",
    "mean_theta", "max_theta", "cx", "cy", "cz",
)
#: Columns ZONES.csv adds after :data:`ZONE_COLUMNS`: the area, length and width in
#: the table's own unit (``area_m2``, ``length_m`` and ``width_m`` stay in metres,
#: as named, for the scripts that read them).
ZONE_FILE_COLUMNS: tuple[str, ...] = ("area", "length", "width")
#: Columns of :data:`ZONE_COLUMNS` in the table's unit (roughness and the centroid).
ZONE_LENGTHS: frozenset[str] = frozenset({"mean_theta", "max_theta", "cx", "cy", "cz"})

#: Below this ``|mean normal x long axis|`` (sin 30 degrees) the width is measured
#: along the second principal axis of the cell centres instead.
_ACROSS_MIN_SIN = 0.5
#: Dense neighbour look-up (one int64 per cell of the occupied box) up to this many
#: box cells or ``8 x`` the cells with a value; beyond, a sorted search.
_DENSE_BOX = 1 << 24


def _forward_offsets() -> list[tuple[tuple[int, int, int], int]]:
    """The 13 neighbour offsets (di, dj, dk) with a positive linear key, each with its
    class: 1 = shares a face, 2 = an edge, 3 = a corner."""
    out = []
    for dk in (-1, 0, 1):
        for dj in (-1, 0, 1):
            for di in (-1, 0, 1):
                if (dk, dj, di) > (0, 0, 0):
                    out.append(((di, dj, dk), abs(di) + abs(dj) + abs(dk)))
    return sorted(out, key=lambda o: o[1])


@dataclass(frozen=True, eq=False)
class Zones:
    """The zones of one map at one threshold: a label per cell and a row per zone.

    Per-zone arrays have length ``n_zones``; row ``k`` is zone ``k + 1``.
    """

    labels: np.ndarray
    """(M,) int32 zone id of every cell of the grid, 0 = in no zone."""
    map_name: MapName
    """Map whose normalised roughness was thresholded."""
    threshold: float
    """Cells with normalised roughness ``>= threshold`` are rough."""
    connectivity: Connectivity
    """Which cells touch."""
    min_cells: int
    """Smaller groups were dropped."""
    cell_size: float
    """Grid cell edge, metres."""
    cells: np.ndarray
    """(Z,) int64 cells per zone (descending)."""
    points: np.ndarray
    """(Z,) int64 points per zone."""
    area_m2: np.ndarray
    """(Z,) area on the face (whole-cloud ODR plane), square metres."""
    length_m: np.ndarray
    """(Z,) extent along the long axis plus one cell, metres."""
    width_m: np.ndarray
    """(Z,) extent across the long axis plus one cell, metres."""
    trace_azimuth_deg: np.ndarray
    """(Z,) trend of the long axis, degrees clockwise from +y."""
    trace_plunge_deg: np.ndarray
    """(Z,) plunge of the long axis, degrees below horizontal."""
    dip_deg: np.ndarray
    """(Z,) dip of the mean ODR normal's plane, degrees."""
    dip_direction_deg: np.ndarray
    """(Z,) dip direction, degrees clockwise from +y."""
    mean_theta: np.ndarray
    """(Z,) mean roughness of the zone's cells (the chosen map), metres."""
    max_theta: np.ndarray
    """(Z,) largest roughness of the zone's cells, metres."""
    centroid: np.ndarray
    """(Z, 3) centroid of the zone's points, metres."""
    axis: np.ndarray
    """(Z, 3) unit long axis (downward, as the trace)."""
    normal: np.ndarray
    """(Z, 3) unit mean ODR normal (upward)."""

    @property
    def n_zones(self) -> int:
        """Number of zones."""
        return int(self.cells.shape[0])

    @property
    def ids(self) -> np.ndarray:
        """(Z,) zone ids 1..Z."""
        return np.arange(1, self.n_zones + 1, dtype=np.int64)

    def table(self, unit_m: float = 1.0) -> dict[str, np.ndarray]:
        """Column name -> (Z,) values, in :data:`ZONE_COLUMNS` order; the lengths
        :data:`ZONE_LENGTHS` divided by ``unit_m`` (metres per output unit), the
        columns named in metres (``area_m2``, ``length_m``, ``width_m``) in metres."""
        cols: dict[str, np.ndarray] = {"zone": self.ids}
        for name in ZONE_COLUMNS[1:12]:
            cols[name] = getattr(self, name)
        for a, name in enumerate(("cx", "cy", "cz")):
            cols[name] = self.centroid[:, a]
        if unit_m != 1.0:
            cols = {k: v / unit_m if k in ZONE_LENGTHS else v for k, v in cols.items()}
        return cols

    def file_table(self, unit_m: float = 1.0) -> dict[str, np.ndarray]:
        """ZONES.csv: :meth:`table` in the output unit, then :data:`ZONE_FILE_COLUMNS`
        (area in its square, length and width) in it too."""
        return {**self.table(unit_m), "area": self.area_m2 / unit_m**2,
                "length": self.length_m / unit_m, "width": self.width_m / unit_m}

@dataclass(frozen=True, eq=False)
class ZoneLabeller:
    """Everything about the cells of one grid result that zones need, computed once.

    Build with :meth:`build`; then :meth:`label` (labels only) and :meth:`zones`
    (labels and the zone table) are cheap and never touch the points.
    """

    result: GridRoughness
    """The grid result (cells, maps, normals)."""
    map_name: MapName
    """Map whose normalised roughness is thresholded."""
    normalised: np.ndarray
    """(M,) min-max normalised roughness of every cell (NaN where none)."""
    rows: np.ndarray
    """(V,) int64 cells with a value, ascending: the nodes of the neighbour graph."""
    pair_a: np.ndarray
    """(E,) one end of every pair of touching cells (index into ``rows``)."""
    pair_b: np.ndarray
    """(E,) the other end."""
    pair_ends: tuple[int, int, int]
    """Pairs ``[:pair_ends[0]]`` share a face, ``[:pair_ends[1]]`` a face or an edge,
    ``[:pair_ends[2]]`` (all) a face, edge or corner."""
    coverage: FaceCoverage
    """Face pixels covered by every cell: the zones' areas."""

    @classmethod
    def build(cls, result: GridRoughness, map_name: MapName = "odr", *,
              keep_outliers: bool = False) -> ZoneLabeller:
        """Prepare zone labelling of ``result``'s map ``map_name``. Cells larger than
        the cell (:mod:`rough_viewer.grid.outliers`) take no part, as if they had no
        value, unless ``keep_outliers``: they would set the normalisation's maximum.

        Cost: one sort-or-look-up per neighbour offset (13) over the cells with a
        value, and one clipping of every cell's plane; memory about 100 bytes per cell.
        """
        if map_name not in MAPS:
            raise InputError(f"unknown map {map_name!r}; expected one of {', '.join(MAPS)}")
        values = analysed_values(result, map_name, keep_outliers=keep_outliers)
        rows = np.flatnonzero(np.isfinite(values) & np.all(np.isfinite(result.normal), axis=1))
        v = int(rows.shape[0])
        # pairs (<= 13 per cell, two int64 ends), per-offset temporaries, the dense
        # look-up, the (M,) outputs, the face pixels (about 4 to 12 per cell) and the
        # face-coverage chunks
        require(v * (13 * 16 + 100 + 200) + 8.0 * max(_DENSE_BOX, 8 * v)
                + 24.0 * result.n_cells + 64 * 2**20,
                f"zone labelling of {v:,} cells", hint="choose a larger grid size")
        a, b, ends = _neighbour_pairs(result.ijk[rows])
        return cls(
            result=result,
            map_name=map_name,
            normalised=normalise(values),
            rows=rows.astype(np.int64),
            pair_a=a,
            pair_b=b,
            pair_ends=ends,
            coverage=face_coverage(result),
        )

    def label(
        self,
        threshold: float,
        *,
        connectivity: Connectivity = "vertex",
        min_cells: int = DEFAULT_MIN_CELLS,
    ) -> np.ndarray:
        """(M,) int32 zone id of every cell (0 = in no zone), ids 1..Z by size.

        Parameters
        ----------
        threshold : float
            In [0, 1]: cells with normalised roughness ``>= threshold`` are rough.
        connectivity : {"vertex", "edge", "face"}
            26, 18 or 6 neighbours.
        min_cells : int
            Groups with fewer cells are dropped (>= 1).
        """
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        end = _check(threshold, connectivity, min_cells, self.pair_ends)
        rough = self.normalised[self.rows] >= threshold  # NaN never (rows have values)
        nodes = np.flatnonzero(rough)
        k = nodes.shape[0]
        labels = np.zeros(self.result.n_cells, dtype=np.int32)
        if k == 0:
            return labels
        a = self.pair_a[:end]
        b = self.pair_b[:end]
        keep = rough[a]
        keep &= rough[b]
        local = np.full(self.rows.shape[0], -1, dtype=np.int64)
        local[nodes] = np.arange(k)
        ra = local[a[keep]]
        rb = local[b[keep]]
        graph = coo_matrix((np.ones(ra.shape[0], dtype=np.int8), (ra, rb)), shape=(k, k))
        _, comp = connected_components(graph.tocsr(), directed=False)
        sizes = np.bincount(comp)
        # components are numbered in order of their first node, i.e. grid order
        order = np.argsort(-sizes, kind="stable")
        order = order[sizes[order] >= min_cells]
        new_id = np.zeros(sizes.shape[0], dtype=np.int32)
        new_id[order] = np.arange(1, order.shape[0] + 1, dtype=np.int32)
        labels[self.rows[nodes]] = new_id[comp]
        return labels

    def zones(
        self,
        threshold: float,
        *,
        connectivity: Connectivity = "vertex",
        min_cells: int = DEFAULT_MIN_CELLS,
    ) -> Zones:
        """The zones at ``threshold`` with their table (see :meth:`label`)."""
        labels = self.label(threshold, connectivity=connectivity, min_cells=min_cells)
        return self.measure(labels, threshold=threshold, connectivity=connectivity,
                            min_cells=min_cells)

    def measure(
        self,
        labels: np.ndarray,
        *,
        threshold: float,
        connectivity: Connectivity,
        min_cells: int,
    ) -> Zones:
        """The zone table of ``labels`` (from :meth:`label`; ids 1..Z, 0 = none)."""
        res = self.result
        labels = np.asarray(labels, dtype=np.int32)
        if labels.shape != (res.n_cells,):
            raise ValueError(f"labels must have shape ({res.n_cells},), got {labels.shape}")
        sel = np.flatnonzero(labels > 0)
        zi = labels[sel].astype(np.int64) - 1
        n_z = int(labels.max()) if labels.size else 0
        order = np.argsort(zi, kind="stable")
        sel, zi = sel[order], zi[order]
        cells = np.bincount(zi, minlength=n_z).astype(np.int64)
        starts = np.cumsum(cells) - cells
        g = res.grid.cell_size
        npts = res.n_points[sel].astype(np.float64)
        points = np.bincount(zi, weights=npts, minlength=n_z)

        def zsum(w: np.ndarray) -> np.ndarray:
            return np.bincount(zi, weights=w, minlength=n_z)

        # centroid of the points, relative to the grid origin (no loss on UTM values)
        rel = res.centroid[sel] - res.grid.origin
        centroid = np.column_stack([zsum(npts * rel[:, a]) for a in range(3)]) / points[:, None]
        centroid += res.grid.origin
        # long axis: principal axis of the cell centres
        centres = (res.ijk[sel] - res.ijk.min(axis=0)).astype(np.float64) * g
        axes = _principal_axes(zi, centres, n_z, centred=True)
        long_axis = axes[:, :, 2]
        # mean normal: principal axis of the orientation tensor, cells weighted by
        # their points (a sliver of a cell with a few points has a poor plane)
        mean_normal = _principal_axes(zi, res.normal[sel], n_z, centred=False,
                                      weights=npts)[:, :, 2]
        mean_normal = orient_normals(mean_normal, res.whole_plane.normal)
        dip, dd = dip_and_direction(mean_normal)
        across = np.cross(mean_normal, long_axis)
        size = np.linalg.norm(across, axis=1)
        across = np.where((size >= _ACROSS_MIN_SIN)[:, None],
                          across / np.where(size > 0, size, 1.0)[:, None], axes[:, :, 1])
        along_s = np.einsum("ij,ij->i", centres, long_axis[zi])
        across_s = np.einsum("ij,ij->i", centres, across[zi])
        length = _extent(along_s, starts, n_z) + g
        width = _extent(across_s, starts, n_z) + g
        trend, plunge = trend_and_plunge(long_axis)
        theta = res.values(self.map_name)[sel]
        max_theta = np.maximum.reduceat(theta, starts) if n_z else np.zeros(0)
        return Zones(
            labels=labels,
            map_name=self.map_name,
            threshold=float(threshold),
            connectivity=connectivity,
            min_cells=int(min_cells),
            cell_size=g,
            cells=cells,
            points=points.astype(np.int64),
            area_m2=self.coverage.zone_area(sel, zi, n_z),
            length_m=length,
            width_m=width,
            trace_azimuth_deg=trend,
            trace_plunge_deg=plunge,
            dip_deg=dip,
            dip_direction_deg=dd,
            mean_theta=zsum(theta) / cells,
            max_theta=max_theta,
            centroid=centroid,
            axis=line_vectors(trend, plunge),
            normal=mean_normal,
        )


def find_zones(
    result: GridRoughness,
    threshold: float,
    *,
    map_name: MapName = "odr",
    connectivity: Connectivity = "vertex",
    min_cells: int = DEFAULT_MIN_CELLS,
    keep_outliers: bool = False,
) -> Zones:
    """The zones of ``result``'s map at ``threshold`` (builds a :class:`ZoneLabeller`;
    keep one instead to re-label at other thresholds; outliers as there)."""
    return ZoneLabeller.build(result, map_name, keep_outliers=keep_outliers).zones(
        threshold, connectivity=connectivity, min_cells=min_cells)


def _check(
    threshold: float, connectivity: str, min_cells: int, ends: tuple[int, int, int]
) -> int:
    """The number of neighbour pairs of ``connectivity``; InputError on bad options."""
    if not (np.isfinite(threshold) and 0.0 <= threshold <= 1.0):
        raise InputError(f"threshold must lie in [0, 1], got {threshold:g}")
    if connectivity not in CONNECTIVITIES:
        raise InputError(f"unknown connectivity {connectivity!r}; expected vertex, edge or face")
    if int(min_cells) != min_cells or min_cells < 1:
        raise InputError(f"min cells must be a whole number >= 1, got {min_cells}")
    return ends[("face", "edge", "vertex").index(connectivity)]


def _neighbour_pairs(ijk: np.ndarray) -> tuple[np.ndarray, np.ndarray, tuple[int, int, int]]:
    """Every pair of touching cells among ``ijk`` (V, 3), each pair once, grouped by
    class (faces, then edges, then corners). Indices are rows of ``ijk``."""
    v = ijk.shape[0]
    dtype = np.int32 if v < 2**31 else np.int64
    if v == 0:
        empty = np.zeros(0, dtype=dtype)
        return empty, empty.copy(), (0, 0, 0)
    lo = ijk.min(axis=0)
    rel = ijk - lo
    ext = rel.max(axis=0) + 1
    nx, ny = int(ext[0]), int(ext[1])
    key = (rel[:, 2] * ny + rel[:, 1]) * nx + rel[:, 0]
    box = float(ext[0]) * float(ext[1]) * float(ext[2])
    dense = box <= max(_DENSE_BOX, 8 * v)
    if dense:
        lookup = np.full(int(box), -1, dtype=dtype)
        lookup[key] = np.arange(v, dtype=dtype)
    else:
        order = np.argsort(key, kind="stable")
        sorted_key = key[order]
    pa: list[np.ndarray] = []
    pb: list[np.ndarray] = []
    ends = [0, 0, 0]
    count = 0
    for (di, dj, dk), cls in _forward_offsets():
        q = rel + (di, dj, dk)
        inb = np.flatnonzero(np.all((q >= 0) & (q < ext), axis=1))
        qk = key[inb] + (dk * ny + dj) * nx + di
        if dense:
            hit = lookup[qk]
            found = hit >= 0
            other = hit[found]
        else:
            pos = np.minimum(np.searchsorted(sorted_key, qk), v - 1)
            found = sorted_key[pos] == qk
            other = order[pos[found]]
        pa.append(inb[found].astype(dtype))
        pb.append(other.astype(dtype))
        count += int(found.sum())
        ends[cls - 1] = count
    return np.concatenate(pa), np.concatenate(pb), (ends[0], ends[1], ends[2])


def _principal_axes(
    zi: np.ndarray,
    vecs: np.ndarray,
    n_z: int,
    *,
    centred: bool,
    weights: np.ndarray | None = None,
) -> np.ndarray:
    """(Z, 3, 3) eigenvectors (columns, ascending eigenvalue) per zone of the scatter
    of ``vecs`` (N, 3): the covariance when ``centred``, else ``sum w v v^T``."""
    w = np.ones(zi.shape[0]) if weights is None else weights
    m = np.zeros((n_z, 3, 3))
    total = np.bincount(zi, weights=w, minlength=n_z)
    mean = np.zeros((n_z, 3))
    if centred:
        for a in range(3):
            mean[:, a] = np.bincount(zi, weights=w * vecs[:, a], minlength=n_z) / total
    for a in range(3):
        for b in range(a, 3):
            s = np.bincount(zi, weights=w * vecs[:, a] * vecs[:, b], minlength=n_z) / total
            m[:, a, b] = m[:, b, a] = s - mean[:, a] * mean[:, b]
    return np.linalg.eigh(m)[1]


def _extent(values: np.ndarray, starts: np.ndarray, n_z: int) -> np.ndarray:
    """(Z,) max - min of ``values`` over each zone's run (values sorted by zone)."""
    if n_z == 0:
        return np.zeros(0)
    return np.maximum.reduceat(values, starts) - np.minimum.reduceat(values, starts)


@dataclass(frozen=True, eq=False)
class FaceCoverage:
    """The face pixels each cell's surface covers: how zone areas are measured.

    Every cell's ODR plane (through its centroid) clipped to the cell is a convex
    polygon. Projected on the whole-cloud ODR plane, it covers the centres of some
    pixels of a grid of :attr:`pixel_size` = half a cell laid on that plane. A zone's
    area is the number of distinct pixels its cells cover times the pixel area: the
    area of the union of the projected polygons, to the pixel. For a planar face
    this is the face area the cells hold, at any orientation (a tilted face crosses
    cells in a staircase and their polygons abut), and a face that wavers across a
    cell boundary (two cells through its thickness) is counted once.
    """

    pixel_size: float
    """Pixel edge on the face plane, metres (half the cell size)."""
    indptr: np.ndarray
    """(M + 1,) int64: the pixels of cell ``i`` are ``keys[indptr[i]:indptr[i + 1]]``."""
    keys: np.ndarray
    """int64 pixel keys (row-major over the pixels covered by any cell)."""
    n_keys: int
    """Number of possible keys (key < n_keys)."""

    @property
    def cell_area(self) -> np.ndarray:
        """(M,) area on the face of every cell alone, square metres (0 where no plane)."""
        return np.diff(self.indptr).astype(np.float64) * self.pixel_size**2

    def zone_area(self, cells: np.ndarray, zone: np.ndarray, n_zones: int) -> np.ndarray:
        """(Z,) area on the face of each zone, square metres.

        ``cells`` (K,) are cell rows and ``zone`` (K,) their zone index 0..Z-1.
        """
        start = self.indptr[cells]
        count = self.indptr[cells + 1] - start
        total = int(count.sum())
        if total == 0:
            return np.zeros(n_zones)
        first = np.cumsum(count) - count
        idx = np.repeat(start - first, count) + np.arange(total)
        owner = np.repeat(zone.astype(np.int64), count)
        if self.n_keys * (n_zones + 1) < 2**62:
            pair = np.sort(owner * self.n_keys + self.keys[idx])
            first = np.ones(pair.shape[0], dtype=bool)
            np.not_equal(pair[1:], pair[:-1], out=first[1:])
            distinct = pair[first] // self.n_keys
        else:
            distinct = np.unique(np.column_stack([owner, self.keys[idx]]), axis=0)[:, 0]
        return np.bincount(distinct, minlength=n_zones) * self.pixel_size**2


#: Candidate pixels per axis of one cell's projected polygon (its extent is at most
#: sqrt(3) cells = 3.5 pixels of half a cell, so it spans at most 5 pixel centres).
_CANDIDATES = 5


def face_coverage(result: GridRoughness) -> FaceCoverage:
    """The face pixels (half a cell) covered by every cell's clipped ODR plane,
    projected on the whole-cloud ODR plane (see :class:`FaceCoverage`).

    Parameters
    ----------
    result : GridRoughness
        Cells with their ODR normals and centroids; cells without a plane cover
        nothing.
    """
    m = result.n_cells
    g = result.grid.cell_size
    s = 0.5 * g
    ok = np.flatnonzero(np.all(np.isfinite(result.normal), axis=1)
                        & np.all(np.isfinite(result.centroid), axis=1))
    face = np.asarray(result.whole_plane.normal, dtype=np.float64)
    origin = np.asarray(result.whole_plane.centroid, dtype=np.float64)
    helper = np.eye(3)[int(np.argmin(np.abs(face)))]
    u_axis = np.cross(face, helper)
    u_axis /= np.linalg.norm(u_axis)
    w_axis = np.cross(face, u_axis)
    # pixel index range over every cell (its centre +- sqrt(3) h): the key space
    rel = result.centre[ok] - origin
    cu, cw = rel @ u_axis, rel @ w_axis
    reach = np.sqrt(3.0) * g
    a_lo = int(np.floor((cu.min() - reach) / s)) if ok.size else 0
    b_lo = int(np.floor((cw.min() - reach) / s)) if ok.size else 0
    n_a = int(np.floor((cu.max() + reach) / s)) - a_lo + 1 if ok.size else 1
    n_b = int(np.floor((cw.max() + reach) / s)) - b_lo + 1 if ok.size else 1
    h = 0.5 * g
    corner, along = _cube_edges(h)
    step = 2.0 * h * np.eye(3)[along]  # (12, 3)
    counts = np.zeros(m, dtype=np.int64)
    pieces: list[np.ndarray] = []
    for first in range(0, ok.size, _COVER_CHUNK):
        rows = ok[first:first + _COVER_CHUNK]
        su, sw, valid = _cell_polygons(result, rows, (corner, along, step), origin,
                                       (u_axis, w_axis))
        ca, cb, inside = _pixels_inside(su, sw, valid, s, g)
        counts[rows] = inside.sum(axis=1)
        pieces.append((ca[inside] - a_lo) * n_b + (cb[inside] - b_lo))
    indptr = np.zeros(m + 1, dtype=np.int64)
    np.cumsum(counts, out=indptr[1:])
    keys = np.concatenate(pieces) if pieces else np.zeros(0, dtype=np.int64)
    # pieces follow ``ok`` (ascending rows), the order of indptr
    return FaceCoverage(pixel_size=s, indptr=indptr, keys=keys, n_keys=n_a * n_b)


def _cell_polygons(result: GridRoughness, rows: np.ndarray,
                   edges: tuple[np.ndarray, np.ndarray, np.ndarray], origin: np.ndarray,
                   axes: tuple[np.ndarray, np.ndarray]
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The polygon where the ODR plane of each cell ``rows`` cuts its cube, projected on
    the face (``axes``: its in-plane unit axes, from ``origin``): (K, 12) vertex
    coordinates ``su``, ``sw`` (metres), counter-clockwise, and (K, 12) ``valid`` (the
    unused slots last, repeating the first vertex: zero-length edges). ``edges``: the
    cube's edges (:func:`_cube_edges` start corners, axes, (12, 3) steps)."""
    corner, along, step = edges
    u_axis, w_axis = axes
    h = 0.5 * result.grid.cell_size
    n = result.normal[rows]
    c = result.centroid[rows] - result.centre[rows]  # centroid within the cell
    n_e = n[:, along]  # (K, 12)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = (n @ corner.T - np.einsum("ij,ij->i", n, c)[:, None]) / (-2.0 * h * n_e)
    hit = np.isfinite(t) & (t >= 0.0) & (t <= 1.0)
    pts = corner[None] + np.where(hit, t, 0.0)[:, :, None] * step[None]  # (K, 12, 3)
    pts += (result.centre[rows] - origin)[:, None, :]
    pu = pts @ u_axis
    pw = pts @ w_axis
    n_hit = np.maximum(hit.sum(axis=1), 1)
    mu = np.where(hit, pu, 0.0).sum(axis=1) / n_hit
    mw = np.where(hit, pw, 0.0).sum(axis=1) / n_hit
    ang = np.where(hit, np.arctan2(pw - mw[:, None], pu - mu[:, None]), np.inf)
    o = np.argsort(ang, axis=1)  # counter-clockwise; unused slots last
    valid = np.take_along_axis(hit, o, axis=1)
    su = np.take_along_axis(pu, o, axis=1)
    sw = np.take_along_axis(pw, o, axis=1)
    su = np.where(valid, su, su[:, :1])  # unused slots repeat the first vertex:
    sw = np.where(valid, sw, sw[:, :1])  # zero-length edges that never exclude
    return su, sw, valid


def _pixels_inside(su: np.ndarray, sw: np.ndarray, valid: np.ndarray, s: float, g: float
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The candidate pixels (size ``s``, metres) of every polygon (:func:`_cell_polygons`)
    and which have their centre inside it: (K, 25) pixel indices ``ca``, ``cb`` and
    ``inside`` (a polygon of fewer than 3 vertices covers none; ``g`` the cell size)."""
    grid_offsets = np.arange(_CANDIDATES)
    da = np.repeat(grid_offsets, _CANDIDATES)
    db = np.tile(grid_offsets, _CANDIDATES)
    eu = np.roll(su, -1, axis=1) - su
    ew = np.roll(sw, -1, axis=1) - sw
    a0 = np.ceil(np.where(valid, su, np.inf).min(axis=1) / s - 0.5).astype(np.int64)
    b0 = np.ceil(np.where(valid, sw, np.inf).min(axis=1) / s - 0.5).astype(np.int64)
    a_hi = np.floor(np.where(valid, su, -np.inf).max(axis=1) / s - 0.5).astype(np.int64)
    b_hi = np.floor(np.where(valid, sw, -np.inf).max(axis=1) / s - 0.5).astype(np.int64)
    ca = a0[:, None] + da[None]  # (K, 25) candidate pixels
    cb = b0[:, None] + db[None]
    qu = (ca + 0.5) * s
    qw = (cb + 0.5) * s
    cross = (eu[:, None, :] * (qw[:, :, None] - sw[:, None, :])
             - ew[:, None, :] * (qu[:, :, None] - su[:, None, :]))
    inside = np.all(cross >= -1e-12 * g * g, axis=2)
    inside &= (ca <= a_hi[:, None]) & (cb <= b_hi[:, None])
    inside &= (valid.sum(axis=1) >= 3)[:, None]
    return ca, cb, inside


#: Cells per chunk of :func:`face_coverage` (bounds its (K, 25, 12) temporaries).
_COVER_CHUNK = 4096


def _cube_edges(h: float) -> tuple[np.ndarray, np.ndarray]:
    """The 12 edges of the cube ``[-h, h]^3``: (12, 3) start corners and (12,) the axis
    each runs along (from the start corner, length ``2 h``)."""
    starts, along = [], []
    for ax in range(3):
        o1, o2 = [a for a in range(3) if a != ax]
        for s1 in (-h, h):
            for s2 in (-h, h):
                c = np.full(3, -h)
                c[o1], c[o2] = s1, s2
                starts.append(c)
                along.append(ax)
    return np.array(starts), np.array(along)
