"""Reading and writing points: readers by format, the decode cache, LAS writing, safe
output files and the one JSON conversion.

The science of this package knows nothing of the terminal: progress is a callback
and every problem with a file is an :class:`rough_viewer.vocabulary.InputError`
that names it.
"""

from rough_viewer.io.cache import cache_dir
from rough_viewer.io.cloud import PointCloud
from rough_viewer.io.crs import CrsInfo, read_crs
from rough_viewer.io.las import load_las_with_extra, read_las_extra, write_las
from rough_viewer.io.load import SUPPORTED_SUFFIXES, TEXT_SUFFIXES, load_points, resolve_units

__all__ = [
    "SUPPORTED_SUFFIXES",
    "TEXT_SUFFIXES",
    "CrsInfo",
    "PointCloud",
    "cache_dir",
    "load_las_with_extra",
    "load_points",
    "read_crs",
    "read_las_extra",
    "resolve_units",
    "write_las",
]
