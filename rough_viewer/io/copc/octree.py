"""The COPC octree: cube, voxel keys and level-of-detail selection.

Points are placed on an integer lattice of ``2**BITS`` steps per axis over the
octree's cube (:func:`quantize`); the key of the node at depth ``d`` holding a
lattice point ``q`` is ``q >> (BITS - d)`` per axis (COPC's VoxelKey). A node
keeps, for level of detail, the first point in each cell of a ``2**GRID_BITS``
grid over its cube (:func:`first_per_cell`); the other points go to its children,
so parents hold an even subset and every point lands in exactly one node.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Lattice steps per axis over the cube, as a power of two (21: codes of three
#: axes fit one int64).
BITS = 21
#: Level-of-detail cells per node and axis, as a power of two (128, as PDAL).
GRID_BITS = 7
#: Deepest node: its cells are lattice steps; it keeps every point that reaches it.
MAX_DEPTH = BITS - GRID_BITS


@dataclass(frozen=True)
class Cube:
    """The octree's root cube.

    Attributes
    ----------
    center : tuple of float
        Centre (x, y, z), in the file's coordinate units.
    halfsize : float
        Half the side, same units.
    """

    center: tuple[float, float, float]
    halfsize: float

    @property
    def spacing(self) -> float:
        """Distance between level-of-detail cells of the root node (units)."""
        return 2.0 * self.halfsize / 2 ** GRID_BITS


def cube_of_bounds(mins: np.ndarray, maxs: np.ndarray) -> Cube:
    """The cube around a bounding box: centred on it, side its longest extent plus
    a margin of 1e-6 of it (at least 1e-6 units), so no point lies on the far face."""
    lo = np.asarray(mins, float)
    hi = np.asarray(maxs, float)
    centre = (lo + hi) / 2.0
    span = float(np.max(hi - lo))
    half = span / 2.0 + max(span * 1e-6, 1e-6)
    return Cube((float(centre[0]), float(centre[1]), float(centre[2])), half)


def quantize(xyz: np.ndarray, cube: Cube) -> np.ndarray:
    """Lattice coordinates of points, int64 (N, 3) in ``[0, 2**BITS)``.

    Parameters
    ----------
    xyz : (N, 3) float array
        Coordinates (units of the cube).
    cube : Cube
    """
    lo = np.asarray(cube.center) - cube.halfsize
    step = 2.0 * cube.halfsize / 2 ** BITS
    q = np.floor((np.asarray(xyz, float) - lo) / step).astype(np.int64)
    return np.clip(q, 0, 2 ** BITS - 1, out=q)


def pack(k: np.ndarray) -> np.ndarray:
    """One int64 per row of non-negative (N, 3) integers below ``2**BITS``."""
    return (k[:, 0] << (2 * BITS)) | (k[:, 1] << BITS) | k[:, 2]


def unpack(code: np.ndarray) -> np.ndarray:
    """Inverse of :func:`pack`: (N, 3) int64."""
    mask = (1 << BITS) - 1
    c = np.asarray(code, np.int64)
    return np.stack([(c >> (2 * BITS)) & mask, (c >> BITS) & mask, c & mask], axis=1)


def node_codes(q: np.ndarray, depth: int) -> np.ndarray:
    """Packed keys of the depth-``depth`` nodes holding lattice points ``q``."""
    return pack(q >> (BITS - depth))


def cell_codes(q: np.ndarray, depth: int) -> np.ndarray:
    """Packed level-of-detail cells of depth-``depth`` nodes (a node's key is a
    prefix of its cells' codes, so cells of different nodes never share a code)."""
    return pack(q >> (BITS - depth - GRID_BITS))


def first_per_cell(cells: np.ndarray, taken: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """The first point of each cell not yet taken.

    Parameters
    ----------
    cells : (N,) int64
        Cell code of each point.
    taken : sorted (M,) int64, optional
        Cells that already hold a point (a stream's earlier chunks).

    Returns
    -------
    chosen : (N,) bool
        The points that take a cell.
    taken : sorted int64
        ``taken`` with the newly filled cells.
    """
    uniq, first = np.unique(cells, return_index=True)
    if taken is not None and taken.size:
        pos = np.searchsorted(taken, uniq).clip(max=taken.size - 1)
        fresh = taken[pos] != uniq
        uniq, first = uniq[fresh], first[fresh]
        merged = np.concatenate([taken, uniq])
        merged.sort(kind="stable")
    else:
        merged = uniq
    chosen = np.zeros(cells.size, bool)
    chosen[first] = True
    return chosen, merged


@dataclass(frozen=True)
class Subtree:
    """Points of one region placed in its nodes.

    Attributes
    ----------
    order : (N,) int64
        Point indices, node by node (nodes in the order of ``depths``/``keys``).
    depths : (K,) int64
        Depth of each node.
    keys : (K, 3) int64
        VoxelKey (x, y, z) of each node at its depth.
    counts : (K,) int64
        Points of each node (slices of ``order``, in order).
    """

    order: np.ndarray
    depths: np.ndarray
    keys: np.ndarray
    counts: np.ndarray


def _spread(v: np.ndarray) -> np.ndarray:
    """Bits of 21-bit integers spread to every third bit (for :func:`morton`)."""
    v = v.astype(np.uint64) & np.uint64(0x1FFFFF)
    for shift, mask in ((32, 0x1F00000000FFFF), (16, 0x1F0000FF0000FF), (8, 0x100F00F00F00F00F),
                        (4, 0x10C30C30C30C30C3), (2, 0x1249249249249249)):
        v = (v | (v << np.uint64(shift))) & np.uint64(mask)
    return v


def morton(q: np.ndarray) -> np.ndarray:
    """Morton (Z-order) codes, uint64, of lattice points (N, 3): sorted by them, the
    points of every node and of every level-of-detail cell, at every depth, are
    contiguous (their keys are prefixes of the code: ``code >> 3 * (BITS - depth)``)."""
    return (_spread(q[:, 0]) << np.uint64(2)) | (_spread(q[:, 1]) << np.uint64(1)) | _spread(
        q[:, 2])


def _runs(sorted_codes: np.ndarray) -> np.ndarray:
    """Start of each run of equal values (True where a run starts)."""
    starts = np.ones(sorted_codes.size, bool)
    if sorted_codes.size > 1:
        np.not_equal(sorted_codes[1:], sorted_codes[:-1], out=starts[1:])
    return starts


def build_subtree(q: np.ndarray, depth: int, *, leaf_points: int,
                  max_depth: int = MAX_DEPTH) -> Subtree:
    """Place the points of one depth-``depth`` region (all in one node at that
    depth) in that node and its descendants.

    A node whose region holds at most ``leaf_points`` points, or at
    ``max_depth``, keeps them all; another keeps one point of each level-of-detail
    cell (the first in Morton order) and passes the rest to its children.
    Vectorised over all nodes of a depth at once, after one sort by Morton code.

    Parameters
    ----------
    q : (N, 3) int64
        Lattice coordinates (:func:`quantize`).
    depth : int
        Depth of the region's root node.
    leaf_points : int
        Most points a node keeps when it has no children.
    max_depth : int
        Deepest node (at most :data:`MAX_DEPTH`).
    """
    codes = morton(q)
    active = np.argsort(codes, kind="stable")
    codes = codes[active]
    parts: list[np.ndarray] = []
    depths: list[np.ndarray] = []
    keys: list[np.ndarray] = []
    counts: list[np.ndarray] = []
    d = depth
    while active.size:
        node = codes >> np.uint64(3 * (BITS - d))
        starts = _runs(node)
        first = np.flatnonzero(starts)
        sizes = np.diff(np.r_[first, node.size])
        leaf = np.repeat((sizes <= leaf_points) | (d >= max_depth), sizes)
        if d < max_depth:
            cell = codes >> np.uint64(3 * (BITS - d - GRID_BITS))
            keep = leaf | _runs(cell)
        else:
            keep = leaf
        taken = active[keep]
        node_starts = _runs(node[keep])
        parts.append(taken)
        idx = np.flatnonzero(node_starts)
        counts.append(np.diff(np.r_[idx, taken.size]))
        keys.append(q[taken[idx]] >> (BITS - d))
        depths.append(np.full(idx.size, d, np.int64))
        active, codes = active[~keep], codes[~keep]
        d += 1
    if not parts:
        return Subtree(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3), np.int64),
                       np.zeros(0, np.int64))
    return Subtree(order=np.concatenate(parts), depths=np.concatenate(depths),
                   keys=np.concatenate(keys), counts=np.concatenate(counts))
