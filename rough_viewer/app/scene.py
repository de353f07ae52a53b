"""The 3-D scene: the map's point cloud, the cameras, markers, lines and clouds of
the features.

:class:`Scene` is the only writer of viser's scene: every method asserts it runs on
the worker (:meth:`rough_viewer.app.worker.Worker.require_worker`), so the scene
changes on one thread only. Features keep the node handles it returns and change
them through it (:meth:`Scene.update`, :meth:`Scene.remove`). The camera poses and
sizes are plain functions of the loaded cloud.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import viser

from rough_viewer.app.cloud import LoadedCloud
from rough_viewer.app.colouring import CellInfo, Colouring
from rough_viewer.app.stage import Stage, stage_of
from rough_viewer.lod.camera import ViewCamera, camera_moved
from rough_viewer.lod.copc import CopcTree
from rough_viewer.lod.encode import EncodedNode, encode_node, encode_points, node_scale
from rough_viewer.lod.octree import Octree
from rough_viewer.lod.residency import Residency
from rough_viewer.lod.select import DEFAULT_BUDGET, LodTree, node_points_for, select_nodes
from rough_viewer.report.view import Camera
from rough_viewer.visual.app import CONTROL_WIDTH
from rough_viewer.vocabulary import InputError

if TYPE_CHECKING:
    from rough_viewer.app.campaign_nodes import CopcNodes, DecodedNode

AXIS_VECTORS = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}
AXIS_COLOUR = (230, 60, 40)
PICK_COLOUR = (255, 30, 200)
GREY = 190


#: The browser window the initial camera is framed for, px (a laptop's browser; the
#: presets frame each browser's own window).
FRAME_WINDOW = (1600, 1000)
#: Width of the window the floating control panel covers at its right, px (the panel
#: and its margin).
PANEL_PX = CONTROL_WIDTH + 24
#: viser's initial vertical field of view, radians.
DEFAULT_FOV = float(np.radians(75.0))
#: The cloud fills this share of the free part of the window (the rest is margin).
FILL = 0.9
#: Text of the scene markers: labels are drawn on top of the points and sized in
#: screen pixels (viser draws labels without depth test), so a marker never hides
#: inside a dense cloud and keeps its size when zoomed out.
MARKER = "✚"
#: Thickness of outlines and profile lines, screen pixels.
LINE_PX = 3.0


@dataclass(frozen=True)
class Pose:
    """A camera: where it stands and looks (display frame, metres), its up vector and
    its clipping planes (distances from the camera, metres)."""

    eye: np.ndarray
    target: np.ndarray
    up: np.ndarray
    near: float
    far: float


def _directions(loaded: LoadedCloud, preset: str) -> tuple[np.ndarray, np.ndarray]:
    """(view direction from the cloud to the camera, up) of a preset."""
    normal = np.asarray(loaded.plane.normal, dtype=np.float64)
    z = np.array([0.0, 0.0, 1.0])
    horizontal = abs(normal[2]) > 0.8
    if preset == "top":
        direction, up = z.copy(), np.array([0.0, 1.0, 0.0])
    elif preset == "side":
        direction = np.cross(normal, z) if not horizontal else np.array([1.0, 0.0, 0.0])
        if direction[0] + direction[1] < 0:
            direction = -direction
        up = z
    elif preset == "face-on":
        if horizontal:  # near-horizontal surface: from above, tilted so it reads as ground
            direction = np.array([0.0, -0.6, 0.8])
        else:
            direction = normal.copy()
            if normal[0] - normal[1] < 0:  # keep +x (or +y) to the right on screen
                direction = -direction
            direction[2] = 0.1 * float(np.hypot(direction[0], direction[1]))  # a little from above
        up = z
    else:
        raise ValueError(f"unknown camera preset {preset!r}")
    return direction / np.linalg.norm(direction), up


def camera_pose(loaded: LoadedCloud, preset: str = "face-on", *,
                window: tuple[int, int] = FRAME_WINDOW, panel_px: float = PANEL_PX,
                fov: float = DEFAULT_FOV) -> Pose:
    """The camera of a preset that frames the whole cloud in the part of a
    ``window`` (width, height px) the control panel leaves free, at vertical field of
    view ``fov`` (radians), at any extent (a 20 mm joint, a 10 km tile).

    ``face-on``: along the whole-cloud face normal (steep faces from the side that
    keeps +x, or +y, to the right; near-horizontal surfaces from above); ``top``:
    straight down, north up; ``side``: along the face, horizontally (the strike
    direction), so the relief shows in profile. The camera stands back until the
    cloud's extent across the view fits :data:`FILL` of the free width and height,
    and looks right of the cloud's centre so that the cloud sits in the middle of the
    free part, left of the panel. The clipping planes follow the cloud's extent (viser's
    default far plane of 1 km left a larger tile blank).
    """
    direction, up = _directions(loaded, preset)
    right = np.cross(-direction, up)
    right /= np.linalg.norm(right)
    screen_up = np.cross(right, -direction)
    pts = loaded.display_points.astype(np.float64)
    if len(pts) > 200_000:  # the extent of an even subset is the extent
        pts = pts[:: len(pts) // 200_000 + 1]
    along = pts @ np.stack([right, screen_up, direction], axis=1)
    lo, hi = along.min(axis=0), along.max(axis=0)
    half = np.maximum(0.5 * (hi - lo), 1e-9)
    centre = 0.5 * (lo[0] + hi[0]) * right + 0.5 * (lo[1] + hi[1]) * screen_up \
        + 0.5 * (lo[2] + hi[2]) * direction
    width, height = (max(int(v), 1) for v in window)
    free = max(width - float(panel_px), 0.25 * width) / width
    aspect = width / height
    t = float(np.tan(0.5 * fov))
    # fitted at the cloud's near side (perspective draws it largest): the camera
    # stands that far from it, and looks right of the centre by as much as the free
    # part's centre lies left of the window's there. Farther points come out smaller
    # and nearer the window's centre: inside the free part too, unless the panel
    # covers that centre (a narrow window), where a deep cloud needs more distance
    wide = half[0] / (t * aspect)
    fits = [wide / free, half[1] / t]
    if free < 0.5:
        fits.append((wide + (1.0 - 2.0 * free) * 2.0 * half[2]) / free)
    near_side = max(fits) / FILL
    distance = near_side + half[2]
    target = centre + (1.0 - free) * near_side * t * aspect * right
    extent = float(2.0 * half.max())
    near = max(1e-3 * extent, 1e-6)
    far = 100.0 * (distance + extent)
    return Pose(target + distance * direction, target, up, near, far)


def default_point_size(loaded: LoadedCloud) -> float:
    """A point size (metres) that closes the gaps between displayed points, at any
    extent (a 20 mm joint's tenth of a millimetre, a 10 km tile's tens of metres)."""
    w = loaded.plane.eigenvalues  # descending: the two largest are the face's spreads
    area = 12.0 * np.sqrt(max(w[0], 1e-18) * max(w[1], 1e-18))
    spacing = np.sqrt(area / max(loaded.n_display, 1))
    size = float(np.clip(1.5 * spacing, 1e-6, 0.1 * np.sqrt(area)))
    return float(f"{size:.2g}")


def axis_segment(loaded: LoadedCloud, axis: str) -> tuple[np.ndarray, np.ndarray]:
    """((2, 3) ends, (3,) label position) of the dependent-axis line, display frame:
    8 % of the cloud's extent long, along ``axis``, under the middle of the cloud as
    the face-on camera draws it (its top 2 % of the window's height below the point
    lowest on that camera's screen, perspective included), going away from the rock;
    the label at its top end, beside it. Never over the rock."""
    pose = camera_pose(loaded, "face-on")
    back = pose.eye - pose.target
    back /= np.linalg.norm(back)
    right = np.cross(-back, pose.up)
    right /= np.linalg.norm(right)
    screen_up = np.cross(right, -back)
    pts = loaded.display_points.astype(np.float64)
    if len(pts) > 200_000:
        pts = pts[:: len(pts) // 200_000 + 1]
    rel = pts - pose.eye
    depth = np.maximum(rel @ -back, 1e-12)
    t = float(np.tan(0.5 * DEFAULT_FOV))
    lowest = float(((rel @ screen_up) / depth).min()) * (1.0 / t)  # NDC y of the lowest point
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    extent = float(np.max(hi - lo)) or 1.0
    centre = 0.5 * (lo + hi)  # the line stands under the middle of the cloud
    d_c = float((centre - pose.eye) @ -back)
    y_c = float((centre - pose.eye) @ screen_up) / (d_c * t)
    top = centre - (y_c - (lowest - 0.04)) * d_c * t * screen_up
    vec = np.asarray(AXIS_VECTORS[axis], dtype=np.float64)
    if float(vec @ screen_up) > 0:  # drawn downwards, away from the rock
        vec = -vec
    return np.stack([top, top + 0.08 * extent * vec]), top


def box_edges(centre: np.ndarray, size: float) -> np.ndarray:
    """(12, 2, 3) float32 edges of the axis-aligned cube of edge ``size`` at ``centre``."""
    c = np.asarray(centre, dtype=np.float64)
    corners = c + 0.5 * size * np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1)
                                         for z in (-1, 1)], dtype=np.float64)
    pairs = [(a, b) for a in range(8) for b in range(a + 1, 8)
             if bin(a ^ b).count("1") == 1]  # corners differing in one coordinate
    return np.array([[corners[a], corners[b]] for a, b in pairs], dtype=np.float32)


@dataclass(eq=False)
class Tab:
    """What one browser tab shows of the cloud: its nodes of the octree (level of
    detail from its own camera)."""

    residency: Residency
    handles: dict[int, viser.PointCloudHandle] = field(default_factory=dict)
    camera: ViewCamera | None = None
    """The camera the tab's nodes were chosen for."""
    nearest_m: float = float("inf")
    """Distance to the nearest node shown (how far a camera move shifts the view)."""
    sent_points: int = 0
    """Points sent to the tab so far (every node once; a colour change resends none)."""
    missing: list[int] = field(default_factory=list)
    """Nodes its last selection chose that were not at hand (a campaign's nodes being
    decoded), largest on its screen first."""
    stale: set[int] = field(default_factory=set)
    """Decoded nodes it holds whose colours are out of date because their points left
    the cache: recoloured when they are decoded again."""


class Scene:
    """The scene of one app (see the module docstring).

    The cloud is shown in every browser tab by level of detail: each tab (viser's
    per-client scene) holds the nodes of the cloud's octree (:mod:`rough_viewer.lod`)
    its own camera sees, within the point budget (:meth:`refine`), and every node is
    coloured by the one :data:`~rough_viewer.app.colouring.Colouring` of the points
    (:meth:`colour_by`): the map's, or a feature's (the zones, the sets).

    Parameters
    ----------
    server
        The viser server whose scene this writes (shared by every tab), or a stage
        (one tab's own scene: :mod:`rough_viewer.app.stage`).
    require_writer
        ``require_writer(what)`` raises unless the calling thread may write.
    budget
        Most points a tab shows at once.
    """

    def __init__(self, server: viser.ViserServer | Stage,
                 require_writer: Callable[[str], None], *,
                 budget: int = DEFAULT_BUDGET) -> None:
        self._server = stage_of(server)
        self._require = require_writer
        self.point_size = 0.01
        """The size of the points (metres); clouds added with a ``size_factor`` follow it."""
        self.budget = int(budget)
        """Most points a browser tab shows at once."""
        self._followers: dict[str, tuple[viser.PointCloudHandle, float]] = {}
        self._loaded: LoadedCloud | None = None
        self._tree: LodTree | None = None
        self._nodes: CopcNodes | None = None
        """A campaign's node points (the COPC file's nodes decoded on demand), or None
        (the cloud's own octree: every node's points are rows of the cloud)."""
        self._colouring: Colouring | None = None
        self._by_position: Colouring | None = None
        """The last colouring by cell given (its ``at`` colours a decoded node's points
        by position): what a decoded node shows under a colouring of rows only."""
        self._arrived: Callable[[frozenset[int]], None] | None = None
        self._node_failed: Callable[[str], None] | None = None
        self.tabs: dict[int, Tab] = {}
        """Each connected browser's nodes, by client id."""

    def _check(self, what: str) -> None:
        self._require(f"the scene ({what})")

    @property
    def initial_camera(self) -> Any:
        """The camera a browser opens with (viser's ``InitialCameraConfig``; read it)."""
        return self._server.initial_camera

    def on_click(self, callback: Callable[[viser.SceneClickEvent], None]) -> None:
        """Call ``callback`` (on viser's thread pool: submit a job) for each click."""
        self._server.scene.on_click()(callback)

    def on_rect_select(self, callback: Callable[[viser.SceneRectSelectEvent], None]) -> None:
        """Call ``callback`` (on viser's thread pool: submit a job) for each rectangle
        a browser drags with Shift held (viser's rectangle selection)."""
        self._server.scene.on_rect_select(modifier="shift")(callback)

    # ------------------------------------------------------------------ the cloud
    def show_cloud(self, loaded: LoadedCloud, point_size: float) -> None:
        """Show ``loaded`` (grey until it is coloured) in every tab, replacing the cloud
        before: its octree is built here (once per cloud, memory checked), with nodes
        sized for the point budget (:func:`rough_viewer.lod.select.node_points_for`);
        a campaign's tree is its COPC file's hierarchy
        (:meth:`rough_viewer.app.campaign.CampaignCloud.lod_nodes`)."""
        from rough_viewer.app.campaign import CampaignCloud

        self._check("show_cloud")
        self.point_size = float(point_size)
        old = self._nodes
        nodes = loaded.lod_nodes() if isinstance(loaded, CampaignCloud) else None
        if old is not None and old is not nodes:  # a crop of the campaign, another cloud
            old.listen(None, None)
            for cid in self.tabs:
                old.forget(cid)
            old.cache.clear()
        tree: LodTree = nodes.tree if nodes is not None else loaded.octree(
            node_points_for(self.budget))
        self._loaded, self._tree, self._nodes = loaded, tree, nodes
        if nodes is not None:
            nodes.listen(self._arrived, self._node_failed)
        for tab in self.tabs.values():
            self._drop_nodes(tab)
            tab.residency = Residency(tree.counts, self._tab_budget())
        grey = np.array([GREY, GREY, GREY], dtype=np.uint8)
        self._colouring = lambda idx: np.broadcast_to(grey, (len(idx), 3))
        self._by_position = None
        # every connected tab, not only those that chose nodes before: a tab whose
        # camera came while the file loaded (no octree yet) has no Tab so far
        for client_id in set(self.tabs) | set(self._server.clients()):
            self.refine(client_id)

    def on_nodes(self, arrived: Callable[[frozenset[int]], None],
                 failed: Callable[[str], None]) -> None:
        """A campaign's decoding thread calls ``arrived(client_ids)`` when nodes those
        tabs wait for were decoded (submit their refinement) and ``failed(line)`` for
        a node that cannot be drawn (show the line); neither on the worker."""
        self._arrived, self._node_failed = arrived, failed
        if self._nodes is not None:
            self._nodes.listen(arrived, failed)

    @property
    def nodes(self) -> CopcNodes | None:
        """A campaign's node points (None: the cloud's own octree)."""
        return self._nodes

    def colour_by(self, colouring: Colouring) -> None:
        """Colour the cloud's points by ``colouring`` in every tab (the nodes it shows
        now; hidden ones when shown again). A campaign's decoded nodes take their
        colours by position (:meth:`rough_viewer.app.colouring.CellColouring.at`);
        under a colouring of the cloud's rows only (a crop's selection, the distance
        layer) they keep the last colouring by cell's."""
        self._check("colour_by")
        self._colouring = colouring
        if getattr(colouring, "result", None) is not None:
            self._by_position = colouring
        if self._tree is None:
            return
        for cid, tab in self.tabs.items():
            ids = tab.residency.colours_changed()
            for k, colours in self._node_colours(tab, ids).items():
                tab.handles[k].colors = colours
            self._want(cid, tab)

    def colours(self, idx: np.ndarray) -> np.ndarray:
        """(K, 3) uint8: the colours points ``idx`` of the cloud show now."""
        if self._colouring is None:
            return np.full((len(idx), 3), GREY, dtype=np.uint8)
        return np.asarray(self._colouring(np.asarray(idx)))

    def colours_at(self, x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
        """(K, 3) uint8: the colours points at x, y, z (metres, the cloud's frame; a
        campaign's decoded points) show now: their cells' under the colouring shown,
        or under the last colouring by cell where the one shown colours rows only,
        grey where there is none."""
        for colouring in (self._colouring, self._by_position):
            at = getattr(colouring, "at", None)
            got = at(x, y, z) if at is not None else None
            if got is not None:
                return np.asarray(got)
        return np.full((len(x), 3), GREY, dtype=np.uint8)

    def _rows(self, k: int) -> np.ndarray | None:
        """Rows of the cloud holding node ``k``'s points (None: a decoded node)."""
        if self._nodes is not None:
            return self._nodes.rows(k)
        assert isinstance(self._tree, Octree)
        return self._tree.rows(k)

    def _node_colours(self, tab: Tab, ids: Sequence[int]) -> dict[int, np.ndarray]:
        """The colours of nodes ``ids`` under the colouring shown: those of rows in
        one call; a decoded node's by position, or, its points out of the cache, none
        (it goes stale in ``tab``, to be decoded again)."""
        out: dict[int, np.ndarray] = {}
        by_rows: list[tuple[int, np.ndarray]] = []
        for k in ids:
            rows = self._rows(k)
            if rows is not None:
                by_rows.append((k, rows))
                continue
            pts = self._nodes.points(k) if self._nodes is not None else None
            if pts is None:
                tab.stale.add(k)
            else:
                tab.stale.discard(k)
                out[k] = self.colours_at(pts.x, pts.y, pts.z)
        if by_rows and self._colouring is not None:
            colours = self._colouring(np.concatenate([r for _, r in by_rows]))
            at = 0
            for k, r in by_rows:
                out[k] = colours[at:at + len(r)]
                at += len(r)
        return out

    def _want(self, client_id: int, tab: Tab) -> None:
        """A campaign's tab wishes for the nodes it lacks: its selection's and the
        stale ones it shows."""
        if self._nodes is None:
            return
        stale = [k for k in tab.residency.shown if k in tab.stale]
        self._nodes.want(client_id, list(dict.fromkeys(tab.missing + stale)))

    def set_point_size(self, size: float) -> None:
        """The points' size (metres); clouds that follow it scale with it."""
        self._check("set_point_size")
        self.point_size = float(size)
        for tab in self.tabs.values():
            for k, handle in tab.handles.items():
                handle.point_size = self._node_size(k)
        for node, factor in self._followers.values():
            node.point_size = factor * self.point_size

    def _node_size(self, k: int) -> float:
        assert self._tree is not None
        scale = node_scale(float(self._tree.size[k]))
        return self.point_size / scale

    # ------------------------------------------------------------------ tabs
    def set_budget(self, budget: int) -> None:
        """Most points a tab shows (every tab chooses its nodes again)."""
        self._check("set_budget")
        self.budget = int(budget)
        for client_id, tab in self.tabs.items():
            tab.residency.set_budget(self._tab_budget())
            tab.camera = None
            self.refine(client_id)

    def _tab_budget(self) -> int:
        """A tab's budget: the point budget, but at least the octree's root (so that
        a budget below the root's points shows the root, not nothing)."""
        root = int(self._tree.counts[0]) if self._tree is not None and self._tree.n_nodes else 0
        return max(self.budget, root)

    def refine(self, client_id: int, *, force: bool = False) -> bool:
        """Choose the nodes tab ``client_id`` should show for its camera now and send,
        show, hide or drop nodes to match (the nodes it held are kept hidden until
        twice the budget). False when the tab has no camera yet or it did not move
        enough (unless ``force``)."""
        self._check("refine")
        client = self._server.clients().get(client_id)
        if client is None or self._tree is None or self._loaded is None:
            return False
        tab = self.tabs.get(client_id)
        if tab is None:
            tab = self.tabs[client_id] = Tab(Residency(self._tree.counts, self._tab_budget()))
        try:
            camera = ViewCamera.from_viser(client.camera, self._loaded.origin)
        except (AssertionError, AttributeError, InputError, ValueError, ZeroDivisionError):
            return False  # no camera message yet
        if not (force or tab.camera is None
                or camera_moved(tab.camera, camera, distance_m=tab.nearest_m)):
            return False
        sel = select_nodes(self._tree, camera, tab.residency.budget)
        chosen, decoded = self._at_hand(tab, sel.nodes.tolist())
        plan = tab.residency.plan(chosen)
        tab.camera, tab.nearest_m = camera, sel.nearest_m
        for k in plan.evict:
            handle = tab.handles.pop(k, None)
            tab.stale.discard(k)
            if handle is not None:
                handle.remove()
        for k in plan.hide:
            tab.handles[k].visible = False
        recolour = set(plan.recolour) | (tab.stale & set(tab.residency.shown))
        for k, colours in self._node_colours(tab, sorted(recolour)).items():
            tab.handles[k].colors = colours
        for k in plan.show:
            tab.handles[k].visible = True
        for k in plan.send:
            tab.handles[k] = self._send(client, k, decoded.get(k))
            tab.sent_points += int(self._tree.counts[k])
        self._want(client_id, tab)
        return True

    def _at_hand(self, tab: Tab, chosen: list[int]) -> tuple[list[int], dict[int, DecodedNode]]:
        """Of the nodes chosen, those whose points are at hand (all, but in a campaign:
        the overview's, those the tab holds and those decoded so far, with their
        points); the rest, but those that cannot be decoded, become ``tab.missing``."""
        decoded: dict[int, DecodedNode] = {}
        if self._nodes is None:
            return chosen, decoded
        at_hand = []
        tab.missing = []
        counts = self._nodes.tree.node_counts
        for k in chosen:
            if counts[k] == 0:
                continue  # an empty node the hierarchy lacks: nothing to draw
            if self._nodes.in_overview(k) or k in tab.handles:  # the tab holds it already
                at_hand.append(k)
                continue
            pts = self._nodes.points(k)
            if pts is not None:
                decoded[k] = pts
                at_hand.append(k)
            elif not self._nodes.failed(k):
                tab.missing.append(k)
        return at_hand, decoded

    def _send(self, client: viser.ClientHandle, k: int,
              decoded: DecodedNode | None = None) -> viser.PointCloudHandle:
        assert self._tree is not None and self._loaded is not None
        enc: EncodedNode
        if isinstance(self._tree, Octree):
            node = self._tree.node(k)
            enc = encode_node(self._loaded.cloud, node)
            colours = self.colours(node.rows)
        else:
            assert isinstance(self._tree, CopcTree)
            size = float(self._tree.size[k])
            centre = self._tree.centre(k)
            rows = self._rows(k)
            if rows is not None:
                cloud = self._loaded.cloud
                enc = encode_points((cloud.x, cloud.y, cloud.z), rows, centre, size, node=k)
                colours = self.colours(rows)
            else:
                assert decoded is not None
                enc = encode_points((decoded.x, decoded.y, decoded.z), None, centre, size,
                                    node=k)
                colours = self.colours_at(decoded.x, decoded.y, decoded.z)
        return client.scene.add_point_cloud(
            f"/lod/{k}", points=enc.points, colors=colours, point_size=self._node_size(k),
            point_shape="square", point_shading="flat", precision="float16",
            position=_vec(enc.centre - self._loaded.origin), scale=enc.scale)

    def drop_tab(self, client_id: int) -> None:
        """A browser left: forget its nodes."""
        self._check("drop_tab")
        self.tabs.pop(client_id, None)
        if self._nodes is not None:
            self._nodes.forget(client_id)

    def _drop_nodes(self, tab: Tab) -> None:
        for handle in tab.handles.values():
            handle.remove()
        tab.handles.clear()
        tab.camera = None
        tab.missing, tab.stale = [], set()

    def shown_points(self, client_id: int) -> np.ndarray:
        """Indices of the cloud's points tab ``client_id`` shows now (a campaign: of
        its overview's nodes; its decoded nodes' points are no rows of the cloud)."""
        tab = self.tabs.get(client_id)
        if tab is None or self._tree is None:
            return np.empty(0, dtype=np.int64)
        rows = [r for r in (self._rows(k) for k in tab.residency.shown) if r is not None]
        if not rows:
            return np.empty(0, dtype=np.int64)
        return np.concatenate(rows)


    # ------------------------------------------------------------------ nodes
    def add_points(self, name: str, points: np.ndarray, colours: np.ndarray, *,
                   size_factor: float = 1.0) -> viser.PointCloudHandle:
        """A cloud of displayed-frame points whose size follows the map's point size
        times ``size_factor``."""
        self._check("add_points")
        node = self._server.scene.add_point_cloud(
            name, points=points, colors=colours, point_size=size_factor * self.point_size,
            point_shape="square", point_shading="flat", precision="float32")
        self._followers[name] = (node, float(size_factor))
        return node

    def add_label(self, name: str, text: str, position: Sequence[float]) -> viser.LabelHandle:
        self._check("add_label")
        p = np.asarray(position, dtype=np.float64).reshape(3)
        return self._server.scene.add_label(name, text, position=(float(p[0]), float(p[1]),
                                                                   float(p[2])))

    def marker(self, name: str, local: np.ndarray, text: str = MARKER) -> viser.LabelHandle:
        """A marker at ``local`` (display frame): a label, drawn on top and sized in
        screen pixels."""
        self._check("marker")
        return self._server.scene.add_label(
            name, text, position=np.asarray(local[:3], dtype=np.float64),
            anchor="center-center", font_screen_scale=1.4, depth_test=False)

    def lines(self, name: str, segments: np.ndarray, colour: tuple[int, int, int], *,
              thickness: float = LINE_PX, visible: bool = True) -> viser.LineSegmentsHandle:
        """Line segments ``(K, 2, 3)`` (display frame), ``thickness`` screen pixels."""
        self._check("lines")
        return self._server.scene.add_line_segments(
            name, np.asarray(segments, dtype=np.float32), colour, thickness=thickness,
            thickness_units="screen", visible=visible)

    def segments(self, name: str, segments: np.ndarray, colours: np.ndarray, *,
                 thickness: float = LINE_PX, visible: bool = True) -> viser.LineSegmentsHandle:
        """Line segments ``(K, 2, 3)`` (display frame) each in its own colours
        ``(K, 2, 3)`` uint8, ``thickness`` screen pixels."""
        self._check("segments")
        return self._server.scene.add_line_segments(
            name, np.asarray(segments, dtype=np.float32), np.asarray(colours, dtype=np.uint8),
            thickness=thickness, thickness_units="screen", visible=visible)

    def update(self, node: viser.SceneNodeHandle, **props: Any) -> None:
        """Set properties of a node this scene made (``colors``, ``visible``, ...)."""
        self._check("update")
        for key, value in props.items():
            setattr(node, key, value)

    def remove(self, nodes: Iterable[viser.SceneNodeHandle]) -> None:
        """Remove nodes this scene made."""
        self._check("remove")
        for node in nodes:
            self._followers = {k: v for k, v in self._followers.items() if v[0] is not node}
            node.remove()

    # ------------------------------------------------------------------ what the map draws
    def draw_axis(self, loaded: LoadedCloud, axis: str, *, chosen: bool, visible: bool) -> None:
        """The OLS dependent axis as a red line with its label, under the cloud,
        outside the rock (:func:`axis_segment`)."""
        self._check("draw_axis")
        seg, label = axis_segment(loaded, axis)
        self._server.scene.add_line_segments("/axis/line", seg[None].astype(np.float32),
                                             AXIS_COLOUR, thickness=4.0,
                                             thickness_units="screen", visible=visible)
        how = "chosen" if chosen else "auto"
        self._server.scene.add_label("/axis/label", f"OLS dependent axis {axis} ({how})",
                                     position=_vec(label), anchor="center-left",
                                     visible=visible)

    def mark_pick(self, loaded: LoadedCloud, info: CellInfo, local: np.ndarray,
                  cell_size: float) -> list[viser.SceneNodeHandle]:
        """A marker on the picked point (on top, screen-sized) and the outline of its
        cell (lines a few pixels thick)."""
        c = np.asarray(info.centre) - loaded.origin
        return [self.marker("/pick/point", local),
                self.lines("/pick/cell", box_edges(c, cell_size), PICK_COLOUR)]

    def surface_line(self, name: str, local: np.ndarray, normal: np.ndarray, lift: float,
                     colour: tuple[int, int, int],
                     max_segments: int = 400) -> list[viser.SceneNodeHandle]:
        """A polyline along the surface (``local``: (K, 3) display frame, NaN rows
        skipped) drawn twice, lifted by ``lift`` metres to either side of the surface
        along ``normal``, so the points in front of it on either side cannot hide it."""
        self._check("surface_line")
        pts = np.asarray(local, dtype=np.float64)
        pts = pts[np.all(np.isfinite(pts), axis=1)]
        if len(pts) < 2:
            return []
        step = max(1, int(np.ceil((len(pts) - 1) / max_segments)))
        pts = pts[::step] if (len(pts) - 1) % step == 0 else np.vstack([pts[::step], pts[-1:]])
        n = np.asarray(normal, dtype=np.float64) / np.linalg.norm(normal)
        nodes: list[viser.SceneNodeHandle] = []
        for side, sign in (("front", 1.0), ("back", -1.0)):
            p = pts + sign * lift * n
            seg = np.stack([p[:-1], p[1:]], axis=1)
            nodes.append(self.lines(f"{name}/{side}", seg, colour, thickness=LINE_PX + 1))
        return nodes

    # ------------------------------------------------------------------ cameras
    def frame(self, loaded: LoadedCloud) -> None:
        """Make the face-on view of ``loaded`` every browser's initial camera (framed
        for :data:`FRAME_WINDOW`: viser's "reset view" returns there) and frame each
        connected browser in its own window."""
        self._check("frame")
        pose = camera_pose(loaded, "face-on")
        init = self._server.initial_camera
        init.position, init.look_at = _vec(pose.eye), _vec(pose.target)
        init.up = _vec(pose.up)
        init.fov = DEFAULT_FOV
        init.near, init.far = pose.near, pose.far
        for client in self._server.clients().values():
            _place(client, camera_pose(loaded, "face-on", **_window(client)))

    def move_cameras(self, loaded: LoadedCloud, preset: str) -> None:
        """Move every connected browser's camera to a preset, framed in its window
        (:func:`camera_pose`)."""
        self._check("move_cameras")
        for client in self._server.clients().values():
            _place(client, camera_pose(loaded, preset, **_window(client)))

    def place_camera(self, loaded: LoadedCloud, camera: Camera) -> None:
        """Put every browser at ``camera`` (a saved view's: file frame, metres), with
        clipping planes for ``loaded``'s extent and the camera's distance."""
        self._check("place_camera")
        eye = np.asarray(camera.position) - loaded.origin
        look = np.asarray(camera.look_at) - loaded.origin
        framed = camera_pose(loaded)
        far = max(framed.far, 100.0 * float(np.linalg.norm(eye - look)))
        self.set_camera(eye, look, camera.up, float(np.radians(camera.fov_deg)),
                        near=framed.near, far=far)

    def set_camera(self, position: Sequence[float], look_at: Sequence[float],
                   up: Sequence[float], fov_rad: float, *, near: float, far: float) -> None:
        """Make this camera (display frame) the initial camera of every browser and
        move the connected ones there."""
        self._check("set_camera")
        p, t, u = (_vec(a) for a in (position, look_at, up))
        init = self._server.initial_camera
        init.position, init.look_at, init.up, init.fov = p, t, u, float(fov_rad)
        init.near, init.far = float(near), float(far)
        for client in self._server.clients().values():
            client.camera.near, client.camera.far = float(near), float(far)
            client.camera.position = p
            client.camera.look_at = t
            client.camera.up_direction = u
            client.camera.fov = float(fov_rad)


def _vec(v: Sequence[float] | np.ndarray) -> tuple[float, float, float]:
    a = np.asarray(v, dtype=np.float64).reshape(3)
    return float(a[0]), float(a[1]), float(a[2])


#: A canvas wider than this many pixels is taken to be drawn at two device pixels per
#: CSS pixel (viser reports the canvas in device pixels; the panel is CSS pixels).
HIDPI_WIDTH = 2200


def _window(client: viser.ClientHandle) -> dict[str, Any]:
    """A browser's window (CSS px) and field of view, once it has sent its camera."""
    try:
        cam = client.camera
        w, h, fov = int(cam.image_width), int(cam.image_height), float(cam.fov)
    except (AssertionError, AttributeError, TypeError, ValueError):
        return {}
    if w <= 0 or h <= 0 or not 0.0 < fov < np.pi:
        return {}
    scale = 2 if w > HIDPI_WIDTH else 1
    return {"window": (w // scale, h // scale), "fov": fov}


def _place(client: viser.ClientHandle, pose: Pose) -> None:
    """Put one browser's camera at ``pose``. Order matters in viser: setting the
    position moves the look-at point along, so the position goes first, then the
    look-at point, then the up direction."""
    with client.atomic():
        client.camera.near = pose.near
        client.camera.far = pose.far
        client.camera.position = _vec(pose.eye)
        client.camera.look_at = _vec(pose.target)
        client.camera.up_direction = _vec(pose.up)


def nodes_colours_of(tree: Octree, ids: Sequence[int], colouring: Colouring
                     ) -> list[np.ndarray]:
    """The colours of several nodes under ``colouring``: one call for all their points,
    then one array per node."""
    if not ids:
        return []
    rows = [tree.node(k).rows for k in ids]
    colours = colouring(np.concatenate(rows))
    out, at = [], 0
    for r in rows:
        out.append(colours[at:at + len(r)])
        at += len(r)
    return out
