"""Level of detail at survey scale: octree build time against LAZ decode time, memory
per point, and the per-camera costs (selection, encoding, recolouring a budget).

    PYTHONPATH=. python benchmarks/bench_lod.py [--points 20000000] [--repeat 3]
        [--cameras 50] [--budget 3000000] [--folder /tmp/rough_viewer_bench_lod]
    PYTHONPATH=. python benchmarks/bench_lod.py --points 100000000   # needs ~9 GB: see below
    PYTHONPATH=. python benchmarks/bench_lod.py --points 100000000 --in-memory  # ~5 GB

The input is a synthetic outcrop written once as LAZ (LAS 1.4 point format 7:
intensity and RGB, as terrestrial scans are exported) into ``--folder`` and reused.
Every figure is the median of ``--repeat`` runs (cameras: of ``--cameras``).

- decode: :func:`rough_viewer.io.load.load_points` without the cache (lazrs,
  parallel where installed); build: :func:`rough_viewer.lod.build_octree`;
- memory: the octree's own bytes per point, the build's peak of new allocations
  (tracemalloc sees numpy's arrays) per point, and the peak RSS of a fresh process
  that reads the LAZ and builds the octree (``VmHWM``), against the issue's target of
  64 bytes per point plus 1 GB;
- per camera (random cameras around and inside the cloud, 1920 x 1080 windows):
  :func:`rough_viewer.lod.select_nodes` within the budget, encoding the selected
  nodes (:func:`rough_viewer.lod.encode_node`), and gathering their colours from a
  per-point colour array in one call (:func:`rough_viewer.lod.nodes_colours`: what a
  model change costs on every resident node, server side, before the colours go out).

Targets (issue 23, 100 M points, 2 cores): build within 1.5 x the decode time; peak
RSS at most 64 B/point + 1 GB. At 100 M the points alone are 2.4 GB, the decode
peaks near 75 B/point (``rough_viewer.io.formats.las.READ_BYTES_PER_POINT``) and the build at
16 B/point more: run it only where ``free -g`` shows 10 GB free. ``--in-memory``
generates the same points in memory instead (no LAZ, no decode figures): the build,
memory and per-camera figures at 100 M within about 5 GB.
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

CHUNK = 2_000_000
OFFSET = np.array([512_000.0, 4_170_000.0, 100.0])


def outcrop_chunk(start: int, n: int, total: int) -> tuple[np.ndarray, np.ndarray]:
    """Points ``start .. start + n`` of a ``total``-point synthetic outcrop: a 100 m x
    20 m face (x along it, z up) facing -y, undulating at 10 m and 1 m, cut by vertical
    and horizontal joints (grooves 2-8 cm wide), with a talus fan at its foot, 2 mm of
    noise; and the intensity."""
    rng = np.random.default_rng([7, start])
    x = rng.uniform(0.0, 100.0, n)
    z = rng.uniform(0.0, 20.0, n)
    y = 0.8 * np.sin(0.6 * x) * np.cos(0.3 * z) + 0.05 * np.sin(6.0 * x + 2.0 * z)
    joint_x = np.abs(((x + 1.3) % 2.7) - 1.35)
    joint_z = np.abs(((z + 0.4) % 1.9) - 0.95)
    y += np.where(joint_x < 0.04, 0.06, 0.0) + np.where(joint_z < 0.02, 0.04, 0.0)
    talus = z < 2.0
    y[talus] -= (2.0 - z[talus]) * 1.5 * rng.random(int(talus.sum()))
    y += rng.normal(0.0, 0.002, n)
    intensity = (30_000 + 10_000 * np.sin(0.1 * x) + rng.normal(0, 2000, n)).clip(0, 65535)
    return np.column_stack([x, y, z]) + OFFSET, intensity.astype(np.uint16)


def make_laz(path: Path, total: int) -> None:
    """Write the synthetic outcrop as LAZ, a chunk at a time."""
    import laspy

    from rough_viewer.io.formats.las import laz_backend

    header = laspy.LasHeader(version="1.4", point_format=7)
    header.scales = np.array([1e-4, 1e-4, 1e-4])
    header.offsets = OFFSET
    tmp = path.with_suffix(".part.laz")
    with laspy.open(tmp, mode="w", header=header, do_compress=True,
                    laz_backend=laz_backend()) as writer:
        for start in range(0, total, CHUNK):
            n = min(CHUNK, total - start)
            xyz, intensity = outcrop_chunk(start, n, total)
            rec = laspy.ScaleAwarePointRecord.zeros(n, header=header)
            rec.x, rec.y, rec.z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
            rec.intensity = intensity
            shade = (intensity >> 1).astype(np.uint16)
            rec.red, rec.green, rec.blue = shade, shade, shade
            rec.return_number = np.ones(n, dtype=np.uint8)
            rec.number_of_returns = np.ones(n, dtype=np.uint8)
            writer.write_points(rec)
    tmp.replace(path)


def median_time(fn, repeat: int) -> tuple[float, float, object]:
    """Median wall-clock and CPU seconds (all threads) of ``fn()``, and its result."""
    walls, cpus, out = [], [], None
    for _ in range(repeat):
        out = None
        t, c = time.perf_counter(), time.process_time()
        out = fn()
        walls.append(time.perf_counter() - t)
        cpus.append(time.process_time() - c)
    return statistics.median(walls), statistics.median(cpus), out


def random_camera(rng, lo, hi, cloud_xyz_sample):
    from rough_viewer.lod import ViewCamera

    centre, extent = 0.5 * (lo + hi), float(np.max(hi - lo))
    target = cloud_xyz_sample[rng.integers(cloud_xyz_sample.shape[0])]
    if rng.random() < 0.4:  # close to the rock: 0.5 to 5 m in front of a patch
        position = target + np.array([0.0, -1.0, 0.0]) * rng.uniform(0.5, 5.0) + rng.normal(0, 0.3, 3)
    else:
        d = rng.normal(size=3)
        d[1] = -abs(d[1]) - 0.5  # from the open side of the face
        position = centre + d / np.linalg.norm(d) * extent * rng.uniform(0.2, 1.2)
    return ViewCamera.looking_at(position, target, fov_rad=math.radians(50.0),
                                 aspect=16 / 9, height_px=1080)


def peak_rss_child(path: Path) -> str:
    """Peak RSS of a fresh process that reads the LAZ and builds the octree."""
    code = (
        "import sys\n"
        "from rough_viewer.io.load import load_points\n"
        "from rough_viewer.lod import build_octree\n"
        "c = load_points(sys.argv[1], cache=False)\n"
        "def hwm():\n"
        "    for line in open('/proc/self/status'):\n"
        "        if line.startswith('VmHWM'): return int(line.split()[1]) * 1024\n"
        "after_load = hwm()\n"
        "t = build_octree(c)\n"
        "print(c.n, after_load, hwm())\n"
    )
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parent.parent)}
    out = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True,
                         env=env, check=True).stdout.split()
    n, after_load, peak = int(out[0]), int(out[1]), int(out[2])
    target = 64 * n + 2**30
    return (f"peak RSS {peak / 2**30:.2f} GiB = {peak / n:.0f} B/point "
            f"(after reading {after_load / 2**30:.2f} GiB; target 64 B/point + 1 GB = "
            f"{target / 2**30:.2f} GiB: {'met' if peak <= target else 'MISSED'})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=20_000_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--cameras", type=int, default=50)
    ap.add_argument("--budget", type=int, default=3_000_000)
    ap.add_argument("--folder", default="/tmp/rough_viewer_bench_lod")
    ap.add_argument("--no-rss", action="store_true", help="skip the fresh-process peak RSS")
    ap.add_argument("--in-memory", action="store_true",
                    help="generate the points in memory (no LAZ written or decoded)")
    args = ap.parse_args()

    from rough_viewer.io.load import load_points
    from rough_viewer.lod import (
        Residency,
        build_bytes,
        build_octree,
        encode_node,
        nodes_colours,
        select_nodes,
    )

    n = args.points
    load = os.getloadavg()[0]
    if args.in_memory:
        from rough_viewer.io import PointCloud

        cols = [np.empty(n) for _ in range(3)]
        for start in range(0, n, CHUNK):
            xyz, _ = outcrop_chunk(start, min(CHUNK, n - start), n)
            for a in range(3):
                cols[a][start:start + xyz.shape[0]] = xyz[:, a]
        cloud = PointCloud(x=cols[0], y=cols[1], z=cols[2], source="in memory")
        print(f"\n{n:,} points in memory, {os.cpu_count()} CPUs; medians of {args.repeat} runs")
        decode_s = decode_cpu = math.nan
    else:
        folder = Path(args.folder)
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / f"outcrop_{args.points}.laz"
        if not path.exists():
            t = time.perf_counter()
            make_laz(path, args.points)
            print(f"wrote {path} ({path.stat().st_size / 2**20:.0f} MiB) in "
                  f"{time.perf_counter() - t:.0f} s")
        print(f"\n{n:,} points, {path.name}, {os.cpu_count()} CPUs; medians of {args.repeat} runs")
        decode_s, decode_cpu, cloud = median_time(lambda: load_points(path, cache=False),
                                                  args.repeat)
        print(f"  decode LAZ (load_points, no cache): {decode_s:7.2f} s wall, {decode_cpu:6.2f} s "
              f"CPU ({n / decode_s / 1e6:.1f} M points/s)")
    build_s, build_cpu, tree = median_time(lambda: build_octree(cloud), args.repeat)
    print(f"  build octree:                       {build_s:7.2f} s wall, {build_cpu:6.2f} s CPU "
          f"= {build_s / decode_s:.2f} x decode wall, {build_cpu / decode_cpu:.2f} x decode CPU "
          "(target <= 1.5 x)")
    print(f"  (load average {load:.1f} on {os.cpu_count()} CPUs when it started: wall times grow "
          "with it; CPU times do not)")
    print(f"  octree: {tree.n_nodes:,} nodes, depth {tree.depth}, root spacing "
          f"{tree.root_spacing * 100:.1f} cm, largest node {int(tree.counts.max()):,} points")
    print(f"  octree keeps {tree.nbytes / n:.2f} B/point ({tree.nbytes / 2**20:.0f} MiB)")
    tracemalloc.start()
    build_octree(cloud)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    print(f"  build peak of new allocations: {peak / n:.1f} B/point "
          f"(estimated {build_bytes(n) / n:.1f})")
    if not (args.no_rss or args.in_memory):
        print("  read + build in a fresh process: " + peak_rss_child(path))

    rng = np.random.default_rng(0)
    lo, hi = tree.box_lo[0], tree.box_hi[0]
    sample = np.column_stack([cloud.x[:: max(1, n // 100_000)], cloud.y[:: max(1, n // 100_000)],
                              cloud.z[:: max(1, n // 100_000)]])
    colours = np.zeros((n, 3), dtype=np.uint8)
    colours[:, 0] = (cloud.z * 10).astype(np.int64) % 256
    sel_ms, enc_ms, col_ms, points, nodes, sent = [], [], [], [], [], []
    tab = Residency(tree.counts, args.budget)
    for _ in range(args.cameras):
        cam = random_camera(rng, lo, hi, sample)
        t = time.perf_counter()
        sel = select_nodes(tree, cam, args.budget)
        sel_ms.append(1e3 * (time.perf_counter() - t))
        plan = tab.plan(sel.nodes)
        t = time.perf_counter()
        for k in plan.send:
            encode_node(cloud, tree.node(k))
        if plan.send:
            enc_ms.append(1e3 * (time.perf_counter() - t) / sum(int(tree.counts[k]) for k in plan.send)
                          * 1e6)
        t = time.perf_counter()
        nodes_colours(colours, tree, tab.shown)
        col_ms.append(1e3 * (time.perf_counter() - t))
        points.append(sel.points)
        nodes.append(sel.nodes.shape[0])
        sent.append(sum(int(tree.counts[k]) for k in plan.send))
    print(f"  per camera ({args.cameras} random cameras, budget {args.budget:,}, 1920 x 1080):")
    print(f"    select: median {statistics.median(sel_ms):.1f} ms, max {max(sel_ms):.1f} ms; "
          f"median {statistics.median(nodes):.0f} nodes, {statistics.median(points):,.0f} points "
          f"(max {max(points):,})")
    print(f"    encode float16: median {statistics.median(enc_ms):.0f} ms per million points; "
          f"median sent {statistics.median(sent):,.0f} points per camera, max {max(sent):,}")
    print(f"    colours of every shown node (one gather): median {statistics.median(col_ms):.0f} ms "
          f"for {statistics.median(points):,.0f} points")
    print(f"    tab holds {tab.held_points:,} points (<= 2 x budget = {2 * args.budget:,})")


if __name__ == "__main__":
    main()
