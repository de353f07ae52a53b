"""Benchmark of joint sets: how long :func:`rough_viewer.structure.sets.joint_sets` takes
after the grid, and what the figures cost.

For the bundled demo outcrop (2 M points; ``--input`` for another cloud) and the
synthetic joint block, at each grid size:

- ``grid``: :func:`grid_roughness` with the ODR model only (what ``sets`` computes);
- ``sets``: :func:`joint_sets` with the default settings (density, peaks, sets,
  planes, their fits, chords, spacing), the part an app's Sets view recomputes when
  a setting changes;
- ``figures``: the stereonet, the set table and the plane table
  (:mod:`rough_viewer.visual.sets`);
- ``colours``: the scene's colours of every point by set.

Prints medians over ``--repeat`` runs and the process's peak resident memory.

    python benchmarks/bench_sets.py
    python benchmarks/bench_sets.py --input scan.laz --grids 2 4 --repeat 3
"""

from __future__ import annotations

import argparse
import functools
import os
import resource
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_zones import median_time  # noqa: E402

from rough_viewer.grid.roughness import grid_roughness  # noqa: E402
from rough_viewer.io import load_points  # noqa: E402
from rough_viewer.structure.sets import joint_sets  # noqa: E402
from rough_viewer.synthetic.demos import demo_path  # noqa: E402
from rough_viewer.synthetic.joints import generate_joint_block  # noqa: E402
from rough_viewer.visual.sets import (  # noqa: E402
    planes_table_figure,
    point_colours,
    sets_stereonet_figure,
    sets_table_figure,
)


def figures(sets, res) -> None:
    kw = {"axis": res.axis, "n_points": res.n_points_total}
    sets_stereonet_figure(sets, **kw)
    sets_table_figure(sets, **kw)
    planes_table_figure(sets, **kw)


def run(name: str, cloud, grids: list[float], repeat: int) -> None:
    print(f"\n{name}: {cloud.n:,} points")
    print(f"{'g':>7} {'cells':>8} {'planar':>7} {'sets':>4} {'planes':>6} {'grid (s)':>9} "
          f"{'sets (s)':>9} {'figures (s)':>11} {'colours (s)':>11}")
    for g in grids:
        t_grid = median_time(functools.partial(grid_roughness, cloud, g, models=("odr",)),
                             max(1, repeat // 2))
        res = grid_roughness(cloud, g, models=("odr",))
        t_sets = median_time(functools.partial(joint_sets, res, cloud), repeat)
        sets = joint_sets(res, cloud)
        t_fig = median_time(functools.partial(figures, sets, res), repeat)
        t_col = median_time(functools.partial(point_colours, sets, res.point_cell), repeat)
        print(f"{g:7g} {res.n_cells:8,} {int(sets.planar.sum()):7,} {sets.n_sets:4} "
              f"{sets.planes.n_planes:6,} {t_grid:9.2f} {t_sets:9.2f} {t_fig:11.2f} "
              f"{t_col:11.3f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--input", help="a cloud to read instead of the demo outcrop")
    ap.add_argument("--grids", type=float, nargs="+", default=[0.5, 0.25, 0.125])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    print(f"joint sets; median of {args.repeat} runs; {os.cpu_count()} cores")
    path = Path(args.input) if args.input else demo_path("outcrop")
    run(path.name, load_points(path), args.grids, args.repeat)
    if not args.input:
        run("synthetic joint block", generate_joint_block().cloud, [0.5, 0.25], args.repeat)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"\npeak resident memory {peak:,.0f} MiB")


if __name__ == "__main__":
    main()
