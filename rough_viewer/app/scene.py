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
from dataclasses import dataclass
from typing import Any

import numpy as np
import viser

from rough_viewer.app.state import CellInfo, LoadedCloud
from rough_viewer.visual.app import CONTROL_WIDTH

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
    8 % of the cloud's extent long, along ``axis``, under the cloud as the face-on
    camera draws it (from 3 % of the extent below the point lowest on its screen,
    perspective included), going away from the rock; the label at its top end,
    beside it. Never over the rock."""
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
    depth = rel @ -back
    lowest = pts[int(np.argmin((rel @ screen_up) / np.maximum(depth, 1e-12)))]
    extent = float(np.max(pts.max(axis=0) - pts.min(axis=0))) or 1.0
    top = lowest - 0.03 * extent * screen_up
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


class Scene:
    """The scene of one app (see the module docstring).

    Parameters
    ----------
    server
        The viser server whose scene this writes.
    require_writer
        ``require_writer(what)`` raises unless the calling thread may write.
    """

    def __init__(self, server: viser.ViserServer, require_writer: Callable[[str], None]) -> None:
        self._server = server
        self._require = require_writer
        self.cloud: viser.PointCloudHandle | None = None
        """The map's cloud: the displayed points, coloured by the map."""
        self.point_size = 0.01
        """The size of the map's points (metres); clouds added with a ``size_factor``
        follow it."""
        self._followers: dict[str, tuple[viser.PointCloudHandle, float]] = {}

    def _check(self, what: str) -> None:
        self._require(f"the scene ({what})")

    @property
    def initial_camera(self) -> Any:
        """The camera a browser opens with (viser's ``InitialCameraConfig``; read it)."""
        return self._server.initial_camera

    def on_click(self, callback: Callable[[viser.SceneClickEvent], None]) -> None:
        """Call ``callback`` (on viser's thread pool: submit a job) for each click."""
        self._server.scene.on_click()(callback)

    # ------------------------------------------------------------------ the map's cloud
    def show_cloud(self, loaded: LoadedCloud, point_size: float) -> viser.PointCloudHandle:
        """Draw the displayed points of ``loaded`` as the map's cloud (grey until the
        map colours them), replacing the cloud before."""
        self._check("show_cloud")
        self.point_size = float(point_size)
        grey = np.full((loaded.n_display, 3), GREY, dtype=np.uint8)
        self.cloud = self._server.scene.add_point_cloud(
            "/cloud", points=loaded.display_points, colors=grey, point_size=self.point_size,
            point_shape="square", point_shading="flat", precision="float32")
        return self.cloud

    def colour(self, colours: np.ndarray) -> None:
        """Colour the map's cloud (one RGB triple per displayed point)."""
        self._check("colour")
        assert self.cloud is not None
        self.cloud.colors = colours

    def show_map(self, visible: bool) -> None:
        """Show or hide the map's cloud (a feature shows its own cloud instead)."""
        self._check("show_map")
        if self.cloud is not None:
            self.cloud.visible = visible

    def set_point_size(self, size: float) -> None:
        """The map's point size (metres); clouds that follow it scale with it."""
        self._check("set_point_size")
        self.point_size = float(size)
        if self.cloud is not None:
            self.cloud.point_size = self.point_size
        for node, factor in self._followers.values():
            node.point_size = factor * self.point_size

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
        for client in self._server.get_clients().values():
            _place(client, camera_pose(loaded, "face-on", **_window(client)))

    def move_cameras(self, loaded: LoadedCloud, preset: str) -> None:
        """Move every connected browser's camera to a preset, framed in its window
        (:func:`camera_pose`)."""
        self._check("move_cameras")
        for client in self._server.get_clients().values():
            _place(client, camera_pose(loaded, preset, **_window(client)))

    def set_camera(self, position: Sequence[float], look_at: Sequence[float],
                   up: Sequence[float], fov_rad: float, *, near: float, far: float) -> None:
        """Make this camera (display frame) the initial camera of every browser and
        move the connected ones there."""
        self._check("set_camera")
        p, t, u = (_vec(a) for a in (position, look_at, up))
        init = self._server.initial_camera
        init.position, init.look_at, init.up, init.fov = p, t, u, float(fov_rad)
        init.near, init.far = float(near), float(far)
        for client in self._server.get_clients().values():
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
