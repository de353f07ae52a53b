"""The level-of-detail tree of a COPC file, from its hierarchy alone (no point read).

A COPC file's octree is additive as :mod:`rough_viewer.lod.octree`'s is: every point
lies in exactly one node, and a child adds detail to its parent. So its hierarchy
serves :func:`rough_viewer.lod.select.select_nodes` as it stands
(:class:`~rough_viewer.lod.select.LodTree`): :func:`copc_tree` lays the
hierarchy's nodes out as the in-memory octree's rows (by depth, then by Morton
index, so that a node's children are contiguous rows), in metres:

- the **cube** of node ``(d, x, y, z)`` is the root cube's (the COPC info VLR's
  centre and half size) cell of edge ``side / 2**d`` at ``(x, y, z)``;
- its **box** (what culling tests) is that cube clipped to the header's bounding
  box (a face's thin axis), never a bound of points read;
- its **spacing** is the root's (the info VLR's spacing, else a 128-cell grid)
  halved at each level;
- a node the hierarchy lacks but whose descendants hold points (COPC allows empty
  nodes) is a node of 0 points, so that every node has its parent.

The hierarchy was checked by :func:`rough_viewer.io.copc.reader.open_copc` (no
node past the end, no loop, no key outside its depth, no node twice); here a
hierarchy whose empty ancestors would outnumber its nodes with points (a crafted
file of scattered deep nodes) is refused in one line.

>>> import numpy as np
>>> from rough_viewer.io.copc.reader import ENTRY_DTYPE, CopcFile
>>> nodes = np.array([(0, 0, 0, 0, 100, 1, 10), (2, 3, 0, 1, 200, 1, 5),
...                   (1, 0, 0, 0, 300, 1, 7)], dtype=ENTRY_DTYPE)
>>> c = CopcFile("f", 22, 6, 30, np.ones(3), np.zeros(3), np.zeros(3), np.full(3, 8.0),
...              np.full(3, 4.0), 4.0, b"", nodes)
>>> tree = copc_tree(c)
>>> tree.level.tolist(), tree.counts.tolist(), tree.file_row.tolist()
([0, 1, 1, 2], [10, 7, 0, 5], [0, 2, -1, 1])
>>> tree.cube_lo[3].tolist(), float(tree.size[3])
([6.0, 0.0, 2.0], 2.0)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rough_viewer.io.copc.reader import MAX_DEPTH, CopcFile
from rough_viewer.lod.octree import _spread21
from rough_viewer.vocabulary import InputError

#: Sample cells per axis of a node's cube where the file does not say its spacing
#: (PDAL's and ``rough-viewer index``'s 128).
DEFAULT_ROOT_GRID = 128
#: Bytes per node of the tree's arrays.
NODE_BYTES = 1 + 8 + 8 + 4 + 4 + 4 + 9 * 8 + 8


@dataclass(frozen=True)
class CopcTree:
    """The nodes of a COPC file's hierarchy as level-of-detail rows (see the
    module's text); the arrays of :class:`~rough_viewer.lod.select.LodTree`."""

    origin: np.ndarray
    """(3,) lowest corner of the root cube, metres."""
    side: float
    """Edge of the root cube, metres (the largest where x, y and z have different
    units)."""
    root_grid: int
    """Sample cells per axis of a node's cube: the root's spacing is ``side /
    root_grid``."""
    level: np.ndarray
    """(M,) int8 depth of each node."""
    code: np.ndarray
    """(M,) uint64 Morton index of each node's cube at its depth (x in bit 0)."""
    parent: np.ndarray
    """(M,) int32 row of the parent, -1 for the root."""
    child_start: np.ndarray
    """(M,) int32 first child row."""
    child_stop: np.ndarray
    """(M,) int32 one past the last child row."""
    cube_lo: np.ndarray
    """(M, 3) corner of each node's cube, metres."""
    cube_size: np.ndarray
    """(M, 3) edges of each node's cube along x, y, z, metres (equal unless z has
    its own unit)."""
    box_lo: np.ndarray
    """(M, 3) each node's cube clipped to the file's bounding box, metres."""
    box_hi: np.ndarray
    """(M, 3) its upper corner."""
    node_counts: np.ndarray
    """(M,) int64 points of each node (0: an empty node the hierarchy lacks)."""
    file_row: np.ndarray
    """(M,) int64 row of each node in :attr:`rough_viewer.io.copc.reader.CopcFile.nodes`
    (-1: an empty node)."""

    @property
    def n_nodes(self) -> int:
        return int(self.level.shape[0])

    @property
    def n_points(self) -> int:
        return int(self.node_counts.sum())

    @property
    def counts(self) -> np.ndarray:
        """(M,) points of each node."""
        return self.node_counts

    @property
    def size(self) -> np.ndarray:
        """(M,) edge of each node's cube, metres (the largest axis's)."""
        return self.side / np.exp2(self.level.astype(np.float64))

    @property
    def spacing(self) -> np.ndarray:
        """(M,) distance between each node's sample cells, metres."""
        return self.size / self.root_grid

    @property
    def depth(self) -> int:
        return int(self.level.max())

    @property
    def nbytes(self) -> int:
        return int(sum(a.nbytes for a in (
            self.level, self.code, self.parent, self.child_start, self.child_stop,
            self.cube_lo, self.cube_size, self.box_lo, self.box_hi, self.node_counts,
            self.file_row)))

    def children(self, k: int) -> range:
        """Rows of node ``k``'s children."""
        return range(int(self.child_start[k]), int(self.child_stop[k]))

    def centre(self, k: int) -> np.ndarray:
        """(3,) centre of node ``k``'s cube, metres."""
        return self.cube_lo[k] + 0.5 * self.cube_size[k]


def morton(x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
    """(N,) uint64 Morton codes of cell indices below ``2**21`` (x in bit 0): the
    children of a cell of code ``c`` have codes ``8 c`` to ``8 c + 7``."""
    out = _spread21(np.asarray(x, dtype=np.uint32))
    out |= _spread21(np.asarray(y, dtype=np.uint32)) << np.uint64(1)
    out |= _spread21(np.asarray(z, dtype=np.uint32)) << np.uint64(2)
    return out


def _levels(depth: np.ndarray, code: np.ndarray, path: str) -> list[np.ndarray]:
    """Sorted codes of every node of each level: the file's and their ancestors."""
    top = int(depth.max()) if depth.size else 0
    levels: list[np.ndarray] = [np.empty(0, dtype=np.uint64)] * (top + 1)
    below = np.empty(0, dtype=np.uint64)
    n_real = int(code.shape[0])
    total = 0
    for d in range(top, -1, -1):
        mine = np.union1d(code[depth == d], below >> np.uint64(3))
        total += int(mine.shape[0])
        if total > 2 * n_real + MAX_DEPTH + 1:
            raise InputError(f"{path} is not a readable COPC file: its hierarchy's nodes "
                             f"with points ({n_real:,}) lie so scattered that their empty "
                             "ancestors outnumber them")
        levels[d] = mine
        below = mine
    if levels[0].shape[0] != 1:  # cannot happen: depth 0 has one cell
        raise InputError(f"{path} is not a readable COPC file: its hierarchy has no root")
    return levels


def copc_tree(copc: CopcFile, *, factor: float = 1.0, z_factor: float | None = None
              ) -> CopcTree:
    """The level-of-detail tree of ``copc``'s hierarchy, in metres.

    Parameters
    ----------
    copc : CopcFile
        From :func:`rough_viewer.io.copc.reader.open_copc` (hierarchy checked).
    factor, z_factor : float
        Metres per unit of the file's x and y, and of its z (None: ``factor``).

    Raises
    ------
    InputError
        A hierarchy whose empty ancestors would outnumber its nodes (one line).
    """
    fz = float(factor if z_factor is None else z_factor)
    per = np.array([factor, factor, fz], dtype=np.float64)
    nodes = copc.nodes
    depth = nodes["depth"].astype(np.int64)
    code = morton(nodes["x"], nodes["y"], nodes["z"])
    levels = _levels(depth, code, str(copc.path))
    sizes = [lv.shape[0] for lv in levels]
    offsets = np.concatenate(([0], np.cumsum(sizes))).astype(np.int64)
    m = int(offsets[-1])
    level = np.concatenate([np.full(s, d, dtype=np.int8) for d, s in enumerate(sizes)])
    all_codes = np.concatenate(levels).astype(np.uint64)
    # each node's row in the file's nodes (-1: empty): the file's (depth, code) sorted
    file_row = np.full(m, -1, dtype=np.int64)
    counts = np.zeros(m, dtype=np.int64)
    for d in range(len(levels)):
        at = np.flatnonzero(depth == d)
        if at.size:
            pos = np.searchsorted(levels[d], code[at]) + offsets[d]
            file_row[pos] = at
            counts[pos] = nodes["count"][at].astype(np.int64)
    parent = np.full(m, -1, dtype=np.int32)
    child_start = np.full(m, m, dtype=np.int32)
    child_stop = np.full(m, m, dtype=np.int32)
    for d in range(1, len(levels)):
        up = levels[d] >> np.uint64(3)
        above = levels[d - 1]
        parent[offsets[d]:offsets[d + 1]] = np.searchsorted(above, up) + offsets[d - 1]
        child_start[offsets[d - 1]:offsets[d]] = np.searchsorted(up, above, "left") + offsets[d]
        child_stop[offsets[d - 1]:offsets[d]] = np.searchsorted(up, above, "right") + offsets[d]
    ijk = np.empty((m, 3), dtype=np.int64)
    from rough_viewer.lod.octree import _compact_bits

    for d in range(len(levels)):
        sl = slice(offsets[d], offsets[d + 1])
        for axis in range(3):
            ijk[sl, axis] = _compact_bits(all_codes[sl], axis, d)
    edge_units = 2.0 * copc.halfsize / np.exp2(level.astype(np.float64))
    lo_units = copc.cube_min + ijk * edge_units[:, None]
    cube_lo = lo_units * per
    cube_size = edge_units[:, None] * per
    bounds_lo, bounds_hi = copc.mins * per, copc.maxs * per
    box_lo = np.maximum(cube_lo, bounds_lo)
    box_hi = np.minimum(cube_lo + cube_size, bounds_hi)
    box_hi = np.maximum(box_hi, box_lo)  # a node outside the header's box: a flat box
    side = 2.0 * copc.halfsize * float(per.max())
    return CopcTree(origin=copc.cube_min * per, side=side, root_grid=_root_grid(copc),
                    level=level, code=all_codes, parent=parent, child_start=child_start,
                    child_stop=child_stop, cube_lo=cube_lo, cube_size=cube_size,
                    box_lo=box_lo, box_hi=box_hi, node_counts=counts, file_row=file_row)


def _root_grid(copc: CopcFile) -> int:
    """Sample cells per axis of the root: its edge over the spacing the file gives, a
    power of two from 2 to 1024 (else :data:`DEFAULT_ROOT_GRID`)."""
    spacing = float(getattr(copc, "spacing", 0.0) or 0.0)
    if not spacing > 0:
        return DEFAULT_ROOT_GRID
    g = 2.0 * copc.halfsize / spacing
    if not np.isfinite(g) or g < 1.5:
        return DEFAULT_ROOT_GRID
    return int(min(1024, max(2, 2 ** round(float(np.log2(g))))))


__all__ = ["CopcTree", "copc_tree", "morton"]
