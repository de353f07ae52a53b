"""Joint sets of a planted joint block: orientation, Fisher scatter, spacing and
persistence of three sets, against what was planted (issue 26, docs/sets.md).

    python examples/09_joint_sets.py

The smooth cells of the grid are pieces of discontinuity planes: their poles gather
into sets (density peaks on the lower hemisphere), the sets' touching cells into
single planes, measured from their points.
"""

from __future__ import annotations

import numpy as np

import rough_viewer as rv
from rough_viewer.synthetic.joints import JOINT_BLOCK, generate_joint_block

scan = generate_joint_block()  # three planted sets, scanned from one side
res = rv.grid_roughness(scan.cloud, 0.25, models=("odr",))
sets = rv.joint_sets(res, scan.cloud)  # default SetOptions: cone 20 degrees, ...
print(f"{scan.cloud.n:,} points, {int(sets.planar.sum()):,} planar cells, "
      f"{sets.n_sets} sets, {sets.planes.n_planes} planes")

print("set  dip/dir   kappa  spacing m  persistence m   planted: dip/dir  kappa  spacing")
for k in range(sets.n_sets):
    # the planted set nearest the found mean normal
    p = int(np.argmax(np.abs(scan.set_normal @ sets.normal[k])))
    spec = JOINT_BLOCK.sets[p]
    print(f"{k + 1:3d}  {sets.dip_deg[k]:2.0f}/{sets.dip_direction_deg[k]:03.0f}  "
          f"{sets.kappa[k]:6.0f}  {sets.spacing_mean[k]:9.3f}  {sets.persistence_mean[k]:13.3f}"
          f"           {spec.dip_deg:2.0f}/{spec.dip_direction_deg:03.0f}  {spec.kappa:5.0f}"
          f"  {scan.spacings(p + 1).mean():7.3f}")

planes = sets.plane_table()  # PLANES.csv's columns, metres
print(f"largest plane: set {planes['set_id'][0]}, "
      f"{planes['persistence_dip'][0]:.2f} m along dip x "
      f"{planes['persistence_strike'][0]:.2f} m along strike, rms {planes['rms'][0] * 1e3:.1f} mm")
