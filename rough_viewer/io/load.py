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
  cell's centre (:mod:`rough_viewer.io.formats.dem`).

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

Each format is one :class:`Reader` in :data:`READERS`. Before a file is read its
header is checked and its peak memory estimated (:mod:`rough_viewer.io.estimates`:
measured figures, the decompression-bomb guard); an ``untrusted`` reader then runs in
a child process with memory and time limits (:mod:`rough_viewer.io.sandbox.isolate`), so a
file that crashes its decoder is one error line, never the end of this process.
"""

from __future__ import annotations

import importlib
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rough_viewer.io import estimates
from rough_viewer.io.cache import cache_lookup, cache_write
from rough_viewer.io.cloud import (
    MAX_COORDINATE_M,
    PointCloud,
    check_input_file,
    known_bounds,
    on_faces,
)
from rough_viewer.io.formats.crs import read_crs
from rough_viewer.io.formats.dem import DEM_SUFFIXES, read_dem
from rough_viewer.io.formats.e57 import read_e57
from rough_viewer.io.formats.las import read_las
from rough_viewer.io.formats.ply import read_ply
from rough_viewer.io.formats.stl import read_stl
from rough_viewer.io.formats.text import read_npy, read_text
from rough_viewer.io.sandbox import isolate
from rough_viewer.memory import require
from rough_viewer.vocabulary import (
    UNIT_LABELS,
    UNIT_METRES,
    InputError,
    ProgressFn,
    Unit,
    error_line,
    foreign_errors,
)

TEXT_SUFFIXES = (".xyz", ".txt", ".csv", ".pts")



@dataclass(frozen=True)
class Reader:
    """One file format's reader, as the dispatch of :func:`load_points` knows it.

    A new format is one entry in :data:`READERS`. An ``untrusted`` reader (its
    decoder runs native code on bytes anyone can craft) runs in a child process with
    memory and time limits (:mod:`rough_viewer.io.sandbox.isolate`).
    """

    label: str
    """The format as messages name it (``"LAZ"``, ``"E57"``)."""
    suffixes: tuple[str, ...]
    """File name extensions, lower case, with the dot."""
    read: str
    """``"module:function"``: ``function(path, *, progress, max_points) -> PointCloud``
    (importable by name, so the child process can run it)."""
    estimate: Callable[[Path, int | None], estimates.Estimate]
    """Points and peak memory expected, from the header (checks it; in this process:
    pure Python on bounded bytes)."""
    untrusted: bool = True
    """Run in a child process."""
    cached: bool = False
    """Decoded coordinates kept in the decode cache (:mod:`rough_viewer.io.cache`)."""


def _las_file(p: Path, *, progress: ProgressFn | None, max_points: int | None) -> PointCloud:
    return read_las(p, progress=progress, cache=False)


def _e57_file(p: Path, *, progress: ProgressFn | None, max_points: int | None) -> PointCloud:
    return read_e57(p, progress=progress, max_points=max_points)


def _text_file(p: Path, *, progress: ProgressFn | None, max_points: int | None) -> PointCloud:
    return read_text(p)


def _npy_file(p: Path, *, progress: ProgressFn | None, max_points: int | None) -> PointCloud:
    return read_npy(p)


def _ply_file(p: Path, *, progress: ProgressFn | None, max_points: int | None) -> PointCloud:
    return read_ply(p)


def _stl_file(p: Path, *, progress: ProgressFn | None, max_points: int | None) -> PointCloud:
    return read_stl(p)


def _dem_file(p: Path, *, progress: ProgressFn | None, max_points: int | None) -> PointCloud:
    return read_dem(p)


READERS: tuple[Reader, ...] = (
    Reader("LAS", (".las",), f"{__name__}:_las_file", estimates.estimate_las),
    Reader("LAZ", (".laz",), f"{__name__}:_las_file", estimates.estimate_las, cached=True),
    Reader("E57", (".e57",), f"{__name__}:_e57_file", estimates.estimate_e57),
    Reader("text", TEXT_SUFFIXES, f"{__name__}:_text_file", estimates.estimate_text),
    # numpy's own format, its header checked first (estimates.npy_rows): read here
    Reader("NPY", (".npy",), f"{__name__}:_npy_file", estimates.estimate_npy, untrusted=False),
    Reader("PLY", (".ply",), f"{__name__}:_ply_file", estimates.estimate_ply),
    Reader("STL", (".stl",), f"{__name__}:_stl_file", estimates.estimate_stl),
    Reader("DEM", DEM_SUFFIXES, f"{__name__}:_dem_file", estimates.estimate_dem),
)

SUPPORTED_SUFFIXES = tuple(s for r in READERS for s in r.suffixes)


def reader_for(path: str | os.PathLike[str]) -> Reader | None:
    """The reader of ``path``'s extension, or None."""
    suffix = Path(path).suffix.lower()
    return next((r for r in READERS if suffix in r.suffixes), None)


def load_points(
    path: str | os.PathLike[str],
    *,
    progress: ProgressFn | None = None,
    cache: bool = True,
    units: Unit | None = None,
    max_points: int | None = None,
) -> PointCloud:
    """Read a point cloud file into metres.

    Parameters
    ----------
    path : path-like
        A ``.las .laz .e57 .xyz .txt .csv .pts .npy .ply .stl .asc .tif .tiff`` file.
    progress : callable, optional
        ``progress(done, total)`` in points; an exception it raises stops the read
        (and its child process).
    cache : bool
        Use (and fill) the decoded-coordinate cache for LAZ files.
    units : {"m", "mm", "ft", "us-ft"}, optional
        Unit of the file's coordinates; default: its CRS's linear unit where it
        declares one (LAS/LAZ), else metres.
    max_points : int, optional
        A compressed file (LAZ, E57) may declare up to this many points however
        small it is (default :data:`rough_viewer.io.estimates.DEFAULT_MAX_POINTS`);
        beyond, it must be of a size that can hold them (the decompression-bomb
        guard, ``--max-points``).

    Returns
    -------
    PointCloud
        Coordinates in metres; ``source_unit`` the unit the file was read in;
        ``warnings`` what the user should know (header counts, units vs CRS, a
        damaged cache entry decoded again).

    Raises
    ------
    InputError
        Missing or unreadable file, unknown extension, malformed content, fewer than
        3 finite points, a file whose reading cannot fit in memory, a decompression
        bomb, coordinates beyond :data:`MAX_COORDINATE_M`, a reader that crashed or
        went past its memory or time limit (one line naming the file).

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
    if p.is_dir():  # before the suffix: "." or "scans" is a folder, not an unknown type
        check_input_file(p)
    reader = reader_for(p)
    if reader is None:
        raise InputError(
            f"unknown file type {p.suffix or '(none)'!r} for {p}; "
            f"supported: {' '.join(SUPPORTED_SUFFIXES)}"
        )
    check_input_file(p)
    if not os.access(p, os.R_OK):
        raise InputError(f"cannot read {p}: permission denied")
    if units is not None and units not in UNIT_METRES:
        raise InputError(f"unknown unit {units!r}; choose one of {', '.join(UNIT_METRES)}")
    if max_points is not None and max_points < 1:
        raise InputError(f"--max-points must be positive, got {max_points}")
    with foreign_errors(f"cannot read {p}", libraries=("laspy", "lazrs")):
        cloud = _read(p, reader, progress=progress, cache=cache, max_points=max_points)
        unit, z_unit, notes = axis_units(p, units)
        check_coordinates((cloud.x, cloud.y, cloud.z), p,
                          factor=max(UNIT_METRES[unit], UNIT_METRES[z_unit]))
    return cloud.scaled(UNIT_METRES[unit], unit,
                        z_metres_per_unit=UNIT_METRES[z_unit]).with_warnings(*notes)


def _read(p: Path, reader: Reader, *, progress: ProgressFn | None, cache: bool,
          max_points: int | None) -> PointCloud:
    notice = None
    if cache and reader.cached:
        found = cache_lookup(p)
        if found.cloud is not None:
            if progress:
                progress(found.cloud.n, found.cloud.n)
            return found.cloud
        notice = found.notice
    est = reader.estimate(p, max_points)
    require(est.typical, est.what(p), hint="use a smaller file or a machine with more memory")
    module, _, name = reader.read.partition(":")
    function = getattr(importlib.import_module(module), name)
    cloud = isolate.run_reader(
        reader.read, lambda: _in_process(function, p, progress, max_points), p,
        isolate=reader.untrusted, label=reader.label,
        limits=est.limits(p.stat().st_size), progress=progress,
        options={"max_points": max_points}, expected=est.points)
    if cache and reader.cached:
        cache_write(p, cloud)
    return cloud if notice is None else cloud.with_warnings(notice)


def _in_process(function: Callable[..., PointCloud], p: Path, progress: ProgressFn | None,
                max_points: int | None) -> PointCloud:
    """A reader in this process (trusted, or where isolation is unavailable): library
    errors become one line, as the child process does."""
    try:
        return function(p, progress=progress, max_points=max_points)
    except (InputError, MemoryError, OSError, ValueError, EOFError, KeyError, IndexError):
        raise
    except Exception as exc:  # laspy, lazrs, pye57 raise their own types
        raise InputError(f"cannot read {p}: {error_line(exc)}") from None
    except BaseException as exc:
        if type(exc).__name__ == "PanicException":  # lazrs (pyo3) panics are BaseExceptions
            raise InputError(f"cannot read {p}: the decoder failed ({error_line(exc)})") from None
        raise


def check_coordinates(columns: tuple[np.ndarray, ...], p: Path | str, *,
                      factor: float = 1.0) -> None:
    """Refuse coordinate columns (x, y, z, in a unit of ``factor`` metres) that reach
    beyond :data:`MAX_COORDINATE_M`.

    >>> check_coordinates((np.zeros(3), np.zeros(3), np.array([0, 1, 1e290])), "a.xyz")
    Traceback (most recent call last):
    rough_viewer.vocabulary.InputError: coordinates of a.xyz reach 1e+290 m in z; a scan lies within 1e+09 m of its origin: the file is damaged, or its coordinates are not in the unit given
    """
    noted = None
    if len(columns) == 3:  # the bounds a reader noted, just now
        x, y, z = columns
        noted = known_bounds(x, y, z)
        if noted is not None and not on_faces(x, y, z, *noted):
            noted = None
    for a, (axis, col) in enumerate(zip("xyz", columns, strict=True)):
        if col.size:
            low, high = (noted[0][a], noted[1][a]) if noted is not None else (np.min(col),
                                                                             np.max(col))
            top = max(abs(float(low)), abs(float(high))) * factor
            if top > MAX_COORDINATE_M:
                raise InputError(
                    f"coordinates of {p} reach {top:.3g} m in {axis}; a scan lies within "
                    f"{MAX_COORDINATE_M:.0e} m of its origin: the file is damaged, or its "
                    "coordinates are not in the unit given")


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
