"""Peak memory of each reader per byte of file and per point: the figures of
``rough_viewer.io.estimates.COSTS`` (issue 21, "honest estimates").

    PYTHONPATH=. python benchmarks/bench_read_memory.py [--points 400000] [--repeat 3]

For each format, files of several shapes are written (text rows of 3 short numbers,
of full-precision numbers, of 9 columns; LAS/LAZ with and without colour; PLY and STL
ASCII and binary; E57; NPY) at two sizes, and each is read by its reader in a fresh
process (in that process, not isolated: the reader's own cost). A process reports
its peak resident memory (``VmHWM``) and address space (``VmPeak``) above what it
held just before the read. Per format it prints the largest peak per point of the
larger files (where the libraries' fixed buffers no longer count) and the largest
peak per byte of file of the worst shapes (a text file of one long line of numbers,
of digits), beside the figures the estimates use. The fixed part (lazrs' thread pool
and buffers, the same for every file) is covered by the isolated reader's allowance
(``rough_viewer.io.sandbox.isolate.CHILD_ALLOWANCE``), not by the estimates. Prints the
median over ``--repeat`` runs of each file.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

#: Code run in a fresh process: read FILE with the reader of KIND, print the peaks.
_CHILD = r"""
import json, sys
from pathlib import Path
import numpy as np, laspy, lazrs
import rough_viewer.io.load as load
def status():
    out = {}
    for line in open("/proc/self/status"):
        k, _, v = line.partition(":")
        if k in ("VmRSS", "VmHWM", "VmSize", "VmPeak"):
            out[k] = int(v.split()[0]) * 1024
    return out
p = Path(sys.argv[1])
reader = load.reader_for(p)
module, _, name = reader.read.partition(":")
import importlib
fn = getattr(importlib.import_module(module), name)
if p.suffix == ".e57":
    import pye57
if p.suffix == ".ply":
    import plyfile
# a clean peak counter: VmHWM restarts at the current RSS
open("/proc/self/clear_refs", "w").write("5")
before = status()
n = -1
try:
    cloud = fn(p, progress=None, max_points=None)
    n = cloud.n
except Exception as exc:
    n = -1
after = status()
print(json.dumps({"rss": after["VmHWM"] - before["VmRSS"],
                  "vm": after["VmPeak"] - before["VmSize"], "n": n}))
"""


def _text_rows(rng: np.random.Generator, n: int, kind: str) -> str:
    xyz = rng.uniform(0.0, 100.0, (n, 3)) + [512_000.0, 4_170_000.0, 100.0]
    if kind == "short":
        return "\n".join(f"{a:.3f} {b:.3f} {c:.3f}" for a, b, c in xyz) + "\n"
    if kind == "precise":
        return "\n".join(f"{float(a)!r},{float(b)!r},{float(c)!r}" for a, b, c in xyz) + "\n"
    extra = rng.integers(0, 65535, (n, 6))
    return "\n".join(" ".join([f"{a:.4f}", f"{b:.4f}", f"{c:.4f}"] + [str(e) for e in row])
                     for (a, b, c), row in zip(xyz, extra, strict=True)) + "\n"


def make_files(folder: Path, n: int) -> list[tuple[str, str, Path, int, bool]]:
    """(cost kind, shape, path, points, worst) of every file."""
    import laspy
    from plyfile import PlyData, PlyElement

    from rough_viewer.io.cloud import PointCloud
    from rough_viewer.io.formats.las import write_las

    rng = np.random.default_rng(0)
    out: list[tuple[str, str, Path, int, bool]] = []
    xyz = rng.uniform(0.0, 100.0, (n, 3)) + [512_000.0, 4_170_000.0, 100.0]
    cloud = PointCloud.from_xyz(xyz, intensity=rng.integers(0, 65535, n).astype(np.uint16))
    for suffix in (".laz", ".las"):
        path = folder / f"plain_{n}{suffix}"
        write_las(path, cloud)
        out.append((suffix[1:], "format 1, intensity", path, n, False))
        path = folder / f"rgb_{n}{suffix}"
        hdr = laspy.LasHeader(point_format=7, version="1.4")
        hdr.scales, hdr.offsets = [1e-4] * 3, np.floor(xyz.min(axis=0))
        las = laspy.LasData(hdr)
        las.x, las.y, las.z = xyz.T
        las.red, las.green, las.blue = rng.integers(0, 65535, (3, n)).astype(np.uint16)
        las.write(str(path), do_compress=suffix == ".laz")
        out.append((suffix[1:], "format 7, RGB", path, n, False))
    for shape in ("short", "precise", "wide"):
        path = folder / f"{shape}_{n}.xyz"
        path.write_text(_text_rows(rng, n, shape))
        out.append(("text", f"rows: {shape}", path, n, False))
    path = folder / f"oneline_{n}.xyz"  # one row of 3 n numbers: a bad layout
    path.write_text(" ".join(f"{v:.4f}" for v in xyz.ravel()) + "\n0 0 0\n1 0 0\n")
    out.append(("text", "one long line", path, 3, True))
    path = folder / f"digits_{n}.xyz"  # one row of 3 n digits: the worst layout
    path.write_text(" ".join(str(v) for v in rng.integers(0, 10, 3 * n)) + "\n0 0 0\n1 0 0\n")
    out.append(("text", "one long line of digits", path, 3, True))
    rec = np.empty(n, dtype=[("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("i", "<u2")])
    rec["x"], rec["y"], rec["z"] = xyz.T
    rec["i"] = 7
    path = folder / f"bin_{n}.ply"
    PlyData([PlyElement.describe(rec, "vertex")], byte_order="<").write(str(path))
    out.append(("ply-binary", "f8 x, y, z + u2", path, n, False))
    path = folder / f"ascii_{n}.ply"
    PlyData([PlyElement.describe(rec, "vertex")], text=True).write(str(path))
    out.append(("ply-ascii", "ASCII rows", path, n, False))
    path = folder / f"ascii_wide_{n}.ply"
    wide = np.empty(n, dtype=[("x", "<f8"), ("y", "<f8"), ("z", "<f8")]
                    + [(f"s{k}", "<f4") for k in range(6)])
    wide["x"], wide["y"], wide["z"] = xyz.T
    for k in range(6):
        wide[f"s{k}"] = rng.random(n)
    PlyData([PlyElement.describe(wide, "vertex")], text=True).write(str(path))
    out.append(("ply-ascii", "ASCII rows of 9", path, n, False))
    m = max(1, n // 3)
    tri = rng.uniform(0.0, 10.0, (m, 3, 3)).astype(np.float32)
    path = folder / f"bin_{n}.stl"
    data = np.zeros(m, dtype=[("normal", "<f4", (3,)), ("v", "<f4", (3, 3)), ("attr", "<u2")])
    data["v"] = tri
    with open(path, "wb") as fh:
        fh.write(b"\0" * 80 + np.uint32(m).tobytes())
        data.tofile(fh)
    out.append(("stl-binary", "binary", path, 3 * m, False))
    path = folder / f"ascii_{n}.stl"
    with open(path, "w") as fh:
        fh.write("solid bench\n")
        for t in tri:
            fh.write(" facet normal 0 0 1\n  outer loop\n")
            for v in t:
                fh.write(f"   vertex {v[0]:.6e} {v[1]:.6e} {v[2]:.6e}\n")
            fh.write("  endloop\n endfacet\n")
        fh.write("endsolid bench\n")
    out.append(("stl-ascii", "ASCII", path, 3 * m, False))
    path = folder / f"pts_{n}.npy"
    np.save(path, xyz)
    out.append(("npy", "(N, 3) float64", path, n, False))
    try:
        import pye57

        path = folder / f"scan_{n}.e57"
        e57 = pye57.E57(str(path), mode="w")
        e57.write_scan_raw({"cartesianX": xyz[:, 0], "cartesianY": xyz[:, 1],
                            "cartesianZ": xyz[:, 2],
                            "intensity": rng.random(n).astype(np.float32)})
        e57.close()
        out.append(("e57", "float64 x, y, z + intensity", path, n, False))
    except ImportError:
        pass
    return out


def measure(path: Path, repeat: int) -> tuple[float, float]:
    """Median (resident, address-space) peak above the start, bytes (the reader must
    read the file: a failure stops the benchmark)."""
    rss, vm = [], []
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", MALLOC_ARENA_MAX="4")
    for _ in range(repeat):
        out = subprocess.run([sys.executable, "-c", _CHILD, str(path)], capture_output=True,
                             text=True, env=env, check=True)
        got = json.loads(out.stdout.strip().splitlines()[-1])
        if got["n"] < 0:
            raise SystemExit(f"the reader failed on {path}")
        rss.append(got["rss"])
        vm.append(got["vm"])
    return statistics.median(rss), statistics.median(vm)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=400_000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--only", nargs="*", default=None, metavar="FORMAT",
                        help="measure these formats only (laz las text ply-ascii ...)")
    args = parser.parse_args()
    from rough_viewer.io.estimates import COSTS

    rows: dict[str, list[tuple[int, int, float, float, bool]]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        print(f"{'format':<11} {'shape':<28} {'points':>9} {'file MB':>8} {'peak MiB':>9} "
              f"{'VM MiB':>8} {'B/byte':>7} {'B/point':>8}")
        for n in (args.points // 4, args.points):
            for kind, shape, path, points, worst in make_files(folder, n):
                if args.only and kind not in args.only:
                    path.unlink()
                    continue
                size = path.stat().st_size
                rss, vm = measure(path, args.repeat)
                rows.setdefault(kind, []).append((size, points, rss, vm, worst))
                print(f"{kind:<11} {shape:<28} {points:>9,} {size / 1e6:>8.1f} "
                      f"{rss / 2**20:>9.1f} {vm / 2**20:>8.1f} {rss / size:>7.1f} "
                      f"{rss / max(points, 1):>8.1f}", flush=True)
                path.unlink()
    print()
    print(f"{'format':<11} {'B/point':>8} {'VM/point':>9} {'worst B/byte':>13}   "
          "in COSTS (per point, worst per byte)")
    for kind, got in rows.items():
        big = max(n for _, n, _, _, w in got if not w)
        per_point = max(r / n for _, n, r, _, w in got if not w and n == big)
        vm_point = max(v / n for _, n, _, v, w in got if not w and n == big)
        worst = max((r / s for s, _, r, _, w in got if w), default=0.0)
        c = COSTS[kind]
        print(f"{kind:<11} {per_point:>8.1f} {vm_point:>9.1f} {worst:>13.1f}   "
              f"({c.per_point:g}, {c.worst_per_byte:g})")


if __name__ == "__main__":
    main()
