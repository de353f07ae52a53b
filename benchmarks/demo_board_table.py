"""Print the 2012 paper's Table 1 for the simulated board: theta per model per rotation.

    PYTHONPATH=. python benchmarks/demo_board_table.py [--spacing 0.002] [--noise 0]

The whole board is one cell (grid 5 m), dependent axis y, as in the paper.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.synthetic import PAPER_ROTATIONS_DEG, board_scan


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--spacing", type=float, default=0.002)
    ap.add_argument("--noise", type=float, default=0.0)
    args = ap.parse_args()
    t0 = time.perf_counter()
    print("alpha  beta   theta_ols   theta_hyb   theta_odr   odr/odr00  N        N/(N00 cos a cos b)")
    n00 = odr00 = None
    for a in PAPER_ROTATIONS_DEG:
        for b in PAPER_ROTATIONS_DEG:
            scan = board_scan(a, b, spacing=args.spacing, noise=args.noise)
            r = grid_roughness(scan.cloud, 5.0, axis="y")
            if n00 is None:
                n00, odr00 = scan.cloud.n, r.theta_odr[0]
                print(f"# theoretical roughness {scan.theoretical_roughness:.6e} m")
            cc = np.cos(np.radians(a)) * np.cos(np.radians(b))
            print(f"{a:5.2f} {b:5.2f}  {r.theta_ols[0]:.8f}  {r.theta_hybrid[0]:.8f}  "
                  f"{r.theta_odr[0]:.8f}  {r.theta_odr[0] / odr00:.4f}     {scan.cloud.n:7d}  "
                  f"{scan.cloud.n / (n00 * cc):.4f}")
    print(f"# 25 scans + roughness in {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
