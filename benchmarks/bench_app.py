"""Server-side timings of the app: seconds from a GUI change until the point
colours are assigned (``colours_s``), and until the panels are refreshed.

    PYTHONPATH=. python benchmarks/bench_app.py [--points 5000000] [--demo]

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


def run(cloud, label: str, *, prefetch: bool) -> None:
    import viser

    from rough_viewer.app.server import build_app
    from rough_viewer.app.state import PRESET_CELL_SIZES

    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    t0 = time.perf_counter()
    app = build_app(server, cloud, variogram=True, prefetch=prefetch)
    app.wait_idle(None)
    how = "idle prefetch of presets ON" if prefetch else "no prefetch (plain core)"
    print(f"\n{label}: {cloud.n:,} points, {app.shown.loaded.n_display:,} shown; {how}")
    print(f"  build_app + first map (0.25 m): {time.perf_counter() - t0:6.2f} s "
          f"(colours {app.timings[-1]['colours_s']:.2f} s, panels "
          f"{app.timings[-1].get('panels_s', float('nan')):.2f} s)")
    if prefetch:
        t = time.perf_counter()
        loaded = app.shown.loaded
        while not all(loaded.is_cached(app.shown.settings.with_(cell_size=c))
                      for c in PRESET_CELL_SIZES):
            time.sleep(0.02)
        print(f"  presets prefetched in the background after {time.perf_counter() - t:.2f} s")
    g = app.gui
    steps = [
        ("preset grid 0.5 m", lambda: setattr(g.grid, "value", "0.5")),
        ("preset grid 1 m", lambda: setattr(g.grid, "value", "1")),
        ("preset grid 0.125 m", lambda: setattr(g.grid, "value", "0.125")),
        ("free grid 0.3 m", lambda: setattr(g.grid_free, "value", 0.3)),
        ("preset grid 0.5 m", lambda: setattr(g.grid, "value", "0.5")),
        ("model OLS", lambda: setattr(g.model, "value", "OLS")),
        ("binary view", lambda: setattr(g.display, "value", "binary")),
        ("threshold 0.2", lambda: setattr(g.threshold, "value", 0.2)),
        ("colour map cividis", lambda: setattr(g.colormap, "value", "cividis")),
    ]
    for name, action in steps:
        t = time.perf_counter()
        action()
        app.wait_idle(None)
        rec = app.timings[-1]
        state = "cached " if rec["cached"] else "compute"
        print(f"  {name:22s} {state} colours {rec['colours_s']:6.3f} s   panels "
              f"{rec.get('panels_s', 0.0):6.3f} s   wall {time.perf_counter() - t:6.3f} s")
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
        run(demo, "demo outcrop", prefetch=True)
    t = time.perf_counter()
    cloud = synthetic_face(args.points)
    print(f"synthetic cloud made in {time.perf_counter() - t:.1f} s")
    run(cloud, "synthetic face", prefetch=False)
    run(cloud, "synthetic face", prefetch=True)


if __name__ == "__main__":
    main()
