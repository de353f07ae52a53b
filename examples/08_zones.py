"""Fracture zones on the demo outcrop: count, measure, orient, and check against the
demo's ground truth (issue 14, docs/zones.md).

    python examples/08_zones.py

Zones are connected groups of cells whose normalised ODR roughness is at or above a
threshold. A ZoneLabeller is built once per grid result; re-labelling at another
threshold then takes milliseconds, as a slider needs.
"""

from __future__ import annotations

import numpy as np

import rough_viewer as rv
from rough_viewer.synthetic.demos import load_demo_with_truth

cloud, truth = load_demo_with_truth("outcrop-small")
res = rv.grid_roughness(cloud, 0.125)
labeller = rv.ZoneLabeller.build(res)  # once per grid result
dip, direction = rv.dip_and_direction(res.whole_normal[None])
print(f"face: dip {dip[0]:.1f}, dip direction {direction[0]:.1f} degrees")

for threshold in (0.05, 0.1, 0.2):
    zones = labeller.zones(threshold)  # connectivity "vertex", at least 3 cells
    in_zone = zones.labels[res.point_cell] > 0
    rubble = truth.labels == truth.names.index("rubble")
    rock = truth.labels == truth.names.index("rock")
    print(f"threshold {threshold:4.2f}: {zones.n_zones:3d} zones, "
          f"rubble points in zones {np.mean(in_zone[rubble]):.2f}, "
          f"rock points in zones {np.mean(in_zone[rock]):.2f}")

zones = labeller.zones(0.1)
print("zone  cells  area m2  length m  trace az/plunge  dip/direction")
for k in range(min(5, zones.n_zones)):
    print(f"{k + 1:4d} {zones.cells[k]:6d} {zones.area_m2[k]:8.2f} {zones.length_m[k]:9.2f}"
          f"   {zones.trace_azimuth_deg[k]:5.0f} / {zones.trace_plunge_deg[k]:2.0f}"
          f"      {zones.dip_deg[k]:4.0f} / {zones.dip_direction_deg[k]:3.0f}")

net = rv.cell_stereonet(res)  # poles of every cell, lower hemisphere, equal area
print(f"stereonet: {net.n_poles:,} poles, peak density {np.nanmax(net.density):.1f} MUD")
