"""Fractal dimension of a gridded fault surface's rows and columns with the default
and the paper's roughness-length windows, against a Hurst reference.

Usage::

    python benchmarks/fault_dem_windows.py coronaA_grids.npz [reference.csv]

The .npz holds ``xg`` (C,), ``yg`` (R,), ``Z_grid`` and ``Z_detrended`` (R, C) in
metres (the Corona Heights fault DEM of the project's real-scan folder). Prints, for
each window rule, the mean, spread and range of D over (a) the grid's own rows and
columns (longest finite run of ``Z_detrended``, as the reference's script) and (b)
profiles extracted from the DEM read as points (one per cell centre, through an ESRI
ASCII grid written here: docs/real-scans.md's recipe), every 12th row and column,
with the count outside [1, 2]; then the reference's D = 2 - H by estimator.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

from rough_viewer.io import load_points
from rough_viewer.profiles.extraction import extract_profile
from rough_viewer.profiles.fractal import roughness_length


def write_asc(npz: Path, out: Path) -> None:
    """The DEM as an ESRI ASCII grid (the recipe of docs/real-scans.md)."""
    d = np.load(npz, allow_pickle=False)
    z, xg, yg = d["Z_grid"], d["xg"], d["yg"]
    dx = float(xg[1] - xg[0])
    if yg[1] > yg[0]:                      # ESRI grids list the northernmost row first
        z = z[::-1]
    with open(out, "w") as fh:
        fh.write(f"ncols {z.shape[1]}\nnrows {z.shape[0]}\nxllcenter {float(xg[0])!r}\n"
                 f"yllcenter {float(min(yg[0], yg[-1]))!r}\ncellsize {dx!r}\n"
                 "NODATA_value -9999\n")
        np.savetxt(fh, np.where(np.isfinite(z), z, -9999.0), fmt="%.9g")


def longest_run(h: np.ndarray) -> np.ndarray:
    ok = np.r_[False, np.isfinite(h), False]
    edges = np.flatnonzero(np.diff(ok.astype(int)))
    starts, stops = edges[::2], edges[1::2]
    if starts.size == 0:
        return h[:0]
    k = int(np.argmax(stops - starts))
    return h[starts[k]:stops[k]]


def stats(d: list[float]) -> str:
    a = np.array(d)
    out = int(np.count_nonzero((a < 1) | (a > 2)))
    return f"{a.mean():.3f} +- {a.std():.3f} [{a.min():.2f}, {a.max():.2f}], {out}/{a.size} outside"


def main(argv: list[str]) -> None:
    npz = Path(argv[0])
    d = np.load(npz, allow_pickle=False)
    zd, xg, yg = d["Z_detrended"], d["xg"], d["yg"]
    dx = float(d["dx"])
    with tempfile.TemporaryDirectory() as tmp:
        asc = Path(tmp) / "dem.asc"
        write_asc(npz, asc)
        cloud = load_points(asc)
    z_at = {(i, j): v for (i, j), v in np.ndenumerate(d["Z_grid"])}
    print(f"{npz.name}: {zd.shape[0]} x {zd.shape[1]} grid at {dx * 1e3:.2f} mm, "
          f"{cloud.n:,} points read back from the ESRI grid")
    for rule in ("default", "paper"):
        direct: dict[str, list[float]] = {"rows (x)": [], "columns (y)": []}
        for i in range(zd.shape[0]):
            h = longest_run(zd[i])
            if h.size >= 50:
                direct["rows (x)"].append(roughness_length(h, dx, windows=rule).dimension)
        for j in range(zd.shape[1]):
            h = longest_run(zd[:, j])
            if h.size >= 50:
                direct["columns (y)"].append(roughness_length(h, dx, windows=rule).dimension)
        extracted: dict[str, list[float]] = {"rows (x)": [], "columns (y)": []}
        for i in range(5, zd.shape[0] - 5, 12):
            a = (xg[3], yg[i], z_at[(i, 3)])
            b = (xg[-4], yg[i], z_at[(i, zd.shape[1] - 4)])
            if np.all(np.isfinite(a + b)):
                p = extract_profile(cloud, a, b)
                extracted["rows (x)"].append(
                    roughness_length(p.heights, p.spacing, windows=rule).dimension)
        for j in range(5, zd.shape[1] - 5, 12):
            a = (xg[j], yg[3], z_at[(3, j)])
            b = (xg[j], yg[-4], z_at[(zd.shape[0] - 4, j)])
            if np.all(np.isfinite(a + b)):
                p = extract_profile(cloud, a, b)
                extracted["columns (y)"].append(
                    roughness_length(p.heights, p.spacing, windows=rule).dimension)
        print(f"windows {rule}:")
        for what in ("rows (x)", "columns (y)"):
            print(f"  grid {what:12s} D {stats(direct[what])}")
            print(f"  extracted {what:8s} D {stats(extracted[what])}")
    if len(argv) > 1:
        print("reference D = 2 - H:")
        with open(argv[1]) as fh:
            next(fh)
            for line in fh:  # its profiles column holds unquoted commas: split from the right
                head, method, mean_h, _, _ = line.strip().rsplit(",", 4)
                print(f"  {head.split(',')[0]} {method:4s} D {2 - float(mean_h):.3f}")


if __name__ == "__main__":
    main(sys.argv[1:])
