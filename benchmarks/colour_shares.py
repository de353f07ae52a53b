"""How much of the demo face one colour covers, min-max against the default stretch.

For each roughness map at 0.25 m (the app's default grid) this prints the largest
share of cells and of points drawn in one colour-map entry, and in any band of 8
neighbouring entries (1/32 of the map, barely distinguishable), under

- ``min-max``: the old default, normalised roughness over the full range;
- ``default``: :data:`rough_viewer.visual.colormaps.ROUGHNESS_STRETCH`
  (percentiles 2-98, log);
- ``linear 2-98``: the robust percentiles without the log scale.

Run: ``python benchmarks/colour_shares.py [outcrop-small|outcrop] [--min-points K]``.
"""

from __future__ import annotations

import argparse

import numpy as np

from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.synthetic.demos import load_demo
from rough_viewer.visual import colormaps as cm
from rough_viewer.vocabulary import MAPS

STRETCHES = {
    "min-max": cm.Stretch("percentile", 0.0, 100.0),
    "default": cm.ROUGHNESS_STRETCH,
    "linear 2-98": cm.Stretch("percentile", 2.0, 98.0),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("demo", nargs="?", default="outcrop-small")
    ap.add_argument("--grid", type=float, default=0.25)
    ap.add_argument("--min-points", type=int, default=3)
    args = ap.parse_args()
    cloud = load_demo(args.demo)
    res = grid_roughness(cloud, args.grid, min_points=args.min_points)
    print(f"{args.demo}: {cloud.n:,} points, grid {args.grid:g} m, min points "
          f"{args.min_points}; largest share in one colour / in 8 neighbouring colours")
    print(f"{'map':7} {'stretch':12} {'range (mm)':>18} {'cells 1':>8} {'cells 8':>8} "
          f"{'points 1':>9} {'points 8':>9}")
    for name in MAPS:
        values = res.values(name)
        for label, stretch in STRETCHES.items():
            rng = cm.resolve(values, stretch)
            cells = cm.positions(values, rng)
            points = cells[res.point_cell]
            print(f"{name:7} {label:12} {rng.lo * 1e3:8.3g}–{rng.hi * 1e3:<9.4g} "
                  f"{cm.largest_colour_share(cells):8.3f} "
                  f"{cm.largest_colour_share(cells, band=8):8.3f} "
                  f"{cm.largest_colour_share(points):9.3f} "
                  f"{cm.largest_colour_share(points, band=8):9.3f}")


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
