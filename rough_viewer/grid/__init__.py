"""Grid roughness (SCIENCE.md section 1): the one grid, plane fits, per-cell ODR, OLS
and hybrid roughness, Table-1 statistics, face-plane maps and semivariograms.

Data flow: points -> :mod:`.cells` (cell of every point, moment sums) ->
:mod:`.planes` (batched fits) -> :mod:`.roughness` (per-cell maps) ->
:mod:`.summary`, :mod:`.maps`, :mod:`.variogram`, :mod:`.zones` (connected rough
cells; :mod:`.orientation` for dips, traces and the stereonet); :mod:`.spacing`
chooses the default grid from the point spacing.
"""

from rough_viewer.grid.cells import GridSpec, make_grid
from rough_viewer.grid.maps import FaceMaps, FacePlane, face_frame, face_maps, face_raster
from rough_viewer.grid.planes import PlaneFit, dominant_axis, fit_plane
from rough_viewer.grid.roughness import (
    GridRoughness,
    PreparedGrid,
    coarsen_prepared,
    grid_roughness,
    prepare_grid,
    whole_cloud_axis,
)
from rough_viewer.grid.spacing import default_cell_size, point_spacing, preset_cell_sizes
from rough_viewer.grid.summary import (
    Histogram,
    Summary,
    binary,
    histogram,
    normalise,
    summaries,
    summarise,
)
from rough_viewer.grid.variogram import (
    Semivariogram,
    VariogramPlan,
    face_semivariogram,
    plan_semivariogram,
    semivariogram,
)
from rough_viewer.grid.zones import ZoneLabeller, Zones, find_zones

__all__ = [
    "FaceMaps",
    "FacePlane",
    "GridRoughness",
    "GridSpec",
    "Histogram",
    "PlaneFit",
    "PreparedGrid",
    "Semivariogram",
    "Summary",
    "VariogramPlan",
    "ZoneLabeller",
    "Zones",
    "binary",
    "coarsen_prepared",
    "default_cell_size",
    "dominant_axis",
    "face_frame",
    "face_maps",
    "face_raster",
    "face_semivariogram",
    "find_zones",
    "fit_plane",
    "grid_roughness",
    "histogram",
    "make_grid",
    "normalise",
    "plan_semivariogram",
    "point_spacing",
    "prepare_grid",
    "preset_cell_sizes",
    "semivariogram",
    "summaries",
    "summarise",
    "whole_cloud_axis",
]
