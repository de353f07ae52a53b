"""Server-side timings of the app on a big LAZ: seconds from reading the file to the
first coloured map, then for a GUI change the seconds of the map's own jobs on the
worker (the grid and the points' colours: what the issue's targets time) and the
seconds until the app is idle again (the panels drawn too: the histogram and the
across-scales panel, and with ``--panels`` the semivariograms): a preset grid, a
free grid, a model, and a few cheap changes.

    PYTHONPATH=. python benchmarks/bench_app.py --points 5000000 [--repeat 3]
    PYTHONPATH=. python benchmarks/bench_app.py --laz scan.laz --panels
    PYTHONPATH=. python benchmarks/bench_app.py --points 20000000   # ~6 GB: a big machine

The app is driven only through its public surface (``build_app``, the values of
the Map tab's GUI handles a browser sets, ``app.map``, ``App.wait_idle`` and the
worker's job records), so the benchmark keeps working
while the app's insides change. Without ``--panels`` the semivariogram panel is off
(``build_app(variogram=False)``); the other panels are always drawn. Idle prefetching of the presets is off, so every first visit
of a grid computes it (``--prefetch`` turns it on, as ``serve`` runs).

Each repeat builds a fresh app on the same cloud (its grid cache empty); figures are
medians over the repeats. Targets (issue 24, 20 M points): a preset grid change and
a model change within 0.5 s server side.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def synthetic_face(n: int, seed: int = 0):
    """A 40 m x 12 m vertical face in UTM-sized coordinates, waved, with noise that
    grows along it, the points in scan columns (as a terrestrial scanner writes them)."""
    from rough_viewer.io import PointCloud

    rng = np.random.default_rng(seed)
    x = rng.uniform(0.0, 40.0, n)
    z = rng.uniform(0.0, 12.0, n)
    y = 0.3 * np.sin(0.7 * x) * np.cos(0.9 * z) + (0.001 + 0.0005 * x) * rng.standard_normal(n)
    order = np.lexsort((z, np.floor(x / 0.02)))
    xyz = np.column_stack([x[order], y[order], z[order]]) + [512_000.0, 4_170_000.0, 100.0]
    return PointCloud.from_xyz(xyz, source=f"synthetic-{n}")


#: Jobs that make the map itself (the grid and the points' colours), not the panels.
MAP_JOBS = frozenset({"RenderJob", "ShowJob"})
#: Prefix of the map-only figure of a step.
MAP = "map: "


def _grid_sizes(options: tuple[str, ...]) -> list[str]:
    """The preset labels of the grid dropdown, coarsest first (``free`` left out)."""
    presets = [o for o in options if o != "free"]
    return sorted(presets, key=float, reverse=True)


def one_app(cloud, *, panels: bool, prefetch: bool) -> dict[str, float]:
    """Seconds of each step on a fresh app."""
    import viser

    from rough_viewer.app.server import build_app

    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    out: dict[str, float] = {}
    t = time.perf_counter()
    app = build_app(server, cloud, variogram=panels, prefetch=prefetch)
    app.wait_idle(None)
    out["first coloured map (build_app until idle)"] = time.perf_counter() - t
    g = app.map  # the Map tab's controls
    presets = _grid_sizes(tuple(g.grid.options))
    finest = float(presets[-1])
    free = float(f"{2.4 * finest:.2g}")
    other_model = next(o for o in g.model.options if o != g.model.value)

    def last() -> int:
        return max((r.number for r in app.worker.records), default=0)

    def step(name: str, change: Callable[[], None]) -> None:
        before = last()
        start = time.perf_counter()
        change()
        app.wait_idle(None)
        out[name] = time.perf_counter() - start
        # the map's own jobs (the grid and the colours), without the panels after them
        out[MAP + name] = sum(r.seconds for r in app.worker.records
                              if r.number > before and r.kind in MAP_JOBS)

    steps: list[tuple[str, Callable[[], None]]] = []
    if len(presets) >= 2:
        steps.append((f"preset grid {presets[-2]} (from {presets[-1]})",
                      lambda: setattr(g.grid, "value", presets[-2])))
        steps.append((f"preset grid {presets[0]}", lambda: setattr(g.grid, "value", presets[0])))
    steps += [
        (f"free grid {free:g}", lambda: setattr(g.grid_free, "value", free)),
        (f"back to preset {presets[-1]} (cached)", lambda: setattr(g.grid, "value", presets[-1])),
        (f"model {other_model}", lambda: setattr(g.model, "value", other_model)),
        ("threshold 0.2", lambda: setattr(g.threshold, "value", 0.2)),
        ("colour map cividis", lambda: setattr(g.colormap, "value", "cividis")),
    ]
    for name, change in steps:
        step(name, change)
    app.stop()
    server.stop()
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--points", type=int, default=5_000_000,
                    help="points of the synthetic LAZ written first (default 5 M)")
    ap.add_argument("--laz", help="read this LAS/LAZ instead of writing a synthetic one")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--panels", action="store_true", help="semivariogram panel on")
    ap.add_argument("--prefetch", action="store_true", help="idle prefetch of presets on")
    args = ap.parse_args()
    from rough_viewer.io import load_points, write_las

    print(f"load average: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    with tempfile.TemporaryDirectory() as tmp:
        os.environ["ROUGH_VIEWER_CACHE"] = str(Path(tmp) / "cache")  # a cold decode cache
        path = Path(args.laz) if args.laz else Path(tmp) / "face.laz"
        if not args.laz:
            t = time.perf_counter()
            write_las(path, synthetic_face(args.points))
            print(f"synthetic LAZ of {args.points:,} points written in "
                  f"{time.perf_counter() - t:.1f} s ({path.stat().st_size / 2**20:.0f} MiB)")
        t = time.perf_counter()
        cloud = load_points(path, cache=False)
        read = time.perf_counter() - t
        print(f"{path.name}: {cloud.n:,} points read (LAZ decoded, parallel lazrs) in {read:.2f} s")
        runs: dict[str, list[float]] = defaultdict(list)
        for _ in range(args.repeat):
            for name, sec in one_app(cloud, panels=args.panels, prefetch=args.prefetch).items():
                runs[name].append(sec)
    print(f"panels {'on' if args.panels else 'off'}, prefetch {'on' if args.prefetch else 'off'}; "
          f"median of {args.repeat} fresh apps, seconds: the map's own jobs (grid, colours) "
          "and until idle (the panels too)")
    for name, secs in runs.items():
        if name.startswith(MAP):
            continue
        own = runs.get(MAP + name)
        mine = f"{statistics.median(own):7.3f}" if own else " " * 7
        print(f"  {name:<44} {mine}   {statistics.median(secs):7.3f}")
    first = statistics.median(runs["first coloured map (build_app until idle)"])
    print(f"  read + first coloured map                    {read + first:7.3f}")
    print(f"load average: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
