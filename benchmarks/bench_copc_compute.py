"""Benchmark of issue 33's compute targets: ``rough-viewer compute`` on one COPC file
(read by tiles, each point decoded once) against ``compute`` on the LAZ scans it was
indexed from (streamed: decoded once into the decode cache, read again from it), both
under ``--memory``; then the COPC run on Dask (``--scheduler processes``) with 1, 2, ...
workers.

Writes the synthetic outcrop of bench_compute.py as ``--files`` LAZ files (or reuses
``--data DIR``), indexes them once with ``rough-viewer index`` (timed, once), then runs
each configuration ``--repeat`` times in child processes and prints medians of wall
time, points per second, CPU time and peak RSS, and whether the cells equal the LAZ
run's. The LAZ run starts from an empty decode cache every time (a first run, as the
COPC run is).

    flock /tmp/rough_viewer_heavy.lock python benchmarks/bench_copc_compute.py
    python benchmarks/bench_copc_compute.py --points 2e6 --files 3 --repeat 1   # quick look
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_scale import RV, compare, make_files, run  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--points", type=float, default=2e7)
    ap.add_argument("--files", type=int, default=10)
    ap.add_argument("--grid", type=float, default=0.25)
    ap.add_argument("--memory", default="1GB")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--data", type=Path, help="folder for the LAZ and COPC files (kept)")
    args = ap.parse_args()
    n = int(args.points)
    tmp = Path(tempfile.mkdtemp(prefix="rv-bench-copc-"))
    data = args.data or tmp / "data"
    data.mkdir(parents=True, exist_ok=True)
    try:
        paths = make_files(data, n, args.files)
        copc = data / "campaign.copc.laz"
        env0 = dict(os.environ, ROUGH_VIEWER_CACHE=str(tmp / "cache-index"))
        if not copc.exists():
            wall, peak, _ = run([*RV, "index", *map(str, paths), "--out", str(copc),
                                 "--memory", args.memory, "--quiet"], env0)
            print(f"index: {wall:.1f} s, peak RSS {peak / 2**30:.2f} G")
        size = sum(p.stat().st_size for p in paths)
        print(f"{n:,} points in {len(paths)} LAZ files ({size / 1e6:.0f} MB) and one COPC file "
              f"({copc.stat().st_size / 1e6:.0f} MB), grid {args.grid} m, {os.cpu_count()} "
              f"cores; median of {args.repeat} runs; load average before: "
              f"{' '.join(f'{v:.2f}' for v in os.getloadavg())}")
        mem = ["--memory", args.memory]
        tail = ["--grid", str(args.grid), "--quiet", "--force"]
        configs: list[tuple[str, list[str]]] = [
            (f"{len(paths)} LAZ files --memory {args.memory}", [*map(str, paths), *mem]),
            (f"COPC --memory {args.memory}", [str(copc), *mem]),
        ]
        for w in args.workers:
            configs.append((f"COPC --memory {args.memory} --scheduler processes --workers {w}",
                            [str(copc), *mem, "--scheduler", "processes", "--workers", str(w)]))
        print(f"{'configuration':<58} {'wall s':>7} {'Mpts/s':>7} {'CPU s':>6} {'peak RSS':>9}"
              "  cells")
        ref = None
        times: dict[str, float] = {}
        for i, (label, argv) in enumerate(configs):
            out = tmp / f"cells-{i}.csv"
            cache = tmp / f"cache-{i}"
            env = dict(os.environ, ROUGH_VIEWER_CACHE=str(cache))
            walls, peaks, cpus = [], [], []
            for _ in range(args.repeat):
                shutil.rmtree(cache, ignore_errors=True)
                wall, peak, cpu = run([*RV, "compute", *argv, *tail, "--out", str(out)], env)
                walls.append(wall)
                peaks.append(peak)
                cpus.append(cpu)
            times[label] = statistics.median(walls)
            verdict = "reference" if ref is None else compare(ref, out)
            ref = ref or out
            print(f"{label:<58} {times[label]:>7.2f} {n / times[label] / 1e6:>7.2f} "
                  f"{statistics.median(cpus):>6.1f} {max(peaks) / 2**30:>7.2f} G  {verdict}",
                  flush=True)
        laz, one = times[configs[0][0]], times[configs[1][0]]
        print(f"\nCOPC / LAZ files: {one / laz:.2f}x (target 0.6x)")
        dask = [times[c[0]] for c in configs[2:]]
        for w, t in zip(args.workers[1:], dask[1:], strict=False):
            print(f"Dask {w} workers / 1 worker: {t / dask[0]:.2f}x "
                  f"(target 0.65x for 2 on 2 idle cores)")
        print(f"load average after: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
