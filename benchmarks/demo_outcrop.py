"""Time the outcrop generator, check it rewrites the bundled file byte for byte, and
print how well high-roughness cells find the ground-truth fractures and rubble.

    PYTHONPATH=. python benchmarks/demo_outcrop.py [--skip-generate]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.grid.summary import binary, normalise
from rough_viewer.synthetic.demos import demo_path, load_demo_with_truth, write_demo


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--skip-generate", action="store_true")
    args = ap.parse_args()
    for name in ("outcrop", "outcrop-small"):
        if not args.skip_generate:
            with tempfile.TemporaryDirectory() as tmp:
                out = Path(tmp) / f"{name}.laz"
                t0 = time.perf_counter()
                n = write_demo(name, out)
                dt = time.perf_counter() - t0
                same = out.read_bytes() == demo_path(name).read_bytes()
                print(f"{name}: generated {n} points in {dt:.1f} s, "
                      f"{out.stat().st_size / 1e6:.1f} MB, identical to bundled: {same}")
        cloud, truth = load_demo_with_truth(name)
        for g in (0.5, 0.25, 0.125):
            r = grid_roughness(cloud, g)
            m = r.n_points.shape[0]
            frac = np.bincount(r.point_cell, (truth.labels > 0).astype(float), m) / r.n_points
            face = np.bincount(r.point_cell, truth.face.astype(float), m) / r.n_points
            for model in ("odr", "ols"):
                th = r.values(model)
                valid = np.isfinite(th)
                flag = binary(normalise(th))
                true = valid & (frac > 0)
                prec = (flag & true).sum() / max(flag.sum(), 1)
                rec = (flag & true).sum() / max(true.sum(), 1)
                rock = valid & (frac == 0)
                print(f"  g={g:<5} {model}: cells {valid.sum():5d}  first bin "
                      f"{1 - flag[valid].mean():.3f}  base rate {true.sum() / valid.sum():.3f}  "
                      f"precision {prec:.3f}  recall {rec:.3f}  rock flagged main/bend "
                      f"{flag[rock & (face == 0)].mean():.3f}/{flag[rock & (face == 2)].mean():.3f}")


if __name__ == "__main__":
    main()
