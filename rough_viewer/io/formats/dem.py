"""Elevation rasters (DEMs) as point clouds: ESRI ASCII grids (``.asc``) and GeoTIFF
rasters (``.tif``, ``.tiff``).

Every raster cell with a value becomes one point at the cell's centre, its height
``z``; cells holding the raster's nodata value (or NaN) are dropped and counted in
``PointCloud.dropped_nonfinite``. Coordinates follow the file's georeferencing:

- ESRI ASCII grid: a header of ``ncols``, ``nrows``, ``xllcorner`` or ``xllcenter``,
  ``yllcorner`` or ``yllcenter``, ``cellsize`` (or GDAL's ``dx`` and ``dy``) and an
  optional ``nodata_value``, then ``nrows`` rows of values, the first row the
  northernmost. With ``xllcorner`` the centre of column ``c`` is
  ``xllcorner + (c + 0.5) cellsize``; with ``xllcenter`` it is ``xllcenter + c
  cellsize``; rows likewise from the bottom. A ``.prj`` file beside it (same name)
  gives the CRS (WKT).
- GeoTIFF (through the optional package tifffile, ``pip install 'rough_viewer[dem]'``):
  the first band of the first image; ``ModelTransformationTag`` (an affine matrix,
  rotation allowed) or ``ModelTiepointTag`` with ``ModelPixelScaleTag``; the
  raster type key says whether a tie point is a pixel's corner (``PixelIsArea``, the
  default: centres are half a pixel in) or its centre (``PixelIsPoint``); nodata from
  GDAL's ``GDAL_NODATA`` tag; the CRS from the GeoKeys
  (:func:`rough_viewer.io.formats.crs.parse_geotiff_keys`), read by
  :func:`rough_viewer.io.formats.crs.read_crs`.

A DEM is a 2.5-D surface sampled on a lattice: cells of a roughness grid holding two
rows of it fit their plane exactly (roughness 0, counted as exact fits), and the
lattice spacing is the point spacing.

>>> import tempfile, pathlib
>>> p = pathlib.Path(tempfile.mkdtemp()) / "dem.asc"
>>> _ = p.write_text("ncols 3\\nnrows 2\\nxllcorner 100\\nyllcorner 200\\ncellsize 10\\n"
...                  "NODATA_value -9999\\n1 2 3\\n4 -9999 6\\n")
>>> cloud = read_esri_ascii(p)
>>> cloud.x.tolist(), cloud.y.tolist(), cloud.z.tolist(), cloud.dropped_nonfinite
([105.0, 115.0, 125.0, 105.0, 125.0], [215.0, 215.0, 215.0, 205.0, 205.0], [1.0, 2.0, 3.0, 4.0, 6.0], 1)
"""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np

from rough_viewer.io.cloud import PointCloud, finite_cloud
from rough_viewer.memory import require
from rough_viewer.vocabulary import InputError

#: File suffixes read as elevation rasters.
DEM_SUFFIXES = (".asc", ".tif", ".tiff")
#: How to get the optional GeoTIFF reader.
TIFF_HINT = "pip install 'rough_viewer[dem]' (or pip install tifffile)"
#: Bytes per raster cell at the peak of reading: the grid (float64), its mask and the
#: point cloud's three float64 columns with the temporaries of making them.
BYTES_PER_CELL = 72

#: TIFF tags of the GeoTIFF standard and GDAL read here.
MODEL_PIXEL_SCALE = 33550
MODEL_TIEPOINT = 33922
MODEL_TRANSFORMATION = 34264
GEO_KEY_DIRECTORY = 34735
GEO_DOUBLE_PARAMS = 34736
GEO_ASCII_PARAMS = 34737
GDAL_NODATA = 42113
#: GeoKey GTRasterTypeGeoKey: 1 = PixelIsArea (default), 2 = PixelIsPoint.
RASTER_TYPE = 1025
PIXEL_IS_POINT = 2

_ESRI_KEYS = ("ncols", "nrows", "xllcorner", "xllcenter", "yllcorner", "yllcenter",
              "cellsize", "dx", "dy", "nodata_value")


def raster_points(z: np.ndarray, affine: np.ndarray, path: Path, *,
                  nodata: float | None = None) -> PointCloud:
    """The points of a raster: one per cell with a value, at the cell's centre.

    Parameters
    ----------
    z : (R, C) array
        Heights, row 0 first (as stored).
    affine : (2, 3) array
        ``[x, y] = affine @ [col, row, 1]`` for the CENTRE of the cell in column
        ``col`` and row ``row`` (0-based).
    path : Path
        The file (for messages and ``source``).
    nodata : float, optional
        Value of cells without data (dropped, as NaN cells are).
    """
    grid = np.asarray(z)
    if grid.ndim != 2 or grid.size == 0:
        raise InputError(f"{path} holds no 2-D elevation grid (shape {grid.shape})")
    if grid.dtype.kind not in "biuf":
        raise InputError(f"{path} holds {grid.dtype} values, not heights (an elevation "
                         "raster holds real numbers): not read")
    rows, cols = grid.shape
    require(float(grid.size) * BYTES_PER_CELL, f"reading the {cols:,} x {rows:,} raster {path}",
            hint="crop or resample the raster first")
    heights = grid.astype(np.float64, copy=True).ravel()
    if nodata is not None:
        heights[nodata_cells(grid, nodata).ravel()] = np.nan
    r, c = np.divmod(np.arange(heights.size, dtype=np.int64), cols)
    a = np.asarray(affine, dtype=np.float64)
    x = a[0, 0] * c + a[0, 1] * r + a[0, 2]
    y = a[1, 0] * c + a[1, 1] * r + a[1, 2]
    return finite_cloud(x, y, heights, None, path)


def nodata_cells(grid: np.ndarray, nodata: float) -> np.ndarray:
    """Where ``grid`` holds its nodata value, compared in the grid's own type as GDAL
    does: a float32 band's ``-9999.9`` is the float32 nearest it (in float64 no cell
    equals it), within 1e-5 of float32's largest magnitude that magnitude (GDAL's
    ``-3.4028234663852886e+38``, often printed ``-3.40282e+38``: 1e-6 off); an integer band's nodata is a
    whole number within its type's range, or no cell is nodata. NaN: no cell here
    (NaN cells are dropped anyway).

    >>> nodata_cells(np.array([1.0, -9999.9], dtype=np.float32), -9999.9).tolist()
    [False, True]
    """
    if grid.dtype.kind == "f":
        top = float(np.finfo(np.float32).max)
        with np.errstate(over="ignore", invalid="ignore"):
            cells = np.asarray(grid == grid.dtype.type(nodata))
            if grid.dtype == np.float32 and abs(abs(nodata) - top) < 1e-5 * top:
                # GDALAdjustNoDataCloseToFloatMax; a printed -3.40282e+38 is 1e-6 off
                # the float32 lowest the cells of such a band hold
                cells |= grid == grid.dtype.type(math.copysign(top, nodata))
        return cells
    if grid.dtype.kind in "iu" and math.isfinite(nodata) and nodata == int(nodata):
        info = np.iinfo(grid.dtype)
        if info.min <= int(nodata) <= info.max:
            return np.asarray(grid == grid.dtype.type(int(nodata)))
    return np.zeros(grid.shape, dtype=bool)


# ----------------------------------------------------------------------------- ESRI ASCII


#: Most characters of an ESRI ASCII grid's values read at once.
MAX_ESRI_PIECE = 1 << 20

def _esri_header(p: Path) -> tuple[dict[str, float], int]:
    """The header values and the number of header lines.

    Bounded before it is read (it runs in the server's own process, for the memory
    estimate): a header line may be at most :data:`~rough_viewer.io.formats.ply.MAX_HEADER_LINE`
    bytes and the header :data:`~rough_viewer.io.formats.ply.MAX_HEADER_BYTES`, as PLY's; a
    line of data is recognised by its first bytes, never read whole here."""
    from rough_viewer.io.formats.ply import MAX_HEADER_BYTES, MAX_HEADER_LINE

    head: dict[str, float] = {}
    lines = 0
    with open(p, "rb") as fh:
        while True:
            raw = fh.readline(MAX_HEADER_LINE + 1)
            fields = raw.decode("ascii", errors="replace").split()
            if not raw or fields and not fields[0][:1].isalpha():
                break  # the end, or the first row of values
            if len(raw) > MAX_HEADER_LINE or fh.tell() > MAX_HEADER_BYTES:
                raise InputError(f"{p} is not an ESRI ASCII grid: a header line longer than "
                                 f"{MAX_HEADER_LINE:,} bytes or a header longer than "
                                 f"{MAX_HEADER_BYTES:,}")
            lines += 1
            if not fields:
                continue
            line = " ".join(fields)
            key = fields[0].lower()
            if key not in _ESRI_KEYS or len(fields) != 2:
                raise InputError(f"{p} is not an ESRI ASCII grid: unknown header line "
                                 f"{line[:60]!r}")
            try:
                head[key] = float(fields[1])
            except ValueError:
                raise InputError(f"{p}: header value {line[:60]!r} is not a number") from None
    for need in ("ncols", "nrows"):
        value = head.get(need, 0.0)
        if not (math.isfinite(value) and value >= 1 and value == int(value)):
            raise InputError(f"{p} is not an ESRI ASCII grid: no whole {need} in its header"
                             + (f" (it gives {value:g})" if need in head else ""))
    return head, lines


def esri_affine(head: dict[str, float], p: Path) -> np.ndarray:
    """The cell-centre affine of an ESRI ASCII header (see the module docstring)."""
    dx = head.get("cellsize", head.get("dx"))
    dy = head.get("cellsize", head.get("dy"))
    if dx is None or dy is None or not (dx > 0 and dy > 0):
        raise InputError(f"{p}: the header needs a positive cellsize (or dx and dy)")
    rows = int(head["nrows"])

    def first_centre(axis: str, step: float) -> float:
        """The lower-left cell centre along ``axis``: from its corner or its centre."""
        if f"{axis}llcorner" in head:
            return head[f"{axis}llcorner"] + 0.5 * step
        if f"{axis}llcenter" in head:
            return head[f"{axis}llcenter"]
        raise InputError(f"{p}: the header needs {axis}llcorner or {axis}llcenter")

    x0, y_bottom = first_centre("x", dx), first_centre("y", dy)
    # row 0 is the top: its centre is (rows - 1) cells above the bottom row's
    return np.array([[dx, 0.0, x0], [0.0, -dy, y_bottom + (rows - 1) * dy]])


def read_esri_ascii(p: Path) -> PointCloud:
    """The points of an ESRI ASCII grid (module docstring)."""
    head, skip = _esri_header(p)
    rows, cols = int(head["nrows"]), int(head["ncols"])
    affine = esri_affine(head, p)
    require(float(rows) * cols * (BYTES_PER_CELL + 40), f"reading the {cols:,} x {rows:,} "
            f"grid {p}", hint="crop or resample the raster first")
    count = 0

    def values_of(text: str, line: int):
        nonlocal count
        for t in text.split():
            try:
                value = float(t)
            except ValueError:
                raise InputError(f"cannot read the values of {p}: {t[:20]!r} on line "
                                 f"{line + 1} is not a number") from None
            count += 1
            yield value

    def numbers(fh):
        """The values in file order, read in pieces of at most MAX_ESRI_PIECE
        characters (values may wrap over lines or all stand on one: a line of 512 MB
        was read and split whole)."""
        line, carry = 0, ""
        while piece := fh.readline(MAX_ESRI_PIECE):
            whole = piece.endswith("\n")
            if line < skip:
                line += whole
                continue
            text, carry = carry + piece, ""
            if not whole and not piece[-1].isspace():  # its last value may go on
                cut = max(text.rfind(c) for c in " \t\r")
                text, carry = text[:cut + 1], text[cut + 1:]
                if len(carry) > MAX_ESRI_PIECE:
                    raise InputError(f"cannot read the values of {p}: line {line + 1} holds "
                                     f"a value longer than {MAX_ESRI_PIECE:,} characters")
            yield from values_of(text, line)
            line += whole
        yield from values_of(carry, line)

    with open(p, encoding="ascii", errors="replace") as fh:
        stream = numbers(fh)
        try:  # values may wrap over lines: read them as one stream, row-major
            values = np.fromiter(stream, dtype=np.float64, count=rows * cols)
        except InputError:
            raise
        except ValueError:  # the stream ended early
            raise InputError(f"{p} holds {count:,} values; its header says {rows:,} rows "
                             f"of {cols:,} = {rows * cols:,}") from None
        extra = sum(1 for _ in stream)
    if extra:
        raise InputError(f"{p} holds {rows * cols + extra:,} values; its header says {rows:,} "
                         f"rows of {cols:,} = {rows * cols:,}")
    return raster_points(values.reshape(rows, cols), affine, p,
                         nodata=head.get("nodata_value"))


def prj_beside(p: Path) -> Path | None:
    """The ``.prj`` file beside a raster (same name), if there is one."""
    for suffix in (".prj", ".PRJ"):
        candidate = p.with_suffix(suffix)
        if candidate.is_file():
            return candidate
    return None


# ----------------------------------------------------------------------------- GeoTIFF


def _tifffile():
    if importlib.util.find_spec("tifffile") is None:
        raise InputError(f"reading GeoTIFF elevation rasters needs the optional package "
                         f"tifffile: {TIFF_HINT}")
    import tifffile

    return tifffile


def geotiff_tags(p: Path) -> dict[int, object]:
    """The georeferencing tags of the first image of a TIFF file (tag code -> value),
    read without decoding the pixels."""
    tifffile = _tifffile()
    with tifffile.TiffFile(p) as tif:
        tags = tif.pages[0].tags
        return {code: tags[code].value for code in (
            MODEL_PIXEL_SCALE, MODEL_TIEPOINT, MODEL_TRANSFORMATION, GEO_KEY_DIRECTORY,
            GEO_DOUBLE_PARAMS, GEO_ASCII_PARAMS, GDAL_NODATA) if code in tags}


def geokey_bytes(tags: dict[int, object]) -> tuple[bytes, bytes, bytes]:
    """The GeoKey directory, double and ASCII parameters as the bytes
    :func:`rough_viewer.io.formats.crs.parse_geotiff_keys` reads (LAS stores them so)."""
    directory = np.asarray(tags.get(GEO_KEY_DIRECTORY, ()), dtype="<u2").tobytes()
    doubles = np.asarray(tags.get(GEO_DOUBLE_PARAMS, ()), dtype="<f8").tobytes()
    text = tags.get(GEO_ASCII_PARAMS, "")
    ascii_params = (text.encode("ascii", "replace") if isinstance(text, str)
                    else bytes(text) if isinstance(text, bytes | bytearray) else b"")
    return directory, doubles, ascii_params


def _geokey(directory: bytes, key: int) -> int | None:
    words = np.frombuffer(directory[: len(directory) // 2 * 2], dtype="<u2")
    if words.size < 4:
        return None
    entries = words[4: 4 + 4 * int(words[3])].reshape(-1, 4)
    hit = entries[(entries[:, 0] == key) & (entries[:, 1] == 0)]
    return int(hit[0, 3]) if hit.size else None


def geotiff_affine(tags: dict[int, object], p: Path) -> np.ndarray:
    """The cell-centre affine of a GeoTIFF from its tags (module docstring)."""
    directory, _, _ = geokey_bytes(tags)
    offset = 0.0 if _geokey(directory, RASTER_TYPE) == PIXEL_IS_POINT else 0.5
    if MODEL_TRANSFORMATION in tags:
        m = np.asarray(tags[MODEL_TRANSFORMATION], dtype=np.float64).reshape(4, 4)
        # raster (i, j) -> model: x = m00 i + m01 j + m03; the centre is (c + offset, r + offset)
        return np.array([[m[0, 0], m[0, 1], m[0, 3] + offset * (m[0, 0] + m[0, 1])],
                         [m[1, 0], m[1, 1], m[1, 3] + offset * (m[1, 0] + m[1, 1])]])
    if MODEL_TIEPOINT in tags and MODEL_PIXEL_SCALE in tags:
        tie = np.asarray(tags[MODEL_TIEPOINT], dtype=np.float64)[:6]
        scale = np.asarray(tags[MODEL_PIXEL_SCALE], dtype=np.float64)[:2]
        i, j, x, y = tie[0], tie[1], tie[3], tie[4]
        sx, sy = scale
        if not (sx > 0 and sy > 0):
            raise InputError(f"{p}: the GeoTIFF pixel scale must be positive, got {sx:g}, {sy:g}")
        return np.array([[sx, 0.0, x + (offset - i) * sx], [0.0, -sy, y - (offset - j) * sy]])
    raise InputError(f"{p} is a TIFF without georeferencing (no ModelTiepointTag and "
                     "ModelPixelScaleTag or ModelTransformationTag): not a GeoTIFF elevation "
                     "raster")


def read_geotiff(p: Path) -> PointCloud:
    """The points of a GeoTIFF elevation raster's first band (module docstring)."""
    tifffile = _tifffile()
    tags = geotiff_tags(p)
    affine = geotiff_affine(tags, p)
    with tifffile.TiffFile(p) as tif:
        page = tif.pages[0]
        shape = tuple(int(s) for s in page.shape)
        cells = int(np.prod(shape[:2])) if len(shape) >= 2 else 0
        require(float(cells) * (BYTES_PER_CELL + page.dtype.itemsize * (
            shape[2] if len(shape) > 2 else 1)), f"reading the raster {p}",
            hint="crop or resample the raster first")
        data = page.asarray()
    if data.ndim == 3:  # several samples per pixel: the first band is the elevation
        data = data[..., 0] if data.shape[-1] <= 8 else data[0]
    nodata = None
    text = tags.get(GDAL_NODATA)
    if text is not None:
        try:
            nodata = float(str(text).strip().strip("\0"))
        except ValueError:
            raise InputError(f"{p}: GDAL_NODATA {str(text)[:40]!r} is not a number") from None
    return raster_points(data, affine, p, nodata=nodata)


def read_dem(p: Path) -> PointCloud:
    """The points of an elevation raster, by suffix (:data:`DEM_SUFFIXES`)."""
    if p.suffix.lower() == ".asc":
        return read_esri_ascii(p)
    return read_geotiff(p)
