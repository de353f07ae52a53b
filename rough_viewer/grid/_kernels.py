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


# ----------------------------------------------------------------------------- octree
# The level-of-detail octree's Morton sort (rough_viewer.lod.octree): the same codes as
# its NumPy reference (`_morton_chunk`: ``floor((p - o) * scale)`` clipped to [0, 2**21
# - 1] per axis, bits interleaved x, y, z from the lowest), sorted stably (equal codes
# keep the points' order).

TOP_SHIFT = np.uint64(54)  # 63 - 9: the level-3 cell of a code (512 buckets)
DIGIT_BITS = 9
_SPREAD_MASKS = (np.uint64(0x1F00000000FFFF), np.uint64(0x1F0000FF0000FF),
                 np.uint64(0x100F00F00F00F00F), np.uint64(0x10C30C30C30C30C3),
                 np.uint64(0x1249249249249249))
_M0, _M1, _M2, _M3, _M4 = _SPREAD_MASKS
_TOP21 = 2**21 - 1
_INDEX_KINDS = ("int32[::1]", "int64[::1]")


@njit(inline="always", **OPTS)
def _spread21(q):
    v = np.uint64(q)
    v = (v | (v << np.uint64(32))) & _M0
    v = (v | (v << np.uint64(16))) & _M1
    v = (v | (v << np.uint64(8))) & _M2
    v = (v | (v << np.uint64(4))) & _M3
    v = (v | (v << np.uint64(2))) & _M4
    return v


@njit(inline="always", **OPTS)
def _cell21(p, o, scale):
    f = (p - o) * scale
    if f < 0.0:
        f = 0.0
    q = np.int64(f)  # floor of a non-negative value
    if q > _TOP21:
        q = _TOP21
    return q


@njit(inline="always", **OPTS)
def _morton(xi, yi, zi, o, scale):
    return (_spread21(_cell21(xi, o[0], scale))
            | (_spread21(_cell21(yi, o[1], scale)) << np.uint64(1))
            | (_spread21(_cell21(zi, o[2], scale)) << np.uint64(2)))


@njit(f"void({F1}, {F1}, {F1}, {F1}, float64, int64, uint16[::1], int64[:, ::1])",
      parallel=True, **OPTS)
def morton_buckets(x, y, z, o, scale, chunk, bucket, hist):
    """``bucket[i]`` = the top 9 bits of point ``i``'s Morton code, and ``hist[t]`` the
    bucket sizes of chunk ``t`` (``chunk`` points each)."""
    n = x.shape[0]
    for t in prange(hist.shape[0]):
        h = hist[t]
        h[:] = 0
        for i in range(t * chunk, min(n, (t + 1) * chunk)):
            b = np.int64(_morton(x[i], y[i], z[i], o, scale) >> TOP_SHIFT)
            bucket[i] = b
            h[b] += 1


@njit([f"void({F1}, {F1}, {F1}, {F1}, float64, int64, uint16[::1], int64[:, ::1], "
       f"uint64[::1], {kind})" for kind in _INDEX_KINDS], parallel=True, **OPTS)
def morton_scatter(x, y, z, o, scale, chunk, bucket, offset, codes, rest):
    """Each point's code and index to its bucket's place: chunk ``t``'s points of
    bucket ``b`` from ``offset[t, b]`` on, in the points' order (a stable counting
    sort by the top bits)."""
    n = x.shape[0]
    for t in prange(offset.shape[0]):
        at = offset[t].copy()
        for i in range(t * chunk, min(n, (t + 1) * chunk)):
            b = bucket[i]
            j = at[b]
            at[b] = j + 1
            codes[j] = _morton(x[i], y[i], z[i], o, scale)
            rest[j] = i


@njit(**OPTS)
def _radix_run(codes, rest, a, b, bits, tmp_c, tmp_r):
    """Sort ``codes[a:b]`` (and ``rest`` with them) stably by their low ``bits`` bits,
    least significant digit first; a digit every value shares is skipped."""
    n = b - a
    if n < 2:
        return
    if n <= 24:  # insertion sort: stable, no buffers
        for i in range(a + 1, b):
            c = codes[i]
            r = rest[i]
            j = i - 1
            while j >= a and codes[j] > c:
                codes[j + 1] = codes[j]
                rest[j + 1] = rest[j]
                j -= 1
            codes[j + 1] = c
            rest[j + 1] = r
        return
    src_c = codes[a:b]
    src_r = rest[a:b]
    dst_c = tmp_c[:n]
    dst_r = tmp_r[:n]
    hist = np.zeros(1 << DIGIT_BITS, dtype=np.int64)
    mask = np.uint64((1 << DIGIT_BITS) - 1)
    swapped = False
    for shift in range(0, bits, DIGIT_BITS):
        s = np.uint64(shift)
        hist[:] = 0
        for i in range(n):
            hist[np.int64((src_c[i] >> s) & mask)] += 1
        if hist.max() == n:
            continue
        total = 0
        for d in range(hist.shape[0]):
            c = hist[d]
            hist[d] = total
            total += c
        for i in range(n):
            d = np.int64((src_c[i] >> s) & mask)
            j = hist[d]
            hist[d] = j + 1
            dst_c[j] = src_c[i]
            dst_r[j] = src_r[i]
        src_c, dst_c = dst_c, src_c
        src_r, dst_r = dst_r, src_r
        swapped = not swapped
    if swapped:  # the sorted values are in the buffers
        codes[a:b] = src_c
        rest[a:b] = src_r


@njit([f"void(uint64[::1], {kind}, int64[::1], int64[::1], int64[::1], int64)"
       for kind in _INDEX_KINDS], parallel=True, **OPTS)
def sort_buckets(codes, rest, start, plan, plan_start, bits):
    """Each bucket ``codes[start[k]:start[k + 1]]`` sorted stably by its low ``bits``
    bits, the buckets of task ``t`` (``plan[plan_start[t]:plan_start[t + 1]]``) on
    one thread."""
    for t in prange(plan_start.shape[0] - 1):
        most = 0
        for p in range(plan_start[t], plan_start[t + 1]):
            k = plan[p]
            most = max(most, start[k + 1] - start[k])
        tmp_c = np.empty(most, dtype=np.uint64)
        tmp_r = np.empty(most, dtype=rest.dtype)
        for p in range(plan_start[t], plan_start[t + 1]):
            k = plan[p]
            _radix_run(codes, rest, start[k], start[k + 1], bits, tmp_c, tmp_r)


@njit([f"void({kind}, int64[::1], {F1}, {F1}, {F1}, int32[::1], int64[:, ::1], {F3}, {F2}, {F2})"
       for kind in _INDEX_KINDS], parallel=True, **OPTS)
def rows_and_boxes(order, start, x, y, z, run_of, hist, partial, lo, hi):
    """Each run ``order[start[k]:start[k + 1]]`` (a node's points) put in ascending
    order, and ``lo[k]``, ``hi[k]`` the (x, y, z) minimum and maximum of its points:
    every point's run noted (``run_of``), then the points visited in order, chunk by
    chunk (``hist.shape[0]`` chunks; ``hist`` and ``partial`` their counts and boxes
    per run), each chunk's points of run ``k`` written after the earlier chunks'
    (a counting sort by run: the same rows as sorting each run)."""
    n = order.shape[0]
    m = start.shape[0] - 1
    tasks = hist.shape[0]
    step = (n + tasks - 1) // tasks
    for k in prange(m):
        for p in range(start[k], start[k + 1]):
            run_of[order[p]] = k
    for t in prange(tasks):
        h = hist[t]
        box = partial[t]
        h[:] = 0
        for k in range(m):
            box[k, 0] = box[k, 1] = box[k, 2] = np.inf
            box[k, 3] = box[k, 4] = box[k, 5] = -np.inf
        for i in range(t * step, min(n, (t + 1) * step)):
            k = run_of[i]
            h[k] += 1
            a = x[i]
            b = y[i]
            c = z[i]
            box[k, 0] = min(box[k, 0], a)
            box[k, 1] = min(box[k, 1], b)
            box[k, 2] = min(box[k, 2], c)
            box[k, 3] = max(box[k, 3], a)
            box[k, 4] = max(box[k, 4], b)
            box[k, 5] = max(box[k, 5], c)
    for k in prange(m):
        at = start[k]
        for j in range(3):
            lo[k, j] = np.inf
            hi[k, j] = -np.inf
        for t in range(tasks):
            c = hist[t, k]
            hist[t, k] = at
            at += c
            for j in range(3):
                lo[k, j] = min(lo[k, j], partial[t, k, j])
                hi[k, j] = max(hi[k, j], partial[t, k, 3 + j])
    for t in prange(tasks):
        h = hist[t]
        for i in range(t * step, min(n, (t + 1) * step)):
            k = run_of[i]
            order[h[k]] = i
            h[k] += 1


@njit([f"UniTuple(int64, 3)(uint64[::1], {kind}, int64, uint64, uint64, int64, boolean, {kind}, "
       f"int64, uint64[::1], int64[::1])" for kind in _INDEX_KINDS], **OPTS)
def octree_level(codes, rest, n_rest, sample_shift, node_shift, cap, last, order, placed,
                 node_key, node_count):
    """One level of the octree over the sorted ``codes[:n_rest]`` (their points in
    ``rest``), node by node (a run of equal ``code >> node_shift``): the middle point
    of each sample cell (a run of equal ``code >> sample_shift``), at most ``cap`` a
    node kept evenly (rank ``r`` of ``c > cap`` cells is kept where ``(r + 1) cap // c
    > r cap // c``), every point on the ``last`` level, appended to ``order`` from
    ``placed``; each node's key and count to ``node_key``, ``node_count``; the points
    not taken moved down in place, in order. Returns (points placed in all, points
    left, nodes of the level)."""
    write = 0
    nodes = 0
    i = 0
    while i < n_rest:
        node = codes[i] >> node_shift
        j = i + 1
        while j < n_rest and (codes[j] >> node_shift) == node:
            j += 1
        before = placed
        if last:
            for p in range(i, j):
                order[placed] = rest[p]
                placed += 1
        else:
            cells = 1
            for p in range(i + 1, j):
                if (codes[p] >> sample_shift) != (codes[p - 1] >> sample_shift):
                    cells += 1
            s = i
            r = 0
            while s < j:
                cell = codes[s] >> sample_shift
                e = s + 1
                while e < j and (codes[e] >> sample_shift) == cell:
                    e += 1
                mid = s + (e - s) // 2
                keep = cells <= cap or ((r + 1) * cap) // cells > (r * cap) // cells
                if keep:
                    order[placed] = rest[mid]
                    placed += 1
                for p in range(s, e):
                    if not (keep and p == mid):
                        codes[write] = codes[p]
                        rest[write] = rest[p]
                        write += 1
                r += 1
                s = e
        node_key[nodes] = node
        node_count[nodes] = placed - before
        nodes += 1
        i = j
    return placed, write, nodes


@njit("int64(uint64[::1], int64, uint64)", **OPTS)
def count_runs(codes, n, shift):
    """Runs of equal ``code >> shift`` in ``codes[:n]`` (the nodes of an octree level)."""
    if n == 0:
        return 0
    runs = 1
    for p in range(1, n):
        if (codes[p] >> shift) != (codes[p - 1] >> shift):
            runs += 1
    return runs


# ----------------------------------------------------------------------------- overview sample
# rough_viewer.app.sampling.display_subset's voxel pass: the same voxel keys (``t = p -
# lo; t /= size``, truncated, clipped to the box), buckets (``key % table``) and
# priorities (splitmix64 of the index) as its NumPy chunks.

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)


@njit(inline="always", **OPTS)
def _priority(i, seed_term):
    z = np.uint64(i) + seed_term
    z = (z ^ (z >> np.uint64(30))) * _MIX1
    z = (z ^ (z >> np.uint64(27))) * _MIX2
    z ^= z >> np.uint64(31)
    return np.float32(z >> np.uint64(40)) / np.float32(2**24)


@njit(inline="always", **OPTS)
def _voxel_bucket(xi, yi, zi, lo, size, d0, d1, d2, table):
    a = min(np.int64((xi - lo[0]) / size), d0 - 1)
    b = min(np.int64((yi - lo[1]) / size), d1 - 1)
    c = min(np.int64((zi - lo[2]) / size), d2 - 1)
    return ((a * d1 + b) * d2 + c) % table


@njit(f"void({F1}, {F1}, {F1}, {F1}, float64, int64[::1], uint64, int64, float32[::1], "
      "boolean[::1])", parallel=True, **OPTS)
def voxel_sample(x, y, z, lo, size, dims, seed_term, tasks, best, taken):
    """``best[b]`` = the smallest priority of the points in bucket ``b`` (its voxels
    hashed), each of ``tasks`` tasks reading every point and keeping the buckets of
    its share of the table (a minimum: the order does not matter), then ``taken[i]``
    = point ``i`` holds its bucket's smallest."""
    n = x.shape[0]
    table = best.shape[0]
    d0, d1, d2 = dims[0], dims[1], dims[2]
    share = (table + tasks - 1) // tasks
    for t in prange(tasks):
        first = t * share
        last = min(table, first + share)
        for i in range(n):
            b = _voxel_bucket(x[i], y[i], z[i], lo, size, d0, d1, d2, table)
            if b >= first and b < last:
                p = _priority(i, seed_term)
                if p < best[b]:
                    best[b] = p
    for i in prange(n):
        b = _voxel_bucket(x[i], y[i], z[i], lo, size, d0, d1, d2, table)
        taken[i] = _priority(i, seed_term) == best[b]
