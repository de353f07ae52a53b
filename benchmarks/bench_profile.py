"""Benchmark of the profile tools: extraction, de-noising comparison, roughness length,
and the accuracy of D on exact fBm.

    python benchmarks/bench_profile.py            # timings and accuracy
    python benchmarks/bench_profile.py --quick    # smaller sizes, fewer seeds
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from timing import median_seconds  # noqa: E402

from rough_viewer.profiles.comparison import compare_denoising  # noqa: E402
from rough_viewer.profiles.extraction import extract_profile  # noqa: E402
from rough_viewer.profiles.fractal import roughness_length, roughness_length_2d  # noqa: E402
from rough_viewer.synthetic.fbm import fbm_profile  # noqa: E402


def timed(fn, repeat: int) -> float:
    return median_seconds(fn, repeat)[0]


def face(n: int, seed: int = 0) -> np.ndarray:
    """n points on a 10 m x 3 m vertical face (UTM-like), 2 mm noise."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(0, 10, n)
    z = rng.uniform(0, 3, n)
    y = 0.05 * np.sin(x * 3) + 0.01 * np.sin(17 * x + 5 * z) + rng.normal(0, 0.002, n)
    return np.column_stack([x + 500000.0, y + 4_200_000.0, z + 300.0])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    sizes = (200_000, 1_000_000) if args.quick else (1_000_000, 5_000_000)
    print("profile extraction (1 m line on a 10 m x 3 m face):")
    for n in sizes:
        xyz = face(n)
        start = np.array([500004.0, 4_200_000.0, 301.5])
        end = np.array([500005.0, 4_200_000.0, 301.5])
        t = timed(lambda xyz=xyz, s=start, e=end: extract_profile(xyz, s, e), args.repeat)
        p = extract_profile(xyz, start, end)
        print(f"  {n:>9,} points: {t * 1e3:8.1f} ms  ({p.distance.size} samples at "
              f"{p.spacing * 1e3:.2f} mm, {p.n_points} band points, {len(p.gaps)} gaps)")
    print("de-noising comparison (16 variants + 17 roughness-length fits):")
    for k in (1_000, 10_000, 100_000):
        h = fbm_profile(k, 0.7, rng=1) + np.random.default_rng(1).normal(0, 1e-3, k)
        t = timed(lambda h=h: compare_denoising(h, 1e-3), args.repeat)
        print(f"  {k:>9,} samples: {t * 1e3:8.1f} ms")
    print("roughness length:")
    for k in (100_000, 1_000_000):
        h = fbm_profile(k, 0.5, rng=2)
        t = timed(lambda h=h: roughness_length(h, 1e-3), args.repeat)
        print(f"  1-D {k:>9,} samples: {t * 1e3:8.1f} ms")
    z = np.cumsum(np.random.default_rng(3).normal(size=(512, 512)), axis=1)
    t = timed(lambda: roughness_length_2d(z, 1e-3), args.repeat)
    print(f"  2-D 512 x 512 grid:      {t * 1e3:8.1f} ms")
    seeds = 20 if args.quick else 200
    print(f"accuracy of D on exact fBm (2048 samples, default windows, {seeds} seeds):")
    for hurst in (0.3, 0.4, 0.5, 0.6, 0.7, 0.8):
        err = np.array([
            roughness_length(fbm_profile(2048, hurst, rng=s), 1e-3).dimension - (2 - hurst)
            for s in range(seeds)
        ])
        print(f"  H {hurst:.1f}: bias {err.mean():+.3f}  sd {err.std():.3f}  "
              f"max |err| {np.abs(err).max():.3f}")


if __name__ == "__main__":
    main()
