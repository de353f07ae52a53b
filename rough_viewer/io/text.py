"""Text point files (``.xyz .txt .csv .pts``): ``x y z`` columns separated by
whitespace, commas or semicolons, extra columns ignored, ``#`` comments, an optional
header line or point count; and ``.npy`` arrays."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np

from rough_viewer.io.cloud import PointCloud, finite_cloud
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


def read_npy(p: Path) -> PointCloud:
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


