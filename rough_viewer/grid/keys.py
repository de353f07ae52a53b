"""Cell keys and their bookkeeping, shared by the NumPy reference
(:mod:`rough_viewer.grid.cells`) and the compiled kernels (:mod:`rough_viewer.grid.fast`),
so that neither imports the other's module for them.

>>> decode_keys(np.array([0, 1, 6]), (2, 3, 4), np.array([10, 20, 30])).tolist()
[[10, 20, 30], [11, 20, 30], [10, 20, 31]]
"""

from __future__ import annotations

import numpy as np

#: Dense bookkeeping (one int64 per grid cell) is used up to this many grid cells
#: or ``4 * n_points``, whichever is larger; beyond, a sort-based path is used.
DENSE_LIMIT = 1 << 25


def chunk_size(n_cells: int) -> int:
    """Points per chunk of a pass over the points: per-chunk bincounts allocate
    ``n_cells``-long arrays, so chunks are at least as long (and 2 M points)."""
    return max(1 << 21, int(n_cells))


def decode_keys(keys: np.ndarray, shape: tuple[int, int, int], index_min: np.ndarray) -> np.ndarray:
    """(M, 3) cell indices from linear keys ``i + nx (j + ny k)`` (x fastest)."""
    nx, ny, _ = shape
    k = keys // (nx * ny)
    rem = keys - k * (nx * ny)
    j = rem // nx
    i = rem - j * nx
    return np.stack([i, j, k], axis=1) + index_min


def dense_bookkeeping(total: int, n_points: int, dense_limit: int = DENSE_LIMIT) -> bool:
    """Whether cells are found with one int64 per cell of the bounding grid (``total``
    cells) rather than by sorting the keys: up to ``dense_limit`` or ``4 n_points``
    cells, whichever is larger."""
    return total <= max(int(dense_limit), 4 * int(n_points))
