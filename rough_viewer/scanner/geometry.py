"""How each grid cell was seen by the scanner(s): scans, range, incidence, point
density against the expected one, and occlusion (docs/scanner.md).

Per cell of a :class:`~rough_viewer.grid.roughness.GridRoughness` (arrays aligned with
its rows), from the scanner positions and each point's scan
(:func:`rough_viewer.scanner.positions.cloud_scanners`):

- ``scans``: scans with at least one point in the cell;
- ``range_m``: distance from the scanner to the cell's centroid, averaged over the
  scans seeing it, weighted by their points in the cell;
- ``incidence_deg``: angle between the beam (scanner to centroid) and the cell's
  ODR normal, averaged the same way (0 = the beam meets the face head on);
- ``density_ratio``: points in the cell over the points the scanner's angular grid
  puts there, ``N0 A cos(i) / (r^2 cos(e))`` summed over the scans seeing it: ``N0``
  rays per steradian (``1 / step^2`` for an angular step in radians, else fitted:
  the median over the cells of the observed ratio, per scan), ``A`` the cell's area
  of face, ``i`` the incidence, ``r`` the range and ``e`` the beam's elevation (a
  levelled scanner steps azimuth and elevation, so its rays crowd by ``1 / cos(e)``
  towards the zenith). The 2012 paper's point count ``N0 cos(alpha) cos(beta)`` is
  this density summed over its board;
- ``occlusion``: the share of points the cell lacks against its best-covered
  neighbour along the beam, ``1 - c / max(c_before, c_behind)`` clipped to [0, 1],
  ``c`` the coverage (points over those the scanner would put on the whole cut of the
  cell's plane), the neighbours the cells one cell size away along the beam's
  projection on the cell's plane: a protrusion casts its shadow along that direction.
  From the points alone a shadow and the end of the face look alike, so cells where
  the face ends read as occluded too.

The face area ``A`` of the density ratio is where the scanner saw the cell: the area
of its ODR plane inside the cube, cut exactly (:func:`plane_cut_area`), or the extent
of its points where that is smaller (a cell the face, or the view, only partly fills):
``12 sqrt(l1 l2)`` of the two largest eigenvalues of the cell's point covariance
(exact for a uniformly filled parallelogram), with Sheppard's correction for points
on a lattice. The coverage uses the whole cut.

Everything is vectorised over cells and (cell, scan) pairs; one pass over the points
gives the pairs and one the cell moments.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from rough_viewer.grid.cells import CellIndex, cell_moments
from rough_viewer.grid.roughness import GridRoughness
from rough_viewer.io.cloud import PointCloud, as_columns
from rough_viewer.memory import require
from rough_viewer.vocabulary import Engine, InputError, ProgressFn

N0Source = Literal["angular step", "fitted"]

#: Cells of one block of :func:`plane_cut_area` (about 3 kB of temporaries a cell).
CUT_BLOCK = 65_536

#: The extent area of points filling a convex cut of a cube uniformly is at most
#: ``12 / (6 sqrt(3))`` (a triangle: 1.155) times the cut's area and exactly it for a
#: parallelogram; a cut smaller than the extent by more than this misrepresents the
#: points (a plane through a sliver of them), and the extent is used.
MAX_EXTENT_OVER_CUT = 1.25

#: Cells where the scanner's grid puts fewer points than this get no density ratio.
MIN_EXPECTED = 1.0

#: The unit cube's corners (x fastest) and its 12 edges as corner pairs.
_CORNERS = np.array([[i, j, k] for k in (0, 1) for j in (0, 1) for i in (0, 1)], dtype=np.float64)
_EDGES = np.array([(a, b) for a in range(8) for b in range(a + 1, 8)
                   if np.abs(_CORNERS[a] - _CORNERS[b]).sum() == 1])


@dataclass(frozen=True)
class ScanGeometry:
    """How every cell of a grid result was seen; (M,) arrays aligned with the
    result's cells, NaN where a cell has no value (below ``min_points``, no plane)."""

    scans: np.ndarray
    """(M,) int64 scans with at least one point in the cell."""
    range_m: np.ndarray
    """(M,) mean range from the scanner(s) to the cell centroid, metres."""
    incidence_deg: np.ndarray
    """(M,) mean angle between the beam and the cell's ODR normal, degrees."""
    density_ratio: np.ndarray
    """(M,) points in the cell / points expected from the scanner's angular grid."""
    occlusion: np.ndarray
    """(M,) share of points missing against the densest neighbour along the beam, 0..1."""
    expected_points: np.ndarray
    """(M,) points the scanner(s) would put where they saw the cell's face
    (``N0 A cos i / (r^2 cos e)``)."""
    coverage: np.ndarray
    """(M,) points in the cell / points the scanner(s) would put on the whole cut of
    its plane: below 1 where part of the cell was not seen (a shadow, or the face
    ends in the cell)."""
    area_m2: np.ndarray
    """(M,) area of face the points cover in the cell, square metres."""
    plane_variance: np.ndarray
    """(M,) mean squared orthogonal distance of the cell's points to its ODR plane (the
    smallest eigenvalue of their covariance), square metres: the variance range noise
    adds to (:mod:`rough_viewer.scanner.trust`)."""
    beam: np.ndarray
    """(M, 3) mean unit beam direction (scanner to cell), point-weighted over scans."""
    n0: np.ndarray
    """(S,) rays per steradian of every scan (NaN for a scan that sees no cell)."""
    n0_source: N0Source
    """``"angular step"`` (``1 / step^2``) or ``"fitted"`` (median over the cells)."""
    positions: np.ndarray
    """(S, 3) scanner positions, metres."""
    n_pairs: int
    """(cell, scan) pairs with points."""


def plane_cut_area(normal: np.ndarray, point: np.ndarray, lower: np.ndarray,
                   size: float) -> np.ndarray:
    """Area of each plane inside its axis-aligned cube.

    Parameters
    ----------
    normal : (M, 3) array
        Unit normals of the planes.
    point : (M, 3) array
        A point of each plane, metres.
    lower : (M, 3) array
        Lower corner of each cube, metres.
    size : float
        Cube edge, metres.

    Returns
    -------
    (M,) array
        Square metres; 0 where the plane misses its cube.

    Examples
    --------
    A plane through the centre of the unit cube, normal (1, 1, 1), cuts a regular
    hexagon of area ``3 sqrt(3) / 4``:

    >>> n = np.array([[1.0, 1.0, 1.0]]) / np.sqrt(3.0)
    >>> round(float(plane_cut_area(n, np.full((1, 3), 0.5), np.zeros((1, 3)), 1.0)[0]), 6)
    1.299038
    """
    normal = np.asarray(normal, dtype=np.float64)
    m = normal.shape[0]
    out = np.zeros(m)
    edge = (_CORNERS[_EDGES[:, 1]] - _CORNERS[_EDGES[:, 0]]) * size         # (12, 3)
    start = _CORNERS[_EDGES[:, 0]] * size                                   # (12, 3)
    for s in range(0, m, CUT_BLOCK):
        sl = slice(s, min(m, s + CUT_BLOCK))
        out[sl] = _cut_block(normal[sl], np.asarray(point[sl]) - np.asarray(lower[sl]),
                             edge, start)
    return out


def _cut_block(n: np.ndarray, rel: np.ndarray, edge: np.ndarray, start: np.ndarray) -> np.ndarray:
    """:func:`plane_cut_area` of one block, the plane's point relative to the cube."""
    ne = n @ edge.T                                                         # (m, 12)
    d = np.einsum("mj,mkj->mk", n, rel[:, None, :] - start[None])           # (m, 12)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = d / ne
    tol = 1e-9
    ok = (np.abs(ne) > 1e-12) & (t >= -tol) & (t <= 1.0 + tol)
    t = np.clip(np.where(ok, t, 0.0), 0.0, 1.0)
    q = start[None] + t[..., None] * edge[None]                             # (m, 12, 3)
    cnt = ok.sum(axis=1)
    w = ok.astype(np.float64)
    centre = np.einsum("mk,mkj->mj", w, q) / np.maximum(cnt, 1)[:, None]
    # two in-plane axes
    helper = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    u = np.cross(n, helper)
    u /= np.linalg.norm(u, axis=1)[:, None]
    v = np.cross(n, u)
    rq = q - centre[:, None, :]
    x = np.einsum("mkj,mj->mk", rq, u)
    y = np.einsum("mkj,mj->mk", rq, v)
    angle = np.where(ok, np.arctan2(y, x), np.inf)
    order = np.argsort(angle, axis=1)                 # the convex polygon's vertices, in turn
    x = np.take_along_axis(np.where(ok, x, 0.0), order, axis=1)
    y = np.take_along_axis(np.where(ok, y, 0.0), order, axis=1)
    valid = np.take_along_axis(ok, order, axis=1)
    k = np.arange(12)[None, :]
    nxt = np.where(k + 1 < cnt[:, None], k + 1, 0)
    xn = np.take_along_axis(x, nxt, axis=1)
    yn = np.take_along_axis(y, nxt, axis=1)
    area = 0.5 * np.abs(np.where(valid, x * yn - xn * y, 0.0).sum(axis=1))
    return np.where(cnt >= 3, area, 0.0)


def points_extent_area(eigenvalues: np.ndarray, n_points: np.ndarray) -> np.ndarray:
    """Area covered by each cell's points from the two largest eigenvalues of their
    covariance (square metres): ``12 sqrt(l1 l2)``, exact for points filling a
    parallelogram uniformly, with Sheppard's correction ``l + s^2 / 12`` for points on
    a lattice of spacing ``s`` (``s^2 = A / n``), solved for ``A``.

    >>> round(float(points_extent_area(np.array([[1 / 12, 1 / 12, 0.0]]), np.array([10**6]))[0]), 4)
    1.0
    """
    lam = np.asarray(eigenvalues, dtype=np.float64)
    l1 = np.clip(lam[:, 0], 0.0, None)
    l2 = np.clip(lam[:, 1], 0.0, None)
    n = np.asarray(n_points, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        # s = A / 12 solves s^2 = (l1 + s / n)(l2 + s / n)
        q = 1.0 - 1.0 / (n * n)
        b = (l1 + l2) / n
        s = (b + np.sqrt(b * b + 4.0 * q * l1 * l2)) / (2.0 * q)
    return np.where(n > 1, 12.0 * s, np.nan)


def _pairs(point_cell: np.ndarray, point_scan: np.ndarray, n_scans: int,
           counts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(cell, scan, points) of every (cell, scan) pair that has points."""
    if n_scans == 1:
        cells = np.flatnonzero(counts > 0)
        return cells, np.zeros(cells.shape[0], dtype=np.int64), counts[cells].astype(np.int64)
    n = int(point_cell.shape[0])
    require(n * 8.0 * 4, f"pairing {n:,} points with {n_scans} scans")
    key = point_cell.astype(np.int64) * n_scans + point_scan
    uniq, k = np.unique(key, return_counts=True)
    return uniq // n_scans, uniq % n_scans, k.astype(np.int64)


def _lookup_rows(result: GridRoughness, ijk: np.ndarray) -> np.ndarray:
    """Row of each cell index in ``result`` (-1 where the cell is not occupied)."""
    lo = result.ijk.min(axis=0)
    span = result.ijk.max(axis=0) - lo + 1
    def key(a: np.ndarray) -> np.ndarray:
        r = a - lo
        return r[:, 0] + span[0] * (r[:, 1] + span[1] * r[:, 2])
    keys = key(result.ijk)
    order = np.argsort(keys)
    sorted_keys = keys[order]
    inside = np.all((ijk >= lo) & (ijk < lo + span), axis=1)
    q = key(np.where(inside[:, None], ijk, lo))
    pos = np.clip(np.searchsorted(sorted_keys, q), 0, sorted_keys.shape[0] - 1)
    found = inside & (sorted_keys[pos] == q)
    return np.where(found, order[pos], -1)


def scan_geometry(
    cloud: PointCloud | np.ndarray,
    result: GridRoughness,
    positions: np.ndarray,
    point_scan: np.ndarray | None = None,
    *,
    angular_step_rad: float | None = None,
    engine: Engine = "auto",
    progress: ProgressFn | None = None,
) -> ScanGeometry:
    """How every cell of ``result`` was seen from the scanner positions.

    Parameters
    ----------
    cloud : PointCloud or (N, 3) array
        The points ``result`` was computed from, metres.
    result : GridRoughness
        The grid result (with its point-to-cell map: not an out-of-core result).
    positions : (S, 3) array
        Scanner positions, metres, the cloud's frame.
    point_scan : (N,) int array, optional
        Row of ``positions`` of every point; default all 0 (one scanner).
    angular_step_rad : float, optional
        The scanners' angular step (azimuth and elevation), radians: ``N0 =
        1 / step^2`` rays per steradian. Default: fitted per scan (the median cell
        then has a density ratio of 1).
    engine : {"auto", "numpy", "numba"}
        Engine of the pass over the points for the cell moments.
    progress : callable, optional
        ``progress(done, total)`` over 3 stages.

    Returns
    -------
    ScanGeometry

    Examples
    --------
    A flat face 10 m in front of the scanner, seen head on:

    >>> from rough_viewer.grid.roughness import grid_roughness
    >>> g = np.linspace(-0.495, 0.495, 100)
    >>> x, z = np.meshgrid(g, g)
    >>> face = np.column_stack([x.ravel(), np.full(x.size, 10.0), z.ravel()])
    >>> res = grid_roughness(face, 0.5, origin=(-0.5, 9.75, -0.5), models=("odr",))
    >>> geo = scan_geometry(face, res, np.zeros((1, 3)))
    >>> np.round(geo.incidence_deg, 2), np.round(geo.range_m, 3)
    (array([2.02, 2.02, 2.02, 2.02]), array([10.006, 10.006, 10.006, 10.006]))
    """
    tick = progress or (lambda done, total: None)
    x, y, z = as_columns(cloud)
    pos = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    scan = _checked_scans(result, int(x.shape[0]), pos.shape[0], point_scan, angular_step_rad)
    m = result.n_cells
    require(m * 400.0, f"the scanner geometry of {m:,} cells")
    tick(0, 3)
    beams = _beams(result, pos, scan)
    tick(1, 3)
    area, area_cut, plane_variance = _face_areas(x, y, z, result, beams.has, engine)
    tick(2, 3)
    # expected points: N0 A cos(i) / (r^2 cos(e)) per pair
    pc, ps, has = beams.pc, beams.ps, beams.has
    with np.errstate(invalid="ignore", divide="ignore"):
        # steradians of the cell's face, per pair
        solid = area[pc] * beams.cos_i / (beams.r * beams.r * beams.cos_e)
        n0, source = _rays_per_steradian(ps, beams.pn, solid, pos.shape[0], angular_step_rad,
                                         result.min_points)
        expected = np.bincount(pc, weights=np.nan_to_num(n0[ps] * solid), minlength=m)
        expected[~has] = np.nan
        # below one expected point (a sliver of points whose plane holds the beam) the
        # scanner's grid predicts nothing to compare with
        density = np.where(expected >= MIN_EXPECTED, result.n_points / expected, np.nan)
        whole = expected * (area_cut / area)
        coverage = np.where(whole >= MIN_EXPECTED, result.n_points / whole, np.nan)
    occlusion = _occlusion(result, coverage, beams.beam, has)
    tick(3, 3)
    return ScanGeometry(scans=beams.scans, range_m=beams.range_m,
                        incidence_deg=beams.incidence, density_ratio=density,
                        occlusion=occlusion, expected_points=expected, coverage=coverage,
                        area_m2=area, plane_variance=plane_variance, beam=beams.beam, n0=n0,
                        n0_source=source, positions=pos, n_pairs=int(pc.shape[0]))


def _checked_scans(result: GridRoughness, n: int, n_scans: int,
                   point_scan: np.ndarray | None, angular_step_rad: float | None
                   ) -> np.ndarray:
    """The scan (row of the positions) of every one of the ``n`` points, the inputs of
    :func:`scan_geometry` checked."""
    if n_scans == 0:
        raise InputError("no scanner positions")
    if result.point_cell.shape[0] != n:
        raise InputError("the grid result holds no cell for every point (an out-of-core "
                         "result, or another cloud): scanner geometry needs the points")
    scan = (np.zeros(n, dtype=np.int64) if point_scan is None
            else np.asarray(point_scan).astype(np.int64, copy=False))
    if scan.shape != (n,) or (n and (scan.min() < 0 or scan.max() >= n_scans)):
        raise ValueError(f"point scans must be {n:,} rows of 0..{n_scans - 1}")
    if angular_step_rad is not None and not (np.isfinite(angular_step_rad)
                                             and 0 < angular_step_rad < np.pi):
        raise InputError(f"angular step must be in (0, pi) radians, got {angular_step_rad!r}")
    return scan


@dataclass(frozen=True)
class _Beams:
    """The (cell, scan) pairs of the cells with a plane and their geometry, and per
    cell the point-weighted means over its pairs."""

    scans: np.ndarray
    """(M,) scans with points in every cell (planes or not)."""
    has: np.ndarray
    """(M,) bool: the cell has a centroid and a normal."""
    pc: np.ndarray
    """(P,) cell of every pair."""
    ps: np.ndarray
    """(P,) scan of every pair."""
    pn: np.ndarray
    """(P,) points of every pair."""
    r: np.ndarray
    """(P,) range from the scanner to the cell's centroid, metres."""
    cos_i: np.ndarray
    """(P,) cosine of the incidence angle (beam to the cell's normal)."""
    cos_e: np.ndarray
    """(P,) cosine of the beam's elevation."""
    range_m: np.ndarray
    """(M,) mean range, metres (NaN without a plane)."""
    incidence: np.ndarray
    """(M,) mean incidence angle, degrees (NaN without a plane)."""
    beam: np.ndarray
    """(M, 3) mean unit beam direction."""


def _beams(result: GridRoughness, pos: np.ndarray, scan: np.ndarray) -> _Beams:
    """The beams from the scanners ``pos`` to every cell their points ``scan`` are in."""
    m = result.n_cells
    pc, ps, pn = _pairs(result.point_cell, scan, pos.shape[0], result.n_points)
    scans = np.bincount(pc, minlength=m).astype(np.int64)  # every cell, planes or not
    has = np.isfinite(result.centroid[:, 0]) & np.isfinite(result.normal[:, 0])
    keep = has[pc]
    pc, ps, pn = pc[keep], ps[keep], pn[keep]
    v = result.centroid[pc] - pos[ps]
    r = np.linalg.norm(v, axis=1)
    b = v / np.where(r > 0, r, 1.0)[:, None]
    cos_i = np.clip(np.abs(np.einsum("ij,ij->i", b, result.normal[pc])), 0.0, 1.0)
    cos_e = np.hypot(b[:, 0], b[:, 1])
    w = pn.astype(np.float64)
    wsum = np.bincount(pc, weights=w, minlength=m)
    with np.errstate(invalid="ignore", divide="ignore"):
        range_m = np.bincount(pc, weights=w * r, minlength=m) / wsum
        incidence = np.degrees(np.bincount(pc, weights=w * np.arccos(cos_i), minlength=m) / wsum)
        beam = np.stack([np.bincount(pc, weights=w * b[:, a], minlength=m) for a in range(3)],
                        axis=1).astype(np.float64)
        beam = beam / np.linalg.norm(beam, axis=1)[:, None]
    range_m[~has] = np.nan
    incidence[~has] = np.nan
    return _Beams(scans=scans, has=has, pc=pc, ps=ps, pn=pn, r=r, cos_i=cos_i, cos_e=cos_e,
                  range_m=range_m, incidence=incidence, beam=beam)


def _face_areas(x: np.ndarray, y: np.ndarray, z: np.ndarray, result: GridRoughness,
                has: np.ndarray, engine: Engine
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per cell: the face area the scanner saw and the area of the whole cell's face
    (square metres), and the variance of its points about their plane (square
    metres); NaN without a plane."""
    g = result.grid.cell_size
    index = CellIndex(grid=result.grid, ijk=result.ijk, counts=result.n_points,
                      point_cell=result.point_cell)
    cov = cell_moments(x, y, z, index, engine=engine).covariance()
    eig = np.linalg.eigvalsh(np.where(has[:, None, None], cov, 0.0))[:, ::-1]
    extent = points_extent_area(eig, result.n_points)
    plane_variance = np.where(has, np.clip(eig[:, 2], 0.0, None), np.nan)
    lower = result.grid.origin + result.ijk * g
    normal = np.where(has[:, None], result.normal, [[0.0, 0.0, 1.0]])
    centroid = np.where(has[:, None], result.centroid, lower + 0.5 * g)
    cut = plane_cut_area(normal, centroid, lower, g)
    with np.errstate(invalid="ignore", divide="ignore"):
        fill = extent / cut
    plane_ok = (cut > 0) & (fill <= MAX_EXTENT_OVER_CUT)
    # where the scanner saw: the exact cut where the points fill it, their own extent
    # where they fill only part of it (a shadow, or the face ends in the cell) or where
    # the plane misrepresents them (a sliver of points)
    area = np.where(plane_ok & (fill > 1.0), cut, extent)
    # the whole cell: the cut wherever the plane represents the points
    area_cut = np.where(plane_ok, cut, extent)
    area[~has] = np.nan
    area_cut[~has] = np.nan
    return area, area_cut, plane_variance


def _rays_per_steradian(ps: np.ndarray, pn: np.ndarray, solid: np.ndarray, n_scans: int,
                        angular_step_rad: float | None, min_points: int
                        ) -> tuple[np.ndarray, N0Source]:
    """``N0`` of every scan (rays per steradian; NaN for a scan with no pair) and where
    it comes from: the angular step given, else the median over the scan's pairs of
    points per steradian of face (``solid``), those of at least ``min_points`` points
    where it has any. A loop over scans, not points."""
    n0 = np.full(n_scans, np.nan)
    if angular_step_rad is not None:
        n0[np.unique(ps)] = 1.0 / float(angular_step_rad) ** 2
        return n0, "angular step"
    with np.errstate(invalid="ignore", divide="ignore"):
        good = (solid > 0) & np.isfinite(solid) & (pn >= min_points)
        ratio = pn / solid
    for k in np.unique(ps):  # one median per scan (a loop over scans, not points)
        sel = (ps == k) & good
        if not np.any(sel):
            sel = (ps == k) & (solid > 0) & np.isfinite(solid)
        if np.any(sel):
            n0[k] = float(np.median(ratio[sel]))
    return n0, "fitted"


def _occlusion(result: GridRoughness, density: np.ndarray, beam: np.ndarray,
               has: np.ndarray) -> np.ndarray:
    """``1 - rho / max(rho of the two neighbours along the beam)``, clipped to [0, 1],
    ``rho`` the cells' coverage."""
    g = result.grid.cell_size
    n = np.where(has[:, None], result.normal, 0.0)
    t = beam - np.einsum("ij,ij->i", beam, n)[:, None] * n
    norm = np.linalg.norm(t, axis=1)
    along = has & np.isfinite(norm) & (norm > 1e-9)
    t = np.where(along[:, None], t / np.where(norm > 0, norm, 1.0)[:, None], 0.0)
    ref = np.full(result.n_cells, np.nan)
    for sign in (-1.0, 1.0):
        q = np.where(along[:, None], result.centroid + sign * g * t, result.grid.origin)
        ijk = np.floor((q - result.grid.origin) / g).astype(np.int64)
        row = _lookup_rows(result, ijk)
        row = np.where(along & (row >= 0) & (row != np.arange(result.n_cells)), row, -1)
        nb = np.where(row >= 0, density[np.maximum(row, 0)], np.nan)
        ref = np.fmax(ref, nb)
    with np.errstate(invalid="ignore", divide="ignore"):
        occ = np.where(ref > 0, np.clip(1.0 - density / ref, 0.0, 1.0), np.nan)
    # seen head on (the beam along the normal): nothing casts a shadow across the cell
    occ[has & ~along & np.isfinite(density)] = 0.0
    return occ
