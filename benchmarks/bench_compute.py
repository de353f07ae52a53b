"""Benchmark of the compute core: grid roughness stages on synthetic outcrops, the
whole ``rough-viewer compute`` process against a plain NumPy bincount pipeline, and
LAS/LAZ read rates.

Prints, for each engine (numba, the NumPy reference), N and grid size, the median
over ``--repeat`` runs of each stage (cell keys + moments, plane fits, distances,
assembly), points per second, and the peak memory allocated during the computation
beyond the input coordinates (numpy allocations, measured with tracemalloc in a
separate run so timings are not slowed). Then coarser presets from a fine grid's
sums against the same grids from the points, ``load_points`` of a ``--whole-points``
.npy in-process, and for that .npy the median wall time of whole processes:
``rough-viewer compute`` with each engine and :func:`plain_pipeline` (the same
numbers with nothing but NumPy bincounts), and their ratio.

    flock /tmp/rough_viewer_heavy.lock python benchmarks/bench_compute.py --sizes 2e7 --grids 0.25 --no-io
    python benchmarks/bench_compute.py                     # 1M, 5M, 20M points, 4 grids
    python benchmarks/bench_compute.py --sizes 1e6 --repeat 3 --no-io --no-whole
"""

from __future__ import annotations

import argparse
import csv
import os
import statistics
import subprocess
import sys
import tempfile
import time
import tracemalloc
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rough_viewer.grid.roughness import (  # noqa: E402
    coarsen_prepared,
    grid_roughness,
    prepare_grid,
)
from rough_viewer.io import PointCloud, load_points, write_las  # noqa: E402

STAGES = ("keys+moments", "plane fits", "distances", "assembly")


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


def time_stages(cloud: PointCloud, g: float, engine: str) -> tuple[float, list[float]]:
    marks: list[float] = []

    def tick(done: int, total: int) -> None:
        marks.append(time.perf_counter())

    t0 = time.perf_counter()
    grid_roughness(cloud, g, progress=tick, engine=engine)  # type: ignore[arg-type]
    total = time.perf_counter() - t0
    stages = [marks[i + 1] - marks[i] for i in range(4)]
    return total, stages


def peak_bytes(cloud: PointCloud, g: float, engine: str) -> int:
    tracemalloc.start()
    tracemalloc.reset_peak()
    base = tracemalloc.get_traced_memory()[0]
    res = grid_roughness(cloud, g, engine=engine)  # type: ignore[arg-type]
    peak = tracemalloc.get_traced_memory()[1] - base
    tracemalloc.stop()
    del res
    return peak


def bench_grid(sizes: list[int], grids: list[float], repeat: int, order: str,
               engines: list[str]) -> None:
    print(f"grid roughness in-process, all three models; median of {repeat} runs; "
          f"{os.cpu_count()} cores; points in {order} order")
    head = (f"{'engine':>6} {'N':>11} {'g (m)':>6} {'cells':>9} "
            + " ".join(f"{s:>12}" for s in STAGES))
    head += f" {'total s':>8} {'Mpts/s':>7} {'peak B/pt':>9}"
    print(head)
    for n in sizes:
        cloud = synthetic_outcrop(n, order=order)
        for engine in engines:
            # compile (or load) the kernels before timing
            grid_roughness(synthetic_outcrop(1000), 1.0, engine=engine)  # type: ignore[arg-type]
            for g in grids:
                runs = [time_stages(cloud, g, engine) for _ in range(repeat)]
                total = statistics.median(r[0] for r in runs)
                stages = [statistics.median(r[1][i] for r in runs) for i in range(4)]
                cells = grid_roughness(cloud, g, engine=engine).n_cells  # type: ignore[arg-type]
                peak = peak_bytes(cloud, g, engine)
                print(f"{engine:>6} {n:>11,} {g:>6g} {cells:>9,} "
                      + " ".join(f"{s:>11.3f}s" for s in stages)
                      + f" {total:>8.3f} {n / total / 1e6:>7.2f} {peak / n:>9.1f}", flush=True)
        del cloud


def bench_presets(n: int, fine: float, factors: list[int], repeat: int) -> None:
    """A coarser preset from the finest one's partial sums (:func:`coarsen_prepared`,
    the distance pass the only one over the points) against the same grid computed
    from the points, in-process, numba, warm."""
    print(f"\npresets from a {fine:g} m grid's sums, {n:,} points, all models; median of "
          f"{repeat} runs")
    cloud = synthetic_outcrop(n)
    prep = prepare_grid(cloud, fine)
    grid_roughness(cloud, fine * factors[0], prepared=coarsen_prepared(prep, factors[0]))
    for k in factors:
        g = fine * k
        coarse = [_timed(lambda k=k, g=g: grid_roughness(cloud, g,
                                                         prepared=coarsen_prepared(prep, k)))
                  for _ in range(repeat)]
        direct = [_timed(lambda g=g: grid_roughness(cloud, g)) for _ in range(repeat)]
        print(f"  {g:g} m: from the {fine:g} m sums {statistics.median(coarse):.3f} s, from the "
              f"points {statistics.median(direct):.3f} s")


def _timed(run: Callable[[], object]) -> float:
    t = time.perf_counter()
    run()
    return time.perf_counter() - t


def bench_load(n: int, repeat: int) -> None:
    """``load_points`` of an .npy in this process (page cache warm): the file read
    once, split into columns, checked and its bounds noted on the way."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "cloud.npy"
        np.save(path, synthetic_outcrop(n).xyz())
        load_points(path)
        times = [_timed(lambda: load_points(path)) for _ in range(repeat)]
    print(f"\nload_points of a {n:,}-point .npy (in-process, warm page cache): median "
          f"{statistics.median(times):.3f} s of {repeat} (min {min(times):.3f} s)")


def plain_pipeline(path: str, g: float, out: str) -> None:
    """The same per-cell roughness (ODR, OLS along the auto axis, hybrid) with nothing
    but NumPy: keys, ``np.unique``, weighted ``np.bincount`` sums, batched ``eigh``,
    and a CSV. The whole-process yardstick of the compute core."""
    xyz = np.load(path)
    lo = xyz.min(axis=0)
    ijk = np.floor((xyz - lo) / g).astype(np.int64)
    dims = ijk.max(axis=0) + 1
    keys = (ijk[:, 2] * dims[1] + ijk[:, 1]) * dims[0] + ijk[:, 0]
    cells, inv, counts = np.unique(keys, return_inverse=True, return_counts=True)
    m = cells.shape[0]
    centre = lo + (np.stack([cells % dims[0], cells // dims[0] % dims[1],
                             cells // (dims[0] * dims[1])], axis=1) + 0.5) * g
    local = xyz - centre[inv]
    s1 = np.stack([np.bincount(inv, local[:, a], m) for a in range(3)], axis=1)
    s2 = np.empty((m, 3, 3))
    for a in range(3):
        for b in range(a, 3):
            s2[:, a, b] = s2[:, b, a] = np.bincount(inv, local[:, a] * local[:, b], m)
    n = counts.astype(float)
    mean = s1 / n[:, None]
    cov = s2 / n[:, None, None] - mean[:, :, None] * mean[:, None, :]
    w, v = np.linalg.eigh(cov)
    normal = v[:, :, 0]
    d0 = xyz - xyz.mean(axis=0)
    axis = int(np.argmax(np.abs(np.linalg.eigh(d0.T @ d0)[1][:, 0])))
    u, vv = [i for i in range(3) if i != axis]
    det = cov[:, u, u] * cov[:, vv, vv] - cov[:, u, vv] ** 2
    safe = np.where(det > 0, det, 1.0)
    wols = np.zeros((m, 3))
    wols[:, axis] = 1.0
    wols[:, u] = -(cov[:, vv, vv] * cov[:, u, axis] - cov[:, u, vv] * cov[:, vv, axis]) / safe
    wols[:, vv] = -(cov[:, u, u] * cov[:, vv, axis] - cov[:, u, vv] * cov[:, u, axis]) / safe
    theta = {}
    for name, vec in (("odr", normal), ("ols", wols)):
        d = np.einsum("ij,ij->i", local - mean[inv], vec[inv])
        ma = np.bincount(inv, np.abs(d), m) / n
        ms = np.bincount(inv, d * d, m) / n
        theta[name] = np.sqrt(np.clip(ms - ma * ma, 0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        theta["hybrid"] = theta["odr"] / np.abs(normal[:, axis])
    ok = counts >= 3
    with open(out, "w", newline="") as fh:
        wr = csv.writer(fh)
        wr.writerow(["cx", "cy", "cz", "n_points", "theta_odr", "theta_ols", "theta_hybrid"])
        wr.writerows(zip(*(c[ok].tolist() for c in (centre[:, 0], centre[:, 1], centre[:, 2],
                                                      counts, theta["odr"], theta["ols"],
                                                      theta["hybrid"])), strict=True))


def _wall(argv: list[str], env: dict[str, str], warm: str | None = None) -> float:
    """Wall time of one process; ``warm``: a file read first (untimed), so every row
    finds it in the page cache (the plain pipeline's temporaries evict it)."""
    if warm is not None:
        with open(warm, "rb") as fh:
            while fh.read(1 << 24):
                pass
    t = time.perf_counter()
    subprocess.run(argv, env=env, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t


def bench_whole_process(n: int, g: float, repeat: int) -> None:
    """Whole processes on the same .npy: rough-viewer compute (numba, numpy) and the
    plain NumPy pipeline."""
    print(f"\nwhole process, {n:,} points (.npy), grid {g:g} m, all three models; median of "
          f"{repeat} runs")
    with tempfile.TemporaryDirectory() as tmp:
        path = str(Path(tmp) / "cloud.npy")
        np.save(path, synthetic_outcrop(n).xyz())
        out = str(Path(tmp) / "cells.csv")
        rv = [sys.executable, "-m", "rough_viewer", "compute", path, "--grid", str(g),
              "--out", out, "--force", "--quiet"]
        plain = [sys.executable, __file__, "--plain-pipeline", path, str(g), out]
        rows = [("rough-viewer compute (default)", rv, {}),
                ("rough-viewer compute, numba", rv, {"ROUGH_VIEWER_ENGINE": "numba"}),
                ("rough-viewer compute, numpy", rv, {"ROUGH_VIEWER_ENGINE": "numpy"}),
                ("plain NumPy bincount pipeline", plain, {})]
        walls: dict[str, list[float]] = {label: [] for label, _, _ in rows}
        clean = {k: v for k, v in os.environ.items() if k != "ROUGH_VIEWER_ENGINE"}
        for _label, argv, extra in rows:
            _wall(argv, dict(clean, **extra))  # warm the page cache and numba's disk cache
        for _ in range(repeat):  # alternating, so a busy spell falls on every row alike
            for label, argv, extra in rows:
                walls[label].append(_wall(argv, dict(clean, **extra), warm=path))
        medians = {label: statistics.median(w) for label, w in walls.items()}
        base = medians["plain NumPy bincount pipeline"]
        for label, t in medians.items():
            print(f"{label:<32} {t:7.2f} s   ratio {t / base:.2f}")


#: One fresh process: import, read the .npy, then the first grid_roughness call and
#: the warm ones (``preload`` starts loading the kernels before the read, as the
#: command line does). Prints JSON.
_FIRST_CALL = """
import json, sys, time
t0 = time.perf_counter()
import rough_viewer
from rough_viewer.grid import fast
if {preload}:
    fast.preload()
cloud = rough_viewer.load_points(sys.argv[1])
t1 = time.perf_counter()
rough_viewer.grid_roughness(cloud, float(sys.argv[2]))
t2 = time.perf_counter()
warm = []
for _ in range(5):
    t = time.perf_counter()
    rough_viewer.grid_roughness(cloud, float(sys.argv[2]))
    warm.append(time.perf_counter() - t)
print(json.dumps({{"load": t1 - t0, "first": t2 - t1, "warm": sorted(warm)[2]}}))
"""


def bench_first_call(n: int, g: float, repeat: int) -> None:
    """In-process grid_roughness, first call of a process and warm, and
    ``import rough_viewer; load_points(npy)``, each in fresh processes."""
    import json

    print(f"\n{n:,} points (.npy), grid {g:g} m, all models, default engine; median of "
          f"{repeat} fresh processes")
    with tempfile.TemporaryDirectory() as tmp:
        path = str(Path(tmp) / "cloud.npy")
        np.save(path, synthetic_outcrop(n).xyz())
        for preload in (False, True):
            code = _FIRST_CALL.format(preload=preload)
            argv = [sys.executable, "-c", code, path, str(g)]
            subprocess.run(argv, check=True, capture_output=True)  # page cache, numba cache
            runs = [json.loads(subprocess.run(argv, check=True, capture_output=True,
                                              text=True).stdout) for _ in range(repeat)]
            med = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
            how = "kernels preloaded during the read" if preload else "no preload"
            print(f"  {how:<34} import + load_points {med['load']:.3f} s   grid_roughness "
                  f"first {med['first']:.3f} s, warm {med['warm']:.3f} s "
                  f"(first / warm {med['first'] / med['warm']:.2f})")


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
    ap.add_argument("--engines", nargs="+", default=["numba", "numpy"])
    ap.add_argument("--whole-points", type=float, default=2e7)
    ap.add_argument("--whole-grid", type=float, default=0.25)
    ap.add_argument("--no-whole", action="store_true")
    ap.add_argument("--preset-fine", type=float, default=0.0625,
                    help="finest preset grid the coarser ones are derived from (m)")
    ap.add_argument("--no-presets", action="store_true")
    ap.add_argument("--no-first", action="store_true",
                    help="skip the first-call and load_points timings")
    ap.add_argument("--plain-pipeline", nargs=3, metavar=("NPY", "G", "OUT"),
                    help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.plain_pipeline:
        plain_pipeline(args.plain_pipeline[0], float(args.plain_pipeline[1]),
                       args.plain_pipeline[2])
        return
    print(f"load average: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    bench_grid([int(s) for s in args.sizes], args.grids, args.repeat, args.order, args.engines)
    if not args.no_presets:
        bench_presets(int(args.whole_points), args.preset_fine, [2, 4, 8], args.repeat)
    bench_load(int(args.whole_points), args.repeat)
    if not args.no_first:
        bench_first_call(int(args.whole_points), args.whole_grid, args.repeat)
    if not args.no_whole:
        bench_whole_process(int(args.whole_points), args.whole_grid, args.repeat)
    print(f"load average: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    if not args.no_io:
        bench_io(int(args.io_points), max(3, args.repeat // 2))


if __name__ == "__main__":
    main()
