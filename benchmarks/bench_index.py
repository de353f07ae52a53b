"""``rough-viewer index`` against a plain laspy decode + LAZ encode of the same points.

Makes ``--points`` points in ``--files`` LAZ files (format 6 with one extra dimension,
a rough surface; cached in ``--folder``), then times, ``--repeat`` times each, in
fresh processes under ``/usr/bin/time -v``:

- the floor: laspy reads every file in chunks and writes one LAZ of all the points;
- ``rough-viewer index FILES --out X.copc.laz --memory M [--workers N]``.

Prints the medians of wall time and peak RSS (the largest process of the tree) and
the ratio index / floor (issue 33's target: at most 3x).

    python benchmarks/bench_index.py --points 10000000 --files 5 --memory 1GB
"""

from __future__ import annotations

import argparse
import re
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

FLOOR = """
import sys, laspy
paths, out = sys.argv[1:-1], sys.argv[-1]
with laspy.open(paths[0]) as r0:
    header = r0.header
with laspy.open(out, mode="w", header=header, do_compress=True) as w:
    for p in paths:
        with laspy.open(p) as r:
            for pts in r.chunk_iterator(1_000_000):
                w.write_points(pts)
"""


def make_files(folder: Path, points: int, files: int) -> list[Path]:
    import laspy

    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    per = points // files
    rng = np.random.default_rng(0)
    for i in range(files):
        p = folder / f"scan_{points}_{i}.laz"
        paths.append(p)
        if p.exists():
            continue
        h = laspy.LasHeader(point_format=6, version="1.4")
        h.scales = np.array([0.0005, 0.0005, 0.0005])
        h.offsets = np.zeros(3)
        h.add_extra_dim(laspy.ExtraBytesParams(name="amplitude", type=np.float32))
        with laspy.open(p, mode="w", header=h) as w:
            for s in range(0, per, 1_000_000):
                n = min(1_000_000, per - s)
                rec = laspy.ScaleAwarePointRecord.zeros(n, header=h)
                x = rng.random(n) * 20 + i * 15
                y = rng.random(n) * 20
                rec.x, rec.y = x, y
                rec.z = 0.3 * np.sin(x) * np.cos(y) + rng.normal(0, 0.003, n)
                rec.intensity = rng.integers(0, 65535, n)
                rec.gps_time = np.sort(rng.random(n)) * 100 + i * 100
                rec.amplitude = rng.random(n).astype(np.float32)
                w.write_points(rec)
    return paths


def timed(cmd: list[str]) -> tuple[float, float]:
    """Wall seconds and peak RSS (MB) of a command under /usr/bin/time -v."""
    proc = subprocess.run(["/usr/bin/time", "-v", *cmd], capture_output=True, text=True)
    if proc.returncode:
        sys.exit(f"failed: {' '.join(cmd)}\n{proc.stderr[-2000:]}")
    wall = re.search(r"Elapsed \(wall clock\) time .*: (?:(\d+):)?(\d+):([\d.]+)", proc.stderr)
    rss = re.search(r"Maximum resident set size \(kbytes\): (\d+)", proc.stderr)
    assert wall and rss
    h, m, s = (float(g) if g else 0.0 for g in wall.groups())
    return h * 3600 + m * 60 + s, int(rss.group(1)) / 1024


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=10_000_000)
    ap.add_argument("--files", type=int, default=5)
    ap.add_argument("--memory", default="1GB")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--folder", type=Path, default=Path(tempfile.gettempdir()) / "bench_index")
    a = ap.parse_args()
    paths = make_files(a.folder, a.points, a.files)
    out = a.folder / "out.copc.laz"
    plain = a.folder / "plain.laz"
    floor, index = [], []
    for _ in range(a.repeat):
        floor.append(timed([sys.executable, "-c", FLOOR, *map(str, paths), str(plain)]))
        index.append(timed([sys.executable, "-m", "rough_viewer", "index", *map(str, paths),
                            "--out", str(out), "--force", "--quiet", "--memory", a.memory,
                            "--workers", str(a.workers)]))
    ft = statistics.median(t for t, _ in floor)
    it = statistics.median(t for t, _ in index)
    print(f"{a.points:,} points in {a.files} LAZ files, --memory {a.memory}, "
          f"--workers {a.workers}, median of {a.repeat}")
    print(f"  laspy decode + encode: {ft:7.1f} s  peak RSS {statistics.median(r for _, r in floor):6.0f} MB")
    print(f"  rough-viewer index:    {it:7.1f} s  peak RSS {statistics.median(r for _, r in index):6.0f} MB"
          f"  ({a.points / it / 1e6:.2f} M points/s)")
    print(f"  index / floor: {it / ft:.2f}x; COPC {out.stat().st_size / 1e6:.0f} MB, "
          f"plain LAZ {plain.stat().st_size / 1e6:.0f} MB")


if __name__ == "__main__":
    main()
