"""The numba kernels of :mod:`rough_viewer.grid.fast` (imported only when the compiled
engine is used). Defined at module level so numba's on-disk cache (``cache=True``)
finds them again in the next process, and compiled eagerly for the one signature
each is called with (float64 coordinates, int64 keys and rows, C order), so that
importing this module loads them all from the cache and the first call of a
process runs as fast as the next.

Bit for bit the reference's arithmetic (:mod:`rough_viewer.grid.cells`): every
per-cell sum is taken point by point in the points' order within a block of the
reference's chunk length, starting from 0.0, and the blocks' partial sums are added
to the totals in block order, as ``np.bincount`` per chunk does. Inside a block, the
running sums of the cell the last point fell in stay in registers until a point of
another cell comes (points of a terrestrial scan come cell by cell), which changes
no operation and no order: each cell's sum is still ``((0 + w1) + w2) + ...``.
"""

# mypy: ignore-errors
from __future__ import annotations

import numpy as np
from numba import njit, prange

F1 = "float64[::1]"
I1 = "int64[::1]"
F2 = "float64[:, ::1]"
F3 = "float64[:, :, ::1]"
OPTS = {"cache": True, "nogil": True}


@njit(f"void({F1}, {F1}, {F1}, {F2})", parallel=True, **OPTS)
def bounds(x, y, z, out):
    """``out[t] = (min x, min y, min z, max x, max y, max z, NaN count, and the index
    of the first point of each of the six)`` of task ``t``'s share of the points (one
    pass over the coordinates; the extremes rarely change, so the branches are
    predicted)."""
    n = x.shape[0]
    tasks = out.shape[0]
    step = (n + tasks - 1) // tasks
    for t in prange(tasks):
        lx = ly = lz = np.inf
        hx = hy = hz = -np.inf
        ilx = ily = ilz = ihx = ihy = ihz = -1
        nans = 0
        for i in range(t * step, min(n, (t + 1) * step)):
            a = x[i]
            b = y[i]
            c = z[i]
            if a < lx:
                lx = a
                ilx = i
            if a > hx:
                hx = a
                ihx = i
            if b < ly:
                ly = b
                ily = i
            if b > hy:
                hy = b
                ihy = i
            if c < lz:
                lz = c
                ilz = i
            if c > hz:
                hz = c
                ihz = i
            nans += np.int64(a != a) + np.int64(b != b) + np.int64(c != c)  # no branch
        out[t, 0] = lx
        out[t, 1] = ly
        out[t, 2] = lz
        out[t, 3] = hx
        out[t, 4] = hy
        out[t, 5] = hz
        out[t, 6] = nans
        out[t, 7] = ilx
        out[t, 8] = ily
        out[t, 9] = ilz
        out[t, 10] = ihx
        out[t, 11] = ihy
        out[t, 12] = ihz


@njit(f"void({F1}, {F1}, {F1}, {F1}, float64, {F1}, int64, int64, {I1})", parallel=True, **OPTS)
def keys(x, y, z, origin, g, index_min, nx, ny, out):
    """Linear cell key ``i + nx (j + ny k)`` of every point: the reference's
    operations, ``floor((p - o) / g) - index_min`` per axis."""
    n = x.shape[0]
    for i in prange(n):
        tz = np.floor((z[i] - origin[2]) / g) - index_min[2]
        ty = np.floor((y[i] - origin[1]) / g) - index_min[1]
        tx = np.floor((x[i] - origin[0]) / g) - index_min[0]
        out[i] = np.int64(tz) * (nx * ny) + np.int64(ty * nx) + np.int64(tx)


#: Points whose keys :func:`keys_count` computes before counting them (the key loop
#: vectorises; the counting loop then reads them from the first-level cache).
KEY_BLOCK = 1024


@njit(f"void({F1}, {F1}, {F1}, {F1}, float64, {F1}, int64, int64, {I1}, int64[:, ::1])",
      parallel=True, **OPTS)
def keys_count(x, y, z, origin, g, index_min, nx, ny, out, counts):
    """:func:`keys` and, per task ``t`` (a contiguous share of the points),
    ``counts[t, k]`` the number of its points of key ``k``, in one pass."""
    n = x.shape[0]
    tasks = counts.shape[0]
    step = (n + tasks - 1) // tasks
    for t in prange(tasks):
        own = counts[t]
        stop = min(n, (t + 1) * step)
        for a in range(t * step, stop, KEY_BLOCK):
            b = min(stop, a + KEY_BLOCK)
            for i in range(a, b):
                tz = np.floor((z[i] - origin[2]) / g) - index_min[2]
                ty = np.floor((y[i] - origin[1]) / g) - index_min[1]
                tx = np.floor((x[i] - origin[0]) / g) - index_min[0]
                out[i] = np.int64(tz) * (nx * ny) + np.int64(ty * nx) + np.int64(tx)
            cur = out[a]
            run = 0
            for i in range(a, b):  # a run of one key adds once (no chain through memory)
                k = out[i]
                if k != cur:
                    own[cur] += run
                    cur = k
                    run = 0
                run += 1
            own[cur] += run


@njit(f"{I1}({I1}, int64)", **OPTS)
def count(key, total):
    """Number of points of every key (``np.bincount(key, minlength=total)``)."""
    counts = np.zeros(total, dtype=np.int64)
    for i in range(key.shape[0]):
        counts[key[i]] += 1
    return counts


@njit(f"void({I1}, {I1})", parallel=True, **OPTS)
def relabel(key, lookup):
    """``key[:] = lookup[key]`` in place."""
    for i in prange(key.shape[0]):
        key[i] = lookup[key[i]]


@njit(inline="always", **OPTS)
def _row9(acc, c):
    return (acc[c, 0], acc[c, 1], acc[c, 2], acc[c, 3], acc[c, 4], acc[c, 5], acc[c, 6],
            acc[c, 7], acc[c, 8])


@njit(inline="always", **OPTS)
def _put9(acc, c, s):
    for j in range(9):
        acc[c, j] = s[j]


@njit(**OPTS)
def _moments_block(x, y, z, pc, lookup, cx, cy, cz, start, stop, acc):
    acc[:, :] = 0.0
    if start >= stop:
        return
    relabel = lookup.shape[0] > 0
    cur = lookup[pc[start]] if relabel else pc[start]
    ccx = cx[cur]
    ccy = cy[cur]
    ccz = cz[cur]
    s0 = s1 = s2 = s3 = s4 = s5 = s6 = s7 = s8 = 0.0
    for i in range(start, stop):
        c = pc[i]
        if relabel:
            c = lookup[c]
            pc[i] = c
        if c != cur:
            _put9(acc, cur, (s0, s1, s2, s3, s4, s5, s6, s7, s8))
            cur = c
            s0, s1, s2, s3, s4, s5, s6, s7, s8 = _row9(acc, c)
            ccx = cx[c]
            ccy = cy[c]
            ccz = cz[c]
        lx = x[i] - ccx
        ly = y[i] - ccy
        lz = z[i] - ccz
        s0 += lx
        s1 += ly
        s2 += lz
        s3 += lx * lx
        s4 += lx * ly
        s5 += lx * lz
        s6 += ly * ly
        s7 += ly * lz
        s8 += lz * lz
    _put9(acc, cur, (s0, s1, s2, s3, s4, s5, s6, s7, s8))


@njit(f"void({F1}, {F1}, {F1}, {I1}, {I1}, {F1}, {F1}, {F1}, int64, {F2}, {F3})",
      parallel=True, **OPTS)
def moments(x, y, z, pc, lookup, cx, cy, cz, chunk, total, partial):
    """``total[c] += (sum lx, ly, lz, lx lx, lx ly, lx lz, ly ly, ly lz, lz lz)`` of the
    cell-local coordinates of cell ``c``'s points, block by block (``chunk`` points),
    ``partial.shape[0]`` blocks at a time. With a non-empty ``lookup``, ``pc`` holds
    keys and is relabelled in place (``pc[i] = lookup[pc[i]]``) on the way."""
    n = x.shape[0]
    n_chunks = (n + chunk - 1) // chunk
    width = partial.shape[0]
    for base in range(0, n_chunks, width):
        for t in prange(width):
            k = base + t
            if k < n_chunks:
                _moments_block(x, y, z, pc, lookup, cx, cy, cz, k * chunk,
                               min(n, (k + 1) * chunk), partial[t])
        for t in range(width):  # partial sums added in block order
            if base + t < n_chunks:
                total += partial[t]


@njit(inline="always", **OPTS)
def _distance(lx, ly, lz, vx, vy, vz, offset):
    """``v . local - offset`` in the reference's order (``((lx vx + ly vy) + lz vz) -
    offset``)."""
    d = lx * vx
    d += ly * vy
    d += lz * vz
    return d - offset


@njit(**OPTS)
def _distances_block(x, y, z, pc, lookup, rows, cx, cy, cz, v, two, start, stop, acc):
    acc[:, :] = 0.0
    if start >= stop:
        return
    relabel = lookup.shape[0] > 0
    cur = lookup[pc[start]] if relabel else pc[start]
    a0 = q0 = a1 = q1 = 0.0
    ccx, ccy, ccz = cx[cur], cy[cur], cz[cur]
    v0, v1, v2, v3, v4, v5, v6, v7 = (v[cur, 0], v[cur, 1], v[cur, 2], v[cur, 3],
                                      v[cur, 4], v[cur, 5], v[cur, 6], v[cur, 7])
    for i in range(start, stop):
        c = pc[i]
        if relabel:
            c = lookup[c]
            rows[i] = c
        if c != cur:
            acc[cur, 0] = a0
            acc[cur, 1] = q0
            acc[cur, 2] = a1
            acc[cur, 3] = q1
            cur = c
            a0 = acc[c, 0]
            q0 = acc[c, 1]
            a1 = acc[c, 2]
            q1 = acc[c, 3]
            ccx, ccy, ccz = cx[c], cy[c], cz[c]
            v0, v1, v2, v3, v4, v5, v6, v7 = (v[c, 0], v[c, 1], v[c, 2], v[c, 3],
                                              v[c, 4], v[c, 5], v[c, 6], v[c, 7])
        lx = x[i] - ccx
        ly = y[i] - ccy
        lz = z[i] - ccz
        d = _distance(lx, ly, lz, v0, v1, v2, v3)
        q0 += d * d
        a0 += abs(d)
        if two:
            e = _distance(lx, ly, lz, v4, v5, v6, v7)
            q1 += e * e
            a1 += abs(e)
    acc[cur, 0] = a0
    acc[cur, 1] = q0
    acc[cur, 2] = a1
    acc[cur, 3] = q1


@njit(f"void({F1}, {F1}, {F1}, {I1}, {I1}, {I1}, {F1}, {F1}, {F1}, {F2}, boolean, int64, {F2}, "
      f"{F3})", parallel=True, **OPTS)
def distances(x, y, z, pc, lookup, rows, cx, cy, cz, v, two, chunk, total, partial):
    """Per-cell sums of ``|D|`` and ``D^2`` of one or two (``two``) distance kinds,
    ``D = v[c, 4q:4q+3] . local - v[c, 4q+3]``, into ``total[c] = (|D0|, D0^2, |D1|,
    D1^2)``, block by block as :func:`moments`. With a non-empty ``lookup``, ``pc``
    holds keys (or a finer grid's rows) and ``rows[i] = lookup[pc[i]]`` is written on
    the way (``rows`` may be ``pc``: in place)."""
    n = x.shape[0]
    n_chunks = (n + chunk - 1) // chunk
    width = partial.shape[0]
    for base in range(0, n_chunks, width):
        for t in prange(width):
            k = base + t
            if k < n_chunks:
                _distances_block(x, y, z, pc, lookup, rows, cx, cy, cz, v, two, k * chunk,
                                 min(n, (k + 1) * chunk), partial[t])
        for t in range(width):
            if base + t < n_chunks:
                total += partial[t]


@njit(f"void({F1}, {F1}, {F1}, {F1}, float64, int64, int64, int64, int64, {F2}, {F2})",
      parallel=True, **OPTS)
def pair_sums(px, py, pz, z, scale, n_bins, rows, first, last, ordered, sums):
    """Per lag bin, the ordered pairs of cells and their sums of squared differences,
    for the row chunks ``first .. last - 1`` (``rows`` rows each) of the direct count
    of :func:`rough_viewer.grid.variogram._pair_sums`, chunk ``first + c`` into
    ``ordered[c]`` and ``sums[c]`` (index = bin ``k``, 0 unused). Cells at ``(px, py,
    pz)`` (index units; ``pz`` 0 on a 2-D map, which adds +0.0); bin of a pair
    ``floor(sqrt(d2) * scale + 0.5)``, ``d2`` the squared distance summed axis by
    axis; each chunk's sums are taken pair by pair in row-major order from 0.0, as
    ``np.bincount`` of the chunk's pairs does."""
    m = px.shape[0]
    for c in prange(last - first):
        start = (first + c) * rows
        stop = min(m, start + rows)
        own_n = ordered[c]
        own_s = sums[c]
        own_n[:] = 0.0
        own_s[:] = 0.0
        kb = np.empty(m, dtype=np.int64)
        vb = np.empty(m)
        for i in range(start, stop):
            xi = px[i]
            yi = py[i]
            wi = pz[i]
            zi = z[i]
            for j in range(m):  # the bins and squared differences of row i (vectorises)
                tx = xi - px[j]
                ty = yi - py[j]
                tz = wi - pz[j]
                d2 = tx * tx
                d2 += ty * ty
                d2 += tz * tz
                kb[j] = np.int64(np.floor(np.sqrt(d2) * scale + 0.5))
                e = zi - z[j]
                vb[j] = e * e
            cur = 0
            cn = 0.0
            cs = 0.0
            for j in range(m):  # then added in order; a run of one bin stays in registers
                k = kb[j]
                if k >= 1 and k <= n_bins:
                    if k != cur:
                        if cur != 0:
                            own_n[cur] = cn
                            own_s[cur] = cs
                        cur = k
                        cn = own_n[k]
                        cs = own_s[k]
                    cn += 1.0
                    cs += vb[j]
            if cur != 0:
                own_n[cur] = cn
                own_s[cur] = cs


@njit(inline="always", **OPTS)
def _row10(acc, c):
    return (acc[c, 0], acc[c, 1], acc[c, 2], acc[c, 3], acc[c, 4], acc[c, 5], acc[c, 6],
            acc[c, 7], acc[c, 8], acc[c, 9])


@njit(inline="always", **OPTS)
def _put10(acc, c, s):
    for j in range(10):
        acc[c, j] = s[j]


@njit(**OPTS)
def _box_keys(x, y, z, o, g, im, nx, ny, box, first, last, key):
    """``key[i]`` for ``first <= i < last`` (the operations of :func:`keys`; -1 for a
    point outside ``box``, NaN included); returns how many were outside. The loop
    vectorises: the divisions are most of the work."""
    ox = o[0]
    oy = o[1]
    oz = o[2]
    mx = im[0]
    my = im[1]
    mz = im[2]
    lox = box[0]
    loy = box[1]
    loz = box[2]
    hix = box[3]
    hiy = box[4]
    hiz = box[5]
    nxy = nx * ny
    outside = 0
    for i in range(first, last):
        a = x[i]
        b = y[i]
        c = z[i]
        tz = np.floor((c - oz) / g) - mz
        ty = np.floor((b - oy) / g) - my
        tx = np.floor((a - ox) / g) - mx
        k = np.int64(tz) * nxy + np.int64(ty * nx) + np.int64(tx)
        inside = ((a >= lox) & (a <= hix) & (b >= loy) & (b <= hiy) & (c >= loz)
                  & (c <= hiz))  # False for NaN
        key[i] = k if inside else -1
        outside += np.int64(not inside)
    return outside


@njit(**OPTS)
def _key_sums(x, y, z, key, nx, nxy, cxa, cya, cza, first, last, acc):
    """``acc[k] += (lx, ly, lz, lx lx, lx ly, lx lz, ly ly, ly lz, lz lz, 1)`` of the
    points ``first <= i < last`` of key ``k >= 0``, in their order; a run of one key
    adds in registers (the same operations)."""
    cur = -1
    ccx = ccy = ccz = 0.0
    s0 = s1 = s2 = s3 = s4 = s5 = s6 = s7 = s8 = s9 = 0.0
    for i in range(first, last):
        k = key[i]
        if k != cur:
            if cur >= 0:
                _put10(acc, cur, (s0, s1, s2, s3, s4, s5, s6, s7, s8, s9))
            cur = k
            if k < 0:  # outside the box: in no sum
                continue
            s0, s1, s2, s3, s4, s5, s6, s7, s8, s9 = _row10(acc, k)
            kz = k // nxy
            rem = k - kz * nxy
            ky = rem // nx
            ccx = cxa[rem - ky * nx]
            ccy = cya[ky]
            ccz = cza[kz]
        elif k < 0:
            continue
        lx = x[i] - ccx
        ly = y[i] - ccy
        lz = z[i] - ccz
        s0 += lx
        s1 += ly
        s2 += lz
        s3 += lx * lx
        s4 += lx * ly
        s5 += lx * lz
        s6 += ly * ly
        s7 += ly * lz
        s8 += lz * lz
        s9 += 1.0
    if cur >= 0:
        _put10(acc, cur, (s0, s1, s2, s3, s4, s5, s6, s7, s8, s9))


@njit(**OPTS)
def _fused_block(x, y, z, o, g, im, nx, ny, cxa, cya, cza, box, start, stop, key, acc):
    """One block of :func:`fused`: keys into ``key``, sums into ``acc`` (zeroed here),
    :data:`KEY_BLOCK` points at a time, the keys first, then their sums (read back
    from the first-level cache); returns the number of points outside ``box``."""
    acc[:, :] = 0.0
    outside = 0
    for first in range(start, stop, KEY_BLOCK):
        last = min(stop, first + KEY_BLOCK)
        outside += _box_keys(x, y, z, o, g, im, nx, ny, box, first, last, key)
        _key_sums(x, y, z, key, nx, nx * ny, cxa, cya, cza, first, last, acc)
    return outside


@njit(f"void({F1}, {F1}, {F1}, {F1}, float64, {F1}, int64, int64, int64, {F1}, {F1}, {F1}, "
      f"{F1}, int64, {I1}, {F2}, {F3}, {F1})", parallel=True, **OPTS)
def fused(x, y, z, o, g, im, nx, ny, nz, cxa, cya, cza, box, chunk, key, total, partial,
          state):
    """Cell keys, counts and moment sums in one pass over the points, on a dense grid.

    ``key[i]`` the linear key of point ``i`` (the operations of :func:`keys`; -1 for
    a point outside ``box = (min x, y, z, max x, y, z)``, NaN included, which is
    left out of the sums); ``total[k] += (sum lx, ly, lz, lx lx, lx ly, lx lz, ly ly,
    ly lz, lz lz, count)`` of the points of key ``k``, local coordinates relative to
    the cell centre ``(cxa[i], cya[j], cza[k])``, block by block (``chunk`` points),
    ``partial.shape[0]`` blocks at a time, the blocks' sums added to ``total`` in
    block order (on all threads, each cell's in block order); ``state[b]`` the
    number of block ``b``'s points outside the box."""
    n = x.shape[0]
    n_chunks = (n + chunk - 1) // chunk
    width = partial.shape[0]
    cells = total.shape[0]
    for base in range(0, n_chunks, width):
        for t in prange(width):
            b = base + t
            if b < n_chunks:
                state[b] = _fused_block(x, y, z, o, g, im, nx, ny, cxa, cya, cza, box,
                                        b * chunk, min(n, (b + 1) * chunk), key, partial[t])
        used = min(width, n_chunks - base)
        for c in prange(cells):  # each cell's partial sums added in block order
            for t in range(used):
                for j in range(10):
                    total[c, j] += partial[t, c, j]
