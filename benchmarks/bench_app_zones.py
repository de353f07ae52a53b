"""Benchmark of the app's Zones tab, in the app's job path: how long after a move of
the threshold slider the zones are re-labelled and coloured in the scene.

On a running app (``build_app`` on a real viser server, no browser) with "Show
zones" ticked, for each grid size the Map tab's threshold is set (as a browser's
slider message does) to each value in turn; the worker then runs the map's view
job (the map's colours), the zone job (re-label and colour the zone cloud) and
the zone-table job (table, numbers, stereonet). Printed, as medians over the
thresholds and ``--repeat`` rounds:

- ``slider->zones``: from setting the slider until the zone colours are assigned
  (what the issue's "re-labels in under 0.5 s" asks), the map's view job included;
- ``view``: the map's view job (recolours the map's hidden cloud);
- ``label``: the labels alone; ``zones job``: labels, colours and status;
- ``table``: the table, numbers and stereonet after that;
- ``first``: turning zones on for the grid (the labeller built once per grid, the
  zone cloud sent once per loaded cloud);
- the server's resident memory before zones are turned on and after the thresholds.

    PYTHONPATH=. python benchmarks/bench_app_zones.py                  # 5 M points
    PYTHONPATH=. python benchmarks/bench_app_zones.py --points 1e6 --grids 0.25 --repeat 2
    PYTHONPATH=. python benchmarks/bench_app_zones.py --input scan.laz --grids 2 1
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_compute import synthetic_outcrop  # noqa: E402


def rss_mb() -> float:
    """Resident memory of this process, MiB."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def last(app, kind: str):
    return next(r for r in reversed(app.worker.records) if r.kind == kind)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--points", type=float, default=5e6)
    ap.add_argument("--input", help="a point-cloud file instead of the synthetic outcrop")
    ap.add_argument("--grids", type=float, nargs="+", default=[0.25, 0.125, 0.0625])
    ap.add_argument("--thresholds", type=float, nargs="+", default=[0.05, 0.1, 0.2, 0.4])
    ap.add_argument("--display", choices=("binary", "continuous"), nargs="+",
                    default=["binary", "continuous"], help="the Map tab's display")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()

    import viser

    from rough_viewer.app.binding import assign
    from rough_viewer.app.features.zones import ZonesFeature
    from rough_viewer.app.server import build_app
    from rough_viewer.io.load import load_points

    cloud = load_points(args.input) if args.input else synthetic_outcrop(int(args.points))
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = build_app(server, cloud, prefetch=False, variogram=False)
    app.wait_idle(None)
    m = app.feature(ZonesFeature)
    g = app.map
    print(f"Zones tab, {cloud.n:,} points ({app.session.shown.loaded.n_display:,} shown); "
          f"medians of {len(args.thresholds)} thresholds x {args.repeat} rounds; "
          f"{os.cpu_count()} cores; server memory {rss_mb():.0f} MiB")
    print(f"{'g (m)':>7} {'cells':>9} {'display':>10} {'zones':>11} {'first (s)':>9} "
          f"{'slider->zones':>13} {'view':>6} {'label':>6} {'zones job':>9} {'table':>6} "
          f"{'RSS MiB (zones off -> on)':>25}")
    for cell in args.grids:
        assign(g.grid_free, cell)
        app.wait_idle(None)
        for display in args.display:
            assign(g.display, display)
            app.wait_idle(None)
            assign(g.threshold, 0.5)  # not among the thresholds timed
            app.wait_idle(None)
            rss0 = rss_mb()
            t0 = time.perf_counter()
            assign(m.on, True)
            app.wait_idle(None)
            first = time.perf_counter() - t0
            rows: dict[str, list[float]] = {k: [] for k in ("wall", "view", "label", "job",
                                                            "table")}
            counts = []
            for _ in range(args.repeat):
                for thr in args.thresholds:
                    n = len(m.timings)
                    t0 = time.perf_counter()
                    assign(g.threshold, thr)
                    app.wait_idle(None)
                    assert len(m.timings) == n + 1, "no re-label"
                    rec = m.timings[-1]
                    rows["wall"].append(rec["done"] - t0)
                    rows["view"].append(last(app, "RenderJob").seconds)
                    rows["label"].append(rec["label_s"])
                    rows["job"].append(last(app, "ZonesJob").seconds)
                    rows["table"].append(last(app, "ZoneTableJob").seconds)
                    assert m.labelling is not None
                    counts.append(m.labelling.n_zones)
            med = {k: statistics.median(v) for k, v in rows.items()}
            assert app.session.shown.result is not None
            print(f"{cell:7g} {app.session.shown.result.n_cells:9,} {display:>10} "
                  f"{min(counts):>5,}-{max(counts):<5,} {first:9.2f} {med['wall']:13.3f} "
                  f"{med['view']:6.3f} {med['label']:6.3f} {med['job']:9.3f} "
                  f"{med['table']:6.3f} {rss0:12.0f} -> {rss_mb():<9.0f}")
            assign(m.on, False)
            app.wait_idle(None)
    print(f"zone cache {m.cache.bytes / 2**20:.0f} MiB of {m.cache.budget / 2**20:.0f} MiB; "
          f"grid cache {app.session.shown.loaded.cached_bytes / 2**20:.0f} MiB")
    app.stop()
    server.stop()


if __name__ == "__main__":
    main()
