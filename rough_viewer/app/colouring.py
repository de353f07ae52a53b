"""The colours a grid result gives the points, and the numbers shown beside them
(:class:`MapStats`, the cell report :class:`CellInfo`)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rough_viewer.app.settings import MODEL_LABELS, MapSettings
from rough_viewer.grid.orientation import dip_and_direction
from rough_viewer.grid.outliers import analysed_values, outlier_mask
from rough_viewer.grid.roughness import (
    EXACT_FIT,
    GridRoughness,
)
from rough_viewer.grid.summary import normalise
from rough_viewer.grid.threshold import ThresholdAdvice, threshold_advice
from rough_viewer.report.build import SPARSE_SHARE
from rough_viewer.visual import colormaps


def map_values(result: GridRoughness, settings: MapSettings) -> np.ndarray:
    """(M,) the shown map's roughness as the colours, panels and zones use it, metres:
    NaN without a value and, unless ``settings.keep_outliers``, for outlier cells
    (:func:`rough_viewer.grid.outliers.analysed_values`)."""
    return analysed_values(result, settings.model, keep_outliers=settings.keep_outliers)


def normalised_map(result: GridRoughness, settings: MapSettings) -> np.ndarray:
    """Min-max normalised roughness of every cell of the shown map (NaN: no value, or
    an outlier left out)."""
    return normalise(map_values(result, settings))


def colour_range(result: GridRoughness, settings: MapSettings) -> colormaps.ColourRange:
    """The stretch of ``settings`` resolved on the cells of the shown map (one vote
    per cell with a value, as Table 1 counts; outliers left out unless kept), metres."""
    return colormaps.resolve(map_values(result, settings), settings.stretch)


def shown_outliers(result: GridRoughness, settings: MapSettings) -> np.ndarray | None:
    """(M,) bool: the cells drawn in the outlier colour (None: none, or kept)."""
    if settings.keep_outliers:
        return None
    mask = outlier_mask(result, settings.model)
    return mask if mask.any() else None


Colouring = Callable[[np.ndarray], np.ndarray]
"""What colours the points: ``colouring(idx)`` gives the (K, 3) uint8 colours of cloud
points ``idx`` (indices into the loaded cloud), for any subset (the nodes a browser
tab shows). A :class:`CellColouring` (every colouring by cell) also colours points
that are not rows of the cloud, by position (:meth:`CellColouring.at`)."""

#: The colour of a point whose cell the map lacks (by position: a point of no cell).
NO_CELL_RGB = (190, 190, 190)


@dataclass(eq=False)
class CellColouring:
    """The colouring that gives each point its cell's colour: rows of the cloud by
    ``point_cell``, any point by position (its cell on the result's grid looked up
    among the result's cells: :func:`rough_viewer.grid.cells.cell_rows`)."""

    cell_rgb: np.ndarray
    """(M, 3) uint8 colour of every cell of the result."""
    point_cell: np.ndarray
    """(N,) the result's cell of every point of the cloud."""
    result: GridRoughness | None = None
    """The result whose cells ``cell_rgb`` colours (None: no colours by position)."""
    _keys: np.ndarray | None = None
    _order: np.ndarray | None = None

    def __call__(self, idx: np.ndarray) -> np.ndarray:
        return self.cell_rgb[self.point_cell[idx]]

    def rows_at(self, x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray | None:
        """(K,) the result's cell row of points at x, y, z (metres, the cloud's frame;
        -1: no cell of the map), or None without a result."""
        from rough_viewer.grid.cells import cell_keys_of, cell_rows

        res = self.result
        if res is None:
            return None
        if self._keys is None:
            keys = cell_keys_of(res.ijk, res.grid)
            if keys.size > 1 and not bool(np.all(keys[1:] > keys[:-1])):
                self._order = np.argsort(keys, kind="stable")  # (results are in key order)
                keys = keys[self._order]
            self._keys = keys
        rows = cell_rows(x, y, z, res.grid, self._keys)
        if self._order is not None:
            rows = np.where(rows >= 0, self._order[np.maximum(rows, 0)], -1)
        return rows

    def at(self, x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray | None:
        """(K, 3) uint8 colours of points at x, y, z (metres): their cells' colours,
        :data:`NO_CELL_RGB` where the map has no cell; None without a result."""
        rows = self.rows_at(x, y, z)
        if rows is None:
            return None
        out = np.empty((rows.shape[0], 3), dtype=np.uint8)
        out[:] = NO_CELL_RGB
        hit = rows >= 0
        out[hit] = self.cell_rgb[rows[hit]]
        return out


def by_cell(cell_rgb: np.ndarray, cells: GridRoughness | np.ndarray) -> CellColouring:
    """The colouring that gives each point its cell's colour ((M, 3) ``cell_rgb``):
    ``cells`` is the result whose cells these are (its ``point_cell`` for the
    cloud's rows, its grid for points by position), or a bare point-to-cell map."""
    if isinstance(cells, GridRoughness):
        return CellColouring(cell_rgb, cells.point_cell, cells)
    return CellColouring(cell_rgb, cells)


def cell_colours(
    result: GridRoughness,
    settings: MapSettings,
    *,
    colours_range: colormaps.ColourRange | None = None,
) -> np.ndarray:
    """(M, 3) uint8 colour of every cell of the shown map (see :func:`point_colours`)."""
    out = shown_outliers(result, settings)
    if settings.display == "binary":
        norm = normalised_map(result, settings)
        with np.errstate(invalid="ignore"):
            flags = norm >= settings.threshold
        return colormaps.apply_binary(flags, np.isfinite(norm), settings.colormap, outliers=out)
    rng = colours_range if colours_range is not None else colour_range(result, settings)
    return colormaps.stretch_colours(map_values(result, settings), rng, settings.colormap,
                                     outliers=out)


def point_colours(
    result: GridRoughness,
    settings: MapSettings,
    point_index: np.ndarray,
    *,
    colours_range: colormaps.ColourRange | None = None,
) -> np.ndarray:
    """RGB colour (``(K, 3)`` uint8) of the points ``point_index`` of the cloud.

    Continuous display: each point takes the colour of its cell's roughness under
    the settings' stretch (:func:`colour_range`; robust log percentiles by default,
    or absolute limits) on ``settings.colormap``. Binary display: the 2011 paper's
    transform, min-max normalised roughness ``>= threshold`` in the map's last
    colour, the rest in its first. Points in cells without a value get
    :data:`colormaps.NEUTRAL_RGB`, points in outlier cells (left out)
    :data:`colormaps.OUTLIER_RGB`. ``colours_range`` may pass a precomputed
    :func:`colour_range`.
    """
    return cell_colours(result, settings, colours_range=colours_range)[
        result.point_cell[point_index]]


@dataclass(frozen=True)
class MapStats:
    """Numbers the colour bar and status line show for the current map."""

    theta_min: float
    """Smallest roughness of a valid cell (metres)."""
    theta_max: float
    """Largest roughness of a valid cell (metres)."""
    cells: int
    """Occupied cells."""
    valid_cells: int
    """Cells with a value for this model."""
    rough_share: float
    """Share of valid cells at or above the binary threshold."""
    colour_range: colormaps.ColourRange
    """The stretch resolved on this map (what the colours' ends mean)."""
    exact_fit: int = 0
    """Cells with a value of 0 to round-off (points exactly on a plane, e.g. repeated
    points; :data:`rough_viewer.grid.roughness.EXACT_FIT`)."""
    outliers: int = 0
    """Cells whose roughness is larger than the cell (left out unless kept)."""
    advice: ThresholdAdvice | None = None
    """What the binary threshold flags, and the data's own threshold."""

    @property
    def sparse(self) -> bool:
        """Most occupied cells have no value (fewer than ``SPARSE_SHARE`` of them):
        the grid is too fine for the point density."""
        return self.cells > 0 and self.valid_cells < SPARSE_SHARE * self.cells


def map_stats(result: GridRoughness, settings: MapSettings) -> MapStats:
    """Range and counts of the current map (see :class:`MapStats`); outliers left out
    unless kept."""
    values = map_values(result, settings)
    finite = np.isfinite(values)
    norm = normalise(values)
    valid = int(finite.sum())
    if valid:
        lo, hi = float(values[finite].min()), float(values[finite].max())
        rough = float(np.mean(norm[finite] >= settings.threshold))
    else:
        lo = hi = rough = float("nan")
    return MapStats(lo, hi, len(values), valid, rough,
                    colormaps.resolve(values, settings.stretch),
                    exact_fit=result.cell_report(settings.model)["exact_fit"],
                    outliers=int(outlier_mask(result, settings.model).sum()),
                    advice=threshold_advice(values, settings.threshold,
                                            exact_fit=EXACT_FIT * result.grid.cell_size))


@dataclass(frozen=True)
class CellInfo:
    """What a click on a point reports about its cell (file frame, metres)."""

    cell: int
    """Index into the result's cell arrays."""
    ijk: tuple[int, int, int]
    """Grid index of the cell."""
    centre: tuple[float, float, float]
    n_points: int
    theta: dict[str, float]
    """Roughness per model (``odr``, ``ols``, ``hybrid``, ``e_ols``), metres, NaN if none."""
    normal: tuple[float, float, float]
    """ODR unit normal of the cell (NaN if no plane)."""
    point: tuple[float, float, float]
    """The clicked point, file frame."""
    axis: str
    """Dependent axis used for OLS/hybrid."""
    dip_deg: float = math.nan
    """Dip of the cell's ODR plane, degrees [0, 90] (docs/zones.md; NaN if none)."""
    dip_direction_deg: float = math.nan
    """Azimuth of its down-dip direction, degrees clockwise from +y, [0, 360); a
    vertical plane takes the side of the whole-cloud normal."""


def cell_info(result: GridRoughness, point: int, point_xyz: np.ndarray) -> CellInfo:
    """Describe the cell holding cloud point number ``point`` (see :class:`CellInfo`)."""
    c = int(result.point_cell[point])

    def three(a: np.ndarray) -> tuple[float, float, float]:
        return float(a[0]), float(a[1]), float(a[2])

    i, j, k = (int(v) for v in result.ijk[c])
    dip, dd = dip_and_direction(result.normal[c:c + 1], result.whole_plane.normal)
    return CellInfo(
        cell=c,
        ijk=(i, j, k),
        centre=three(result.centre[c]),
        n_points=int(result.n_points[c]),
        theta={m: float(result.values(m)[c]) for m in MODEL_LABELS},
        normal=three(result.normal[c]),
        point=three(np.asarray(point_xyz, dtype=np.float64)),
        axis=result.axis,
        dip_deg=float(dip[0]),
        dip_direction_deg=float(dd[0]),
    )
