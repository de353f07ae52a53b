"""Benchmark of campaign-scale runs (issue 16 "Targets"): several LAZ files streamed
under a memory budget, and on Dask with 1, 2, ... workers, against the in-memory path.

Writes a synthetic outcrop (the same as bench_compute.py) as ``--files`` LAZ files
into a temporary folder (or ``--data DIR``, kept for re-runs), then runs
``rough-viewer compute`` on them in child processes, each configuration
``--repeat`` times, and prints medians of wall time, points per second and peak
resident memory (the child's ``ru_maxrss``), and whether the cells are identical.

    flock /tmp/rough_viewer_heavy.lock python benchmarks/bench_scale.py
    python benchmarks/bench_scale.py --points 2e6 --files 3 --repeat 1   # quick look

Both the in-memory and the streamed path read LAZ through the decode cache (the
streamed path fills it during its first pass); each is measured cold (an empty
cache folder every run, as on a first open) and warm (cache filled beforehand).
Dask runs (``--scheduler processes --workers W``) are measured cold: the workers
decode every chunk of both passes; their rows give points per second against the
worker count, and the cells must be the same bits for every count.
"""

from __future__ import annotations

import argparse
import csv
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_compute import synthetic_outcrop  # noqa: E402

from rough_viewer.io import PointCloud, write_las  # noqa: E402

RV = [sys.executable, "-m", "rough_viewer"]


def make_files(folder: Path, n: int, n_files: int) -> list[Path]:
    """``n`` points of the synthetic outcrop, in scan order, cut into ``n_files`` LAZ files
    along the face (neighbouring files share cells at their seams). Written by a child
    process, so this one stays small."""
    paths = [folder / f"scan{i:02d}.laz" for i in range(n_files)]
    if all(p.exists() for p in paths):
        return paths
    subprocess.run([sys.executable, __file__, "--write-files", str(folder), str(n), str(n_files)],
                   check=True)
    return paths


def _write_files(folder: Path, n: int, n_files: int) -> None:
    paths = [folder / f"scan{i:02d}.laz" for i in range(n_files)]
    cloud = synthetic_outcrop(n)
    edges = np.linspace(0, n, n_files + 1).astype(int)
    for p, a, b in zip(paths, edges[:-1], edges[1:], strict=True):
        write_las(p, PointCloud(x=cloud.x[a:b], y=cloud.y[a:b], z=cloud.z[a:b]))


def run(argv: list[str], env: dict[str, str]) -> tuple[float, float, float]:
    """Wall time (s), peak RSS (bytes) and CPU time (s, user + system, the child's
    own worker processes included) of one child process.

    The peak is GNU time's ``%M`` where ``/usr/bin/time`` exists: a child forked
    from this (large) process would inherit its high-water mark in ``ru_maxrss``."""
    timer = shutil.which("time") or ("/usr/bin/time" if Path("/usr/bin/time").exists() else None)
    cmd = [timer, "-f", "RV_MAXRSS_KB=%M", *argv] if timer else argv
    t = time.perf_counter()
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode() if proc.stderr else ""
    if proc.returncode != 0:
        raise SystemExit(f"failed ({proc.returncode}): {' '.join(argv)}\n{err}")
    peak = usage.ru_maxrss * 1024.0
    for line in err.splitlines():
        if line.startswith("RV_MAXRSS_KB="):
            peak = float(line.split("=", 1)[1]) * 1024.0
    return wall, peak, usage.ru_utime + usage.ru_stime


def read_cells(path: Path) -> tuple[np.ndarray, np.ndarray]:
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))[1:]
    keys = np.array([[int(r[i]) for i in (0, 1, 2, 6)] for r in rows])
    vals = np.array([[float(v) if v else np.nan for v in r[7:11]] for r in rows])
    return keys, vals


def compare(a: Path, b: Path) -> str:
    ka, va = read_cells(a)
    kb, vb = read_cells(b)
    if ka.shape != kb.shape or not np.array_equal(ka, kb):
        return "DIFFERENT CELLS"
    if not np.array_equal(np.isnan(va), np.isnan(vb)):
        return "different NaNs"
    ok = ~np.isnan(va[:, :3]) & (va[:, :3] > 0)
    rel = np.abs(va[:, :3][ok] - vb[:, :3][ok]) / np.abs(va[:, :3][ok])
    worst = float(rel.max()) if rel.size else 0.0
    return "identical" if worst == 0.0 else f"same cells, max rel diff {worst:.1e}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--points", type=float, default=3e7)
    ap.add_argument("--files", type=int, default=6)
    ap.add_argument("--grid", type=float, default=0.25)
    ap.add_argument("--memory", default="1GB")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--data", type=Path, help="folder for the LAZ files (kept)")
    ap.add_argument("--write-files", nargs=3, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.write_files:
        _write_files(Path(args.write_files[0]), int(args.write_files[1]), int(args.write_files[2]))
        return
    n = int(args.points)
    tmp = Path(tempfile.mkdtemp(prefix="rv-bench-scale-"))
    data = args.data or tmp / "data"
    data.mkdir(parents=True, exist_ok=True)
    try:
        t = time.perf_counter()
        paths = make_files(data, n, args.files)
        size = sum(p.stat().st_size for p in paths)
        print(f"{n:,} points in {len(paths)} LAZ files ({size / 1e6:.0f} MB), grid {args.grid} m, "
              f"{os.cpu_count()} cores; data ready in {time.perf_counter() - t:.0f} s; "
              f"median of {args.repeat} runs; load average before: "
              f"{' '.join(f'{v:.2f}' for v in os.getloadavg())}")
        base = [*RV, "compute", *map(str, paths), "--grid", str(args.grid), "--quiet", "--force"]
        mem = ["--memory", args.memory]
        configs: list[tuple[str, list[str], str]] = [
            ("in memory", [], "cold"),
            ("in memory", [], "warm"),
            (f"--memory {args.memory}", mem, "cold"),
            (f"--memory {args.memory}", mem, "warm"),
        ]
        for w in args.workers:
            configs.append((f"--memory {args.memory} --scheduler processes --workers {w}",
                            [*mem, "--scheduler", "processes", "--workers", str(w)], "cold"))
        print(f"{'configuration':<50} {'cache':>5} {'wall s':>7} {'Mpts/s':>7} {'CPU s':>6} "
              f"{'peak RSS':>9}  cells")
        ref_out = None
        dask_ref: Path | None = None
        times: dict[tuple[str, str], float] = {}
        for label, extra, cache_mode in configs:
            out = tmp / f"cells-{len(times)}.csv"
            cache = tmp / f"cache-{len(times)}"
            argv = [*base, *extra, "--out", str(out)]
            env = dict(os.environ, ROUGH_VIEWER_CACHE=str(cache))
            if cache_mode == "warm":
                run(argv, env)  # fills the cache
            walls, peaks, cpus = [], [], []
            for _ in range(args.repeat):
                if cache_mode == "cold":
                    shutil.rmtree(cache, ignore_errors=True)
                wall, peak, cpu = run(argv, env)
                walls.append(wall)
                peaks.append(peak)
                cpus.append(cpu)
            wall = statistics.median(walls)
            times[(label, cache_mode)] = wall
            verdict = "reference" if ref_out is None else compare(ref_out, out)
            ref_out = ref_out or out
            if "--scheduler" in extra:  # every worker count: the same bits as the first
                if dask_ref is None:
                    dask_ref = out
                else:
                    same = compare(dask_ref, out)
                    verdict += "; " + ("same bits as the first Dask row" if same == "identical"
                                       else f"vs the first Dask row: {same}")
            print(f"{label:<50} {cache_mode:>5} {wall:>7.2f} {n / wall / 1e6:>7.2f} "
                  f"{statistics.median(cpus):>6.1f} {max(peaks) / 2**30:>7.2f} G  {verdict}",
                  flush=True)
        for mode in ("cold", "warm"):
            ratio = times[(f"--memory {args.memory}", mode)] / times[("in memory", mode)]
            print(f"\n--memory {args.memory} / in memory, {mode} cache: {ratio:.2f}x", end="")
        print()
        print(f"load average after: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
