"""Benchmark of zone labelling: how fast a threshold change re-labels zones.

On a synthetic outcrop (the one of ``bench_compute.py``: 90 m x 10 m vertical face,
UTM coordinates, column fractures every ~1.5 m) of N points, for each grid size:

- ``build``: :meth:`ZoneLabeller.build` (neighbour pairs, face coverage), once per
  grid result;
- ``label``: :meth:`ZoneLabeller.label` at each threshold (labels only; what a
  threshold slider needs to recolour the scene);
- ``zones``: :meth:`ZoneLabeller.zones` (labels and the full zone table);
- ``stereonet``: density of every cell's pole.

Prints medians over ``--repeat`` runs (the target: a re-label at 5 M points in under
0.5 s).

    python benchmarks/bench_zones.py                       # 5 M points
    python benchmarks/bench_zones.py --sizes 1e6 --grids 0.25 --repeat 3
"""

from __future__ import annotations

import argparse
import functools
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_compute import synthetic_outcrop  # noqa: E402
from timing import median_seconds  # noqa: E402

from rough_viewer.grid.orientation import stereonet  # noqa: E402
from rough_viewer.grid.roughness import grid_roughness  # noqa: E402
from rough_viewer.structure.zones import ZoneLabeller  # noqa: E402


def median_time(fn, repeat: int) -> float:
    return median_seconds(fn, repeat)[0]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=float, nargs="+", default=[5e6])
    ap.add_argument("--grids", type=float, nargs="+", default=[0.5, 0.25, 0.125, 0.0625, 0.03125])
    ap.add_argument("--thresholds", type=float, nargs="+", default=[0.05, 0.1, 0.2, 0.4])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    print(f"zone labelling; median of {args.repeat} runs; {os.cpu_count()} cores")
    for n in (int(s) for s in args.sizes):
        cloud = synthetic_outcrop(n)
        print(f"\nN = {n:,} points")
        print(f"{'g (m)':>7} {'cells':>9} {'pairs':>10} {'build (s)':>10} {'thr':>5} "
              f"{'conn':>6} {'zones':>6} {'zone cells':>10} {'label (s)':>10} {'zones (s)':>10}")
        for g in args.grids:
            t0 = time.perf_counter()
            res = grid_roughness(cloud, g, models=("odr",))
            t_rough = time.perf_counter() - t0
            build = median_time(functools.partial(ZoneLabeller.build, res),
                                max(1, args.repeat // 2))
            lab = ZoneLabeller.build(res)
            for thr in args.thresholds:
                for conn in ("vertex", "face"):
                    t_label = median_time(
                        functools.partial(lab.label, thr, connectivity=conn), args.repeat)
                    t_zones = median_time(
                        functools.partial(lab.zones, thr, connectivity=conn), args.repeat)
                    z = lab.zones(thr, connectivity=conn)
                    print(f"{g:7g} {res.n_cells:9,} {lab.pair_a.shape[0]:10,} {build:10.3f} "
                          f"{thr:5g} {conn:>6} {z.n_zones:6,} {int(z.cells.sum()):10,} "
                          f"{t_label:10.4f} {t_zones:10.4f}")
            t_net = median_time(functools.partial(stereonet, res.normal), args.repeat)
            print(f"{'':7} grid roughness (ODR only) {t_rough:.2f} s; stereonet of "
                  f"{res.n_cells:,} cell poles {t_net:.3f} s")


if __name__ == "__main__":
    main()
