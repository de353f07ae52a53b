"""Text point files (``.xyz .txt .csv .pts``): ``x y z`` columns separated by
whitespace, commas or semicolons, extra columns ignored, ``#`` comments, an optional
header line or point count; and ``.npy`` arrays."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np

from rough_viewer.io.cloud import PointCloud, finite_cloud, note_bounds
from rough_viewer.memory import require
from rough_viewer.vocabulary import InputError, error_line

#: A number as the first line's x, y, z may hold one: decimal, exponent, or nan/inf
#: (a point with a missing coordinate is data, dropped later, not a header).
_NUM = re.compile(r"^\s*[-+]?((\d+\.?\d*|\.\d+)([eE][-+]?\d+)?|nan|inf|infinity)\s*$",
                  re.IGNORECASE)


#: Field separators a text cloud may use (whitespace, tabs included, otherwise).
SEPARATORS = (",", ";")


def _significant_lines(p: Path, n: int) -> list[tuple[int, str]]:
    """The first ``n`` lines that are neither blank nor ``#`` comments, with their
    0-based line numbers."""
    out: list[tuple[int, str]] = []
    with open(p, encoding="utf-8-sig", errors="replace") as fh:  # a BOM is no header
        for i, line in enumerate(fh):
            text = line.strip()
            if text and not text.startswith("#"):
                out.append((i, line))
                if len(out) == n:
                    break
    return out


def _fields(line: str, delim: str | None) -> list[str]:
    return line.split(delim) if delim else line.split()


def read_text(p: Path) -> PointCloud:
    """x, y, z of a text cloud: the first three columns, separated by commas,
    semicolons or whitespace (tabs too); ``#`` comment lines and blank lines
    anywhere; an optional header line (a first line that is not numbers, e.g.
    ``x,y,z`` or CloudCompare's ``//X,Y,Z``); a first line holding one whole number
    (the point count of Leica ``.pts`` files) is skipped. Extra columns are ignored."""
    lines = _significant_lines(p, 2)
    if not lines:
        raise InputError(f"no points in {p}")
    skip = 0
    first_no, first = lines[0]
    if re.fullmatch(r"\s*\d+\s*", first) and len(lines) > 1:  # a .pts point count
        skip = first_no + 1
        first_no, first = lines[1]
    delim = next((d for d in SEPARATORS if d in first), None)
    fields = _fields(first, delim)
    header = not all(_NUM.match(f) for f in fields[:3]) or len(fields) < 3
    if header:
        skip = first_no + 1
        fields = _fields(lines[1][1], delim) if len(lines) > 1 else []
        if not fields:
            raise InputError(f"no points in {p}")
    if len(fields) < 3:
        seps = "commas, semicolons or whitespace"
        raise InputError(f"expected at least 3 columns (x y z) in {p}, found {len(fields)} "
                         f"(columns separated by {seps})")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # "input contained no data"
            data = np.loadtxt(
                p, delimiter=delim, usecols=(0, 1, 2), skiprows=skip,
                dtype=np.float64, comments="#", ndmin=2, encoding="utf-8-sig",
            )
    except ValueError as exc:
        raise InputError(f"cannot parse {p} as x y z columns: {error_line(exc)}") from None
    if data.shape[0] == 0:
        raise InputError(f"no points in {p}")
    return finite_cloud(data[:, 0].copy(), data[:, 1].copy(), data[:, 2].copy(), None, p)


# ----------------------------------------------------------------------------- npy

#: Rows of a C-order ``.npy`` read and split into columns at a time (1.5 MB of
#: three float64 columns: in the second-level cache while it is split and searched
#: for its extremes; 0.28 s for 20 M points against 0.32 s with 6 MB blocks). A
#: thread loading the compiled kernels meanwhile holds the interpreter lock between
#: the block's NumPy calls: :func:`rough_viewer.grid.fast.preload` shortens the
#: interpreter's switch interval while it runs, so the read waits little for it.
NPY_BLOCK_ROWS = 1 << 16


def _npy_layout(p: Path) -> tuple[tuple[int, ...], bool, np.dtype, int] | None:
    """``(shape, fortran_order, dtype, data offset)`` of a plain numeric 2-D ``.npy``
    whose data are all there, read from its header; None for anything else (left to
    ``np.load`` and its messages)."""
    try:
        with open(p, "rb") as fh:
            version = np.lib.format.read_magic(fh)
            if version == (1, 0):
                shape, fortran, dtype = np.lib.format.read_array_header_1_0(fh)
            elif version == (2, 0):
                shape, fortran, dtype = np.lib.format.read_array_header_2_0(fh)
            else:
                return None
            offset = fh.tell()
    except (OSError, ValueError):
        return None
    if (len(shape) != 2 or shape[1] < 3 or dtype.fields is not None or dtype.hasobject
            or not np.issubdtype(dtype, np.number) or np.issubdtype(dtype, np.complexfloating)):
        return None
    if p.stat().st_size < offset + shape[0] * shape[1] * dtype.itemsize:
        return None  # truncated: np.load says so
    return shape, bool(fortran), dtype, offset


def _read_exactly(fh, view: memoryview) -> None:
    if fh.readinto(view) != len(view):
        raise ValueError("the file ends before the rows its header declares")


def read_npy(p: Path) -> PointCloud:
    """x, y, z of a ``.npy`` array: an (N, K >= 3) numeric array (its first three
    columns) or a structured array with fields ``x``, ``y``, ``z``.

    A plain numeric array is read straight into three float64 columns: a C-order
    file block by block (:data:`NPY_BLOCK_ROWS` rows read, then split, and each
    block's column pieces searched for their smallest and largest values while they
    are in the cache), a Fortran-order file column by column; no (N, K) array and
    no strided copy of one is made, so the peak memory is the columns themselves,
    and the file is read once. The extremes tell whether every coordinate is finite
    (NaN and infinities show there) and give the cloud's bounds, noted for the
    checks after the read and the grid's first pass
    (:func:`rough_viewer.io.cloud.note_bounds`). Anything else goes through
    ``np.load``.
    """
    layout = _npy_layout(p)
    if layout is None:
        return _read_npy_load(p)
    (n, k), fortran, dtype, offset = layout
    require(3 * 8 * n, f"reading {n:,} points from {p}",
            hint="use a smaller file or a machine with more memory")
    cols = [np.empty(n) for _ in range(3)]
    box = _Box()
    with open(p, "rb", buffering=0) as fh:
        if fortran:  # each column is contiguous in the file
            raw = None if dtype == np.dtype(np.float64) else np.empty(n, dtype=dtype)
            for c, col in enumerate(cols):
                fh.seek(offset + c * n * dtype.itemsize)
                target = col if raw is None else raw
                _read_exactly(fh, target.view(np.uint8).data)
                if raw is not None:
                    col[:] = raw
                box.add(c, col, 0)
        else:
            fh.seek(offset)
            buf = np.empty((min(NPY_BLOCK_ROWS, max(n, 1)), k), dtype=dtype)
            view = buf.reshape(-1).view(np.uint8).data
            row_bytes = k * dtype.itemsize
            for start in range(0, n, buf.shape[0]):
                m = min(buf.shape[0], n - start)
                _read_exactly(fh, view[:m * row_bytes])
                block = buf[:m]
                for c, col in enumerate(cols):
                    piece = col[start:start + m]
                    piece[:] = block[:, c]
                    box.add(c, piece, start)
    if box.finite and n >= 3:
        cloud = PointCloud(x=cols[0], y=cols[1], z=cols[2], source=str(p))
        note_bounds(cloud.x, cloud.y, cloud.z, box.lo, box.hi, box.at)
        return cloud
    return finite_cloud(cols[0], cols[1], cols[2], None, p)


class _Box:
    """The running bounds of three columns read piece by piece, with the index of
    the first point of each extreme; ``finite`` turns False at the first NaN or
    infinity (``argmin`` finds a NaN first, and an infinity is an extreme)."""

    def __init__(self) -> None:
        self.lo = np.full(3, np.inf)
        self.hi = np.full(3, -np.inf)
        self.at = np.full(6, -1, dtype=np.int64)
        self.finite = True

    def add(self, c: int, piece: np.ndarray, start: int) -> None:
        if not self.finite or piece.shape[0] == 0:
            return
        i, j = int(np.argmin(piece)), int(np.argmax(piece))
        low, high = piece[i], piece[j]
        if not (np.isfinite(low) and np.isfinite(high)):
            self.finite = False
            return
        if low < self.lo[c]:
            self.lo[c], self.at[c] = low, start + i
        if high > self.hi[c]:
            self.hi[c], self.at[3 + c] = high, start + j


def _read_npy_load(p: Path) -> PointCloud:
    try:
        arr = np.load(p, allow_pickle=False)
    except ValueError as exc:
        if "pickle" in str(exc):  # numpy's text would invite loading it unsafely
            raise InputError(f"{p} is not a NumPy .npy array of numbers (it holds Python "
                             "objects, or is not a .npy file)") from None
        raise InputError(f"cannot read {p} as a numpy array: {exc}") from None
    if arr.dtype.names and all(k in arr.dtype.names for k in "xyz"):
        cols = [np.asarray(arr[k], dtype=np.float64) for k in "xyz"]
        return finite_cloud(cols[0], cols[1], cols[2], None, p)
    if arr.ndim != 2 or arr.shape[1] < 3 or not np.issubdtype(arr.dtype, np.number):
        raise InputError(f"expected an (N, 3) numeric array in {p}, got shape {arr.shape}")
    arr = arr.astype(np.float64, copy=False)
    return finite_cloud(arr[:, 0].copy(), arr[:, 1].copy(), arr[:, 2].copy(), None, p)
