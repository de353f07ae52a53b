"""Which nodes a camera should see: nodes in the view frustum, ranked by their size on
the screen, taken until a point budget is reached (Potree's traversal; docs/lod.md).

- **In view**: the bounding box of the points of a node's subtree meets the view
  frustum (a pyramid from the camera through the window's edges, closed beyond the
  cloud). Tested exactly with the separating-axis theorem: the two convex bodies are
  disjoint iff their projections on one of 26 axes are (the box's 3 face normals,
  the pyramid's 5 face normals, and the 18 cross products of their edge directions).
- **Projected size**: the radius on the screen, in pixels, of the sphere around the
  node's cube, seen from the camera: ``f r / sqrt(d^2 - r^2)`` for a sphere of
  radius ``r`` (half the cube's diagonal) at distance ``d`` from the camera
  (``f`` = focal length in pixels); infinite when the camera is inside the sphere.
  The node's points are then about ``radius_px / (g * sqrt(3) / 2)`` pixels apart on
  the screen, ``g = min(root_grid, sqrt(count))`` points along its edge: its sample
  grid, or fewer where the node holds fewer than a surface's ``root_grid**2`` (a
  sparse node, or the child of a node that kept only a share of its cells: the
  points of a surface then lie ``edge / sqrt(count)`` apart). Nodes whose points would
  lie closer than ``min_spacing_px`` are not taken.
- **Traversal**: from the root, always the largest node on the screen among the
  children of the nodes taken so far (a priority queue; ties to the lower row),
  stopping at the first node that would take the points past the budget. The
  selection is closed under parents (additive nodes need their ancestors), and
  holds at most ``budget`` points.

>>> import numpy as np
>>> from rough_viewer.lod.camera import ViewCamera
>>> from rough_viewer.lod.octree import build_octree
>>> rng = np.random.default_rng(2)
>>> face = np.column_stack([rng.uniform(0, 20, 200_000), rng.normal(0, 0.01, 200_000),
...                         rng.uniform(0, 5, 200_000)])
>>> tree = build_octree(face, root_grid=32, max_node_points=2_000)
>>> far = select_nodes(tree, ViewCamera.looking_at((10, -40, 2.5), (10, 0, 2.5)), 50_000)
>>> near = select_nodes(tree, ViewCamera.looking_at((3, -1, 2.5), (3, 0, 2.5)), 50_000)
>>> far.points <= 50_000 and near.points <= 50_000
True
>>> bool(tree.level[near.nodes].max() > tree.level[far.nodes].max())  # finer where close
True
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from rough_viewer.lod.camera import ViewCamera
from rough_viewer.vocabulary import InputError

#: Default point budget of a tab (the issue's ``serve --point-budget``).
DEFAULT_BUDGET = 3_000_000
#: Default closest spacing on the screen, pixels, of the points of a node taken.
DEFAULT_MIN_SPACING_PX = 1.0
#: Nodes a budget should hold at least (so that it is spent in small steps).
NODES_PER_BUDGET = 64
#: Smallest node size :func:`node_points_for` chooses, points.
MIN_NODE_POINTS = 1_000


def node_points_for(budget: int) -> int:
    """The octree node size a point budget is spent well with: the budget holds at
    least :data:`NODES_PER_BUDGET` nodes, within 1 000 and 20 000 points (Potree's
    node size; the default budget of 3 M gets 20 000-point nodes). With larger
    nodes a small budget is spent on a few coarse nodes that cover the whole cloud,
    and the points in front of the camera never come.

    >>> node_points_for(3_000_000), node_points_for(200_000), node_points_for(10_000)
    (20000, 3125, 1000)
    """
    from rough_viewer.lod.octree import DEFAULT_MAX_NODE_POINTS

    return int(min(DEFAULT_MAX_NODE_POINTS, max(MIN_NODE_POINTS, int(budget) // NODES_PER_BUDGET)))


class LodTree(Protocol):
    """What :func:`select_nodes` reads of a tree of additive nodes: the in-memory
    :class:`~rough_viewer.lod.octree.Octree` of a cloud, or the
    :class:`~rough_viewer.lod.copc.CopcTree` of a COPC file's hierarchy. Nodes are
    rows ordered by level (the root is row 0); the children of node ``k`` are the
    contiguous rows ``child_start[k]:child_stop[k]``; every node holds its own
    points, its children add detail."""

    @property
    def n_nodes(self) -> int: ...
    @property
    def side(self) -> float:
        """Edge of the root cube, metres."""
    @property
    def root_grid(self) -> int:
        """Sample cells per axis of a node's cube (the root's spacing is
        ``side / root_grid``)."""
    @property
    def level(self) -> np.ndarray:
        """(M,) depth of each node."""
    @property
    def cube_lo(self) -> np.ndarray:
        """(M, 3) corner of each node's cube, metres."""
    @property
    def box_lo(self) -> np.ndarray:
        """(M, 3) a lower bound of the points of each node's subtree, metres."""
    @property
    def box_hi(self) -> np.ndarray:
        """(M, 3) an upper bound of them."""
    @property
    def child_start(self) -> np.ndarray: ...
    @property
    def child_stop(self) -> np.ndarray: ...
    @property
    def counts(self) -> np.ndarray:
        """(M,) points of each node."""
    @property
    def spacing(self) -> np.ndarray:
        """(M,) distance between each node's sample cells, metres."""
    @property
    def size(self) -> np.ndarray:
        """(M,) edge of each node's cube, metres."""


@dataclass(frozen=True)
class Selection:
    """The nodes a camera should see."""

    nodes: np.ndarray
    """(k,) int64 node rows in the order taken (largest on the screen first)."""
    radius_px: np.ndarray
    """(k,) their projected radius, pixels (inf where the camera is inside the
    node's sphere)."""
    points: int
    """Points in the selected nodes (at most ``budget``)."""
    budget: int
    """The point budget asked for."""
    complete: bool
    """True when the budget left nothing out: every node in view down to the
    spacing limit is selected."""
    nearest_m: float
    """Distance from the camera to the nearest selected node's points' box, metres,
    but at least the finest selected spacing (for :func:`camera_moved`)."""


def frustum_axes(camera: ViewCamera, far_m: float) -> tuple[np.ndarray, np.ndarray]:
    """The separating axes of axis-aligned boxes against the camera's view pyramid
    closed at ``far_m`` metres, and the pyramid's (5, 3) vertices (apex first)."""
    r = camera.rotation
    tx, ty = camera.half_tangents
    local_edges = np.array([[sx * tx, sy * ty, 1.0] for sx in (-1, 1) for sy in (-1, 1)])
    corner_dirs = local_edges @ r.T
    vertices = np.vstack([camera.position, camera.position + far_m * corner_dirs])
    faces = np.array([[1.0, 0.0, -tx], [-1.0, 0.0, -tx], [0.0, 1.0, -ty], [0.0, -1.0, -ty],
                      [0.0, 0.0, 1.0]]) @ r.T
    edges = np.vstack([corner_dirs, r[:, 0], r[:, 1]])
    box = np.eye(3)
    crosses = np.cross(box[:, None, :], edges[None, :, :]).reshape(-1, 3)
    return np.vstack([box, faces, crosses]), vertices


def boxes_in_view(camera: ViewCamera, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(M,) bool: which axis-aligned boxes ``[lo, hi]`` ((M, 3) each, metres) meet
    the camera's view frustum (exact: separating axes). Boxes are closed: touching
    counts."""
    lo = np.asarray(lo, dtype=np.float64)
    hi = np.asarray(hi, dtype=np.float64)
    if lo.shape[0] == 0:
        return np.zeros(0, dtype=bool)
    reach = np.maximum(np.abs(lo - camera.position), np.abs(hi - camera.position))
    far = 2.0 * float(np.linalg.norm(reach, axis=1).max()) + 1.0  # beyond every box
    axes, vertices = frustum_axes(camera, far)
    proj = vertices @ axes.T
    fmin, fmax = proj.min(axis=0), proj.max(axis=0)
    centre = 0.5 * (lo + hi)
    half = 0.5 * (hi - lo)
    c = centre @ axes.T
    h = half @ np.abs(axes).T
    separated = (c + h < fmin) | (c - h > fmax)
    return ~separated.any(axis=1)


def projected_radius(camera: ViewCamera, centre: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """(M,) screen radius, pixels, of spheres (centres (M, 3), radii (M,), metres):
    ``f r / sqrt(d^2 - r^2)``, inf where the camera is inside."""
    d2 = np.sum((np.asarray(centre, dtype=np.float64) - camera.position) ** 2, axis=1)
    r = np.asarray(radius, dtype=np.float64)
    gap = d2 - r * r
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.where(gap > 0, camera.focal_px * r / np.sqrt(np.maximum(gap, 1e-300)), np.inf)
    return out


def points_per_edge(tree: LodTree) -> np.ndarray:
    """(M,) about how many points of each node lie along its cube's edge (their
    spacing is ``edge / g``): its sample grid ``root_grid``, or ``sqrt(count)`` where
    that is less (the points of a surface spread over its cube)."""
    return np.minimum(float(tree.root_grid), np.sqrt(np.maximum(tree.counts, 1).astype(np.float64)))


def node_screen(tree: LodTree, camera: ViewCamera, min_spacing_px: float = 0.0
                ) -> tuple[np.ndarray, np.ndarray]:
    """Visibility (bool (M,)) and projected radius (pixels, (M,)) of the nodes the
    traversal can reach: level by level, the children of nodes in view whose points
    are at least ``min_spacing_px`` apart on the screen (the root always). A child's
    box lies in its parent's, so a node below one out of view is out of view too;
    nodes not reached are False (radius 0)."""
    m = tree.n_nodes
    visible = np.zeros(m, dtype=bool)
    radius = np.zeros(m)
    per_px = points_per_edge(tree) ** -1.0 / (0.5 * math.sqrt(3.0))
    todo = np.zeros(1, dtype=np.int64)
    while todo.shape[0]:
        size = tree.side / np.exp2(tree.level[todo].astype(np.float64))
        centre = tree.cube_lo[todo] + 0.5 * size[:, None]
        radius[todo] = projected_radius(camera, centre, 0.5 * math.sqrt(3.0) * size)
        visible[todo] = boxes_in_view(camera, tree.box_lo[todo], tree.box_hi[todo])
        ok = todo[visible[todo] & ((radius[todo] * per_px[todo] >= min_spacing_px) | (todo == 0))]
        first, stop = tree.child_start[ok].astype(np.int64), tree.child_stop[ok].astype(np.int64)
        n_kids = stop - first
        todo = np.repeat(first - np.cumsum(n_kids) + n_kids, n_kids) + np.arange(int(n_kids.sum()))
    return visible, radius


def select_nodes(tree: LodTree, camera: ViewCamera, budget: int = DEFAULT_BUDGET, *,
                 min_spacing_px: float = DEFAULT_MIN_SPACING_PX) -> Selection:
    """The nodes ``camera`` should see, within ``budget`` points.

    Parameters
    ----------
    tree : LodTree
        An :class:`~rough_viewer.lod.octree.Octree` or a
        :class:`~rough_viewer.lod.copc.CopcTree`.
    camera : ViewCamera
        In the cloud's frame (metres).
    budget : int
        Most points taken (default 3 000 000).
    min_spacing_px : float
        Nodes whose points would be closer than this on the screen, pixels, are not
        taken (the root excepted); 0 refines as deep as the budget allows.

    Returns
    -------
    Selection
        About 2.5 ms CPU for the 21 000 nodes of 20 M points (benchmarks/bench_lod.py).
    """
    budget = int(budget)
    if budget < 0:
        raise InputError(f"point budget must be >= 0, got {budget}")
    if not (math.isfinite(min_spacing_px) and min_spacing_px >= 0):
        raise InputError(f"min spacing must be a number >= 0 pixels, got {min_spacing_px}")
    visible, radius = node_screen(tree, camera, min_spacing_px)
    spacing_px = radius / (points_per_edge(tree) * 0.5 * math.sqrt(3.0))
    counts = tree.counts
    child_start, child_stop = tree.child_start, tree.child_stop
    taken: list[int] = []
    total = 0
    heap: list[tuple[float, int]] = [(-float(radius[0]), 0)] if visible[0] else []
    complete = True
    while heap:
        _, k = heapq.heappop(heap)
        c = int(counts[k])
        if total + c > budget:
            complete = False
            break
        taken.append(k)
        total += c
        for ch in range(int(child_start[k]), int(child_stop[k])):
            if visible[ch] and spacing_px[ch] >= min_spacing_px:
                heapq.heappush(heap, (-float(radius[ch]), ch))
    nodes = np.asarray(taken, dtype=np.int64)
    return Selection(nodes=nodes, radius_px=radius[nodes], points=total, budget=budget,
                     complete=complete, nearest_m=_nearest(tree, camera, nodes))


def _nearest(tree: LodTree, camera: ViewCamera, nodes: np.ndarray) -> float:
    """Distance from the camera to the nearest box of ``nodes``, at least the finest
    spacing among them (inf when none)."""
    if nodes.shape[0] == 0:
        return math.inf
    p = camera.position
    gap = np.maximum(np.maximum(tree.box_lo[nodes] - p, p - tree.box_hi[nodes]), 0.0)
    nearest = float(np.linalg.norm(gap, axis=1).min())
    return max(nearest, float(tree.spacing[nodes].min()))
