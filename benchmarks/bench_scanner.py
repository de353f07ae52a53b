"""Benchmark and figures of the per-cell scanner trust (docs/scanner.md).

On the bundled demo outcrop (2 M points, one scanner at its spec's position) and on
the 2012 board at its 25 rotations: the median over ``--repeat`` runs of
:func:`rough_viewer.scanner.geometry.scan_geometry` and of
:func:`rough_viewer.scanner.trust.cell_trust` (the bias model's simulations cached after
the first grid: their cost is printed apart), the peak memory those allocate
(tracemalloc, a separate run), and the figures: incidence, density ratio, occlusion,
predicted bias, trusted share; on the outcrop against its ground truth (fracture and
rubble cells vs smooth rock) and per face part (main face, curve, turned wall).

    python benchmarks/bench_scanner.py                   # outcrop at 0.5, 0.25, 0.125 m; board
    python benchmarks/bench_scanner.py --grids 0.25 --repeat 5 --no-board
    python benchmarks/bench_scanner.py --truth --no-board  # + the outcrop without its noise

``--truth`` generates the demo outcrop again without its range noise (the same points,
about 40 s) and compares each cell's roughness less its predicted bias (calibration:
the demo's 2 mm of noise, and the paper's 1.6 mm, no beam) with the noise-free one,
and the noise flag with the cells whose true noise share is above 30 %.
"""

from __future__ import annotations

import argparse
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from timing import median_seconds  # noqa: E402

from rough_viewer.grid.roughness import grid_roughness  # noqa: E402
from rough_viewer.scanner.geometry import scan_geometry  # noqa: E402
from rough_viewer.scanner.positions import cloud_scanners  # noqa: E402
from rough_viewer.scanner.trust import TrustSettings, bias_model, cell_trust  # noqa: E402
from rough_viewer.synthetic.board import PAPER_ROTATIONS_DEG, board_scan  # noqa: E402
from rough_viewer.synthetic.demos import demo_angular_step, load_demo_with_truth  # noqa: E402


def _median_time(fn, repeat: int) -> float:
    return median_seconds(fn, repeat)[0]


def _peak(fn) -> float:
    tracemalloc.start()
    fn()
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak / 2**20


def outcrop(grids: list[float], repeat: int) -> None:
    cloud, truth = load_demo_with_truth("outcrop")
    positions, scan = cloud_scanners(cloud)
    step = demo_angular_step("outcrop")
    settings = TrustSettings(angular_step_rad=step)
    print(f"outcrop: {cloud.n:,} points, scanner {positions[0].tolist()}, angular step "
          f"{np.degrees(step):.4f} degrees, repeat {repeat}")
    t = time.perf_counter()
    bias_model(settings.calibration.noise_sigma_m, (4e-3 / settings.asperity_radius_m,),
               residual="absolute", trials=settings.trials)
    print(f"bias model (one ratio, {settings.trials} trials, cached afterwards): "
          f"{time.perf_counter() - t:.2f} s")
    for g in grids:
        res = grid_roughness(cloud, g)
        t_geo = _median_time(lambda r=res: scan_geometry(cloud, r, positions, scan,
                                                         angular_step_rad=step), repeat)
        t_all = _median_time(lambda r=res: cell_trust(cloud, r, settings), repeat)
        mem = _peak(lambda r=res: cell_trust(cloud, r, settings))
        tr = cell_trust(cloud, res, settings)
        fitted = scan_geometry(cloud, res, positions, scan)
        s = tr.summary()
        k = tr.known
        # the cell's class: fracture / rubble where most of its points are
        labels = np.bincount(res.point_cell, weights=(truth.labels > 0).astype(float),
                             minlength=res.n_cells) / np.maximum(res.n_points, 1)
        face = np.rint(np.bincount(res.point_cell, weights=truth.face.astype(float),
                                   minlength=res.n_cells) / np.maximum(res.n_points, 1))
        rough = k & (labels > 0.5)
        smooth = k & (labels <= 0.5)
        print(f"\ngrid {g:g} m: {res.n_cells:,} cells, {s.cells:,} judged; scan_geometry "
              f"{t_geo:.3f} s, cell_trust {t_all:.3f} s (median), peak {mem:.0f} MiB")
        print("\n".join("  " + line for line in s.lines("m")))
        print(f"  fitted angular step {np.degrees(1 / np.sqrt(fitted.n0[0])):.4f} degrees "
              f"(true {np.degrees(step):.4f})")
        pct = 100 * tr.bias_pred_m / tr.theta_m
        for name, sel in (("fracture/rubble cells", rough), ("smooth rock cells", smooth)):
            print(f"  {name}: {sel.sum():,}, median theta {np.median(tr.theta_m[sel]) * 1e3:.2f}"
                  f" mm, predicted bias {np.median(pct[sel]):+.1f} %, noise-flagged "
                  f"{100 * np.mean(tr.flags[sel] & 4 > 0):.0f} %, trusted "
                  f"{100 * np.mean(tr.flags[sel] == 0):.0f} %")
        for part, name in enumerate(("main face", "curve", "turned wall")):
            sel = k & (face == part)
            if sel.any():
                print(f"  {name}: {sel.sum():,} cells, incidence median "
                      f"{np.median(tr.geometry.incidence_deg[sel]):.1f} degrees, density "
                      f"{np.nanmedian(tr.geometry.density_ratio[sel]):.2f}, occlusion 95 % "
                      f"{np.nanpercentile(tr.geometry.occlusion[sel], 95):.2f}")


def board(grid: float) -> None:
    print(f"\nboard (2 mm at 4.5 m), grid {grid:g} m: rotation, incidence at the centre "
          "(arccos(cos a cos b)), point-weighted mean cell incidence, median density "
          "ratio, N / expected, median occlusion")
    for a in PAPER_ROTATIONS_DEG:
        for b in PAPER_ROTATIONS_DEG:
            sc = board_scan(a, b)
            res = grid_roughness(sc.cloud, grid, models=("odr",))
            geo = scan_geometry(sc.cloud, res, sc.scanner[None, :],
                                angular_step_rad=sc.angular_step_rad)
            ok = np.isfinite(geo.density_ratio)
            w = res.n_points[ok]
            centre = np.degrees(np.arccos(np.cos(np.radians(a)) * np.cos(np.radians(b))))
            print(f"  ({a:5.2f}, {b:5.2f})  {centre:5.1f}  "
                  f"{np.average(geo.incidence_deg[ok], weights=w):5.1f}  "
                  f"{np.median(geo.density_ratio[ok]):.3f}  "
                  f"{w.sum() / geo.expected_points[ok].sum():.3f}  "
                  f"{np.nanmedian(geo.occlusion[ok]):.3f}")


def truth(grids: list[float]) -> None:
    import dataclasses

    from rough_viewer.bias.calibration import calibration
    from rough_viewer.scanner.trust import FLAG_NOISE
    from rough_viewer.synthetic.outcrop import OUTCROP, generate_outcrop

    noisy = generate_outcrop(OUTCROP)
    clean = generate_outcrop(dataclasses.replace(OUTCROP, range_noise_m=0.0))
    lo = np.minimum(noisy.cloud.bounds()[0], clean.cloud.bounds()[0]) - 0.01
    print(f"\noutcrop against its noise-free twin ({noisy.cloud.n:,} points, 2 mm noise)")
    for g in grids:
        rn = grid_roughness(noisy.cloud, g, origin=lo, models=("odr",))
        rc = grid_roughness(clean.cloud, g, origin=lo, models=("odr",))
        row = {tuple(r): i for i, r in enumerate(rn.ijk)}
        pair = np.array([row.get(tuple(r), -1) for r in rc.ijk])
        ic, inn = np.flatnonzero(pair >= 0), pair[pair >= 0]
        for sigma in (0.002, 0.0016):
            tr = cell_trust(noisy.cloud, rn, TrustSettings(
                calibration=calibration(noise_sigma_m=sigma, effective_radius_m=0.0),
                angular_step_rad=OUTCROP.angular_step_rad))
            t_true, t_meas = rc.theta_odr[ic], rn.theta_odr[inn]
            pred = t_meas - tr.bias_pred_m[inn]
            ok = np.isfinite(t_true) & np.isfinite(pred) & tr.known[inn]
            real = ((t_meas - t_true) / t_meas > 0.3)[ok]
            flag = (tr.flags[inn] & FLAG_NOISE > 0)[ok]
            print(f"  grid {g:g} m, noise {sigma * 1e3:g} mm: {ok.sum():,} cells, median "
                  f"measured/true {np.median(t_meas[ok] / t_true[ok]):.3f}, corrected/true "
                  f"{np.median(pred[ok] / t_true[ok]):.3f}; noise flag recall "
                  f"{(real & flag).sum() / max(real.sum(), 1):.2f}, precision "
                  f"{(real & flag).sum() / max(flag.sum(), 1):.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--grids", type=float, nargs="+", default=[0.5, 0.25, 0.125])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--board-grid", type=float, default=0.2)
    ap.add_argument("--no-board", action="store_true")
    ap.add_argument("--truth", action="store_true",
                    help="compare with the outcrop generated without its noise (~40 s)")
    args = ap.parse_args()
    outcrop(args.grids, args.repeat)
    if not args.no_board:
        board(args.board_grid)
    if args.truth:
        truth(args.grids)


if __name__ == "__main__":
    main()
