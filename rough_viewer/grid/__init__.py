"""Grid roughness (docs/science.md section 1): the one grid, plane fits, per-cell ODR, OLS
and hybrid roughness, Table-1 statistics, face-plane maps and semivariograms.

Data flow: points -> :mod:`.cells` (cell of every point, moment sums) ->
:mod:`.planes` (batched fits) -> :mod:`.roughness` (per-cell maps) ->
:mod:`.summary`, :mod:`.maps`, :mod:`.variogram` (:mod:`.orientation` for dips,
traces and the stereonet); :mod:`.spacing` chooses the default grid from the point
spacing. Fracture zones, joint sets and joints are built on the grid in
:mod:`rough_viewer.structure`.

Names are loaded on first use, so importing one module of the package (the
compute path needs :mod:`.roughness`) does not import the others (:mod:`.spacing`
imports SciPy).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rough_viewer.lazy import lazy_names

#: Public name -> module that defines it (loaded on first use, PEP 562).
_API: dict[str, str] = {
    "GridSpec": "rough_viewer.grid.cells",
    "make_grid": "rough_viewer.grid.cells",
    "FaceMaps": "rough_viewer.grid.maps",
    "FacePlane": "rough_viewer.grid.maps",
    "face_frame": "rough_viewer.grid.maps",
    "face_maps": "rough_viewer.grid.maps",
    "face_raster": "rough_viewer.grid.maps",
    "PlaneFit": "rough_viewer.grid.planes",
    "dominant_axis": "rough_viewer.grid.planes",
    "fit_plane": "rough_viewer.grid.planes",
    "GridRoughness": "rough_viewer.grid.roughness",
    "PreparedGrid": "rough_viewer.grid.roughness",
    "coarsen_prepared": "rough_viewer.grid.roughness",
    "grid_roughness": "rough_viewer.grid.roughness",
    "prepare_grid": "rough_viewer.grid.roughness",
    "whole_cloud_axis": "rough_viewer.grid.roughness",
    "default_cell_size": "rough_viewer.grid.spacing",
    "point_spacing": "rough_viewer.grid.spacing",
    "preset_cell_sizes": "rough_viewer.grid.spacing",
    "Histogram": "rough_viewer.grid.summary",
    "Summary": "rough_viewer.grid.summary",
    "binary": "rough_viewer.grid.summary",
    "histogram": "rough_viewer.grid.summary",
    "normalise": "rough_viewer.grid.summary",
    "summaries": "rough_viewer.grid.summary",
    "summarise": "rough_viewer.grid.summary",
    "Semivariogram": "rough_viewer.grid.variogram",
    "VariogramPlan": "rough_viewer.grid.variogram",
    "face_semivariogram": "rough_viewer.grid.variogram",
    "plan_semivariogram": "rough_viewer.grid.variogram",
    "semivariogram": "rough_viewer.grid.variogram",
}

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
    "binary",
    "coarsen_prepared",
    "default_cell_size",
    "dominant_axis",
    "face_frame",
    "face_maps",
    "face_raster",
    "face_semivariogram",
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


__getattr__, __dir__ = lazy_names(__name__, _API)


if TYPE_CHECKING:  # names for type checkers and IDEs; loaded lazily at run time
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
