"""Choose which points to draw when a cloud is too big to display (pure numpy).

Roughness is always computed on every point; only drawing is thinned. The kept
points are spread evenly over the surface: the cloud is cut into small cubes
(voxels) sized so about ``max_points`` of them are occupied, and one random point
is kept per voxel; dense areas near the scanner are thinned most.
"""

from __future__ import annotations

import numpy as np


def _occupied_voxels(xyz: np.ndarray, lo: np.ndarray, size: float) -> tuple[np.ndarray, int]:
    ijk = np.floor((xyz - lo) / size).astype(np.int64)
    dims = ijk.max(axis=0) + 1
    key = (ijk[:, 0] * dims[1] + ijk[:, 1]) * dims[2] + ijk[:, 2]
    uniq, inverse = np.unique(key, return_inverse=True)
    return inverse, len(uniq)


def display_subset(xyz: np.ndarray, max_points: int, *, seed: int = 0) -> np.ndarray:
    """Sorted indices of at most ``max_points`` points, spread evenly over the surface.

    Parameters
    ----------
    xyz
        ``(N, 3)`` point positions in metres.
    max_points
        Display budget; if ``N <= max_points`` every index is returned.
    seed
        Random seed (the same cloud and seed give the same subset).

    Returns
    -------
    np.ndarray
        ``(K,)`` int64 indices into ``xyz``, ascending, ``K <= max_points``.
    """
    n = len(xyz)
    if n <= max_points:
        return np.arange(n, dtype=np.int64)
    if max_points <= 0:
        return np.zeros(0, dtype=np.int64)
    rng = np.random.default_rng(seed)
    lo = xyz.min(axis=0)
    extent = float(np.max(xyz.max(axis=0) - lo)) or 1.0
    # Estimate the surface area from a coarse voxel count, then size the fine
    # voxels so about max_points of them are occupied (a surface: count ~ 1/size^2).
    coarse = extent / 256.0
    _, n_coarse = _occupied_voxels(xyz, lo, coarse)
    size = coarse * np.sqrt(n_coarse / max_points)
    inverse, _ = _occupied_voxels(xyz, lo, size)
    # One random representative per voxel: the first point of each voxel in a
    # random order of the points.
    perm = rng.permutation(n)
    _, first = np.unique(inverse[perm], return_index=True)
    chosen = perm[first]
    if len(chosen) > max_points:
        chosen = rng.choice(chosen, size=max_points, replace=False)
    elif len(chosen) < max_points:
        taken = np.zeros(n, dtype=bool)
        taken[chosen] = True
        rest = perm[~taken[perm]][: max_points - len(chosen)]
        chosen = np.concatenate([chosen, rest])
    return np.sort(chosen).astype(np.int64)
