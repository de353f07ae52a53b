"""Benchmark of roughness by direction (issue 25) on the bundled 2 M-point outcrop:
medians of several runs of each stage, and the peak memory of the process.

    python benchmarks/bench_directions.py                 # the whole outcrop, 3 runs
    python benchmarks/bench_directions.py --points 200000 --repeat 5
"""

from __future__ import annotations

import argparse
import resource
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rough_viewer.demo_data import __file__ as _demo  # noqa: E402
from timing import median_seconds  # noqa: E402

from rough_viewer.grid.planes import whole_cloud_plane  # noqa: E402
from rough_viewer.io import PointCloud, load_points  # noqa: E402
from rough_viewer.profiles.profile_sets import profile_sets  # noqa: E402
from rough_viewer.tin import (  # noqa: E402
    azimuths,
    directional_roughness,
    triangulate_cloud,
    window_roughness,
)


def timed(fn, repeat: int):
    return median_seconds(fn, repeat)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--points", type=int, default=0, help="use this many points (0: all)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--step", type=float, default=15.0, help="azimuth step, degrees")
    args = ap.parse_args()
    cloud = load_points(Path(_demo).parent / "outcrop.laz")
    if args.points and args.points < cloud.n:
        pick = np.random.default_rng(0).choice(cloud.n, args.points, replace=False)
        cloud = PointCloud.from_xyz(cloud.xyz()[np.sort(pick)])
    plane = whole_cloud_plane(cloud)
    az = azimuths(args.step)
    print(f"outcrop: {cloud.n:,} points, {az.size} azimuths, medians of {args.repeat} runs")
    t, sets = timed(lambda: profile_sets(cloud, az, plane=plane), args.repeat)
    used = sum(int(s.used.sum()) for s in sets[: az.size // 2])
    print(f"profile sets:      {t:7.2f} s  ({used:,} profiles measured)")
    t, mesh = timed(lambda: triangulate_cloud(cloud, plane=plane), args.repeat)
    print(f"triangulation:     {t:7.2f} s  ({mesh.n_faces:,} triangles)")
    t, _ = timed(lambda: directional_roughness(mesh, az, plane=plane), args.repeat)
    print(f"TIN, whole face:   {t:7.2f} s")
    t, win = timed(lambda: window_roughness(mesh, az, radius=1.0, step=1.0, plane=plane),
                   args.repeat)
    print(f"windows r 1 m:     {t:7.2f} s  ({win.n_windows:,} windows)")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak memory:       {peak:7.0f} MB ({peak * 2**20 / cloud.n:.0f} B per point)")


if __name__ == "__main__":
    main()
