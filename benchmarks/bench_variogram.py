"""Time the exact FFT semivariogram on a face-sized map of 50,000 cells.

The map imitates the 2011 paper's Box Canyon face at the 0.125 m grid: a wavy
vertical face 90 m long and 10 m high (720 x 80 cells in the plane, about 10 cells
through the thickness), 50,000 occupied cells. Prints the median of several runs
for the 3-D variogram and for the face-plane variant.

Run: PYTHONPATH=. python benchmarks/bench_variogram.py [--runs 7] [--cells 50000]
"""

from __future__ import annotations

import argparse
from types import SimpleNamespace

import numpy as np
from timing import median_seconds

from rough_viewer.grid.variogram import face_semivariogram, semivariogram


def face_cells(n_cells: int, g: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    x = (np.arange(int(90 / g)) + 0.5) * g
    z = (np.arange(int(10 / g)) + 0.5) * g
    xx, zz = np.meshgrid(x, z, indexing="ij")
    y = 0.6 * np.sin(xx / 7.0) + 0.3 * np.sin(zz / 1.7) + 0.05 * rng.normal(size=xx.shape)
    ijk = np.column_stack([
        np.floor(xx.ravel() / g), np.floor((y.ravel() + 1.0) / g), np.floor(zz.ravel() / g)
    ]).astype(np.int64)
    ijk = np.unique(ijk, axis=0)
    keep = rng.choice(len(ijk), size=min(n_cells, len(ijk)), replace=False)
    ijk = ijk[np.sort(keep)]
    values = np.abs(rng.normal(0.007, 0.006, size=len(ijk)))
    return ijk, values


def median_time(fn, runs: int) -> float:
    return median_seconds(fn, runs, warm_up=True)[0]  # warm-up: plans, caches


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=7)
    parser.add_argument("--cells", type=int, default=50_000)
    parser.add_argument("--grid", type=float, default=0.125)
    args = parser.parse_args()
    g = args.grid
    ijk, values = face_cells(args.cells, g)
    shape = tuple(int(s) for s in ijk.max(axis=0) - ijk.min(axis=0) + 1)
    print(f"{len(values)} cells, occupied bounding box {shape} cells of {g} m")
    vg = semivariogram(ijk, values, g)
    print(f"3-D: {len(vg.lag)} bins up to {vg.lag[-1]:.3f} m, {int(vg.pairs.sum())} pairs")
    t3 = median_time(lambda: semivariogram(ijk, values, g), args.runs)
    print(f"3-D semivariogram: median {t3:.3f} s over {args.runs} runs")
    centres = (ijk + 0.5) * g
    plane = SimpleNamespace(centroid=centres.mean(axis=0), normal=np.array([0.0, 1.0, 0.0]))
    t2 = median_time(lambda: face_semivariogram(centres, values, g, plane), args.runs)
    print(f"face-plane semivariogram: median {t2:.3f} s over {args.runs} runs")


if __name__ == "__main__":
    main()
