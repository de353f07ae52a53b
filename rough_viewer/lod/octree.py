"""An additive octree of a whole cloud, for showing every point where the camera looks.

Layout (Potree's and COPC's idea; docs/lod.md "Definitions"):

- The **cube** of the octree: its corner is the bounding-box minimum of the cloud,
  its edge ``side`` the largest extent. Node ``(L, key)`` is the cube's cell of edge
  ``side / 2**L`` whose Morton index at level ``L`` is ``key``; the root is ``(0, 0)``.
- **Additive**: every point is in exactly one node, and the points of a node and of
  all its ancestors together are every point of the cloud inside that node's cube.
- **Spacing**: a node at level ``L`` holds at most one point per cell of a
  ``root_grid**3`` grid over its cube (its *sample cells*): the root's spacing is
  ``side / root_grid`` (default 128), and each level halves it. The point kept in a
  sample cell is the middle one in Morton order (near the cell's centre); the others
  go down to the children.
- A node keeps at most ``max_node_points`` (default 20 000) points: where more
  sample cells are occupied (a crumpled or volumetric cloud), an even share of them,
  in Morton order, is kept and the rest go down a level. Only a leaf of the finest
  level (points closer than ``side / 2**21``: duplicates) can hold more.

Built without a Python loop over points: 63-bit Morton codes (21 bits per axis)
from the coordinates, sorted stably (a counting sort by the level-3 cell, then each
of its 512 buckets on its own, on a thread pool), then one vectorised pass per level
over the points not yet placed (a run-length scan of the sorted codes). Where the
compiled kernels run (:mod:`rough_viewer.grid.fast`: numba, clouds of millions of
points) the same steps are compiled: the buckets by a radix sort of their codes, each
level one pass, the nodes' rows and boxes one counting sort by node; the octree is
the same to the bit (tests). Memory: the octree keeps an
index permutation (4 bytes per point, 8 beyond 2**31 points) and small per-node
arrays, never a copy of the points; the build peaks at about
:data:`BUILD_BYTES_PER_POINT` bytes per point (:func:`build_bytes`).

>>> import numpy as np
>>> rng = np.random.default_rng(0)
>>> xyz = rng.uniform(0.0, 10.0, (50_000, 3))
>>> tree = build_octree(xyz, root_grid=8, max_node_points=500)
>>> int(tree.counts.sum()), bool(np.array_equal(np.sort(tree.order), np.arange(50_000)))
(50000, True)
>>> int(tree.level[0]), int(tree.parent[0])
(0, -1)
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np

from rough_viewer.io.cloud import PointCloud
from rough_viewer.memory import require
from rough_viewer.vocabulary import InputError, ProgressFn

#: Bits of the Morton code per axis (63 bits in all): the finest level of the octree.
DEPTH_BITS = 21
#: Default sample cells per axis of a node's cube: the root spacing is ``side / 128``.
DEFAULT_ROOT_GRID = 128
#: Default largest number of points in one node.
DEFAULT_MAX_NODE_POINTS = 20_000
#: Peak bytes per point while building: the sorted Morton codes (8), the points not
#: yet placed (4) and the output permutation (4); while sorting, a 2-byte bucket per
#: point instead of the output (then 12 bytes per point of the buckets being sorted,
#: checked once their sizes are known).
BUILD_BYTES_PER_POINT = 16
#: Points handled at a time in the passes over the points (bounds the temporaries).
CHUNK_POINTS = 1 << 22
#: Bytes per point of the temporaries of one chunk (codes, shifts, masks, candidates).
CHUNK_BYTES_PER_POINT = 48
#: Points of one task of the parallel counting sort, and its temporaries (bytes).
SORT_CHUNK = 1 << 20
SORT_CHUNK_BYTES_PER_POINT = 64
#: Bits of the Morton code the first pass sorts by (the level-3 cell: 512 buckets).
TOP_BITS = 9
#: Bytes per node of the octree's own arrays.
NODE_BYTES = 8 + 1 + 8 + 4 + 4 + 4 + 6 * 8 + 4 * 8


@dataclass(frozen=True)
class Node:
    """One node: where it is, and which points it holds (a view, no copy)."""

    id: int
    """Row of the node in the octree's arrays."""
    level: int
    """Depth, 0 for the root."""
    cube_lo: np.ndarray
    """(3,) corner of the node's cube, metres."""
    size: float
    """Edge of the node's cube, metres (``side / 2**level``)."""
    spacing: float
    """Distance between the node's sample cells, metres (``size / root_grid``)."""
    rows: np.ndarray
    """(n,) indices of the node's points in the cloud (a view into
    :attr:`Octree.order`)."""

    @property
    def centre(self) -> np.ndarray:
        """(3,) centre of the node's cube, metres."""
        return self.cube_lo + 0.5 * self.size

    @property
    def n(self) -> int:
        """Points in the node."""
        return int(self.rows.shape[0])


@dataclass(frozen=True)
class Octree:
    """An additive octree over a cloud (see the module's text). Nodes are rows of the
    arrays, ordered by level, then by Morton key: the children of a node are
    contiguous rows ``child_start[k]:child_stop[k]`` and node 0 is the root."""

    origin: np.ndarray
    """(3,) corner of the cube (the cloud's bounding-box minimum), metres."""
    side: float
    """Edge of the cube, metres (the cloud's largest extent)."""
    root_grid: int
    """Sample cells per axis of a node's cube (a power of two)."""
    max_node_points: int
    """Largest number of points of a node (finest-level leaves excepted)."""
    order: np.ndarray
    """(N,) int32 (int64 beyond 2**31 points) point indices, node after node: node
    ``k`` holds ``order[start[k]:start[k + 1]]``, ascending (file order)."""
    start: np.ndarray
    """(M + 1,) int64 offsets of the nodes' points in :attr:`order`."""
    level: np.ndarray
    """(M,) int8 depth of each node."""
    key: np.ndarray
    """(M,) uint64 Morton index of each node's cube at its level."""
    parent: np.ndarray
    """(M,) int32 row of the parent, -1 for the root."""
    child_start: np.ndarray
    """(M,) int32 first child row."""
    child_stop: np.ndarray
    """(M,) int32 one past the last child row (= ``child_start`` for a leaf)."""
    cube_lo: np.ndarray
    """(M, 3) corner of each node's cube, metres."""
    box_lo: np.ndarray
    """(M, 3) minimum of the points of each node's subtree (the node and its
    descendants), metres: a tight bound for culling."""
    box_hi: np.ndarray
    """(M, 3) maximum of the points of each node's subtree, metres."""

    @property
    def n_points(self) -> int:
        """Points of the cloud (N)."""
        return int(self.order.shape[0])

    @property
    def n_nodes(self) -> int:
        """Nodes (M)."""
        return int(self.level.shape[0])

    @property
    def counts(self) -> np.ndarray:
        """(M,) points in each node."""
        return np.diff(self.start)

    @property
    def size(self) -> np.ndarray:
        """(M,) edge of each node's cube, metres."""
        return self.side / np.exp2(self.level.astype(np.float64))

    @property
    def spacing(self) -> np.ndarray:
        """(M,) distance between each node's sample cells, metres."""
        return self.size / self.root_grid

    @property
    def root_spacing(self) -> float:
        """The root's spacing, metres (``side / root_grid``)."""
        return self.side / self.root_grid

    @property
    def depth(self) -> int:
        """Deepest level with a node."""
        return int(self.level.max())

    @property
    def nbytes(self) -> int:
        """Bytes held by the octree's arrays."""
        return int(sum(a.nbytes for a in (
            self.order, self.start, self.level, self.key, self.parent, self.child_start,
            self.child_stop, self.cube_lo, self.box_lo, self.box_hi)))

    def rows(self, k: int) -> np.ndarray:
        """Indices of node ``k``'s points in the cloud (a view)."""
        return self.order[self.start[k]:self.start[k + 1]]

    def node(self, k: int) -> Node:
        """Node ``k``."""
        k = int(k)
        if not 0 <= k < self.n_nodes:
            raise IndexError(f"no node {k}: the octree has {self.n_nodes} nodes")
        size = self.side / 2.0 ** int(self.level[k])
        return Node(id=k, level=int(self.level[k]), cube_lo=self.cube_lo[k].copy(), size=size,
                    spacing=size / self.root_grid, rows=self.rows(k))

    def children(self, k: int) -> range:
        """Rows of node ``k``'s children."""
        return range(int(self.child_start[k]), int(self.child_stop[k]))


T = TypeVar("T")
R = TypeVar("R")


def build_bytes(n_points: int, workers: int = 2) -> float:
    """Estimated peak bytes of :func:`build_octree` for ``n_points`` points on
    ``workers`` threads, besides the points themselves (read, never copied) and the
    buckets being sorted (checked once their sizes are known)."""
    n = float(n_points)
    return (n * BUILD_BYTES_PER_POINT + min(n, CHUNK_POINTS) * CHUNK_BYTES_PER_POINT
            + workers * min(n, SORT_CHUNK) * SORT_CHUNK_BYTES_PER_POINT)


def _columns(points: PointCloud | np.ndarray | tuple[np.ndarray, np.ndarray, np.ndarray]
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """x, y, z of a cloud, an (N, 3) array or three columns (views where possible)."""
    if isinstance(points, PointCloud):
        return points.x, points.y, points.z
    if isinstance(points, tuple):
        if len(points) != 3:
            raise InputError("points must be a PointCloud, an (N, 3) array or (x, y, z)")
        cols = tuple(np.asarray(c, dtype=np.float64) for c in points)
        if not (cols[0].ndim == 1 and cols[0].shape == cols[1].shape == cols[2].shape):
            raise InputError("x, y and z must be 1-D arrays of one length")
        return cols[0], cols[1], cols[2]
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InputError(f"points must be an (N, 3) array, got shape {arr.shape}")
    return arr[:, 0], arr[:, 1], arr[:, 2]


def _spread_bits(q: np.ndarray) -> np.ndarray:
    """The 21 low bits of ``q`` (uint32) spread to every third bit of a uint64."""
    v = q.astype(np.uint64)
    for shift, mask in ((32, 0x1F00000000FFFF), (16, 0x1F0000FF0000FF),
                        (8, 0x100F00F00F00F00F), (4, 0x10C30C30C30C30C3),
                        (2, 0x1249249249249249)):
        v |= v << np.uint64(shift)
        v &= np.uint64(mask)
    return v


_SPREAD_TABLE: np.ndarray | None = None


def _spread21(q: np.ndarray) -> np.ndarray:
    """:func:`_spread_bits` of 21-bit values by a 65 536-entry table (twice as fast)."""
    global _SPREAD_TABLE
    if _SPREAD_TABLE is None:
        _SPREAD_TABLE = _spread_bits(np.arange(1 << 16, dtype=np.uint32))
    table = _SPREAD_TABLE
    return table[q & np.uint32(0xFFFF)] | (table[q >> np.uint32(16)] << np.uint64(48))


def _compact_bits(code: np.ndarray, axis: int, bits: int) -> np.ndarray:
    """The cell index along ``axis`` of Morton ``code``s of ``bits`` levels (int64)."""
    out = np.zeros(code.shape[0], dtype=np.int64)
    c = code.astype(np.uint64)
    for b in range(bits):
        out |= ((c >> np.uint64(3 * b + axis)) & np.uint64(1)).astype(np.int64) << b
    return out


def _morton_chunk(x: np.ndarray, y: np.ndarray, z: np.ndarray, s: int, e: int,
                  origin: np.ndarray, scale: float) -> np.ndarray:
    """Morton codes of points ``s:e`` (see :func:`morton_codes`)."""
    top = np.uint32(2**DEPTH_BITS - 1)
    out = np.zeros(e - s, dtype=np.uint64)
    for axis, col in enumerate((x, y, z)):
        f = (col[s:e] - origin[axis]) * scale
        np.clip(f, 0.0, None, out=f)
        q = f.astype(np.uint32)  # floor of a non-negative value
        np.minimum(q, top, out=q)
        out |= _spread21(q) << np.uint64(axis)
    return out


def morton_codes(x: np.ndarray, y: np.ndarray, z: np.ndarray, origin: np.ndarray,
                 side: float) -> np.ndarray:
    """(N,) uint64 Morton codes of points in the cube ``origin + [0, side]**3``: the
    cell index ``floor((p - origin) / side * 2**21)`` per axis (clipped to the cube),
    bits interleaved x, y, z from the lowest (x is bit 0)."""
    n = int(x.shape[0])
    scale = float(2**DEPTH_BITS) / side
    out = np.empty(n, dtype=np.uint64)
    for s in range(0, n, CHUNK_POINTS):
        e = min(n, s + CHUNK_POINTS)
        out[s:e] = _morton_chunk(x, y, z, s, e, origin, scale)
    return out


def _parallel(fn: Callable[[T], R], items: Sequence[T], workers: int) -> list[R]:
    """``[fn(i) for i in items]``, on ``workers`` threads (numpy lets go of the GIL in
    its sorts, gathers and arithmetic on large arrays)."""
    if workers <= 1 or len(items) <= 1:
        return [fn(i) for i in items]
    with ThreadPoolExecutor(max_workers=workers) as pool:
        return list(pool.map(fn, items))


def _bucketed(x: np.ndarray, y: np.ndarray, z: np.ndarray, origin: np.ndarray, side: float,
              index_dtype: type, workers: int, what: str
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The points' Morton codes and indices in order of their top :data:`TOP_BITS`
    bits (a counting sort, chunks in parallel), with the buckets' starts and sizes."""
    n = int(x.shape[0])
    scale = float(2**DEPTH_BITS) / side
    shift = 3 * DEPTH_BITS - TOP_BITS
    top_scale = scale / 2.0 ** (DEPTH_BITS - TOP_BITS // 3)  # a power of two apart: exact
    n_buckets = 1 << TOP_BITS
    chunks = [(s, min(n, s + SORT_CHUNK)) for s in range(0, n, SORT_CHUNK)]
    bucket = np.empty(n, dtype=np.uint16)

    def count(chunk: tuple[int, int]) -> np.ndarray:
        s, e = chunk
        b = np.zeros(e - s, dtype=np.uint16)
        for axis, col in enumerate((x, y, z)):
            f = (col[s:e] - origin[axis]) * top_scale
            np.clip(f, 0.0, 2 ** (TOP_BITS // 3) - 1, out=f)
            b |= _spread21(f.astype(np.uint32)).astype(np.uint16) << np.uint16(axis)
        bucket[s:e] = b
        return np.bincount(b, minlength=n_buckets)

    per_chunk = np.array(_parallel(count, chunks, workers), dtype=np.int64).reshape(-1, n_buckets)
    sizes = per_chunk.sum(axis=0)
    biggest = np.sort(sizes)[-max(1, workers):].sum()
    require(14.0 * n + 12.0 * float(biggest)
            + workers * min(n, SORT_CHUNK) * SORT_CHUNK_BYTES_PER_POINT,
            f"sorting the {n:,} points of {what}")
    bucket_start = np.concatenate(([0], np.cumsum(sizes)))
    chunk_offset = bucket_start[:-1] + np.cumsum(per_chunk, axis=0) - per_chunk
    codes = np.empty(n, dtype=np.uint64)
    rest: np.ndarray = np.empty(n, dtype=index_dtype)

    def scatter(i: int) -> None:
        s, e = chunks[i]
        code = _morton_chunk(x, y, z, s, e, origin, scale)
        b = bucket[s:e]
        by_bucket = np.argsort(b, kind="stable")  # a radix sort of 16-bit keys
        sb = b[by_bucket].astype(np.int64)
        rank = np.arange(e - s, dtype=np.int64) - (np.cumsum(per_chunk[i]) - per_chunk[i])[sb]
        dest = chunk_offset[i][sb] + rank
        if np.any((code[by_bucket] >> np.uint64(shift)).astype(np.int64) != sb):
            raise AssertionError("octree: bucket and Morton code disagree")  # cannot happen
        codes[dest] = code[by_bucket]
        rest[dest] = (by_bucket + s).astype(index_dtype)

    _parallel(scatter, list(range(len(chunks))), workers)
    return codes, rest, bucket_start, sizes


def _sorted_codes(x: np.ndarray, y: np.ndarray, z: np.ndarray, origin: np.ndarray,
                  side: float, index_dtype: type, workers: int, what: str
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The points' Morton codes sorted, and the point index of each.

    A counting sort by the top :data:`TOP_BITS` bits (the level-3 cell,
    :func:`_bucketed`), then each bucket sorted on its own, buckets in parallel: no
    full argsort, and at most 14 bytes per point besides the buckets being sorted."""
    if _compiled(int(x.shape[0])):
        return _sorted_codes_compiled(x, y, z, origin, side, index_dtype, what)
    codes, rest, bucket_start, sizes = _bucketed(x, y, z, origin, side, index_dtype, workers,
                                                 what)

    def sort_bucket(k: int) -> None:
        a, b = int(bucket_start[k]), int(bucket_start[k + 1])
        if b - a > 1:
            local = np.argsort(codes[a:b], kind="stable")  # equal codes keep their order
            rest[a:b] = rest[a:b][local]
            codes[a:b] = codes[a:b][local]

    busy = [int(k) for k in np.argsort(-sizes, kind="stable") if sizes[k] > 1]  # largest first
    _parallel(sort_bucket, busy, workers)
    return codes, rest


def _compiled(n_points: int) -> bool:
    """Whether the build runs the compiled kernels (:mod:`rough_viewer.grid.fast`: numba
    installed and working, for clouds of millions of points or where the kernels are
    loaded; ``$ROUGH_VIEWER_ENGINE=numpy`` keeps the NumPy code). Both give the same
    octree."""
    from rough_viewer.grid import fast

    return fast.resolve_engine("auto", n_points=n_points) == "numba"


def _kernel(name: str) -> Callable[..., Any]:
    from rough_viewer.grid import fast

    return fast._kernels()[name]


def _tasks(sizes: np.ndarray, workers: int) -> tuple[np.ndarray, np.ndarray]:
    """The non-trivial buckets shared out among ``workers`` tasks, largest first to the
    least loaded task: (bucket ids task after task, each task's first place)."""
    busy = [int(k) for k in np.argsort(-sizes, kind="stable") if sizes[k] > 1]
    load = [0] * workers
    owned: list[list[int]] = [[] for _ in range(workers)]
    for k in busy:
        t = load.index(min(load))
        owned[t].append(k)
        load[t] += int(sizes[k])
    plan = np.array([k for own in owned for k in own], dtype=np.int64)
    plan_start = np.concatenate(([0], np.cumsum([len(own) for own in owned]))).astype(np.int64)
    return plan, plan_start


def _sorted_codes_compiled(x: np.ndarray, y: np.ndarray, z: np.ndarray, origin: np.ndarray,
                           side: float, index_dtype: type, what: str
                           ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_sorted_codes` by the compiled kernels: the codes computed twice (the
    bucket of each point, then its code on the way to its bucket), the buckets
    counting-sorted by chunk, then each bucket by a least-significant-digit radix
    sort of the remaining 54 bits (9 at a time, a digit every code shares skipped),
    buckets in parallel. Stable, so equal codes keep the points' order: the points
    come out as ``np.argsort(codes, kind="stable")``. Peak: 14 bytes a point and 12
    of each thread's largest bucket."""
    import numba

    n = int(x.shape[0])
    scale = float(2**DEPTH_BITS) / side
    workers = max(1, int(numba.get_num_threads()))
    n_chunks = max(1, -(-n // SORT_CHUNK))
    o = np.ascontiguousarray(origin, dtype=np.float64)
    cols = [np.ascontiguousarray(c, dtype=np.float64) for c in (x, y, z)]
    require(14.0 * n, f"sorting the {n:,} points of {what}")
    bucket = np.empty(n, dtype=np.uint16)
    hist = np.empty((n_chunks, 1 << TOP_BITS), dtype=np.int64)
    _kernel("morton_buckets")(*cols, o, scale, SORT_CHUNK, bucket, hist)
    sizes = hist.sum(axis=0)
    plan, plan_start = _tasks(sizes, workers)
    most = [max((int(sizes[k]) for k in plan[a:b]), default=0)
            for a, b in zip(plan_start[:-1], plan_start[1:], strict=True)]
    require(14.0 * n + 12.0 * float(sum(most)), f"sorting the {n:,} points of {what}")
    bucket_start = np.concatenate(([0], np.cumsum(sizes))).astype(np.int64)
    offset = np.ascontiguousarray(bucket_start[:-1] + np.cumsum(hist, axis=0) - hist)
    codes = np.empty(n, dtype=np.uint64)
    rest: np.ndarray = np.empty(n, dtype=index_dtype)
    _kernel("morton_scatter")(*cols, o, scale, SORT_CHUNK, bucket, offset, codes, rest)
    del bucket
    _kernel("sort_buckets")(codes, rest, bucket_start, plan, plan_start,
                            3 * DEPTH_BITS - TOP_BITS)
    return codes, rest


def _kept_evenly(counts: np.ndarray, cap: int) -> np.ndarray:
    """For groups of ``counts`` consecutive items, which items to keep so that each
    group keeps ``min(count, cap)`` of them spread evenly through it."""
    total = int(counts.sum())
    group_start = np.repeat(np.cumsum(counts) - counts, counts)
    rank = np.arange(total, dtype=np.int64) - group_start
    c = np.repeat(counts, counts)
    over = c > cap
    keep = np.ones(total, dtype=bool)
    r, cc = rank[over], c[over]
    keep[over] = ((r + 1) * cap) // cc > (r * cap) // cc
    return keep


def _chunk_stop(codes: np.ndarray, start: int, node_shift: int) -> int:
    """End of a run of whole level nodes starting at ``start`` holding about
    :data:`CHUNK_POINTS` points (more when one node is larger)."""
    n = int(codes.shape[0])
    guess = start + CHUNK_POINTS
    if guess >= n or node_shift >= 63:
        return n
    prefix = int(codes[guess - 1]) >> node_shift
    bound = (prefix + 1) << node_shift
    if bound >= 2**64:
        return n
    return int(np.searchsorted(codes[start:], np.uint64(bound), side="left")) + start



def _sample_starts(codes: np.ndarray, a: int, b: int, shift: np.uint64) -> np.ndarray:
    """Positions (relative to ``a``) where a new sample cell (``code >> shift``)
    begins in the sorted ``codes[a:b]``, found a chunk at a time."""
    found = [np.zeros(1, dtype=np.int64)]
    for s in range(a, b, CHUNK_POINTS):
        e = min(b, s + CHUNK_POINTS)
        lo = max(a, s - 1)  # the chunk's first code against the one before it
        cell = codes[lo:e] >> shift
        found.append(np.flatnonzero(cell[1:] != cell[:-1]) + (lo + 1 - a))
    return np.concatenate(found)


def _drop_taken(codes: np.ndarray, rest: np.ndarray, a: int, b: int, take: np.ndarray,
                write: int) -> int:
    """Move the rows of ``[a, b)`` not in ``take`` (positions relative to ``a``,
    ascending) down to ``write``, a chunk at a time, in place; return the new end.
    Safe because ``write <= a``: each chunk is copied out before it is written."""
    for s in range(a, b, CHUNK_POINTS):
        e = min(b, s + CHUNK_POINTS)
        keep = np.ones(e - s, dtype=bool)
        i0, i1 = np.searchsorted(take, [s - a, e - a])
        keep[take[i0:i1] - (s - a)] = False
        kept_codes = codes[s:e][keep]
        kept_rest = rest[s:e][keep]
        m = int(kept_codes.shape[0])
        codes[write:write + m] = kept_codes
        rest[write:write + m] = kept_rest
        write += m
    return write


def _checked_sizes(root_grid: int, max_node_points: int) -> tuple[int, int]:
    """The root grid and the node cap, checked (:func:`build_octree`)."""
    g = int(root_grid)
    if g != root_grid or g < 2 or g > 1024 or g & (g - 1):
        raise InputError(f"root grid must be a power of two from 2 to 1024, got {root_grid}")
    cap = int(max_node_points)
    if cap != max_node_points or cap < 1:
        raise InputError(f"max node points must be a whole number >= 1, got {max_node_points}")
    return g, cap


def _root_cube(x: np.ndarray, y: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, float]:
    """The root cube of the points: its lowest corner (3,) and its side, metres (a
    tiny cube about one spot)."""
    lo = np.array([x.min(), y.min(), z.min()])
    hi = np.array([x.max(), y.max(), z.max()])
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
        raise InputError("the octree needs finite coordinates (a NaN or infinite one found)")
    side = float(np.max(hi - lo))
    if not side > 0.0:
        side = max(1.0, float(np.max(np.abs(lo)))) * 1e-9  # one spot: any cube holds it
    return lo, side


def _samples(codes: np.ndarray, a: int, b: int, sample_shift: np.uint64, node_shift: int,
             cap: int) -> np.ndarray:
    """The points ``a:b`` of the sorted ``codes`` a level takes (offsets from ``a``):
    the middle point of each sample cell, at most ``cap`` per node kept evenly."""
    starts = _sample_starts(codes, a, b, sample_shift)
    runs = np.diff(np.append(starts, b - a))
    take = starts + runs // 2  # the middle point of each sample cell
    node_of = codes[a:b][take] >> np.uint64(node_shift)
    edge = np.flatnonzero(node_of[1:] != node_of[:-1]) + 1
    per_node = np.diff(np.concatenate(([0], edge, [take.shape[0]])))
    if per_node.max() > cap:
        take = take[_kept_evenly(per_node, cap)]
    return take


def build_octree(
    points: PointCloud | np.ndarray | tuple[np.ndarray, np.ndarray, np.ndarray],
    *,
    root_grid: int = DEFAULT_ROOT_GRID,
    max_node_points: int = DEFAULT_MAX_NODE_POINTS,
    workers: int | None = None,
    progress: ProgressFn | None = None,
) -> Octree:
    """Build the additive octree of a cloud.

    Parameters
    ----------
    points : PointCloud, (N, 3) array or (x, y, z) columns
        Finite coordinates, metres (read, never copied).
    root_grid : int
        Sample cells per axis of a node (a power of two from 2 to 1024; default 128:
        the root spacing is about ``extent / 128``).
    max_node_points : int
        Largest number of points of a node (default 20 000).
    workers : int, optional
        Threads for the sorts and gathers (default: the CPU count); the result does
        not depend on it.
    progress : callable, optional
        ``progress(done, total)`` in points placed.

    Returns
    -------
    Octree

    Raises
    ------
    InputError
        No points, a non-finite coordinate, bad settings, or not enough memory
        (:func:`build_bytes`, checked first).
    """
    x, y, z = _columns(points)
    n = int(x.shape[0])
    if n == 0:
        raise InputError("an octree needs at least one point")
    g, cap = _checked_sizes(root_grid, max_node_points)
    workers = max(1, int(workers if workers is not None else (os.cpu_count() or 1)))
    require(build_bytes(n, workers), f"the level-of-detail octree of {n:,} points")
    lo, side = _root_cube(x, y, z)
    g_bits = g.bit_length() - 1
    if progress:
        progress(0, n)

    index_dtype = np.int32 if n < 2**31 else np.int64
    # codes sorted, and the points not yet placed (all of them yet), by code
    codes, rest = _sorted_codes(x, y, z, lo, side, index_dtype, workers,
                                f"the level-of-detail octree of {n:,} points")
    order = np.empty(n, dtype=index_dtype)

    keys: list[np.ndarray] = []
    counts: list[np.ndarray] = []
    if _compiled(n):
        _levels_compiled(codes, rest, order, g_bits, cap, keys, counts, progress)
        del codes, rest
        return _assemble(order, keys, counts, lo, side, g, cap, x, y, z, workers)
    placed = 0
    n_rest = n
    for level in range(DEPTH_BITS + 1):
        if n_rest == 0:
            break
        node_shift = 3 * (DEPTH_BITS - level)
        sample_shift = np.uint64(3 * max(DEPTH_BITS - level - g_bits, 0))
        last = level == DEPTH_BITS
        level_keys: list[np.ndarray] = []
        level_counts: list[np.ndarray] = []
        write = 0
        a = 0
        while a < n_rest:
            b = _chunk_stop(codes[:n_rest], a, node_shift)
            take = (np.arange(b - a, dtype=np.int64) if last
                    else _samples(codes, a, b, sample_shift, node_shift, cap))
            taken = codes[a:b][take] >> np.uint64(node_shift)
            k = int(take.shape[0])
            order[placed:placed + k] = rest[a:b][take]
            placed += k
            edge = np.flatnonzero(taken[1:] != taken[:-1]) + 1
            bounds = np.concatenate(([0], edge, [k]))
            level_keys.append(taken[bounds[:-1]])
            level_counts.append(np.diff(bounds))
            write = _drop_taken(codes, rest, a, b, take, write)
            a = b
        n_rest = write
        keys.append(np.concatenate(level_keys))
        counts.append(np.concatenate(level_counts))
        if progress:
            progress(placed, n)
    del codes, rest
    return _assemble(order, keys, counts, lo, side, g, cap, x, y, z, workers)


def _levels_compiled(codes: np.ndarray, rest: np.ndarray, order: np.ndarray, g_bits: int,
                     cap: int, keys: list[np.ndarray], counts: list[np.ndarray],
                     progress: ProgressFn | None) -> None:
    """The levels of :func:`build_octree` by a compiled pass each over the points not yet
    placed (the same points taken, nodes and order as the NumPy passes): each level's
    node keys and counts appended to ``keys`` and ``counts``, ``order`` filled."""
    level_pass = _kernel("octree_level")
    count_runs = _kernel("count_runs")
    n = int(codes.shape[0])
    placed = 0
    n_rest = n
    for level in range(DEPTH_BITS + 1):
        if n_rest == 0:
            break
        node_shift = np.uint64(3 * (DEPTH_BITS - level))
        sample_shift = np.uint64(3 * max(DEPTH_BITS - level - g_bits, 0))
        m = int(count_runs(codes, n_rest, node_shift))
        level_keys = np.empty(m, dtype=np.uint64)
        level_counts = np.empty(m, dtype=np.int64)
        placed, n_rest, made = level_pass(codes, rest, n_rest, sample_shift, node_shift, cap,
                                          level == DEPTH_BITS, order, placed, level_keys,
                                          level_counts)
        if made != m:
            raise AssertionError("octree: nodes miscounted")  # cannot happen
        keys.append(level_keys)
        counts.append(level_counts)
        if progress:
            progress(placed, n)


def _assemble(order: np.ndarray, keys: list[np.ndarray], counts: list[np.ndarray],
              origin: np.ndarray, side: float, root_grid: int, cap: int,
              x: np.ndarray, y: np.ndarray, z: np.ndarray, workers: int) -> Octree:
    """The node arrays from the per-level keys and counts (levels in order, keys
    ascending within a level, points of ``order`` node after node)."""
    sizes = [k.shape[0] for k in keys]
    offsets = np.concatenate(([0], np.cumsum(sizes))).astype(np.int64)
    m = int(offsets[-1])
    level = np.concatenate([np.full(s, lv, dtype=np.int8) for lv, s in enumerate(sizes)])
    key = np.concatenate(keys).astype(np.uint64)
    start = np.concatenate(([0], np.cumsum(np.concatenate(counts)))).astype(np.int64)
    parent = np.full(m, -1, dtype=np.int32)
    child_start = np.zeros(m, dtype=np.int32)
    child_stop = np.zeros(m, dtype=np.int32)
    for lv in range(1, len(keys)):
        up = keys[lv] >> np.uint64(3)
        above = keys[lv - 1]
        at = np.searchsorted(above, up)
        if np.any(at >= above.shape[0]) or np.any(above[np.minimum(at, above.shape[0] - 1)] != up):
            raise AssertionError("octree: a node without its parent")  # cannot happen
        parent[offsets[lv]:offsets[lv + 1]] = at + offsets[lv - 1]
        child_start[offsets[lv - 1]:offsets[lv]] = np.searchsorted(up, above, "left") + offsets[lv]
        child_stop[offsets[lv - 1]:offsets[lv]] = np.searchsorted(up, above, "right") + offsets[lv]
    last = len(keys) - 1
    child_start[offsets[last]:] = m
    child_stop[offsets[last]:] = m

    cube_lo = np.empty((m, 3))
    cell = side / np.exp2(level.astype(np.float64))
    for axis in range(3):
        idx = np.zeros(m, dtype=np.int64)
        for lv in range(len(keys)):
            sl = slice(offsets[lv], offsets[lv + 1])
            idx[sl] = _compact_bits(key[sl], axis, lv)
        cube_lo[:, axis] = origin[axis] + idx * cell

    if _compiled(int(order.shape[0])):
        box_lo, box_hi = _rows_and_boxes_compiled(order, start, x, y, z)
    else:
        _sort_rows_within_nodes(order, start, workers)
        box_lo, box_hi = _node_boxes(order, start, x, y, z, workers)
    for lv in range(last, 0, -1):  # a subtree's box holds its children's boxes
        sl = slice(offsets[lv], offsets[lv + 1])
        np.minimum.at(box_lo, parent[sl], box_lo[sl])
        np.maximum.at(box_hi, parent[sl], box_hi[sl])
    return Octree(origin=origin, side=side, root_grid=root_grid, max_node_points=cap,
                  order=order, start=start, level=level, key=key, parent=parent,
                  child_start=child_start, child_stop=child_stop, cube_lo=cube_lo,
                  box_lo=box_lo, box_hi=box_hi)


def _rows_and_boxes_compiled(order: np.ndarray, start: np.ndarray, x: np.ndarray,
                             y: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_sort_rows_within_nodes` and :func:`_node_boxes` by one compiled kernel:
    every point's node noted (4 bytes a point, in the room the sort's codes left),
    then the points visited in file order, so each node's rows come out ascending
    (a counting sort by node, the same rows) and its box is taken from the
    coordinates read in order (the same minima and maxima)."""
    import numba

    n = int(order.shape[0])
    m = int(start.shape[0] - 1)
    tasks = max(1, min(int(numba.get_num_threads()), -(-n // SORT_CHUNK)))
    require(4.0 * n + tasks * m * 56.0, f"the nodes of the octree of {n:,} points")
    run_of = np.empty(n, dtype=np.int32)
    hist = np.empty((tasks, m), dtype=np.int64)
    partial = np.empty((tasks, m, 6))
    box_lo = np.empty((m, 3))
    box_hi = np.empty((m, 3))
    cols = [np.ascontiguousarray(c, dtype=np.float64) for c in (x, y, z)]
    _kernel("rows_and_boxes")(order, np.ascontiguousarray(start, dtype=np.int64), *cols, run_of,
                              hist, partial, box_lo, box_hi)
    return box_lo, box_hi


def _node_chunks(start: np.ndarray) -> list[tuple[int, int]]:
    """Runs of whole nodes ``[k, stop)`` of about :data:`CHUNK_POINTS` points each."""
    m = int(start.shape[0] - 1)
    out = []
    k = 0
    while k < m:
        stop = int(np.searchsorted(start, start[k] + CHUNK_POINTS, side="right")) - 1
        stop = min(m, max(stop, k + 1))
        out.append((k, stop))
        k = stop
    return out


def _sort_rows_within_nodes(order: np.ndarray, start: np.ndarray, workers: int) -> None:
    """Each node's rows in ascending order, in place: gathers from the cloud (encoding,
    colours) then read it in file order, which for a scan is nearly spatial order."""
    if order.shape[0] >= 2**32:
        return  # the (node, row) key would not fit 64 bits; the order is still valid

    def run(chunk: tuple[int, int]) -> None:
        k, stop = chunk
        a, b = int(start[k]), int(start[stop])
        local = np.repeat(np.arange(stop - k, dtype=np.uint64), np.diff(start[k:stop + 1]))
        key = (local << np.uint64(32)) | order[a:b].astype(np.uint64)
        key.sort()
        order[a:b] = key & np.uint64(0xFFFFFFFF)

    _parallel(run, _node_chunks(start), workers)


def _node_boxes(order: np.ndarray, start: np.ndarray, x: np.ndarray, y: np.ndarray,
                z: np.ndarray, workers: int) -> tuple[np.ndarray, np.ndarray]:
    """(M, 3) minimum and maximum of each node's own points, a few nodes at a time."""
    m = int(start.shape[0] - 1)
    box_lo = np.empty((m, 3))
    box_hi = np.empty((m, 3))

    def run(job: tuple[tuple[int, int], int]) -> None:
        (k, stop), axis = job
        v = (x, y, z)[axis][order[start[k]:start[stop]]]
        local = start[k:stop] - start[k]
        box_lo[k:stop, axis] = np.minimum.reduceat(v, local)
        box_hi[k:stop, axis] = np.maximum.reduceat(v, local)

    _parallel(run, [(c, axis) for c in _node_chunks(start) for axis in range(3)], workers)
    return box_lo, box_hi
