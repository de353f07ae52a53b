"""The numba kernels of :mod:`rough_viewer.grid.fast` (imported only when numba is
installed and the compiled engine is used). Defined at module level so numba's
on-disk cache (``cache=True``) finds them again in the next process."""

# mypy: ignore-errors
from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True, parallel=True, nogil=True)
def keys(x, y, z, origin, g, index_min, nx, ny, out):
    n = x.shape[0]
    for i in prange(n):
        tz = np.floor((z[i] - origin[2]) / g) - index_min[2]
        ty = np.floor((y[i] - origin[1]) / g) - index_min[1]
        tx = np.floor((x[i] - origin[0]) / g) - index_min[0]
        out[i] = np.int64(tz) * (nx * ny) + np.int64(ty * nx) + np.int64(tx)


@njit(cache=True, nogil=True)
def count(key, total):
    counts = np.zeros(total, dtype=np.int64)
    for i in range(key.shape[0]):
        counts[key[i]] += 1
    return counts


@njit(cache=True, parallel=True, nogil=True)
def relabel(key, lookup):
    for i in prange(key.shape[0]):
        key[i] = lookup[key[i]]


@njit(cache=True, nogil=True)
def moments_chunk(x, y, z, pc, cx, cy, cz, start, stop, acc):
    acc[:] = 0.0
    for i in range(start, stop):
        c = pc[i]
        lx = x[i] - cx[c]
        ly = y[i] - cy[c]
        lz = z[i] - cz[c]
        acc[c, 0] += lx
        acc[c, 1] += ly
        acc[c, 2] += lz
        acc[c, 3] += lx * lx
        acc[c, 4] += lx * ly
        acc[c, 5] += lx * lz
        acc[c, 6] += ly * ly
        acc[c, 7] += ly * lz
        acc[c, 8] += lz * lz


@njit(cache=True, parallel=True, nogil=True)
def moments(x, y, z, pc, cx, cy, cz, chunk, total, partial):
    n = x.shape[0]
    n_chunks = (n + chunk - 1) // chunk
    width = partial.shape[0]
    for base in range(0, n_chunks, width):
        for t in prange(width):
            k = base + t
            if k < n_chunks:
                moments_chunk(x, y, z, pc, cx, cy, cz, k * chunk,
                              min(n, (k + 1) * chunk), partial[t])
        for t in range(width):  # partial sums added in chunk order
            if base + t < n_chunks:
                total += partial[t]


@njit(cache=True, nogil=True)
def distances_chunk(x, y, z, pc, cx, cy, cz, v, off, start, stop, acc):
    acc[:] = 0.0
    n_vec = v.shape[0]
    for i in range(start, stop):
        c = pc[i]
        lx = x[i] - cx[c]
        ly = y[i] - cy[c]
        lz = z[i] - cz[c]
        for q in range(n_vec):
            d = lx * v[q, c, 0]
            d += ly * v[q, c, 1]
            d += lz * v[q, c, 2]
            d -= off[q, c]
            acc[q, 1, c] += d * d
            acc[q, 0, c] += abs(d)


@njit(cache=True, parallel=True, nogil=True)
def distances(x, y, z, pc, cx, cy, cz, v, off, chunk, total, partial):
    n = x.shape[0]
    n_chunks = (n + chunk - 1) // chunk
    width = partial.shape[0]
    for base in range(0, n_chunks, width):
        for t in prange(width):
            k = base + t
            if k < n_chunks:
                distances_chunk(x, y, z, pc, cx, cy, cz, v, off, k * chunk,
                                min(n, (k + 1) * chunk), partial[t])
        for t in range(width):
            if base + t < n_chunks:
                total += partial[t]

