"""Roughness across scales: one point's cells, and the whole face, against grid size.

The 2011 paper's central observation is that roughness depends on the grid size
(its Table 1: mean roughness and the share of rough cells change with the cell
edge). Two views of that, both built from grids the caller already has:

- :func:`point_scales`: for one point of the cloud, the ODR, OLS and hybrid
  roughness (and e_ols) of the cell holding it on each grid. From a list of
  :class:`~rough_viewer.grid.roughness.GridRoughness` results this is a look-up
  (``result.point_cell[point]``). :func:`point_scales_from_prepared` does the same
  from :class:`~rough_viewer.grid.roughness.PreparedGrid` objects (the nested grids
  of :func:`~rough_viewer.grid.roughness.coarsen_prepared`) when the full results
  are not computed yet: it evaluates only the cells that hold the point, by the one
  definition (:func:`~rough_viewer.grid.roughness.grid_roughness` on those cells'
  points), so the numbers equal the full maps'.
- :func:`face_scales`: for the whole face, the Table-1 statistics
  (:func:`~rough_viewer.grid.summary.summarise`) and the share of binary cells
  (normalised roughness ``>= threshold``, :func:`~rough_viewer.grid.summary.binary`)
  of every map on every grid.

Grids are sorted by cell size (finest first) in every result.

>>> import numpy as np
>>> from rough_viewer.grid.roughness import grid_roughness
>>> rng = np.random.default_rng(0)
>>> xy = rng.uniform(0, 2, (20_000, 2))
>>> pts = np.column_stack([xy, 0.01 * np.sin(6 * xy[:, 0]) + 0.001 * rng.standard_normal(20_000)])
>>> grids = [grid_roughness(pts, g, axis="z") for g in (1.0, 0.5, 0.25)]
>>> ps = point_scales(grids, 0)
>>> ps.cell_sizes
array([0.25, 0.5 , 1.  ])
>>> bool(np.all(np.diff(ps.theta_odr) > 0))   # the waves count as roughness on big cells
True
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rough_viewer.grid.cells import CellIndex, cell_moments
from rough_viewer.grid.outliers import analysed_values
from rough_viewer.grid.roughness import GridRoughness, PreparedGrid, grid_roughness, map_values
from rough_viewer.grid.summary import Summary, binary, normalise, summarise
from rough_viewer.io.cloud import PointCloud, as_columns
from rough_viewer.vocabulary import (
    DEFAULT_MIN_POINTS,
    DEFAULT_THRESHOLD,
    MAPS,
    Axis,
    InputError,
    MapName,
    Residual,
)


@dataclass(frozen=True)
class PointScales:
    """Roughness of the cells holding one point, one entry per grid (finest first)."""

    point: int
    """Index of the point in the cloud."""
    cell_sizes: np.ndarray
    """(K,) grid cell edges, metres, ascending."""
    cell: np.ndarray
    """(K,) int64 row of the point's cell in each grid's cell arrays."""
    n_points: np.ndarray
    """(K,) int64 points in that cell."""
    theta_odr: np.ndarray
    """(K,) ODR roughness of the cell, metres (NaN: no value)."""
    theta_ols: np.ndarray
    """(K,) OLS roughness along ``axis``, metres."""
    theta_hybrid: np.ndarray
    """(K,) hybrid roughness, metres."""
    e_ols: np.ndarray
    """(K,) ``|theta_ols - theta_odr|``, metres."""
    axis: Axis
    """Dependent axis of OLS and hybrid."""
    min_points: int
    """Cells with fewer points have no value."""

    def values(self, name: MapName) -> np.ndarray:
        """The (K,) series of map ``"odr"``, ``"ols"``, ``"hybrid"`` or ``"e_ols"``, metres."""
        return map_values(self, name)


def _sorted_results(results: Sequence[GridRoughness]) -> list[GridRoughness]:
    """``results`` finest first, checked to describe one cloud with one axis."""
    if not results:
        raise InputError("need at least one grid")
    ordered = sorted(results, key=lambda r: r.grid.cell_size)
    first = ordered[0]
    for r in ordered[1:]:
        if r.n_points_total != first.n_points_total:
            raise ValueError("the grids were computed on different clouds "
                             f"({r.n_points_total:,} and {first.n_points_total:,} points)")
        if r.axis != first.axis:
            raise ValueError(f"the grids use different dependent axes ({r.axis} and {first.axis})")
        if r.min_points != first.min_points:
            raise ValueError("the grids use different minimum points per cell "
                             f"({r.min_points} and {first.min_points})")
    return ordered


def point_scales(results: Sequence[GridRoughness], point: int) -> PointScales:
    """The roughness of the cells holding cloud point ``point`` on each grid.

    A look-up in the results (no computation).

    Parameters
    ----------
    results : sequence of GridRoughness
        The same cloud on several grid sizes, with one dependent axis and one
        ``min_points`` (e.g. the app's cached preset grids); any order.
    point : int
        Index of the point in the cloud (``0 <= point < N``).

    Returns
    -------
    PointScales
    """
    ordered = _sorted_results(results)
    n = ordered[0].n_points_total
    p = int(point)
    if not 0 <= p < n:
        raise InputError(f"point {point} is not in the cloud (0 to {n - 1})")
    cell = np.array([r.point_cell[p] for r in ordered], dtype=np.int64)

    def pick(name: MapName) -> np.ndarray:
        return np.array([r.values(name)[c] for r, c in zip(ordered, cell, strict=True)],
                        dtype=np.float64)

    return PointScales(
        point=p,
        cell_sizes=np.array([r.grid.cell_size for r in ordered]),
        cell=cell,
        n_points=np.array([r.n_points[c] for r, c in zip(ordered, cell, strict=True)],
                          dtype=np.int64),
        theta_odr=pick("odr"),
        theta_ols=pick("ols"),
        theta_hybrid=pick("hybrid"),
        e_ols=pick("e_ols"),
        axis=ordered[0].axis,
        min_points=ordered[0].min_points,
    )


def point_scales_from_prepared(
    cloud: PointCloud | np.ndarray,
    grids: Sequence[PreparedGrid],
    point: int,
    *,
    axis: Axis,
    min_points: int = DEFAULT_MIN_POINTS,
    residual: Residual = "absolute",
) -> PointScales:
    """:func:`point_scales` without the full maps: only the cells holding ``point``.

    For each prepared grid, the points of the cell holding ``point`` are gathered
    (one comparison over the cell index) and
    :func:`~rough_viewer.grid.roughness.grid_roughness` is run on them alone, as
    that one cell of the same grid: the one definition of roughness, on one cell. Cost: O(N) per grid for the gather plus the cell's points, milliseconds
    where the full map takes a pass over every point.

    Parameters
    ----------
    cloud : PointCloud or (N, 3) array
        The points the grids were prepared on, metres.
    grids : sequence of PreparedGrid
        E.g. the finest grid and its :func:`~rough_viewer.grid.roughness.coarsen_prepared`
        coarsenings; any order.
    point : int
        Index of the point in the cloud.
    axis : {"x", "y", "z"}
        Dependent axis of OLS and hybrid: the one the full maps use
        (``GridRoughness.axis``; ``auto`` is not accepted, since one cell cannot say
        which axis the whole cloud's plane picks).
    min_points, residual
        As for :func:`~rough_viewer.grid.roughness.grid_roughness`.

    Returns
    -------
    PointScales
        Equal to :func:`point_scales` of the full results on the same grids.
    """
    if not grids:
        raise InputError("need at least one grid")
    if axis not in ("x", "y", "z"):
        raise InputError(f"axis must be x, y or z here, got {axis!r}")
    x, y, z = as_columns(cloud)
    n = int(x.shape[0])
    p = int(point)
    if not 0 <= p < n:
        raise InputError(f"point {point} is not in the cloud (0 to {n - 1})")
    ordered = sorted(grids, key=lambda g: g.cell_size)
    rows: list[tuple[int, int, float, float, float]] = []
    for prep in ordered:
        if prep.n_points != n:
            raise ValueError("a prepared grid was made for another cloud")
        point_cell = prep.point_cell()
        c = int(point_cell[p])
        members = np.flatnonzero(point_cell == c)
        del point_cell
        count = int(members.shape[0])
        if count < max(3, int(min_points)):
            rows.append((c, count, np.nan, np.nan, np.nan))
            continue
        xs, ys, zs = x[members], y[members], z[members]
        # the one cell, with the grid's own membership (no re-indexing that could
        # round a boundary point the other way)
        index = CellIndex(grid=prep.index.grid, ijk=prep.index.ijk[c:c + 1],
                          counts=np.array([count], dtype=np.int64),
                          point_cell=np.zeros(count, dtype=np.int64))
        one = grid_roughness(np.column_stack([xs, ys, zs]), prep.cell_size, axis=axis,
                             min_points=min_points, residual=residual,
                             prepared=PreparedGrid(index, cell_moments(xs, ys, zs, index)))
        rows.append((c, count, float(one.theta_odr[0]), float(one.theta_ols[0]),
                     float(one.theta_hybrid[0])))
    cell, counts, odr, ols, hybrid = (np.array(col) for col in zip(*rows, strict=True))
    return PointScales(
        point=p,
        cell_sizes=np.array([g.cell_size for g in ordered]),
        cell=cell.astype(np.int64),
        n_points=counts.astype(np.int64),
        theta_odr=odr.astype(np.float64),
        theta_ols=ols.astype(np.float64),
        theta_hybrid=hybrid.astype(np.float64),
        e_ols=np.abs(ols - odr).astype(np.float64),
        axis=axis,
        min_points=int(min_points),
    )


@dataclass(frozen=True)
class FaceScales:
    """Whole-face statistics of every map on every grid (the 2011 Table-1 trend)."""

    cell_sizes: np.ndarray
    """(K,) grid cell edges, metres, ascending."""
    summaries: tuple[dict[str, Summary], ...]
    """(K,) Table-1 summary of each map (``odr``, ``ols``, ``hybrid``, ``e_ols``) on each
    grid."""
    rough_share: dict[str, np.ndarray]
    """Map name -> (K,) share (0-1) of the cells with a value whose min-max normalised
    roughness is ``>= threshold`` (the binary transform's rough cells)."""
    threshold: float
    """Binary threshold on normalised roughness."""
    axis: Axis
    """Dependent axis of OLS and hybrid."""
    n_points: int
    """Points in the cloud."""

    def statistic(self, name: MapName, what: str = "mean") -> np.ndarray:
        """(K,) one Table-1 statistic of map ``name`` against grid size: ``"mean"``,
        ``"std"``, ``"min"``, ``"max"`` (metres), ``"variance"`` (m^2), ``"cells"`` or
        ``"mean_points"``."""
        if name not in MAPS:
            raise InputError(f"unknown map {name!r}; expected one of {', '.join(MAPS)}")
        if what not in ("mean", "std", "min", "max", "variance", "cells", "mean_points"):
            raise ValueError(f"unknown statistic {what!r}")
        return np.array([getattr(s[name], what) for s in self.summaries], dtype=np.float64)


def face_scales(
    results: Sequence[GridRoughness], *, threshold: float = DEFAULT_THRESHOLD,
    keep_outliers: bool = False,
) -> FaceScales:
    """Table-1 statistics and binary rough-cell shares of every map against grid size.

    Parameters
    ----------
    results : sequence of GridRoughness
        The same cloud on several grid sizes (one axis, one ``min_points``); any order.
    threshold : float
        Binary threshold on min-max normalised roughness (paper: 0.05).
    keep_outliers : bool
        Keep cells larger than the cell (:mod:`rough_viewer.grid.outliers`) in the
        statistics and the normalisation; default: left out.

    Returns
    -------
    FaceScales
    """
    if not 0.0 <= float(threshold) <= 1.0:
        raise InputError(f"threshold must lie in 0-1, got {threshold}")
    ordered = _sorted_results(results)
    shares: dict[str, list[float]] = {name: [] for name in MAPS}
    for r in ordered:
        for name in MAPS:
            v = analysed_values(r, name, keep_outliers=keep_outliers)
            ok = np.isfinite(v)
            rough = binary(normalise(v), threshold)
            shares[name].append(float(rough.sum()) / ok.sum() if ok.any() else float("nan"))
    return FaceScales(
        cell_sizes=np.array([r.grid.cell_size for r in ordered]),
        summaries=tuple({name: summarise(r, name, keep_outliers=keep_outliers) for name in MAPS}
                        for r in ordered),
        rough_share={name: np.array(v) for name, v in shares.items()},
        threshold=float(threshold),
        axis=ordered[0].axis,
        n_points=ordered[0].n_points_total,
    )
