"""Text point files (``.xyz .txt .csv .pts``): ``x y z`` columns, whitespace or comma
separated, extra columns ignored, an optional header line; and ``.npy`` arrays."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from rough_viewer.io.cloud import PointCloud, finite_cloud
from rough_viewer.vocabulary import InputError

#: A number as the first line's x, y, z may hold one: decimal, exponent, or nan/inf
#: (a point with a missing coordinate is data, dropped later, not a header).
_NUM = re.compile(r"^\s*[-+]?((\d+\.?\d*|\.\d+)([eE][-+]?\d+)?|nan|inf|infinity)\s*$",
                  re.IGNORECASE)


def read_text(p: Path) -> PointCloud:
    with open(p, encoding="utf-8", errors="replace") as fh:
        first = ""
        for line in fh:
            if line.strip():
                first = line
                break
    if not first:
        raise InputError(f"no points in {p}")
    delim = "," if "," in first else None
    fields = [f for f in (first.split(",") if delim else first.split())]
    header = not all(_NUM.match(f) for f in fields[:3]) or len(fields) < 3
    if len(fields) < 3:
        raise InputError(f"expected at least 3 columns (x y z) in {p}, found {len(fields)}")
    try:
        data = np.loadtxt(
            p, delimiter=delim, usecols=(0, 1, 2), skiprows=1 if header else 0,
            dtype=np.float64, comments="#", ndmin=2,
        )
    except ValueError as exc:
        msg = str(exc).splitlines()[0]
        raise InputError(f"cannot parse {p} as x y z columns: {msg}") from None
    if data.shape[0] == 0:
        raise InputError(f"no points in {p}")
    return finite_cloud(data[:, 0].copy(), data[:, 1].copy(), data[:, 2].copy(), None, p)


# ----------------------------------------------------------------------------- npy


def read_npy(p: Path) -> PointCloud:
    try:
        arr = np.load(p, allow_pickle=False)
    except ValueError as exc:
        raise InputError(f"cannot read {p} as a numpy array: {exc}") from None
    if arr.dtype.names and all(k in arr.dtype.names for k in "xyz"):
        cols = [np.asarray(arr[k], dtype=np.float64) for k in "xyz"]
        return finite_cloud(cols[0], cols[1], cols[2], None, p)
    if arr.ndim != 2 or arr.shape[1] < 3 or not np.issubdtype(arr.dtype, np.number):
        raise InputError(f"expected an (N, 3) numeric array in {p}, got shape {arr.shape}")
    arr = arr.astype(np.float64, copy=False)
    return finite_cloud(arr[:, 0].copy(), arr[:, 1].copy(), arr[:, 2].copy(), None, p)


