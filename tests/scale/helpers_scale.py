"""Clouds split into LAS/LAZ files whose cells straddle chunk and file boundaries."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rough_viewer.io import PointCloud, load_points, write_las
from tests.helpers import UTM, random_rotation, rough_surface

FIELDS = ("theta_odr", "theta_ols", "theta_hybrid", "e_ols", "normal", "centroid", "centre")


def split_files(folder: Path, n: int = 24_000, parts: tuple[float, ...] = (0.3, 0.45),
                seed: int = 5, suffix: str = ".laz") -> tuple[list[Path], np.ndarray]:
    """A tilted rough surface at UTM coordinates, shuffled and cut into files of
    unequal size: every file covers the whole extent (overlapping extents), so nearly
    every cell has points in every file and in several chunks.

    Returns the paths and the points as read back (metres, file order)."""
    xyz = rough_surface(n, seed=seed, size=3.0) @ random_rotation(seed).T * [1, 1, 0.3] + UTM
    xyz = xyz[np.random.default_rng(seed).permutation(n)]
    cuts = [int(f * n) for f in np.cumsum(parts)]
    paths = []
    for i, piece in enumerate(np.split(xyz, cuts)):
        p = folder / f"part{i}{suffix}"
        write_las(p, PointCloud.from_xyz(piece))
        paths.append(p)
    read = [load_points(p, cache=False) for p in paths]
    return paths, np.concatenate([np.column_stack([c.x, c.y, c.z]) for c in read])


def assert_same_cells(res, ref, rtol: float = 1e-9) -> None:
    """Identical cells and counts; every per-cell value within ``rtol`` relative.

    Values that are zero by construction (a 3-point cell's roughness, a normal's
    vanishing component) carry rounding residue (~1e-18 m) where a relative
    comparison means nothing: an absolute floor of ``1e-12`` of the cell size (of 1
    for unit normals) covers them."""
    np.testing.assert_array_equal(res.ijk, ref.ijk)
    np.testing.assert_array_equal(res.n_points, ref.n_points)
    np.testing.assert_array_equal(res.grid.origin, ref.grid.origin)
    assert res.axis == ref.axis and res.n_points_total == ref.n_points_total
    g = ref.grid.cell_size
    for name in FIELDS:
        a, b = getattr(res, name), getattr(ref, name)
        np.testing.assert_array_equal(np.isnan(a), np.isnan(b), err_msg=name)
        ok = ~np.isnan(b)
        floor = 1e-12 if name == "normal" else 1e-12 * g
        bad = np.abs(a[ok] - b[ok]) > rtol * np.abs(b[ok]) + floor
        assert not bad.any(), f"{name}: {a[ok][bad][:3]} != {b[ok][bad][:3]}"
