"""PLY reading: our reader (rough_viewer.io.formats.ply.read_ply) against plyfile, on the
same files, to decide which one load_points uses (issue 15: plyfile for reading too
if it is at least as fast).

    PYTHONPATH=. python benchmarks/bench_ply_read.py [--points 2000000] [--repeat 5]

Prints the median seconds of each reader on: binary little-endian float64 x, y, z
plus three scalar properties (as our exports write), binary big-endian float32
x, y, z, and ASCII x, y, z (a tenth of the points).
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
from timing import median_seconds


def make_files(folder: Path, n: int) -> dict[str, Path]:
    from plyfile import PlyData, PlyElement

    rng = np.random.default_rng(0)
    xyz = rng.uniform(0.0, 100.0, (n, 3)) + [512_000.0, 4_170_000.0, 100.0]
    files = {}
    rec = np.empty(n, dtype=[("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("theta_odr", "<f4"),
                             ("cell_ix", "<i4"), ("cell_points", "<u4")])
    rec["x"], rec["y"], rec["z"] = xyz.T
    files["binary LE f8 + 3 props"] = folder / "le.ply"
    PlyData([PlyElement.describe(rec, "vertex")], byte_order="<").write(str(files["binary LE f8 + 3 props"]))
    rec32 = np.empty(n, dtype=[("x", ">f4"), ("y", ">f4"), ("z", ">f4")])
    rec32["x"], rec32["y"], rec32["z"] = (xyz - xyz.min(axis=0)).T
    files["binary BE f4"] = folder / "be.ply"
    PlyData([PlyElement.describe(rec32, "vertex")], byte_order=">").write(str(files["binary BE f4"]))
    m = max(3, n // 10)
    files[f"ASCII ({m:,} points)"] = folder / "ascii.ply"
    PlyData([PlyElement.describe(rec[:m], "vertex")], text=True).write(
        str(files[f"ASCII ({m:,} points)"]))
    faces = np.empty(2 * n, dtype=[("vertex_indices", "O")])
    faces["vertex_indices"] = list(rng.integers(0, n, (2 * n, 3)).astype(np.int32))
    files["binary mesh f4 + 2N triangles"] = folder / "mesh.ply"
    PlyData([PlyElement.describe(rec32, "vertex"),
             PlyElement.describe(faces, "face", val_types={"vertex_indices": "int32"})],
            byte_order=">").write(str(files["binary mesh f4 + 2N triangles"]))
    return files


def read_plyfile(path: Path):
    """plyfile (memory-mapped where it can), then the same finite-row step as ours."""
    from plyfile import PlyData

    from rough_viewer.io.cloud import finite_cloud

    v = PlyData.read(str(path))["vertex"].data
    x, y, z = (np.asarray(v[k], dtype=np.float64) for k in "xyz")
    return finite_cloud(x, y, z, None, path)


def read_ours(path: Path):
    from rough_viewer.io.formats.ply import read_ply

    return read_ply(path)


def median_time(fn, path: Path, repeat: int) -> float:
    return median_seconds(lambda: fn(path), repeat)[0]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=2_000_000)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        files = make_files(Path(tmp), args.points)
        print(f"{'file':32} {'ours (s)':>10} {'plyfile (s)':>12}")
        for label, path in files.items():
            a = read_ours(path)
            b = read_plyfile(path)
            assert np.array_equal(a.xyz(), b.xyz()), label
            ours = median_time(read_ours, path, args.repeat)
            theirs = median_time(read_plyfile, path, args.repeat)
            print(f"{label:32} {ours:10.3f} {theirs:12.3f}")


if __name__ == "__main__":
    main()
