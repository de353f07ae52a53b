"""Per-cell surface roughness: ODR, OLS and hybrid models, e_ols, summaries.

Definitions (docs/science.md section 1; 2011 paper Eqs. 3-5, 2012 paper Table 1):

==========  ==================================  ======================================
model       reference plane                     distance ``D_i`` of a point
==========  ==================================  ======================================
``odr``     ODR plane (centroid, min-eigvec)    ``|n . (p_i - c)|``
``ols``     OLS along dependent axis ``a``      ``|residual along a|``
``hybrid``  ODR plane                           ``|n . (p_i - c)| / |n_a|``
==========  ==================================  ======================================

Roughness of a cell: ``theta = sqrt(mean(D^2) - mean(D)^2)``, the population
standard deviation of the ABSOLUTE distances. With ``residual="signed"`` it is the
RMS of the signed distances instead (an option, not the default).

Implementation: one pass over the points for cell keys, one for cell-local moment
sums, planes fitted per cell from the 3x3 covariances (batched), and one pass for
the sums of ``|D|`` and ``D^2``. (``mean(D^2)`` is also ``n^T C n`` from the moments,
but that closed form loses ``sqrt(eps) g`` of absolute precision where a cell is
nearly flat, so both sums come from the points.) The hybrid model needs no pass of
its own: its distances are the ODR ones divided by ``|n_a|``, constant per cell.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from rough_viewer.grid import fast
from rough_viewer.grid.cells import (
    DENSE_LIMIT,
    CellIndex,
    CellMoments,
    GridSpec,
    cell_moments,
    coarsen,
    distance_sums,
    index_points,
    make_grid,
)
from rough_viewer.grid.cells import (
    index_and_moments as cells_index_and_moments,
)
from rough_viewer.grid.fast import resolve_engine
from rough_viewer.grid.planes import (
    PlaneFit,
    axis_index,
    dominant_axis,
    odr_from_covariance,
    ols_from_covariance,
    orient_normal,
    plane_from_scatter,
    whole_cloud_plane,
)
from rough_viewer.io.cloud import PointCloud, as_columns, known_bounds, note_bounds, on_faces
from rough_viewer.vocabulary import (
    AXES,
    DEFAULT_MIN_POINTS,
    MAPS,
    MODELS,
    Axis,
    AxisChoice,
    Engine,
    InputError,
    MapName,
    Model,
    ProgressFn,
    Residual,
)

#: A hybrid distance along axis ``a`` is undefined when the ODR normal is
#: (numerically) perpendicular to ``a``.
HYBRID_MIN_COMPONENT = 1e-9
#: A cell "fits exactly" when its roughness is below this share of the cell size:
#: its points lie on one plane to round-off (e.g. a cell of 6 points holding only 3
#: distinct ones, as duplicate points in airborne scans give, or 4-6 points on two
#: rows of a DEM lattice: 65 of 8,782 cells of the fault DEM at 0.03 m). docs/science.md gives such a
#: cell its value (0); the summaries count it, so a user learns why Table 1's
#: minimum is 0 (see :meth:`GridRoughness.cell_report`).
EXACT_FIT = 1e-9


def exact_fit_text(n: int, valued: int) -> str:
    """Why ``n`` of ``valued`` cells have roughness 0 (:data:`EXACT_FIT`): the one
    sentence the summary, the report and the app show, each adding its own remedy.

    >>> exact_fit_text(3, 6)[:58]
    '3 of 6 cells with a value fit their plane exactly (roughne'
    """
    return (f"{n:,} of {valued:,} cells with a value fit their plane exactly (roughness 0 "
            "to round-off): their points lie on one plane, because the file repeats points "
            "(4+ points, only 3 distinct) or they lie on two rows of a lattice (a DEM's grid: "
            "two parallel lines share a plane), so they set the minimum")


@dataclass(frozen=True)
class PreparedGrid:
    """Cell membership and moment sums of a cloud on one grid: the part of
    :func:`grid_roughness` that does not depend on the model, the axis or
    ``min_points``. Keep one to recompute those quickly, or :func:`coarsen_prepared`
    it to a nested coarser grid without a pass over the points."""

    index: CellIndex
    """Cell membership (``index.point_cell`` empty where :attr:`parent` is set)."""
    moments: CellMoments
    """Cell-local moment sums."""
    fine_cell: np.ndarray | None = None
    """(N,) int64 every point's row on the finer grid this one was coarsened from
    (:func:`coarsen_prepared`), or None."""
    parent: np.ndarray | None = None
    """(M_fine,) int64 the row on this grid of every row of the finer one, or None:
    the row of point ``i`` is ``parent[fine_cell[i]]``, which the distance pass of
    :func:`grid_roughness` applies on its way (so coarsening makes no pass over the
    points of its own)."""

    @property
    def n_points(self) -> int:
        """Number of points."""
        rows = self.index.point_cell if self.fine_cell is None else self.fine_cell
        return int(rows.shape[0])

    def point_cell(self) -> np.ndarray:
        """(N,) int64 every point's row (a gather over the points where this grid
        was coarsened: :attr:`parent`)."""
        if self.parent is None or self.fine_cell is None:
            return self.index.point_cell
        return self.parent[self.fine_cell]

    def pass_index(self) -> tuple[CellIndex, np.ndarray | None]:
        """The index a pass over the points takes, and the row lookup it applies on
        its way (None: ``point_cell`` holds the rows already)."""
        if self.parent is None or self.fine_cell is None:
            return self.index, None
        return replace(self.index, point_cell=self.fine_cell), self.parent

    @property
    def cell_size(self) -> float:
        """Grid cell edge, metres."""
        return self.index.grid.cell_size

    def whole_plane(self) -> PlaneFit:
        """The whole cloud's ODR plane, combined from the per-cell moment sums (no pass
        over the points); see :func:`whole_plane_from_moments`."""
        return whole_plane_from_moments(self.index.grid, self.index.ijk, self.moments)


def whole_plane_from_moments(grid: GridSpec, ijk: np.ndarray, moments: CellMoments) -> PlaneFit:
    """The whole cloud's ODR plane from per-cell moment sums (no pass over the points);
    equal to :func:`~rough_viewer.grid.planes.whole_cloud_plane` of the same points up
    to rounding. Cell means are taken relative to the grid origin, so no precision is
    lost on large coordinates.

    Parameters
    ----------
    grid : GridSpec
        The grid (origin and cell edge in metres).
    ijk : (M, 3) int64
        Cell indices of the rows of ``moments``.
    moments : CellMoments
        Cell-local moment sums.
    """
    mom = moments
    n = mom.counts.astype(np.float64)
    total = n.sum()
    mean_c = (ijk - grid.index_min + 0.5) * grid.cell_size + mom.mean_local()
    mean_all = (n[:, None] * mean_c).sum(axis=0) / total
    d = mean_c - mean_all
    scatter = np.einsum("m,mij->ij", n, mom.covariance()) + np.einsum("m,mi,mj->ij", n, d, d)
    centroid = grid.origin + grid.index_min * grid.cell_size + mean_all
    plane = plane_from_scatter(centroid, scatter / total)
    return replace(plane, normal=orient_normal(plane.normal))


def prepare_grid(
    cloud: PointCloud | np.ndarray, cell_size: float, *, origin: np.ndarray | None = None,
    engine: Engine = "auto",
) -> PreparedGrid:
    """Index the points on the grid of edge ``cell_size`` (metres) and sum their moments
    (``engine``: see :func:`~rough_viewer.grid.cells.index_points`)."""
    x, y, z = as_columns(cloud)
    prepared, lookup = _prepare(x, y, z, cell_size, origin, engine)
    if lookup is not None:  # the fused pass left keys: rows now
        fast.relabel(prepared.index.point_cell, lookup)
    return prepared


def _prepare(x: np.ndarray, y: np.ndarray, z: np.ndarray, cell_size: float,
             origin: np.ndarray | None, engine: Engine
             ) -> tuple[PreparedGrid, np.ndarray | None]:
    """:func:`prepare_grid`, but where the compiled engine's fused pass ran, the
    prepared grid's ``point_cell`` still holds every point's key and the second value
    is the lookup of their rows (:func:`~rough_viewer.grid.cells.distance_sums`
    applies it on its pass); else None.

    The bounds come from :func:`~rough_viewer.io.cloud.known_bounds` where a reader
    or an earlier grid noted them, checked: the six points noted on the box's faces
    must still lie there and the fused pass must find every point inside (the box
    is then the points' bounds exactly); else they are taken again
    (:func:`~rough_viewer.grid.fast.bounds_at`), so a noted box never changes a
    result, and the bounds pass is saved for every grid after the first."""
    if x.shape[0] < 3:
        raise InputError(f"need at least 3 points, got {x.shape[0]}")
    n = int(x.shape[0])
    engine = resolve_engine(engine, n_points=n)
    if engine != "numba":
        lo = np.array([x.min(), y.min(), z.min()])
        hi = np.array([x.max(), y.max(), z.max()])
        grid = make_grid(lo, hi, cell_size, origin, n_points=n)
        index = index_points(x, y, z, grid, engine=engine)
        return PreparedGrid(index=index, moments=cell_moments(x, y, z, index, engine=engine)), None
    hint = known_bounds(x, y, z)
    if hint is not None and not on_faces(x, y, z, *hint):
        hint = None  # changed in place since
    if hint is not None:
        lo, hi, at = hint
        grid = make_grid(lo, hi, cell_size, origin, n_points=n)
        if fast.fused_fits(grid.n_cells, n):
            got = fast.fused_index_and_moments(x, y, z, grid, lo, hi)
            if got.inside:  # and a point on each face: these points' bounds
                return _from_fused(grid, got)
    lo, hi, at = fast.bounds_at(x, y, z)
    grid = make_grid(lo, hi, cell_size, origin, n_points=n)
    note_bounds(x, y, z, lo, hi, at)
    if fast.fused_fits(grid.n_cells, n):
        got = fast.fused_index_and_moments(x, y, z, grid, lo, hi)
        if not got.inside:  # cannot happen: bounds_at saw these very points
            raise AssertionError("the fused pass found points outside their bounds")
        return _from_fused(grid, got)
    index, moments = cells_index_and_moments(x, y, z, grid, dense_limit=DENSE_LIMIT)
    return PreparedGrid(index=index, moments=moments), None


def _from_fused(grid: GridSpec, got: fast.Fused) -> tuple[PreparedGrid, np.ndarray]:
    index = CellIndex(grid=grid, ijk=got.ijk, counts=got.counts, point_cell=got.key)
    return (PreparedGrid(index=index, moments=CellMoments(counts=got.counts, s1=got.s1,
                                                          s2=got.s2)), got.lookup)


def coarsen_prepared(prepared: PreparedGrid, factor: int, *,
                     defer_rows: bool = False) -> PreparedGrid:
    """The prepared grid ``factor`` (a positive integer) times coarser, same origin,
    computed from the fine one's cells without a pass over the coordinates: the
    coarse sums from the fine sums.

    ``defer_rows``: every point's coarse row is not gathered here but left to the
    distance pass of :func:`grid_roughness` (:attr:`PreparedGrid.parent`; the
    coarse ``index.point_cell`` is then empty and :meth:`PreparedGrid.point_cell`
    makes the rows on demand), so that pass is the only one over the points (the
    app's presets). Else the rows are gathered now (one pass over the rows, on all
    threads where the kernels are loaded)."""
    fine_index, lookup = prepared.pass_index()
    index, moments, parent = coarsen(fine_index, prepared.moments, factor, gather=False)
    if lookup is not None:  # coarsened twice: compose the row maps
        parent = parent[lookup]
    lazy = PreparedGrid(index=index, moments=moments, fine_cell=fine_index.point_cell,
                        parent=parent)
    if defer_rows:
        return lazy
    if fast.loaded():
        rows = np.empty(fine_index.point_cell.shape[0], dtype=np.int64)
        fast.relabel_into(fine_index.point_cell, parent, rows)
    else:
        rows = lazy.point_cell()
    return PreparedGrid(index=replace(index, point_cell=rows), moments=moments)


def map_values(holder: Any, name: MapName) -> np.ndarray:
    """The map ``name`` of anything holding ``theta_odr``, ``theta_ols``,
    ``theta_hybrid`` and ``e_ols`` arrays (a grid result, an across-scales series)."""
    if name == "e_ols":
        return np.asarray(holder.e_ols)
    if name in MODELS:
        return np.asarray(getattr(holder, f"theta_{name}"))
    raise InputError(f"unknown map {name!r}; expected one of {', '.join(MAPS)}")


@dataclass(frozen=True)
class GridRoughness:
    """Roughness maps of one cloud on one grid. Cell arrays have one row per occupied
    cell; values are NaN where a cell has no value (too few points, degenerate
    plane, model not asked for)."""

    grid: GridSpec
    """The grid (origin, cell size in metres)."""
    axis: Axis
    """Dependent axis actually used by OLS and hybrid."""
    axis_requested: AxisChoice
    """Axis option as given (``"auto"`` picks the axis closest to the whole-cloud normal)."""
    whole_plane: PlaneFit
    """The whole cloud's ODR plane (normal oriented by
    :func:`~rough_viewer.grid.planes.orient_normal`)."""
    min_points: int
    """Cells with fewer points get no value."""
    residual: Residual
    """``"absolute"`` (docs/science.md default) or ``"signed"`` (RMS of signed distances)."""
    models: tuple[Model, ...]
    """Models computed."""
    ijk: np.ndarray
    """(M, 3) int64 cell indices."""
    centre: np.ndarray
    """(M, 3) cell centres, metres, the file's frame."""
    n_points: np.ndarray
    """(M,) int64 points per cell."""
    centroid: np.ndarray
    """(M, 3) point centroid per cell, metres (NaN below ``min_points``)."""
    normal: np.ndarray
    """(M, 3) ODR unit normal per cell (NaN where no plane)."""
    theta_odr: np.ndarray
    """(M,) ODR roughness, metres."""
    theta_ols: np.ndarray
    """(M,) OLS roughness along the dependent axis, metres."""
    theta_hybrid: np.ndarray
    """(M,) hybrid roughness, metres."""
    e_ols: np.ndarray
    """(M,) OLS error ``|theta_ols - theta_odr|``, metres."""
    point_cell: np.ndarray
    """(N,) int64 row of the cell arrays for every input point (empty when the cells
    were computed out of core, :mod:`rough_viewer.scale`: no per-point array is kept)."""
    n_points_total: int
    """Number of points used."""

    @property
    def n_cells(self) -> int:
        """Number of occupied cells."""
        return int(self.n_points.shape[0])

    @property
    def whole_normal(self) -> np.ndarray:
        """(3,) unit normal of the whole cloud's ODR plane."""
        return self.whole_plane.normal

    def values(self, name: MapName) -> np.ndarray:
        """The (M,) map ``"odr"``, ``"ols"``, ``"hybrid"`` or ``"e_ols"``, metres."""
        return map_values(self, name)

    def point_values(self, name: MapName) -> np.ndarray:
        """(N,) the map's value of each point's cell (NaN where the cell has none)."""
        return self.values(name)[self.point_cell]

    def cell_report(self, name: MapName) -> dict[str, int]:
        """Counts of cells: occupied, below ``min_points``, degenerate, with a value,
        and ``exact_fit``: cells with a value below :data:`EXACT_FIT` times the cell
        size (points on one plane to round-off; 0 for ``e_ols``, a difference). Cells
        larger than the cell are counted by
        :func:`rough_viewer.grid.outliers.outlier_mask`."""
        v = self.values(name)
        below = int(np.count_nonzero(self.n_points < self.min_points))
        finite = np.isfinite(v)
        valued = int(np.count_nonzero(finite))
        exact = 0 if name == "e_ols" else int(np.count_nonzero(
            np.abs(v[finite]) <= EXACT_FIT * self.grid.cell_size))
        return {
            "occupied": self.n_cells,
            "below_min_points": below,
            "degenerate": self.n_cells - below - valued,
            "with_value": valued,
            "exact_fit": exact,
        }


def whole_cloud_axis(cloud: PointCloud | np.ndarray) -> Axis:
    """The coordinate axis closest to the normal of the whole cloud's ODR plane
    (the ``auto`` dependent axis)."""
    return dominant_axis(whole_cloud_plane(cloud).normal)


def grid_roughness(
    cloud: PointCloud | np.ndarray,
    cell_size: float,
    *,
    origin: np.ndarray | None = None,
    min_points: int = DEFAULT_MIN_POINTS,
    axis: AxisChoice = "auto",
    models: Iterable[Model] = MODELS,
    residual: Residual = "absolute",
    progress: ProgressFn | None = None,
    prepared: PreparedGrid | None = None,
    engine: Engine = "auto",
) -> GridRoughness:
    """Roughness of every grid cell of a cloud.

    Parameters
    ----------
    cloud : PointCloud or (N, 3) array
        Points, metres.
    cell_size : float
        Grid cell edge ``g``, metres.
    origin : (3,) array_like, optional
        Grid origin, metres; default the bounding-box minimum.
    min_points : int
        Cells with fewer points get no value (default 4: three points fix a plane
        exactly, so a 3-point cell's roughness is 0 by construction; 3 is accepted
        for the bare definition).
    axis : {"auto", "x", "y", "z"}
        Dependent axis of OLS and hybrid; ``"auto"`` = axis closest to the normal of
        the whole cloud's ODR plane.
    models : iterable of {"odr", "ols", "hybrid"}
        Models to compute (``e_ols`` is filled when both odr and ols are).
    residual : {"absolute", "signed"}
        ``"absolute"``: std of absolute distances (docs/science.md); ``"signed"``: RMS of
        signed distances.
    progress : callable, optional
        ``progress(done, total)`` over the five stages (cell keys, moments, plane
        fits, distances, assembly).
    prepared : PreparedGrid, optional
        Cell index and moments of this cloud on this grid (from
        :func:`prepare_grid` or :func:`coarsen_prepared`), to skip those passes;
        ``cell_size`` and ``origin`` are then taken from it.
    engine : {"auto", "numpy", "numba"}
        Engine of the point passes: ``numpy`` is the reference, ``numba`` the compiled
        kernels of :mod:`rough_viewer.grid.fast` (same arithmetic, several times
        faster); ``auto`` = numba when installed, for clouds of millions of points
        (:func:`~rough_viewer.grid.fast.resolve_engine`; ``$ROUGH_VIEWER_ENGINE``
        overrides).

    Returns
    -------
    GridRoughness

    Examples
    --------
    A flat face with 2 mm of Gaussian noise: ODR roughness is the standard deviation of
    the absolute noise, ``0.002 * sqrt(1 - 2 / pi)`` = 1.206 mm.

    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> xy = rng.uniform(0.0, 2.0, (40_000, 2))
    >>> res = grid_roughness(np.column_stack([xy, 0.002 * rng.standard_normal(40_000)]), 1.0)
    >>> res.n_cells, res.axis
    (4, 'z')
    >>> np.round(res.theta_odr * 1e3, 2)
    array([1.21, 1.21, 1.21, 1.22])
    """
    models_t = check_options(models, axis, residual, min_points)
    x, y, z = as_columns(cloud)
    n_total = int(x.shape[0])
    if n_total < 3:
        raise InputError(f"need at least 3 points, got {n_total}")
    tick = progress or (lambda done, total: None)
    engine = resolve_engine(engine, n_points=n_total)

    tick(0, 5)
    lookup = None
    if prepared is None:
        prepared, lookup = _prepare(x, y, z, cell_size, origin, engine)
    elif prepared.n_points != n_total:
        raise ValueError("prepared grid was made for another cloud")
    tick(2, 5)
    whole = prepared.whole_plane()
    used_axis: Axis = dominant_axis(whole.normal) if axis == "auto" else axis
    planes = cell_planes(prepared.moments, whole.normal, used_axis, int(min_points), models_t,
                         cell_size=prepared.cell_size)
    tick(3, 5)
    index = prepared.index
    rows = None
    if lookup is None:
        pass_index, lookup = prepared.pass_index()
        if lookup is not None:  # coarsened: the rows are made on the way
            rows = np.empty(n_total, dtype=np.int64)
            index = replace(index, point_cell=rows)
    else:
        pass_index = index  # keys, made rows in place on the way
    sums = distance_sums(x, y, z, pass_index, planes.distance_vectors(), engine=engine,
                         lookup=lookup, rows=rows)
    tick(4, 5)
    result = assemble_roughness(
        index.grid, index.ijk, planes, sums, whole=whole, axis=used_axis,
        axis_requested=axis, min_points=int(min_points), residual=residual, models=models_t,
        point_cell=index.point_cell, n_points_total=n_total)
    tick(5, 5)
    return result


def assemble_roughness(
    grid: GridSpec,
    ijk: np.ndarray,
    planes: CellPlanes,
    sums: dict[str, tuple[np.ndarray, np.ndarray]],
    *,
    whole: PlaneFit,
    axis: Axis,
    axis_requested: AxisChoice,
    min_points: int,
    residual: Residual,
    models: tuple[Model, ...],
    point_cell: np.ndarray,
    n_points_total: int,
) -> GridRoughness:
    """The last stage of :func:`grid_roughness`: roughness of every cell from its planes
    and distance sums, packed as a :class:`GridRoughness`. Shared with the chunked and
    Dask paths of :mod:`rough_viewer.scale`, which reach the same sums another way.

    Parameters
    ----------
    grid, ijk
        The grid and the (M, 3) indices of the occupied cells.
    planes : CellPlanes
        From :func:`cell_planes`.
    sums : dict
        From :func:`~rough_viewer.grid.cells.distance_sums` with
        ``planes.distance_vectors()``.
    whole, axis, axis_requested, min_points, residual, models
        As in :class:`GridRoughness`.
    point_cell : (N,) or (0,) int64
        Row of every point's cell (empty out of core).
    n_points_total : int
        Number of points.
    """
    theta = cell_thetas(planes, sums, planes.counts, axis, models, signed=residual == "signed")
    centre = grid.centres(ijk)
    centroid = centre + planes.mean_local
    centroid[~planes.enough] = np.nan
    return GridRoughness(
        grid=grid,
        axis=axis,
        axis_requested=axis_requested,
        whole_plane=whole,
        min_points=int(min_points),
        residual=residual,
        models=models,
        ijk=ijk,
        centre=centre,
        n_points=planes.counts,
        centroid=centroid,
        normal=planes.normal,
        theta_odr=theta["odr"],
        theta_ols=theta["ols"],
        theta_hybrid=theta["hybrid"],
        e_ols=np.abs(theta["ols"] - theta["odr"]),
        point_cell=point_cell,
        n_points_total=int(n_points_total),
    )


def check_options(
    models: Iterable[Model], axis: AxisChoice, residual: Residual, min_points: int
) -> tuple[Model, ...]:
    """The models asked for, without repeats; InputError for any unusable option."""
    models_t = tuple(dict.fromkeys(models))
    for m in models_t:
        if m not in MODELS:
            raise InputError(f"unknown method {m!r}; expected odr, ols or hybrid")
    if axis not in ("auto", *AXES):
        raise InputError(f"unknown axis {axis!r}; expected auto, x, y or z")
    if residual not in ("absolute", "signed"):
        raise InputError(f"unknown residual {residual!r}; expected absolute or signed")
    if int(min_points) < 3:
        raise InputError(f"min points must be at least 3 (a plane needs 3), got {min_points}")
    return models_t


@dataclass(frozen=True)
class CellPlanes:
    """The reference planes of every cell, before any distance is taken."""

    counts: np.ndarray
    """(M,) int64 points per cell."""
    enough: np.ndarray
    """(M,) bool: the cell has at least ``min_points`` points."""
    mean_local: np.ndarray
    """(M, 3) centroid relative to the cell centre, metres."""
    normal: np.ndarray
    """(M, 3) ODR unit normal, oriented like the whole face's; NaN where none."""
    valid_odr: np.ndarray
    """(M,) bool: unique ODR plane and enough points."""
    w_ols: np.ndarray | None
    """(M, 3) OLS residual vector (None when OLS is not asked for)."""
    valid_ols: np.ndarray | None
    """(M,) bool: unique OLS plane and enough points."""
    valid_uv: np.ndarray | None
    """(M,) bool: the two independent coordinates are not degenerate (judged on the
    cell size); where they are, the points lie in a plane containing the dependent
    axis, so neither OLS nor hybrid has a value. None when neither is asked for."""
    need_odr: bool
    """ODR distances are needed (for odr or hybrid)."""

    def distance_vectors(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """name -> (per-cell vector, reference point): the inputs of
        :func:`~rough_viewer.grid.cells.distance_sums`."""
        vectors: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        if self.need_odr:
            vectors["odr"] = (np.where(self.valid_odr[:, None], self.normal, 0.0), self.mean_local)
        if self.w_ols is not None and self.valid_ols is not None:
            vectors["ols"] = (np.where(self.valid_ols[:, None], self.w_ols, 0.0), self.mean_local)
        return vectors


def cell_planes(
    moments: CellMoments,
    whole_normal: np.ndarray,
    axis: Axis,
    min_points: int,
    models: tuple[Model, ...],
    *,
    cell_size: float | None = None,
) -> CellPlanes:
    """Batched ODR and OLS planes of every cell from its moment sums.

    Parameters
    ----------
    moments : CellMoments
        Cell-local moment sums (from one pass, or added up over chunks).
    whole_normal : (3,) array
        The whole cloud's ODR normal: every cell normal is oriented like it.
    axis : {"x", "y", "z"}
        Dependent axis of OLS (and hybrid).
    min_points : int
        Cells with fewer points get no plane.
    models : tuple of str
        Models asked for (OLS planes only when ``"ols"`` is among them).
    cell_size : float, optional
        Grid cell edge, metres: degeneracy is judged against its square (docs/science.md:
        an absolute scale); default each cell's total variance.
    """
    mom = moments
    enough = mom.counts >= min_points
    cov = mom.covariance()
    scale2 = None if cell_size is None else cell_size**2  # the cell's absolute scale
    normal, _, valid_odr = odr_from_covariance(cov, scale2)
    valid_odr &= enough
    # Eigenvectors have arbitrary sign: orient every cell normal like the whole face's.
    normal *= np.where(normal @ whole_normal < 0, -1.0, 1.0)[:, None]
    normal[~valid_odr] = np.nan
    w_ols = valid_ols = valid_uv = None
    if "ols" in models or "hybrid" in models:
        w, valid_uv = ols_from_covariance(cov, axis, scale2)
        if "ols" in models:
            w_ols, valid_ols = w, valid_uv & enough
    return CellPlanes(counts=mom.counts, enough=enough, mean_local=mom.mean_local(), normal=normal,
                       valid_odr=valid_odr, w_ols=w_ols, valid_ols=valid_ols,
                       valid_uv=valid_uv, need_odr=any(m in models for m in ("odr", "hybrid")))


def cell_thetas(
    planes: CellPlanes,
    sums: dict[str, tuple[np.ndarray, np.ndarray]],
    counts: np.ndarray,
    axis: Axis,
    models: tuple[Model, ...],
    *,
    signed: bool,
) -> dict[str, np.ndarray]:
    """Roughness of every cell per model from the distance sums (NaN where none)."""
    m_cells = counts.shape[0]
    theta: dict[str, np.ndarray] = {name: np.full(m_cells, np.nan) for name in MODELS}
    n_f = counts.astype(np.float64)
    if planes.need_odr:
        t = _theta(*sums["odr"], n_f, signed=signed)
        t[~planes.valid_odr] = np.nan
        if "odr" in models:
            theta["odr"] = t
        if "hybrid" in models:
            # The hybrid distance is the ODR one divided by |n_a|, constant per cell;
            # none where the ODR plane contains the axis (n_a = 0 up to round-off, or
            # the independent coordinates degenerate on the cell's absolute scale).
            na = np.abs(planes.normal[:, axis_index(axis)])
            ok = planes.valid_odr & (na > HYBRID_MIN_COMPONENT)
            if planes.valid_uv is not None:
                ok &= planes.valid_uv
            theta["hybrid"][ok] = t[ok] / na[ok]
    if planes.valid_ols is not None:
        t = _theta(*sums["ols"], n_f, signed=signed)
        t[~planes.valid_ols] = np.nan
        theta["ols"] = t
    return theta


def _theta(abs_sum: np.ndarray, sq_sum: np.ndarray, n: np.ndarray, *, signed: bool) -> np.ndarray:
    """Std of absolute distances from their sums; RMS of signed ones when ``signed``."""
    mean_sq = sq_sum / n
    if signed:
        return np.sqrt(mean_sq)
    mean_abs = abs_sum / n
    return np.sqrt(np.clip(mean_sq - mean_abs * mean_abs, 0.0, None))
