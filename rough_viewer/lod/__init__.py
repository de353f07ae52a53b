"""Level of detail: an additive octree of the whole cloud, the nodes a camera should
see within a point budget, their compact encoding, and which nodes each browser tab
holds (docs/lod.md). Science side: no UI here; the app calls these.

- :func:`build_octree` (:mod:`.octree`): once per cloud.
- :class:`ViewCamera` (:mod:`.camera`): a tab's camera, from viser's
  ``client.camera`` with :meth:`ViewCamera.from_viser`; :func:`camera_moved` says
  whether a new camera needs a new selection.
- :func:`select_nodes` (:mod:`.select`): the nodes to show.
- :class:`Residency` (:mod:`.residency`): per tab, what to send, show, hide, evict.
- :func:`encode_node`, :func:`node_colours` (:mod:`.encode`):
  what the scene gets of a node.
"""

from rough_viewer.lod.camera import ViewCamera, camera_moved, in_view, screen_rect_mask
from rough_viewer.lod.encode import EncodedNode, encode_node, node_colours
from rough_viewer.lod.octree import Node, Octree, build_bytes, build_octree
from rough_viewer.lod.residency import Residency, ResidencyPlan
from rough_viewer.lod.select import DEFAULT_BUDGET, Selection, select_nodes

__all__ = [
    "DEFAULT_BUDGET",
    "EncodedNode",
    "Node",
    "Octree",
    "Residency",
    "ResidencyPlan",
    "Selection",
    "ViewCamera",
    "build_bytes",
    "build_octree",
    "camera_moved",
    "encode_node",
    "in_view",
    "node_colours",
    "screen_rect_mask",
    "select_nodes",
]
