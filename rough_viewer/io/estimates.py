"""What reading a file will cost, before it is read: each reader's peak memory per
byte of file and per point (measured, not guessed), the checks that use them, and
the decompression-bomb guard.

The figures in :data:`COSTS` are printed by ``benchmarks/bench_read_memory.py``,
which reads files of several sizes and shapes with each reader in a fresh process
and fits the peak resident memory above the interpreter's own to
``per_byte * file bytes + per_point * points``. ``worst_per_byte`` is the worst
shape measured (one long line, the longest rows): text readers hold their
tokens, so their peak depends on the layout of the lines, which cannot be known
without reading them. A read is refused beforehand when its typical peak cannot
fit in the memory available (:func:`rough_viewer.memory.require`); the isolated
reader's address-space limit (:mod:`rough_viewer.io.sandbox.isolate`) allows the worst
case, as far as the memory available allows, so a file of an unusual shape still
reads and one that asks for more stops with one line instead of taking the
machine's memory.

A compressed file (LAZ, E57) declares its point count in a header; a small file
that declares many more points than its bytes can hold (a 0.34 MB LAZ declaring
50 M points) is a decompression bomb, as Pillow calls an image over its pixel
limit: it is refused before decoding (:func:`check_plausible`) unless its points
are within ``max_points`` (``--max-points``).

>>> COSTS["text"].per_point, COSTS["text"].worst_per_byte
(52.0, 20.0)
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rough_viewer.io.costs import COSTS
from rough_viewer.io.sandbox.isolate import BUDGET_FLOOR, MARGIN, Limits, time_limit
from rough_viewer.memory import USABLE_SHARE, available_bytes, format_bytes
from rough_viewer.vocabulary import InputError

#: Fewest bytes per row of a text cloud (``"0 0 0\n"``): a bound on its points.
MIN_TEXT_ROW = 6
#: Fewest bytes per vertex of an ASCII STL (a facet of three ``vertex 0 0 0`` lines
#: and its four other lines): a bound on its points.
MIN_STL_VERTEX = 27
#: Typical bytes per row of a text cloud (for the progress bar's total).
TYPICAL_TEXT_ROW = 30
#: Typical bytes per point of an E57 file (its points are unknown until its XML is
#: parsed, which only the isolated reader does).
TYPICAL_E57_POINT = 16

#: Most points a byte of a compressed file plausibly holds: genuine LAZ scans take
#: 1.5-5 bytes a point (the bundled outcrop 4.6, an airborne survey 5.0), E57 more;
#: a constant or lattice cloud packs 100 points a byte, which is what a bomb does.
POINTS_PER_BYTE: dict[str, float] = {"laz": 2.0, "e57": 2.0}
#: Points any file may declare without the bomb guard asking (``--max-points``).
DEFAULT_MAX_POINTS = 2_000_000

def max_points_limit(max_points: int | None = None) -> int:
    """The bomb guard's limit: ``max_points`` (the ``--max-points`` of the command,
    passed down with every read), else :data:`DEFAULT_MAX_POINTS`.

    >>> max_points_limit(None), max_points_limit(50_000_000)
    (2000000, 50000000)
    """
    return DEFAULT_MAX_POINTS if max_points is None else int(max_points)


@dataclass(frozen=True)
class Estimate:
    """What reading one file is expected to cost."""

    points: int
    """Points declared (or expected from the size); 0 when unknown."""
    typical: float
    """Peak bytes for a well-formed file of this size and header."""
    worst: float
    """Peak bytes for the worst well-formed file of this size and header."""
    declared: bool = False
    """True when :attr:`points` is what the header declares (not a guess from the size)."""

    def what(self, p: Path) -> str:
        """What the read is, for messages: ``reading 20,000 points from P``."""
        return f"reading {self.points:,} points from {p}" if self.declared else f"reading {p}"

    def limits(self, size_bytes: float) -> Limits:
        """The isolated reader's budget: the worst case, at least the typical peak
        with :data:`MARGIN` (and :data:`BUDGET_FLOOR`), at most the usable memory
        available; the time limit from the file's size."""
        budget = max(MARGIN * self.typical, self.typical + BUDGET_FLOOR, self.worst)
        avail = available_bytes()
        capped = False
        if avail is not None and budget > USABLE_SHARE * avail:
            budget, capped = max(USABLE_SHARE * avail, self.typical), True
        return Limits(memory=budget, seconds=time_limit(size_bytes), capped=capped)


def _cost(kind: str, size: int, points: int, *, declared: bool = False) -> Estimate:
    c = COSTS[kind]
    typical = c.per_byte * size + c.per_point * points
    worst = max(typical, (c.worst_per_byte or c.per_byte) * size + c.per_point * points)
    return Estimate(points=points, typical=typical, worst=worst, declared=declared)


def check_plausible(p: Path, declared: int, *, size: int, kind: str, max_points: int | None,
                    label: str) -> None:
    """Refuse a compressed file that declares more points than its bytes can hold
    (:data:`POINTS_PER_BYTE`), unless they are within ``max_points``
    (:func:`max_points_limit`).

    >>> check_plausible(Path("bomb.laz"), 50_000_000, size=340_000, kind="laz",
    ...                 max_points=None, label="LAZ")
    Traceback (most recent call last):
    rough_viewer.vocabulary.InputError: bomb.laz declares 50,000,000 points in 332.0 KiB (147 a byte; genuine LAZ scans hold at most 2): a decompression bomb or a damaged header, refused before decoding; if the file is genuine, raise the limit with --max-points 50000000
    """
    limit = max_points_limit(max_points)
    plausible = POINTS_PER_BYTE[kind] * max(size, 1)
    if declared > max(limit, plausible):
        raise InputError(
            f"{p} declares {declared:,} points in {format_bytes(size)} ({declared / max(size, 1):.0f} "
            f"a byte; genuine {label} scans hold at most {POINTS_PER_BYTE[kind]:g}): a "
            "decompression bomb or a damaged header, refused before decoding; if the file is "
            f"genuine, raise the limit with --max-points {declared}")


def estimate_las(p: Path, max_points: int | None) -> Estimate:
    """LAS/LAZ: the header's point count (raw bytes, checked by
    :func:`rough_viewer.io.formats.las.check_las_layout`); LAZ through the bomb guard."""
    from rough_viewer.io.formats.las import check_las_layout

    layout = check_las_layout(p)
    if layout.compressed:
        check_plausible(p, layout.point_count, size=layout.size, kind="laz",
                        max_points=max_points, label="LAZ")
    return _cost("laz" if layout.compressed else "las", layout.size, layout.point_count,
                 declared=True)


def estimate_e57(p: Path, max_points: int | None) -> Estimate:
    """E57: its points are in its XML, parsed only by the isolated reader (which
    applies the bomb guard); expected from the size, at worst as many as the guard
    lets through."""
    size = p.stat().st_size
    expected = size // TYPICAL_E57_POINT
    typical = _cost("e57", size, expected)
    most = max(max_points_limit(max_points), int(POINTS_PER_BYTE["e57"] * size))
    return Estimate(points=expected, typical=typical.typical,
                    worst=_cost("e57", size, most).typical)


def estimate_text(p: Path, max_points: int | None) -> Estimate:
    """Text: points expected from the size (at most one per 6 bytes)."""
    size = p.stat().st_size
    est = _cost("text", size, size // MIN_TEXT_ROW)
    return Estimate(points=size // TYPICAL_TEXT_ROW, typical=est.typical, worst=est.worst)


def estimate_ply(p: Path, max_points: int | None) -> Estimate:
    """PLY: the vertex count of its header (checked by
    :func:`rough_viewer.io.formats.ply.read_ply_header`)."""
    from rough_viewer.io.formats.ply import read_ply_header

    with open(p, "rb") as fh:
        header = read_ply_header(fh, p)
    size = p.stat().st_size
    n = header.vertex.count
    if header.format == "ascii":
        return _cost("ply-ascii", size, min(n, size // MIN_TEXT_ROW), declared=True)
    return _cost("ply-binary", size, n, declared=True)


def estimate_stl(p: Path, max_points: int | None) -> Estimate:
    """STL: binary from its triangle count (three vertices each), ASCII from its size."""
    from rough_viewer.io.formats.stl import stl_layout

    binary, n_tri = stl_layout(p)
    size = p.stat().st_size
    if binary:
        return _cost("stl-binary", size, 3 * n_tri, declared=True)
    return _cost("stl-ascii", size, size // MIN_STL_VERTEX)


#: Most raster cells a byte of a compressed GeoTIFF plausibly holds (for the isolated
#: reader's limit; its header is parsed in the child, which checks the cells' memory).
TIFF_CELLS_PER_BYTE = 16


def estimate_dem(p: Path, max_points: int | None) -> Estimate:
    """Elevation rasters (:mod:`rough_viewer.io.formats.dem`): an ESRI ASCII grid from its
    header's rows and columns (a cell takes at least 2 bytes of text); a GeoTIFF,
    whose header only the isolated reader parses, from its size (4 bytes a cell,
    uncompressed float32), at worst :data:`TIFF_CELLS_PER_BYTE` cells a byte."""
    from rough_viewer.io.formats.dem import BYTES_PER_CELL, _esri_header, _tifffile

    size = p.stat().st_size
    if p.suffix.lower() == ".asc":
        head, _ = _esri_header(p)
        cells = min(int(head["nrows"]) * int(head["ncols"]), size // 2)
        return Estimate(points=cells, typical=cells * (BYTES_PER_CELL + 40.0),
                        worst=cells * (BYTES_PER_CELL + 40.0), declared=True)
    _tifffile()  # the optional package's absence said before any work
    cells = size // 4
    most = max(max_points_limit(max_points), TIFF_CELLS_PER_BYTE * size)
    return Estimate(points=cells, typical=cells * float(BYTES_PER_CELL),
                    worst=most * float(BYTES_PER_CELL))


def estimate_npy(p: Path, max_points: int | None) -> Estimate:
    """NPY: rows and columns from its header (:func:`npy_rows`)."""
    rows = npy_rows(p)
    return _cost("npy", p.stat().st_size, rows, declared=True)


def npy_rows(p: Path) -> int:
    """Rows of a ``.npy`` point file, from its header, after checking that it is
    one: an (N, >=3) numeric array, or a 1-D structured array with fields x, y, z,
    whose data the file holds.

    Raises
    ------
    InputError
        An ``.npz`` archive (or anything else) named ``.npy``, an object array, a
        structured array that is not 1-D or lacks x, y, z, a shape that is not one
        point per row, or a file shorter than its header says.
    """
    from rough_viewer.io.cache import read_npy_header

    try:
        with open(p, "rb") as fh:
            magic = fh.read(6)
            if magic[:4] == b"PK\x03\x04":
                raise InputError(f"{p} is a NumPy .npz archive (a zip file), not an .npy "
                                 "array: save the points with numpy.save, or unpack the array")
            if magic != b"\x93NUMPY":
                raise InputError(f"{p} is not a NumPy .npy array (no NumPy header: another kind of file)")
            fh.seek(0)
            shape, _fortran, dtype = read_npy_header(fh)
            data_offset = fh.tell()
    except InputError:
        raise
    except (ValueError, OSError, SyntaxError, TypeError) as exc:
        raise InputError(f"{p} has a damaged NumPy header ({str(exc).splitlines()[0][:120]})") \
            from None
    if dtype.hasobject:
        raise InputError(f"{p} is not a NumPy .npy array of numbers (it holds Python "
                         "objects, or is not a .npy file)")
    if dtype.names is not None:
        if not all(k in dtype.names for k in "xyz"):
            raise InputError(f"{p} holds a structured array without fields x, y, z "
                             f"(fields: {', '.join(dtype.names)})")
        if len(shape) != 1:
            raise InputError(f"{p} holds a structured array of shape {tuple(shape)}; expected "
                             "one record per point (a 1-D array with fields x, y, z)")
        fields: dict[str, Any] = dict(dtype.fields or {})
        for k in "xyz":
            if not np.issubdtype(fields[k][0], np.number):
                raise InputError(f"field {k} of {p} is not numeric")
    elif len(shape) != 2 or shape[1] < 3 or not np.issubdtype(dtype, np.number):
        raise InputError(f"expected an (N, 3) numeric array in {p}, got shape {tuple(shape)}")
    count = int(np.prod(shape, dtype=np.int64)) if shape else 1
    need = data_offset + count * dtype.itemsize
    size = os.path.getsize(p)
    if need > size:
        raise InputError(f"{p} is truncated: its header declares {count * dtype.itemsize:,} "
                         f"bytes of data but the file holds {max(0, size - data_offset):,}")
    return int(shape[0])
