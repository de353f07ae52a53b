"""What a browser tab receives of a node: its points in node-local float16
coordinates, and their colours gathered from the per-point colour array.

Node-local float16 (docs/lod.md "Definitions"): a point ``p`` of a node whose cube
has centre ``c`` and edge ``s`` is sent as ``float16((p - c) / scale)``, where
``scale`` is 1 (metres) for cubes of edge :data:`UNIT_SCALE_RANGE` (every real scan
in metres) and otherwise the power of two nearest ``s``. Every ``|p - c|`` is at
most ``s / 2`` per axis, where float16's spacing is at most ``2**-10`` of the value
(10 stored mantissa bits), so rounding moves a coordinate by at most
``s / 2 * 2**-11 = s / 4096``, about 2.4e-4 of the node's size: within the 1e-3
asked for, at any distance from the origin (the offset ``c`` is kept as float64 and
given to the scene as the node's position).

>>> import numpy as np
>>> from rough_viewer.lod.octree import build_octree
>>> xyz = np.random.default_rng(1).uniform(0.0, 3.0, (20_000, 3)) + [512_000.0, 4_170_000.0, 90.0]
>>> tree = build_octree(xyz, root_grid=16, max_node_points=2_000)
>>> enc = encode_node(xyz, tree.node(5))
>>> enc.points.dtype, enc.scale
(dtype('float16'), 1.0)
>>> bool(np.max(np.abs(enc.decode() - xyz[tree.rows(5)])) <= tree.node(5).size / 4096)
True
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rough_viewer.io.cloud import PointCloud
from rough_viewer.lod.octree import Node, _columns

#: Cube edges (metres) sent in metres (``scale`` 1): float16 keeps its relative
#: precision down to 2**-14 (normal numbers) and up to 65504.
UNIT_SCALE_RANGE = (2.0**-10, 2.0**15)
#: Largest coordinate error of the encoding as a share of the node's cube edge.
ERROR_SHARE = 2.0**-12

Points = PointCloud | np.ndarray | tuple[np.ndarray, np.ndarray, np.ndarray]


@dataclass(frozen=True)
class EncodedNode:
    """A node's points as the scene gets them."""

    node: int
    """Row of the node in the octree."""
    points: np.ndarray
    """(n, 3) float16 node-local coordinates, ``(p - centre) / scale``."""
    centre: np.ndarray
    """(3,) float64 centre of the node's cube, metres, the cloud's frame: the scene
    node's position (less the app's local origin)."""
    scale: float
    """Metres per unit of :attr:`points` (a power of two; 1.0 for every cube edge in
    :data:`UNIT_SCALE_RANGE`)."""

    def decode(self) -> np.ndarray:
        """(n, 3) float64 coordinates, metres, as the browser will place them."""
        return self.points.astype(np.float64) * self.scale + self.centre

    @property
    def nbytes(self) -> int:
        """Bytes of the coordinates sent (6 per point)."""
        return int(self.points.nbytes)


def node_scale(size: float) -> float:
    """The scale of :attr:`EncodedNode.scale` for a cube of edge ``size`` metres."""
    if UNIT_SCALE_RANGE[0] <= size <= UNIT_SCALE_RANGE[1]:
        return 1.0
    return float(2.0 ** round(math.log2(size)))


def encode_node(points: Points, node: Node) -> EncodedNode:
    """A node's points in node-local float16 coordinates.

    Parameters
    ----------
    points : PointCloud, (N, 3) array or (x, y, z) columns
        The cloud the octree was built from, metres.
    node : Node
        From :meth:`rough_viewer.lod.octree.Octree.node`.

    Returns
    -------
    EncodedNode
        Coordinates within ``node.size / 4096`` of the points (see the module text).
    """
    x, y, z = _columns(points)
    rows = node.rows
    if rows.shape[0] and int(rows.max()) >= x.shape[0]:
        raise ValueError(f"node {node.id} refers to point {int(rows.max())} of a cloud of "
                         f"{x.shape[0]} points: not the cloud the octree was built from")
    return encode_points((x, y, z), rows, node.centre, node.size, node=node.id)


def encode_points(columns: tuple[np.ndarray, np.ndarray, np.ndarray], rows: np.ndarray | None,
                  centre: np.ndarray, size: float, *, node: int) -> EncodedNode:
    """Points of a node's cube (centre ``centre``, edge ``size``, metres) in node-local
    float16 coordinates: ``columns`` x, y, z, metres, at ``rows`` (None: all of
    them; the points of a COPC node decoded on their own).

    >>> p = np.array([0.25, 0.5]), np.array([0.0, 0.75]), np.array([0.5, 0.5])
    >>> encode_points(p, None, np.full(3, 0.5), 1.0, node=3).decode().tolist()
    [[0.25, 0.0, 0.5], [0.5, 0.75, 0.5]]
    """
    centre = np.asarray(centre, dtype=np.float64)
    scale = node_scale(float(size))
    n = int(columns[0].shape[0] if rows is None else rows.shape[0])
    out = np.empty((n, 3), dtype=np.float16)
    for axis, col in enumerate(columns):
        local = (col if rows is None else col[rows]) - centre[axis]
        if scale != 1.0:
            local /= scale  # a power of two: exact
        out[:, axis] = local
    return EncodedNode(node=node, points=out, centre=centre, scale=scale)


def node_colours(point_colours: np.ndarray, node: Node) -> np.ndarray:
    """The colours of a node's points: ``point_colours[node.rows]``, (n, 3) (a gather
    of n rows; about 30 microseconds for a node of 20 000 points).

    Parameters
    ----------
    point_colours : (N, 3) array
        One colour per point of the cloud (uint8 RGB, as the app keeps them).
    node : Node
    """
    return np.asarray(point_colours)[node.rows]


