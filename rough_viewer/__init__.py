"""rough_viewer: surface roughness of scanned rock faces.

The public API is flat: everything a notebook needs is importable from here.

>>> import numpy as np
>>> import rough_viewer as rv
>>> rng = np.random.default_rng(0)
>>> xy = rng.uniform(0.0, 2.0, (20_000, 2))
>>> z = 0.002 * rng.standard_normal(20_000)          # a flat face with 2 mm noise
>>> res = rv.grid_roughness(np.column_stack([xy, z]), 0.5)
>>> res.n_cells, res.axis
(16, 'z')
>>> round(float(np.nanmean(res.theta_odr)) * 1e3, 1)   # std of |2 mm noise|, in mm
1.2

Packages, data flowing one way (each imports only those above it):

- :mod:`rough_viewer.vocabulary`: models, maps, axes, labels, the one error type;
- :mod:`rough_viewer.io`: the point cloud, reading and writing points (formats in
  :mod:`rough_viewer.io.formats`, the reader sandbox in :mod:`rough_viewer.io.sandbox`),
  the decode cache;
- :mod:`rough_viewer.grid`: grid roughness, maps, semivariograms, measurements;
- :mod:`rough_viewer.lod`: the level-of-detail octree and node selection;
- :mod:`rough_viewer.profiles`: profiles, wavelets, fractal dimension;
- :mod:`rough_viewer.tin`: directional roughness of triangulated surfaces;
- :mod:`rough_viewer.bias`: scanner-bias measurement and simulation;
- :mod:`rough_viewer.scanner`: scanner positions, scan geometry and per-cell trust;
- :mod:`rough_viewer.directions`: roughness by direction (profiles and TIN);
- :mod:`rough_viewer.structure`: orientation zones, joints and joint sets;
- :mod:`rough_viewer.synthetic`: the demo board and outcrop, fBm profiles;
- :mod:`rough_viewer.visual`: colour maps and plotly figures;
- :mod:`rough_viewer.report`: the HTML/JSON report and saved views;
- :mod:`rough_viewer.app`, :mod:`rough_viewer.cli` on top.

Names are loaded on first use, so ``import rough_viewer`` stays cheap.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rough_viewer._version import __version__
from rough_viewer.lazy import lazy_names

#: Public name -> module that defines it.
_API: dict[str, str] = {
    # vocabulary
    "InputError": "rough_viewer.vocabulary",
    "MODELS": "rough_viewer.vocabulary",
    "MAPS": "rough_viewer.vocabulary",
    "AXES": "rough_viewer.vocabulary",
    # points
    "PointCloud": "rough_viewer.io.cloud",
    "load_points": "rough_viewer.io.load",
    "write_las": "rough_viewer.io.formats.las",
    "read_crs": "rough_viewer.io.formats.crs",
    "CrsInfo": "rough_viewer.io.formats.crs",
    "write_las_fields": "rough_viewer.io.formats.las_out",
    "write_ply_fields": "rough_viewer.io.formats.ply",
    "write_table": "rough_viewer.io.table",
    "CropBox": "rough_viewer.io.crop",
    "crop_cloud": "rough_viewer.io.crop",
    # grid roughness
    "grid_roughness": "rough_viewer.grid.roughness",
    "prepare_grid": "rough_viewer.grid.roughness",
    # many files, out of core, Dask
    "open_sources": "rough_viewer.scale.sources",
    "load_merged": "rough_viewer.scale.sources",
    "chunked_roughness": "rough_viewer.scale.chunked",
    "coarsen_prepared": "rough_viewer.grid.roughness",
    "whole_cloud_axis": "rough_viewer.grid.roughness",
    "GridRoughness": "rough_viewer.grid.roughness",
    "fit_plane": "rough_viewer.grid.planes",
    "whole_cloud_plane": "rough_viewer.grid.planes",
    "signed_distance": "rough_viewer.grid.planes",
    "point_scales": "rough_viewer.grid.scales",
    "point_scales_from_prepared": "rough_viewer.grid.scales",
    "face_scales": "rough_viewer.grid.scales",
    "cell_columns": "rough_viewer.grid.table",
    "point_fields": "rough_viewer.grid.table",
    "summarise": "rough_viewer.grid.summary",
    "summaries": "rough_viewer.grid.summary",
    "normalise": "rough_viewer.grid.summary",
    "binary": "rough_viewer.grid.summary",
    "histogram": "rough_viewer.grid.summary",
    "Summary": "rough_viewer.grid.summary",
    "semivariogram": "rough_viewer.grid.variogram",
    "plan_semivariogram": "rough_viewer.grid.variogram",
    "point_spacing": "rough_viewer.grid.spacing",
    "default_cell_size": "rough_viewer.grid.spacing",
    "preset_cell_sizes": "rough_viewer.grid.spacing",
    "face_semivariogram": "rough_viewer.grid.variogram",
    "face_maps": "rough_viewer.grid.maps",
    "face_raster": "rough_viewer.grid.maps",
    "ZoneLabeller": "rough_viewer.structure.zones",
    "Zones": "rough_viewer.structure.zones",
    "find_zones": "rough_viewer.structure.zones",
    "joint_sets": "rough_viewer.structure.sets",
    "JointSets": "rough_viewer.structure.sets",
    "SetOptions": "rough_viewer.structure.sets",
    "dip_and_direction": "rough_viewer.grid.orientation",
    "trend_and_plunge": "rough_viewer.grid.orientation",
    "stereonet": "rough_viewer.grid.orientation",
    "cell_stereonet": "rough_viewer.grid.orientation",
    "cell_orientation": "rough_viewer.grid.orientation",
    "point_distance": "rough_viewer.grid.measure",
    "region_plane": "rough_viewer.grid.measure",
    # level of detail
    "build_octree": "rough_viewer.lod.octree",
    "select_nodes": "rough_viewer.lod.select",
    "ViewCamera": "rough_viewer.lod.camera",
    # profiles
    "extract_profile": "rough_viewer.profiles.extraction",
    "regular_samples": "rough_viewer.profiles.extraction",
    "noise_sigma": "rough_viewer.profiles.wavelets",
    "denoise": "rough_viewer.profiles.wavelets",
    "denoise_result": "rough_viewer.profiles.wavelets",
    "threshold_value": "rough_viewer.profiles.wavelets",
    "roughness_length": "rough_viewer.profiles.fractal",
    "roughness_length_2d": "rough_viewer.profiles.fractal",
    "detrend": "rough_viewer.profiles.fractal",
    "compare_denoising": "rough_viewer.profiles.comparison",
    # scanner bias
    "range_noise": "rough_viewer.bias.measurement",
    "effective_radius": "rough_viewer.bias.measurement",
    "normalise_population": "rough_viewer.bias.measurement",
    "target_roughness": "rough_viewer.bias.measurement",
    "predict_bias": "rough_viewer.bias.simulation",
    "simulate_target": "rough_viewer.bias.simulation",
    "smoothing_curve": "rough_viewer.bias.simulation",
    # scanner-aware roughness (docs/scanner.md)
    "with_scanner": "rough_viewer.scanner.positions",
    "scan_geometry": "rough_viewer.scanner.geometry",
    "cell_trust": "rough_viewer.scanner.trust",
    "TrustSettings": "rough_viewer.scanner.trust",
    # synthetic data and demos
    "board_scan": "rough_viewer.synthetic.board",
    "generate_outcrop": "rough_viewer.synthetic.outcrop",
    "fbm_profile": "rough_viewer.synthetic.fbm",
    "list_demos": "rough_viewer.synthetic.demos",
    "load_demo": "rough_viewer.synthetic.demos",
    # results out
    "write_figure": "rough_viewer.visual.export",
    "ReportSettings": "rough_viewer.report.export",
    "report_page": "rough_viewer.report.export",
    "View": "rough_viewer.report.view",
    "save_view": "rough_viewer.report.view",
    "load_view": "rough_viewer.report.view",
}

__all__ = ["__version__", *sorted(_API)]


__getattr__, __dir__ = lazy_names(__name__, _API)


if TYPE_CHECKING:  # names for type checkers and IDEs; loaded lazily at run time
    from rough_viewer.bias.measurement import (
        effective_radius,
        normalise_population,
        range_noise,
        target_roughness,
    )
    from rough_viewer.bias.simulation import predict_bias, simulate_target, smoothing_curve
    from rough_viewer.grid.maps import face_maps, face_raster
    from rough_viewer.grid.measure import point_distance, region_plane
    from rough_viewer.grid.orientation import (
        cell_orientation,
        cell_stereonet,
        dip_and_direction,
        stereonet,
        trend_and_plunge,
    )
    from rough_viewer.grid.planes import fit_plane, signed_distance, whole_cloud_plane
    from rough_viewer.grid.roughness import (
        GridRoughness,
        coarsen_prepared,
        grid_roughness,
        prepare_grid,
        whole_cloud_axis,
    )
    from rough_viewer.grid.scales import face_scales, point_scales, point_scales_from_prepared
    from rough_viewer.grid.spacing import default_cell_size, point_spacing, preset_cell_sizes
    from rough_viewer.grid.summary import (
        Summary,
        binary,
        histogram,
        normalise,
        summaries,
        summarise,
    )
    from rough_viewer.grid.table import cell_columns, point_fields
    from rough_viewer.grid.variogram import face_semivariogram, plan_semivariogram, semivariogram
    from rough_viewer.io.cloud import PointCloud
    from rough_viewer.io.crop import CropBox, crop_cloud
    from rough_viewer.io.formats.crs import CrsInfo, read_crs
    from rough_viewer.io.formats.las import write_las
    from rough_viewer.io.formats.las_out import write_las_fields
    from rough_viewer.io.formats.ply import write_ply_fields
    from rough_viewer.io.load import load_points
    from rough_viewer.io.table import write_table
    from rough_viewer.lod.camera import ViewCamera
    from rough_viewer.lod.octree import build_octree
    from rough_viewer.lod.select import select_nodes
    from rough_viewer.profiles.comparison import compare_denoising
    from rough_viewer.profiles.extraction import extract_profile, regular_samples
    from rough_viewer.profiles.fractal import detrend, roughness_length, roughness_length_2d
    from rough_viewer.profiles.wavelets import (
        denoise,
        denoise_result,
        noise_sigma,
        threshold_value,
    )
    from rough_viewer.report.export import ReportSettings, report_page
    from rough_viewer.report.view import View, load_view, save_view
    from rough_viewer.scale.chunked import chunked_roughness
    from rough_viewer.scale.sources import load_merged, open_sources
    from rough_viewer.scanner.geometry import scan_geometry
    from rough_viewer.scanner.positions import with_scanner
    from rough_viewer.scanner.trust import TrustSettings, cell_trust
    from rough_viewer.structure.sets import JointSets, SetOptions, joint_sets
    from rough_viewer.structure.zones import ZoneLabeller, Zones, find_zones
    from rough_viewer.synthetic.board import board_scan
    from rough_viewer.synthetic.demos import list_demos, load_demo
    from rough_viewer.synthetic.fbm import fbm_profile
    from rough_viewer.synthetic.outcrop import generate_outcrop
    from rough_viewer.visual.export import write_figure
    from rough_viewer.vocabulary import AXES, MAPS, MODELS, InputError
