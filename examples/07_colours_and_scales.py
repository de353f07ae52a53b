"""Honest colours and roughness across scales on the demo outcrop (issue 13).

    python examples/07_colours_and_scales.py

1. The default colour stretch (percentiles 2-98 of the cells, log scale) against
   min-max: how much of the face the most used colour covers, and the colour-bar
   ticks in mm.
2. One point's ODR, OLS and hybrid roughness on the nested grids 0.125-1 m, and the
   whole face's mean roughness and binary-cell share per grid (2011 Table-1 trend).
"""

from __future__ import annotations

import numpy as np

import rough_viewer as rv
from rough_viewer.visual import colormaps as cm

cloud = rv.load_demo("outcrop-small")
fine = rv.prepare_grid(cloud, 0.125)  # the finest grid once; the others nest in it
grids = [fine] + [rv.coarsen_prepared(fine, k) for k in (2, 4, 8)]
results = [rv.grid_roughness(cloud, g.cell_size, prepared=g) for g in grids]
quarter = results[1]

print("map     stretch   range (mm)        one colour covers   colour-bar ticks (mm)")
for name in rv.MAPS:
    values = quarter.values(name)
    for label, stretch in (("min-max", cm.Stretch("percentile", 0, 100)),
                           ("default", cm.ROUGHNESS_STRETCH)):
        rng = cm.resolve(values, stretch)
        share = cm.largest_colour_share(cm.positions(values, rng)[quarter.point_cell])
        ticks = ", ".join(cm.colour_ticks(rng).labels)
        print(f"{name:7} {label:9} {rng.lo * 1e3:7.3g}–{rng.hi * 1e3:<9.4g} "
              f"{share * 100:5.1f} % of points    {ticks}")

point = 4321
ps = rv.point_scales(results, point)
print(f"\npoint {point} across scales (theta, mm)")
for k, g in enumerate(ps.cell_sizes):
    print(f"  grid {g:5g} m: ODR {ps.theta_odr[k] * 1e3:7.3f}  OLS {ps.theta_ols[k] * 1e3:7.3f}"
          f"  hybrid {ps.theta_hybrid[k] * 1e3:7.3f}  ({ps.n_points[k]} points in the cell)")

fs = rv.face_scales(results)
print("\nwhole face across scales: mean theta (mm) / binary cells (%)")
for name in rv.MODELS:
    cols = "  ".join(f"{m * 1e3:6.2f} / {s * 100:4.1f}"
                     for m, s in zip(fs.statistic(name, "mean"), fs.rough_share[name],
                                     strict=True))
    print(f"  {name:7} {cols}")
print("  grids  " + "  ".join(f"{g:>13g}" for g in np.asarray(fs.cell_sizes)))
