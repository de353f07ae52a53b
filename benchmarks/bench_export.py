"""Exports of ``rough-viewer compute``: seconds, file size and peak memory of each output
(LAS, LAZ, PLY, CSV, Parquet) for one cloud and grid size.

    PYTHONPATH=. python benchmarks/bench_export.py [INPUT] [--grid 2] [--repeat 3]
    PYTHONPATH=. python benchmarks/bench_export.py --synthetic 8000000 --grid 1

Each output is written ``--repeat`` times in a fresh process (median seconds shown);
"peak +MiB" is how far the process's peak resident memory rose above its peak after
reading and gridding, i.e. what the export itself needed at most. The LAS/LAZ copy
streams in chunks of 1 M points, so its figure should not grow with the cloud.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

FORMATS = ("las", "laz", "ply", "csv", "parquet")

CHILD = r"""
import json, resource, sys, time
from pathlib import Path
from rough_viewer.io import load_points
from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.grid.table import cell_columns, point_fields
from rough_viewer.io.formats.las_out import write_las_fields
from rough_viewer.io.formats.ply import write_ply_fields
from rough_viewer.io.table import write_table

src, grid, fmt, out = sys.argv[1], float(sys.argv[2]), sys.argv[3], Path(sys.argv[4])
cloud = load_points(src, cache=False)
result = grid_roughness(cloud, grid)
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
t = time.perf_counter()
if fmt in ("las", "laz"):
    write_las_fields(out, cloud, point_fields(result))
elif fmt == "ply":
    write_ply_fields(out, cloud, point_fields(result))
else:
    write_table(out, cell_columns(result))
seconds = time.perf_counter() - t
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps({"seconds": seconds, "peak_rise_kib": peak - base, "base_kib": base,
                  "bytes": out.stat().st_size, "points": cloud.n}))
"""


def synthetic_las(path: Path, n: int) -> None:
    """A LAS 1.2 point format 3 file of ``n`` points of a rough hillslope (2 cm noise)."""
    import laspy
    import numpy as np

    rng = np.random.default_rng(0)
    side = np.sqrt(n / 8.0)  # about 8 points per square metre, as airborne lidar
    header = laspy.LasHeader(version="1.2", point_format=3)
    header.scales = np.array([0.01, 0.01, 0.01])
    header.offsets = np.array([238_000.0, 3_765_000.0, 0.0])
    with laspy.open(path, mode="w", header=header) as writer:
        for start in range(0, n, 1_000_000):
            m = min(1_000_000, n - start)
            rec = laspy.ScaleAwarePointRecord.zeros(m, header=header)
            x = rng.uniform(0, side, m)
            y = rng.uniform(0, side, m)
            rec.x = 238_000.0 + x
            rec.y = 3_765_000.0 + y
            rec.z = 250.0 + 0.1 * x + 5.0 * np.sin(y / 20.0) + rng.normal(0, 0.02, m)
            rec.intensity = rng.integers(0, 4000, m)
            rec.gps_time = start + np.arange(m) * 1e-5
            rec.red = rng.integers(0, 65535, m)
            writer.write_points(rec)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("input", nargs="?")
    ap.add_argument("--synthetic", type=int, metavar="N", help="make a LAS of N points instead")
    ap.add_argument("--grid", type=float, default=2.0)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--formats", default=",".join(FORMATS))
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        src = args.input
        if args.synthetic:
            src = str(Path(tmp) / f"synthetic_{args.synthetic}.las")
            synthetic_las(Path(src), args.synthetic)
        if not src:
            ap.error("give INPUT or --synthetic N")
        print(f"{Path(src).name}: {Path(src).stat().st_size / 2**20:.1f} MiB, grid {args.grid:g} m")
        print(f"{'output':8} {'median s':>9} {'size MiB':>9} {'peak +MiB':>10} {'base MiB':>9}")
        for fmt in args.formats.split(","):
            runs = []
            for i in range(args.repeat):
                out = Path(tmp) / f"out{i}.{fmt}"
                done = subprocess.run([sys.executable, "-c", CHILD, src, str(args.grid), fmt,
                                       str(out)], capture_output=True, text=True, check=True)
                runs.append(json.loads(done.stdout.strip().splitlines()[-1]))
                out.unlink()
            med = statistics.median(r["seconds"] for r in runs)
            rise = max(r["peak_rise_kib"] for r in runs) / 1024
            print(f"{fmt:8} {med:9.2f} {runs[0]['bytes'] / 2**20:9.1f} {rise:10.0f} "
                  f"{runs[0]['base_kib'] / 1024:9.0f}")


if __name__ == "__main__":
    main()
