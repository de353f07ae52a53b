"""Server-side timings of the app: seconds from a GUI change until the point
colours are assigned (``colours_s``), and until the panels are refreshed; and the
seconds of a click (cell report plus the roughness of the point's cells on every
preset grid).

    PYTHONPATH=. python benchmarks/bench_app.py [--points 5000000] [--demo] [--repeat 3]

Grids are the cloud's presets from its point spacing (coarsest ``p0`` ... finest
``p3``, the default).

Targets (issue 3, 5 M points): preset grid switch < 0.5 s, free grid < 2 s,
cached grid or threshold change < 0.3 s.
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def synthetic_face(n: int, seed: int = 0):
    from rough_viewer.io import PointCloud

    rng = np.random.default_rng(seed)
    x = rng.uniform(0.0, 40.0, n)
    z = rng.uniform(0.0, 12.0, n)
    y = 0.3 * np.sin(0.7 * x) * np.cos(0.9 * z) + (0.001 + 0.0005 * x) * rng.standard_normal(n)
    xyz = np.column_stack([x, y, z]) + [512_000.0, 4_170_000.0, 100.0]
    return PointCloud.from_xyz(xyz, source=f"synthetic-{n}")


def run(cloud, label: str, *, prefetch: bool, fine: float | None = None) -> None:
    import viser

    from rough_viewer.app.features.map import PickJob
    from rough_viewer.app.server import build_app

    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    t0 = time.perf_counter()
    app = build_app(server, cloud, variogram=True, prefetch=prefetch)
    app.wait_idle(None)
    loaded = app.session.shown.loaded
    presets = loaded.presets
    how = "idle prefetch of presets ON" if prefetch else "no prefetch (plain core)"
    print(f"\n{label}: {cloud.n:,} points, {loaded.n_display:,} shown; {how}; "
          f"presets {presets} m")
    print(f"  build_app + first map ({presets[-1]:g} m): {time.perf_counter() - t0:6.2f} s "
          f"(colours {app.map.timings[-1]['colours_s']:.2f} s, panels "
          f"{app.map.timings[-1].get('panels_s', float('nan')):.2f} s)")
    if prefetch:
        t = time.perf_counter()
        while not all(loaded.is_cached(app.session.shown.settings.with_(cell_size=c)) for c in presets):
            time.sleep(0.02)
        print(f"  presets prefetched in the background after {time.perf_counter() - t:.2f} s")
    g = app.map
    opts = g.grid.options[:-1]  # coarsest first
    free = float(f"{2.4 * presets[-1]:.2g}")
    steps = [
        (f"preset grid p2 {opts[2]}", lambda: setattr(g.grid, "value", opts[2])),
        (f"preset grid p0 {opts[0]}", lambda: setattr(g.grid, "value", opts[0])),
        (f"preset grid p3 {opts[3]}", lambda: setattr(g.grid, "value", opts[3])),
        (f"free grid {free:g}", lambda: setattr(g.grid_free, "value", free)),
        (f"preset grid p2 {opts[2]}", lambda: setattr(g.grid, "value", opts[2])),
        ("model OLS", lambda: setattr(g.model, "value", "OLS")),
        ("absolute stretch", lambda: setattr(g.stretch, "value", "absolute")),
        ("binary view", lambda: setattr(g.display, "value", "binary")),
        ("threshold 0.2", lambda: setattr(g.threshold, "value", 0.2)),
        ("colour map cividis", lambda: setattr(g.colormap, "value", "cividis")),
        ("distance layer", lambda: setattr(g.layer, "value", "distance to face plane")),
    ]
    for name, action in steps:
        t = time.perf_counter()
        action()
        app.wait_idle(None)
        rec = app.map.timings[-1]
        state = "cached " if rec["cached"] else "compute"
        print(f"  {name:22s} {state} colours {rec['colours_s']:6.3f} s   panels "
              f"{rec.get('panels_s', 0.0):6.3f} s   wall {time.perf_counter() - t:6.3f} s")
    rng = np.random.default_rng(1)
    clicks = []
    for i in rng.choice(loaded.n_display, 7, replace=False):
        p = loaded.display_points[i].astype(float)
        o, d = p + 5.0 * loaded.plane.normal, -loaded.plane.normal
        app.submit(PickJob(app.map, tuple(map(float, o)), tuple(map(float, d))))
        app.wait_idle(None)
        clicks.append(app.map.pick_timings[-1]["pick_s"])
    print(f"  click (cell + {len(presets)} grids across scales): median "
          f"{np.median(clicks):.3f} s of {len(clicks)}")
    if fine:
        # a grid change while the panels compute a fine grid's semivariograms: the
        # semivariogram stops at its next block (progress callback), not at its end
        g.grid_free.value = fine
        while app.session.shown.settings.cell_size != fine:
            time.sleep(0.01)
        time.sleep(3.0)  # well into the semivariograms
        t = time.perf_counter()
        g.grid.value = opts[2]
        while app.session.shown.settings.cell_size != presets[2]:
            time.sleep(0.005)
        shown = time.perf_counter() - t
        app.wait_idle(None)
        stopped = [r for r in app.worker.records
                   if r.kind == "PanelsJob" and r.outcome == "cancelled"]
        what = f"stopped after {stopped[-1].seconds:.1f} s" if stopped else "none stopped"
        print(f"  grid {opts[2]} during the semivariograms of grid {fine:g}: shown after "
              f"{shown:.2f} s (fine-grid panels {what})")
    app.stop()
    server.stop()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--points", type=int, default=5_000_000)
    ap.add_argument("--demo", action="store_true", help="also time the demo outcrop")
    args = ap.parse_args()
    if args.demo:
        from rough_viewer.synthetic import demos

        demo = demos.load_demo("outcrop")
        run(demo, "demo outcrop", prefetch=False)
        run(demo, "demo outcrop", prefetch=True, fine=0.02)
    t = time.perf_counter()
    cloud = synthetic_face(args.points)
    print(f"synthetic cloud made in {time.perf_counter() - t:.1f} s")
    run(cloud, "synthetic face", prefetch=False)
    run(cloud, "synthetic face", prefetch=True)


if __name__ == "__main__":
    main()
