"""Reading point clouds from files, and writing LAS/LAZ.

Supported inputs (by file extension):

- ``.las``, ``.laz``: laspy, read in chunks; LAZ decoded with the parallel lazrs
  backend and its decoded coordinates cached (see :func:`cache_dir`), so a second
  open is near-instant. Intensity is kept.
- ``.xyz``, ``.txt``, ``.csv``, ``.pts``: whitespace- or comma-separated ``x y z``,
  extra columns ignored, an optional header line.
- ``.npy``: an (N, 3) (or wider: the first three columns) numeric array.
- ``.ply``: ASCII or binary (either endianness) vertex ``x``, ``y``, ``z``.
- ``.stl``: ASCII or binary; the mesh's vertices, each once.
- ``.e57``: every scan, transformed by its pose into the file's frame and merged
  (pye57); intensity, colour, scan index and scanner positions kept.
- ``.asc`` (ESRI ASCII grid), ``.tif``/``.tiff`` (GeoTIFF, needs the optional
  package tifffile): elevation rasters, one point per cell with a value at the
  cell's centre (:mod:`rough_viewer.io.dem`).

Units: the cloud is always in metres. A file's coordinates are taken to be in
``units`` when given, else in the linear unit of its CRS (LAS/LAZ, GeoTIFF, an ESRI
grid's ``.prj``; E57 is metres), else metres, and scaled to metres on reading
(``PointCloud.source_unit`` says which unit the file was in). Given units that
contradict the CRS are used as asked, with a warning on the cloud naming the file.
A CRS whose vertical unit differs from its horizontal one (z in US feet, x and y in
metres) has z converted by its own unit, as a reprojection to a metre CRS would do:
z is never taken to be in the horizontal unit (:func:`axis_units`).

Rows with NaN or infinite coordinates are dropped and counted
(:attr:`PointCloud.dropped_nonfinite`). Every problem raises
:class:`rough_viewer.vocabulary.InputError` with the file's name.
"""

from __future__ import annotations

import os
from pathlib import Path

from rough_viewer.io.cloud import PointCloud, check_input_file, read_errors
from rough_viewer.io.crs import read_crs
from rough_viewer.io.dem import DEM_SUFFIXES, read_dem
from rough_viewer.io.e57 import read_e57
from rough_viewer.io.las import read_las
from rough_viewer.io.ply import read_ply
from rough_viewer.io.stl import read_stl
from rough_viewer.io.text import read_npy, read_text
from rough_viewer.vocabulary import (
    UNIT_LABELS,
    UNIT_METRES,
    InputError,
    ProgressFn,
    Unit,
)

TEXT_SUFFIXES = (".xyz", ".txt", ".csv", ".pts")
SUPPORTED_SUFFIXES = (".las", ".laz", ".e57", *TEXT_SUFFIXES, ".npy", ".ply", ".stl",
                      *DEM_SUFFIXES)


def load_points(
    path: str | os.PathLike[str],
    *,
    progress: ProgressFn | None = None,
    cache: bool = True,
    units: Unit | None = None,
) -> PointCloud:
    """Read a point cloud file into metres.

    Parameters
    ----------
    path : path-like
        A ``.las .laz .e57 .xyz .txt .csv .pts .npy .ply .stl .asc .tif .tiff`` file.
    progress : callable, optional
        ``progress(done, total)`` in points, for LAS/LAZ and E57 files.
    cache : bool
        Use (and fill) the decoded-coordinate cache for LAZ files.
    units : {"m", "mm", "ft", "us-ft"}, optional
        Unit of the file's coordinates; default: its CRS's linear unit where it
        declares one (LAS/LAZ), else metres.

    Returns
    -------
    PointCloud
        Coordinates in metres; ``source_unit`` the unit the file was read in;
        ``warnings`` what the user should know (header counts, units vs CRS).

    Raises
    ------
    InputError
        Missing or unreadable file, unknown extension, malformed content, fewer than
        3 finite points.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (folder / "face.xyz").write_text("x y z\\n0 0 0\\n1 0 0\\n0 1 0.01\\n1 1 nan\\n")
    >>> cloud = load_points(folder / "face.xyz")
    >>> cloud.n, cloud.dropped_nonfinite
    (3, 1)
    """
    p = Path(path)
    suffix = p.suffix.lower()
    if p.is_dir():  # before the suffix: "." or "scans" is a folder, not an unknown type
        check_input_file(p)
    if suffix not in SUPPORTED_SUFFIXES:
        raise InputError(
            f"unknown file type {p.suffix or '(none)'!r} for {p}; "
            f"supported: {' '.join(SUPPORTED_SUFFIXES)}"
        )
    check_input_file(p)
    if not os.access(p, os.R_OK):
        raise InputError(f"cannot read {p}: permission denied")
    if units is not None and units not in UNIT_METRES:
        raise InputError(f"unknown unit {units!r}; choose one of {', '.join(UNIT_METRES)}")
    with read_errors(p):
        cloud = _read(p, suffix, progress=progress, cache=cache)
        unit, z_unit, notes = axis_units(p, units)
    return cloud.scaled(UNIT_METRES[unit], unit,
                        z_metres_per_unit=UNIT_METRES[z_unit]).with_warnings(*notes)


def _read(p: Path, suffix: str, *, progress: ProgressFn | None, cache: bool) -> PointCloud:
    if suffix in (".las", ".laz"):
        return read_las(p, progress=progress, cache=cache and suffix == ".laz")
    if suffix == ".e57":
        return read_e57(p, progress=progress)
    if suffix in TEXT_SUFFIXES:
        return read_text(p)
    if suffix == ".npy":
        return read_npy(p)
    if suffix == ".ply":
        return read_ply(p)
    if suffix in DEM_SUFFIXES:
        return read_dem(p)
    return read_stl(p)


def resolve_units(path: str | os.PathLike[str], units: Unit | None) -> tuple[Unit, tuple[str, ...]]:
    """The unit a file's coordinates are read in, and warnings about it.

    ``units`` when given (a warning naming the file if the file's CRS declares
    another linear unit), else the CRS's unit, else metres. A geographic CRS
    (degrees) or a vertical unit unlike the horizontal one also gives a warning
    (:func:`axis_units` has the unit of z).
    """
    unit, _, notes = axis_units(path, units)
    return unit, notes


def axis_units(path: str | os.PathLike[str], units: Unit | None
               ) -> tuple[Unit, Unit, tuple[str, ...]]:
    """(unit of x and y, unit of z, warnings) a file is read in.

    ``units`` given: both axes in it (the user's word overrides the CRS, with a
    warning where they disagree). Else x and y in the CRS's horizontal unit (metres
    without one) and z in the CRS's vertical unit where it declares one, else in the
    horizontal unit; a vertical unit unlike the horizontal one is said once, with
    the conversion.
    """
    p = Path(path)
    info = read_crs(p)
    notes: list[str] = []
    if info.geographic:
        notes.append(f"the CRS of {p} is geographic (degrees): lengths and roughness need "
                     "projected coordinates; reproject the file first")
    unit: Unit = units or info.unit or "m"
    if units is not None and info.unit is not None and info.unit != units:
        notes.append(f"--units {units} contradicts the CRS of {p} "
                     f"({UNIT_LABELS[info.unit]}); reading it in {UNIT_LABELS[units]} as asked")
    z_unit: Unit = unit
    horizontal = info.unit or "m"
    if units is None and info.vertical_unit is not None and info.vertical_unit != horizontal:
        z_unit = info.vertical_unit
        factor = UNIT_METRES[z_unit] / UNIT_METRES[horizontal]
        notes.append(f"the CRS of {p} gives z in {UNIT_LABELS[z_unit]} but x, y in "
                     f"{UNIT_LABELS[horizontal]}: z is converted to {UNIT_LABELS[horizontal]} "
                     f"(x {factor:.7g}), as a reprojection would")
    return unit, z_unit, tuple(notes)
