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


def build_subtree(q: np.ndarray, depth: int, *, leaf_points: int,
                  max_depth: int = MAX_DEPTH) -> Subtree:
    """Place the points of one depth-``depth`` region (all in one node at that
    depth) in that node and its descendants.

    A node whose region holds at most ``leaf_points`` points, or at
    ``max_depth``, keeps them all; another keeps the first point of each
    level-of-detail cell and passes the rest to its children. Vectorised over all
    nodes of a depth at once.

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
    n = q.shape[0]
    node_of = np.full(n, -1, np.int64)  # packed node code, per point
    depth_of = np.zeros(n, np.int64)
    active = np.arange(n)
    d = depth
    while active.size:
        qa = q[active]
        nodes = node_codes(qa, d)
        uniq, inverse, counts = np.unique(nodes, return_inverse=True, return_counts=True)
        leaf = (counts <= leaf_points)[inverse] | (d >= max_depth)
        keep = leaf.copy()
        inner = ~leaf
        if inner.any():
            chosen, _ = first_per_cell(cell_codes(qa[inner], d))
            keep[np.flatnonzero(inner)[chosen]] = True
        node_of[active[keep]] = nodes[keep]
        depth_of[active[keep]] = d
        active = active[~keep]
        d += 1
    order = np.lexsort((node_of, depth_of))
    sorted_depth = depth_of[order]
    sorted_node = node_of[order]
    starts = np.flatnonzero(np.r_[True, (np.diff(sorted_depth) != 0)
                                  | (np.diff(sorted_node) != 0)]) if n else np.zeros(0, int)
    counts = np.diff(np.r_[starts, n])
    return Subtree(order=order, depths=sorted_depth[starts], keys=unpack(sorted_node[starts]),
                   counts=counts)
