"""Reading and writing points: the point cloud (:mod:`.cloud`), loading any file
(:mod:`.load`), the formats (:mod:`.formats`: LAS/LAZ, E57, PLY, STL, text, DEM,
meshes, the CRS, LAS and PLY writing with per-point fields), the reader sandbox
(:mod:`.sandbox`), the decode cache (:mod:`.cache`), cell tables (CSV, Parquet), safe
output files, the crop and the one JSON conversion.

The science of this package knows nothing of the terminal: progress is a callback
and every problem with a file is an :class:`rough_viewer.vocabulary.InputError`
that names it.

Names are loaded on first use, so reading one format imports no other's library.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rough_viewer.lazy import lazy_names

#: Public name -> module that defines it (loaded on first use, PEP 562).
_API: dict[str, str] = {
    "cache_dir": "rough_viewer.io.cache",
    "PointCloud": "rough_viewer.io.cloud",
    "CropBox": "rough_viewer.io.crop",
    "crop_cloud": "rough_viewer.io.crop",
    "crop_mask": "rough_viewer.io.crop",
    "CrsInfo": "rough_viewer.io.formats.crs",
    "read_crs": "rough_viewer.io.formats.crs",
    "load_las_with_extra": "rough_viewer.io.formats.las",
    "read_las_extra": "rough_viewer.io.formats.las",
    "write_las": "rough_viewer.io.formats.las",
    "write_las_fields": "rough_viewer.io.formats.las_out",
    "SUPPORTED_SUFFIXES": "rough_viewer.io.load",
    "TEXT_SUFFIXES": "rough_viewer.io.load",
    "load_points": "rough_viewer.io.load",
    "resolve_units": "rough_viewer.io.load",
    "write_ply_fields": "rough_viewer.io.formats.ply",
    "CellField": "rough_viewer.io.formats.point_fields",
    "PointFields": "rough_viewer.io.formats.point_fields",
    "write_table": "rough_viewer.io.table",
}

__all__ = [
    "SUPPORTED_SUFFIXES",
    "TEXT_SUFFIXES",
    "CellField",
    "CropBox",
    "CrsInfo",
    "PointCloud",
    "PointFields",
    "cache_dir",
    "crop_cloud",
    "crop_mask",
    "load_las_with_extra",
    "load_points",
    "read_crs",
    "read_las_extra",
    "resolve_units",
    "write_las",
    "write_las_fields",
    "write_ply_fields",
    "write_table",
]


__getattr__, __dir__ = lazy_names(__name__, _API)


if TYPE_CHECKING:  # names for type checkers and IDEs; loaded lazily at run time
    from rough_viewer.io.cache import cache_dir
    from rough_viewer.io.cloud import PointCloud
    from rough_viewer.io.crop import CropBox, crop_cloud, crop_mask
    from rough_viewer.io.formats.crs import CrsInfo, read_crs
    from rough_viewer.io.formats.las import load_las_with_extra, read_las_extra, write_las
    from rough_viewer.io.formats.las_out import write_las_fields
    from rough_viewer.io.formats.ply import write_ply_fields
    from rough_viewer.io.formats.point_fields import CellField, PointFields
    from rough_viewer.io.load import SUPPORTED_SUFFIXES, TEXT_SUFFIXES, load_points, resolve_units
    from rough_viewer.io.table import write_table
