"""Per-cell roughness of a scan: load, compute ODR / OLS / hybrid, print Table 1.

    python examples/01_grid_roughness.py [SCAN]      # default: the bundled small outcrop

The 2011 paper's Table 1 (cells, mean points, min, max, mean, variance, std of each
map) at one grid size, and the dependent axis ``auto`` chose.
"""

from __future__ import annotations

import sys

import rough_viewer as rv

cloud = rv.load_points(sys.argv[1]) if len(sys.argv) > 1 else rv.load_demo("outcrop-small")
res = rv.grid_roughness(cloud, 0.5)

print(f"{cloud.n:,} points, grid {res.grid.cell_size:g} m, dependent axis {res.axis}")
for name, s in rv.summaries(res).items():
    print(f"{name:>7}: {s.cells:5d} cells, mean {s.mean * 1e3:7.3f} mm, std {s.std * 1e3:7.3f} mm")
