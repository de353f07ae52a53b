"""Choose an even overview sample of a cloud (pure numpy).

Roughness is always computed on every point, and browser tabs draw the cloud by level
of detail; this sample of at most ``max_points`` points serves what needs a look at
the whole cloud (the camera's framing, the point size). The kept points are spread
evenly over the surface: the cloud is cut into small cubes (voxels) sized so about
``max_points`` of them are occupied, and one point of each voxel is kept (the one
with the smallest fixed pseudo-random priority); dense areas near the scanner are
thinned most.

Linear in the points, without a sort (compiled where the kernels run: the same
keys, buckets and priorities in two passes): the voxels are hashed into a table about
:data:`TABLE_PER_POINT` times the sample's size and each bucket keeps its smallest
priority (``np.minimum.at``), a few million points at a time; two voxels that share a
bucket (a few per cent) give one point, and the sample is topped up at random to its
size. About 1.5 s for 20 M points on 2 cores (a sort-based voxel pass took 20 s).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rough_viewer.io.cloud import PointCloud, as_columns
from rough_viewer.memory import require

#: Hash-table buckets per point of the sample (collisions merge ~1 / (2 x this)).
TABLE_PER_POINT = 8
#: Points handled at a time (bounds the temporaries: about 40 bytes per point of a
#: chunk, besides 9 bytes per point of the cloud).
CHUNK = 1 << 22
#: Points the voxel size is estimated on.
ESTIMATE_POINTS = 1 << 20


def priority(index: np.ndarray, seed: int) -> np.ndarray:
    """(n,) float32 in [0, 1): a fixed pseudo-random number per point index
    (splitmix64 of the index and the seed), the same in every pass.

    >>> p = priority(np.arange(5), 0)
    >>> bool(np.all((p >= 0) & (p < 1))), bool(np.array_equal(p, priority(np.arange(5), 0)))
    (True, True)
    """
    z = index.astype(np.uint64) + np.uint64((int(seed) * 0x9E3779B97F4A7C15) % 2**64)
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    z ^= z >> np.uint64(31)
    return (z >> np.uint64(40)).astype(np.float32) / np.float32(2**24)


def _keys(x: np.ndarray, y: np.ndarray, z: np.ndarray, lo: np.ndarray, size: float,
          dims: np.ndarray) -> np.ndarray:
    """The voxel key of each point (columns ``x, y, z``, metres): the voxel's index
    ``floor((p - lo) / size)`` per axis, clipped to ``dims``, flattened."""
    key = np.zeros(x.shape[0], dtype=np.int64)
    for axis, col in enumerate((x, y, z)):
        t = col - lo[axis]  # >= 0: lo is the minimum, so truncation is the floor
        t /= size
        i = t.astype(np.int64)
        del t
        np.minimum(i, dims[axis] - 1, out=i)
        if axis:
            key *= dims[axis]
        key += i
    return key


def _taken_compiled(x: np.ndarray, y: np.ndarray, z: np.ndarray, lo: np.ndarray, size: float,
                    dims: np.ndarray, seed: int, best: np.ndarray) -> np.ndarray | None:
    """Which points hold their bucket's smallest priority, by the compiled kernel (the
    same keys, buckets and priorities as the NumPy chunks, two passes over the
    coordinates and no per-point arrays but the answer); None where the kernels do
    not run (numba missing, or a small cloud before they are loaded)."""
    from rough_viewer.grid import fast

    n = int(x.shape[0])
    if fast.resolve_engine("auto", n_points=n) != "numba" or np.prod(dims.astype(float)) >= 2**62:
        return None
    taken = np.empty(n, dtype=bool)
    cols = [np.ascontiguousarray(c, dtype=np.float64) for c in (x, y, z)]
    seed_term = np.uint64((int(seed) * 0x9E3779B97F4A7C15) % 2**64)
    import numba

    fast._kernels()["voxel_sample"](*cols, np.ascontiguousarray(lo, dtype=np.float64),
                                    float(size), np.ascontiguousarray(dims, dtype=np.int64),
                                    seed_term, int(numba.get_num_threads()), best, taken)
    return taken


def display_subset(points: PointCloud | np.ndarray, max_points: int, *,
                   seed: int = 0) -> np.ndarray:
    """Sorted indices of at most ``max_points`` points, spread evenly over the surface.

    Parameters
    ----------
    points
        A :class:`~rough_viewer.io.PointCloud` (its columns are read, never copied)
        or ``(N, 3)`` point positions, metres.
    max_points
        Sample size; if ``N <= max_points`` every index is returned.
    seed
        Random seed (the same cloud and seed give the same subset).

    Returns
    -------
    np.ndarray
        ``(K,)`` int64 indices into the points, ascending, ``K <= max_points``.
    """
    x, y, z = as_columns(points)
    n = int(x.shape[0])
    if n <= max_points:
        return np.arange(n, dtype=np.int64)
    if max_points <= 0:
        return np.zeros(0, dtype=np.int64)
    rng = np.random.default_rng(seed)
    lo = np.array([col.min() for col in (x, y, z)], dtype=np.float64)
    hi = np.array([col.max() for col in (x, y, z)], dtype=np.float64)
    extent = float(np.max(hi - lo)) or 1.0
    # Estimate the surface area from the coarse voxels a random subset occupies, then
    # size the fine voxels so about max_points of them are occupied (a surface:
    # count ~ 1/size^2).
    coarse = extent / 256.0
    few = np.sort(rng.choice(n, size=min(n, ESTIMATE_POINTS), replace=False))
    cdims = np.floor((hi - lo) / coarse).astype(np.int64) + 1
    n_coarse = len(np.unique(_keys(x[few], y[few], z[few], lo, coarse, cdims)))
    size = coarse * float(np.sqrt(n_coarse / max_points))
    dims = np.floor((hi - lo) / size).astype(np.int64) + 1
    table_size = int(TABLE_PER_POINT * max_points) | 1
    require(4.0 * table_size + 9.0 * n + 40.0 * min(n, CHUNK),
            f"an overview sample of {n:,} points")
    best = np.full(table_size, np.inf, dtype=np.float32)
    taken = _taken_compiled(x, y, z, lo, size, dims, seed, best)
    if taken is None:
        buckets: np.ndarray[Any, np.dtype[np.signedinteger[Any]]] = np.empty(
            n, dtype=np.int32 if table_size < 2**31 else np.int64)
        prio = np.empty(n, dtype=np.float32)
        for start in range(0, n, CHUNK):
            stop = min(n, start + CHUNK)
            buckets[start:stop] = _keys(x[start:stop], y[start:stop], z[start:stop], lo,
                                        size, dims) % table_size
            prio[start:stop] = priority(np.arange(start, stop), seed)
            np.minimum.at(best, buckets[start:stop], prio[start:stop])
        taken = prio == best[buckets]
        del buckets, prio
    chosen = np.flatnonzero(taken)
    if len(chosen) > max_points:
        chosen = rng.choice(chosen, size=max_points, replace=False)
    elif len(chosen) < max_points:
        rest = np.flatnonzero(~taken)
        chosen = np.concatenate([chosen, rng.choice(rest, size=max_points - len(chosen),
                                                    replace=False)])
    return np.sort(chosen).astype(np.int64)
