"""Reproduce the instrument-bias paper's simulation numbers and time the bias core.

Prints, for the paper's targets A (r = 19 mm) and B (r = 32.5 mm) on a 1 mm raster
with 1.6 mm range noise, over ``--trials`` draws:

- native background : asperity ratio (paper: ~17.75 and ~5.5);
- population-normalised roughness (5 : 1, known classes) without and with noise
  (paper: A 5.07 -> 5.31 mm, +4.7 %; B 8.64 -> 8.79 mm, +1.7 %), in the paper's
  convention (std of signed distances) and in SCIENCE.md's (std of absolute ones);
- X and Y scores of plain K-means and K-means + 3 sigma, and the roughness after
  normalising with those classes (paper: clustering over-estimates);
- the beam-smoothing curve against ER / asperity radius (Fig. 4);
- timings of the main functions.

Run: ``PYTHONPATH=. python benchmarks/reproduce_bias_paper.py [--trials 10]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from rough_viewer.bias.measurement import (
    classification_scores,
    classify_population,
    normalise_population,
    range_noise,
)
from rough_viewer.bias.simulation import paper_target, simulate_target, smoothing_curve

NOISE = 0.0016
PAPER = {"A": (5.07, 5.31, 17.75), "B": (8.64, 8.79, 5.5)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=10)
    args = ap.parse_args()

    for which in "AB":
        layout = paper_target(which)
        rows: dict[str, list[float]] = {}
        for t in range(args.trials):
            clean = simulate_target(layout, seed=t)
            noisy = simulate_target(layout, noise_sigma_m=NOISE, seed=1000 + t)
            truth = clean.labels()
            for res in ("signed", "absolute"):
                for name, sim in (("clean", clean), ("noisy", noisy)):
                    pop = normalise_population(sim.xyz(), truth, seed=t, residual=res)
                    rows.setdefault(f"{name}_{res}", []).append(pop.roughness * 1e3)
            rows.setdefault("native", []).append(pop.native_ratio)
            for method in ("kmeans", "kmeans-3sigma"):
                c = classify_population(noisy.xyz(), noise_sigma=NOISE, method=method)
                sc = classification_scores(truth, c.asperity)
                rows.setdefault(f"{method}_x", []).append(sc.x_score)
                rows.setdefault(f"{method}_y", []).append(sc.y_score)
                for res in ("signed", "absolute"):
                    pop = normalise_population(noisy.xyz(), c.asperity, seed=t, residual=res)
                    rows.setdefault(f"{method}_{res}", []).append(pop.roughness * 1e3)
        m = {k: float(np.mean(v)) for k, v in rows.items()}
        s = {k: float(np.std(v)) for k, v in rows.items()}
        pc, pn, pr = PAPER[which]
        print(f"target {which} (r = {layout.asperity_radius_m * 1e3:g} mm), {args.trials} trials")
        print(f"  native ratio            {m['native']:.2f}   (paper ~{pr})")
        for res in ("signed", "absolute"):
            c, n = m[f"clean_{res}"], m[f"noisy_{res}"]
            ref = f"   (paper {pc} -> {pn} mm, {100 * (pn / pc - 1):+.1f} %)" if res == "signed" \
                else ""
            print(f"  {res:8s} clean {c:.3f} +- {s[f'clean_{res}']:.3f} mm, noisy "
                  f"{n:.3f} +- {s[f'noisy_{res}']:.3f} mm, {100 * (n / c - 1):+.2f} %{ref}")
        for method in ("kmeans", "kmeans-3sigma"):
            print(f"  {method:14s} X {m[f'{method}_x']:6.2f} %  Y {m[f'{method}_y']:5.2f} %  "
                  f"roughness signed {m[f'{method}_signed']:.3f} mm "
                  f"({100 * (m[f'{method}_signed'] / m['noisy_signed'] - 1):+.2f} % vs known), "
                  f"absolute {m[f'{method}_absolute']:.3f} mm "
                  f"({100 * (m[f'{method}_absolute'] / m['noisy_absolute'] - 1):+.2f} % vs known)")

    print("\nbeam smoothing, 1.6 mm noise: measured vs noisy simulation, % (signed / absolute)")
    ratios = np.array([0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.75])
    for which in "AB":
        r = paper_target(which).asperity_radius_m
        cs = smoothing_curve(ratios * r, asperity_radius_m=r, noise_sigma_m=NOISE,
                             residual="signed")
        ca = smoothing_curve(ratios * r, asperity_radius_m=r, noise_sigma_m=NOISE)
        print(f"  target {which}: " + "  ".join(
            f"{q:.2f}:{a:+.1f}/{b:+.1f}" for q, a, b in zip(ratios, cs.vs_noisy_pct,
                                                             ca.vs_noisy_pct, strict=True)))

    print("\ntimings (this machine)")
    layout = paper_target("A")
    t0 = time.perf_counter()
    sim = simulate_target(layout, noise_sigma_m=NOISE, effective_radius_m=0.01)
    t1 = time.perf_counter()
    print(f"  simulate_target A, 757k raster, ER 10 mm   {t1 - t0:6.3f} s")
    xyz = sim.xyz()
    t0 = time.perf_counter()
    classify_population(xyz, noise_sigma=NOISE)
    t1 = time.perf_counter()
    print(f"  classify_population kmeans-3sigma, 757k   {t1 - t0:6.3f} s")
    rng = np.random.default_rng(0)
    board = np.column_stack((rng.uniform(0, 1.244, 1_000_000), rng.uniform(0, 0.609, 1_000_000),
                             rng.normal(0, NOISE, 1_000_000)))
    t0 = time.perf_counter()
    range_noise(board)
    t1 = time.perf_counter()
    print(f"  range_noise, 1M board points              {t1 - t0:6.3f} s")


if __name__ == "__main__":
    main()
