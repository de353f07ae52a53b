"""Spatial structure of a roughness map: the normalised semivariogram (2011 Fig. 4).

    python examples/03_semivariogram.py

Exact over all pairs of cells with a value; the sill near 1 is the map's variance.
"""

from __future__ import annotations

import numpy as np

import rough_viewer as rv

cloud = rv.load_demo("outcrop-small")
res = rv.grid_roughness(cloud, 0.25)
vg = rv.semivariogram(res.ijk, res.theta_odr, res.grid.cell_size)
print(f"ODR map: {vg.n_cells} cells, variance {vg.variance * 1e6:.4f} mm^2")
print("  lag m   pairs   gamma/variance")
for lag, pairs, g in list(zip(vg.lag, vg.pairs, vg.gamma_normalised, strict=True))[:12]:
    print(f"{lag:7.2f} {pairs:7d} {g:14.3f}")
assert np.all(np.isfinite(vg.gamma_normalised[:5]))
