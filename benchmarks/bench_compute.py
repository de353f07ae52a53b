"""Benchmark of the compute core: grid roughness stages on synthetic outcrops, and
LAS/LAZ read rates.

Prints, for each N and grid size, the median over ``--repeat`` runs of each stage
(cell keys, moments, plane fits, distances), points per second, and the peak memory
allocated during the computation beyond the input coordinates (numpy allocations,
measured with tracemalloc in a separate run so timings are not slowed).

    python benchmarks/bench_compute.py                     # 1M, 5M, 20M points
    python benchmarks/bench_compute.py --sizes 1e6 --repeat 3 --no-io
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rough_viewer.grid.roughness import grid_roughness  # noqa: E402
from rough_viewer.io import PointCloud, load_points, write_las  # noqa: E402

STAGES = ("cell keys", "moments", "plane fits", "distances")


def synthetic_outcrop(n: int, seed: int = 0, *, order: str = "scan") -> PointCloud:
    """A 90 m x 10 m vertical face parallel to xz in UTM-sized coordinates: rolling
    relief, column fractures every ~1.5 m and 4 mm range noise.

    ``order="scan"`` stores the points as a terrestrial scanner does, in vertical scan
    columns (neighbours in the file are neighbours on the face); ``"random"`` shuffles
    them, the worst case for memory locality."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.0, 90.0, n)
    z = rng.uniform(0.0, 10.0, n)
    y = 0.3 * np.sin(x / 7.0) * np.cos(z / 3.0) + 0.05 * np.sin(1.7 * x + 0.8 * z)
    frac = np.abs(((x + 0.2 * np.sin(z)) % 1.5) - 0.75) < 0.04
    y += np.where(frac, -0.08, 0.0) + rng.normal(0.0, 0.004, n)
    if order == "scan":
        o = np.lexsort((z, np.floor(x / 0.05)))
        x, y, z = x[o], y[o], z[o]
    return PointCloud(x=x + 512_000.0, y=y + 4_765_000.0, z=z + 1_200.0)


def time_stages(cloud: PointCloud, g: float) -> tuple[float, list[float]]:
    marks: list[float] = []

    def tick(done: int, total: int) -> None:
        marks.append(time.perf_counter())

    t0 = time.perf_counter()
    grid_roughness(cloud, g, progress=tick)
    total = time.perf_counter() - t0
    stages = [marks[i + 1] - marks[i] for i in range(4)]
    return total, stages


def peak_bytes(cloud: PointCloud, g: float) -> int:
    tracemalloc.start()
    tracemalloc.reset_peak()
    base = tracemalloc.get_traced_memory()[0]
    res = grid_roughness(cloud, g)
    peak = tracemalloc.get_traced_memory()[1] - base
    tracemalloc.stop()
    del res
    return peak


def bench_grid(sizes: list[int], grids: list[float], repeat: int, order: str) -> None:
    print(f"grid roughness, all three models; median of {repeat} runs; {os.cpu_count()} cores; "
          f"points in {order} order")
    head = f"{'N':>11} {'g (m)':>6} {'cells':>9} " + " ".join(f"{s:>11}" for s in STAGES)
    head += f" {'total s':>8} {'Mpts/s':>7} {'peak B/pt':>9}"
    print(head)
    for n in sizes:
        cloud = synthetic_outcrop(n, order=order)
        for g in grids:
            runs = [time_stages(cloud, g) for _ in range(repeat)]
            total = statistics.median(r[0] for r in runs)
            stages = [statistics.median(r[1][i] for r in runs) for i in range(4)]
            cells = grid_roughness(cloud, g).n_cells
            peak = peak_bytes(cloud, g)
            print(f"{n:>11,} {g:>6g} {cells:>9,} " + " ".join(f"{s:>10.3f}s" for s in stages)
                  + f" {total:>8.3f} {n / total / 1e6:>7.2f} {peak / n:>9.1f}", flush=True)
        del cloud


def bench_io(n: int, repeat: int) -> None:
    cloud = synthetic_outcrop(n)
    print(f"\nread rates, {n:,} points, median of {repeat} runs")
    with tempfile.TemporaryDirectory() as tmp:
        os.environ["ROUGH_VIEWER_CACHE"] = str(Path(tmp) / "cache")
        for suffix in (".las", ".laz"):
            path = Path(tmp) / f"bench{suffix}"
            write_las(path, cloud)
            size = path.stat().st_size
            times = []
            for _ in range(repeat):
                t = time.perf_counter()
                load_points(path, cache=False)
                times.append(time.perf_counter() - t)
            med = statistics.median(times)
            print(f"{suffix}: {size / n:5.1f} B/pt on disk, read {med:.2f} s = {n / med / 1e6:.2f} M pts/s")
            if suffix == ".laz":
                load_points(path)  # fills the cache
                times = []
                for _ in range(repeat):
                    t = time.perf_counter()
                    load_points(path)
                    times.append(time.perf_counter() - t)
                med = statistics.median(times)
                print(f".laz, cached decode: read {med:.3f} s = {n / med / 1e6:.1f} M pts/s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", nargs="+", type=float, default=[1e6, 5e6, 2e7])
    ap.add_argument("--grids", nargs="+", type=float, default=[1.0, 0.5, 0.25, 0.125])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--io-points", type=float, default=5e6)
    ap.add_argument("--no-io", action="store_true")
    ap.add_argument("--order", choices=("scan", "random"), default="scan")
    args = ap.parse_args()
    bench_grid([int(s) for s in args.sizes], args.grids, args.repeat, args.order)
    if not args.no_io:
        bench_io(int(args.io_points), max(3, args.repeat // 2))


if __name__ == "__main__":
    main()
