"""Reading and writing points: readers by format, the decode cache, LAS/LAZ and PLY
writing with per-point fields, cell tables (CSV, Parquet), safe output files, the
crop and the one JSON conversion.

The science of this package knows nothing of the terminal: progress is a callback
and every problem with a file is an :class:`rough_viewer.vocabulary.InputError`
that names it.
"""

from rough_viewer.io.cache import cache_dir
from rough_viewer.io.cloud import PointCloud
from rough_viewer.io.crop import CropBox, crop_cloud, crop_mask
from rough_viewer.io.crs import CrsInfo, read_crs
from rough_viewer.io.las import load_las_with_extra, read_las_extra, write_las
from rough_viewer.io.las_out import write_las_fields
from rough_viewer.io.load import SUPPORTED_SUFFIXES, TEXT_SUFFIXES, load_points, resolve_units
from rough_viewer.io.ply import write_ply_fields
from rough_viewer.io.point_fields import CellField, PointFields
from rough_viewer.io.table import write_table

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
