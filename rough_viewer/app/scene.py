"""The 3-D scene: the point cloud, the camera, the dependent-axis marker and the
picked cell. Functions of the viser server and plain data; called from the
worker thread only (see :mod:`rough_viewer.app.worker`)."""

from __future__ import annotations

import numpy as np
import viser

from rough_viewer.app.state import CellInfo, LoadedCloud

AXIS_VECTORS = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}
AXIS_COLOUR = (230, 60, 40)
PICK_COLOUR = (255, 30, 200)
GREY = 190


#: Camera distance from the cloud's centre, in units of its largest extent: the
#: cloud then fills most of the view left of the control panel (measured in
#: Chromium at viser's default field of view, 1600 x 1000).
CAMERA_DISTANCE = 0.95
#: The camera looks this far (in units of the largest extent) right of the cloud's
#: centre, so the cloud sits left of the control panel, which floats over the
#: right third of the view.
PANEL_SHIFT = 0.22
#: Text of the scene markers: labels are drawn on top of the points and sized in
#: screen pixels (viser draws labels without depth test), so a marker never hides
#: inside a dense cloud and keeps its size when zoomed out.
MARKER = "✚"
#: Thickness of outlines and profile lines, screen pixels.
LINE_PX = 3.0


def camera_pose(loaded: LoadedCloud, preset: str = "face-on"
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(position, look-at, up) of a camera preset, display frame, metres.

    ``face-on``: along the whole-cloud face normal (steep faces from the side that
    keeps +x, or +y, to the right; near-horizontal surfaces from above); ``top``:
    straight down, north up; ``side``: along the face, horizontally (the strike
    direction), so the relief shows in profile. The camera stands far enough for the
    whole cloud to fit the view, shifted right by :data:`PANEL_SHIFT` so that the
    cloud sits left of the control panel.
    """
    pts = loaded.display_points.astype(np.float64)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre = 0.5 * (lo + hi)
    extent = float(np.max(hi - lo)) or 1.0
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
    direction = direction / np.linalg.norm(direction)
    right = np.cross(-direction, up)
    right /= np.linalg.norm(right)
    target = centre + PANEL_SHIFT * extent * right
    # along the face the cloud reaches towards the camera: stand back further
    distance = CAMERA_DISTANCE * extent * (1.6 if preset == "side" else 1.0)
    return target + distance * direction, target, up


def initial_camera(server: viser.ViserServer, loaded: LoadedCloud) -> None:
    """Set the server's initial camera to the face-on view of the cloud."""
    eye, target, up = camera_pose(loaded, "face-on")
    server.initial_camera.look_at = (float(target[0]), float(target[1]), float(target[2]))
    server.initial_camera.position = (float(eye[0]), float(eye[1]), float(eye[2]))
    server.initial_camera.up = (float(up[0]), float(up[1]), float(up[2]))


def move_cameras(server: viser.ViserServer, loaded: LoadedCloud, preset: str) -> None:
    """Move every connected browser's camera to a preset (:func:`camera_pose`)."""
    eye, target, up = camera_pose(loaded, preset)
    for client in server.get_clients().values():
        _place(client, eye, target, up)


def reset_cameras(server: viser.ViserServer) -> None:
    """Move every connected browser's camera to the initial camera."""
    cam = server.initial_camera
    up = cam.up if cam.up is not None else np.array([0.0, 0.0, 1.0])
    for client in server.get_clients().values():
        _place(client, cam.position, cam.look_at, up)


def _place(client: viser.ClientHandle, eye: np.ndarray, target: np.ndarray,
           up: np.ndarray) -> None:
    """Put one browser's camera at ``eye`` looking at ``target``. Order matters in
    viser: setting the position moves the look-at point along, so the position goes
    first, then the look-at point, then the up direction."""
    with client.atomic():
        client.camera.position = (float(eye[0]), float(eye[1]), float(eye[2]))
        client.camera.look_at = (float(target[0]), float(target[1]), float(target[2]))
        client.camera.up_direction = (float(up[0]), float(up[1]), float(up[2]))


def default_point_size(loaded: LoadedCloud) -> float:
    """A point size (metres) that closes the gaps between displayed points."""
    w = loaded.plane.eigenvalues  # descending: the two largest are the face's spreads
    area = 12.0 * np.sqrt(max(w[0], 1e-12) * max(w[1], 1e-12))
    spacing = np.sqrt(area / max(loaded.n_display, 1))
    size = float(np.clip(1.5 * spacing, 1e-4, 1.0))
    return float(f"{size:.2g}")


def add_cloud(server: viser.ViserServer, loaded: LoadedCloud,
              point_size: float) -> viser.PointCloudHandle:
    """Draw the displayed points (grey until the first map colours them)."""
    grey = np.full((loaded.n_display, 3), GREY, dtype=np.uint8)
    return server.scene.add_point_cloud(
        "/cloud",
        points=loaded.display_points,
        colors=grey,
        point_size=point_size,
        point_shape="square",
        point_shading="flat",
        precision="float32",
    )


def draw_axis(server: viser.ViserServer, loaded: LoadedCloud, axis: str, *, chosen: bool,
              visible: bool) -> None:
    """The OLS dependent axis as a red line with a label through the cloud's centre."""
    pts = loaded.display_points
    lo, hi = pts.min(axis=0).astype(np.float64), pts.max(axis=0).astype(np.float64)
    centre = 0.5 * (lo + hi)
    length = 0.3 * float(np.max(hi - lo))
    vec = np.asarray(AXIS_VECTORS[axis])
    seg = np.array([[centre, centre + length * vec]], dtype=np.float32)
    server.scene.add_line_segments("/axis/line", seg, AXIS_COLOUR, thickness=4.0,
                                   thickness_units="screen", visible=visible)
    end = centre + 1.05 * length * vec
    how = "chosen" if chosen else "auto"
    server.scene.add_label("/axis/label", f"OLS dependent axis {axis} ({how})",
                           position=(float(end[0]), float(end[1]), float(end[2])),
                           visible=visible)


def box_edges(centre: np.ndarray, size: float) -> np.ndarray:
    """(12, 2, 3) float32 edges of the axis-aligned cube of edge ``size`` at ``centre``."""
    c = np.asarray(centre, dtype=np.float64)
    corners = c + 0.5 * size * np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1)
                                         for z in (-1, 1)], dtype=np.float64)
    pairs = [(a, b) for a in range(8) for b in range(a + 1, 8)
             if bin(a ^ b).count("1") == 1]  # corners differing in one coordinate
    return np.array([[corners[a], corners[b]] for a, b in pairs], dtype=np.float32)


def marker(server: viser.ViserServer, name: str, local: np.ndarray,
           text: str = MARKER) -> viser.LabelHandle:
    """A marker at ``local`` (display frame): a label, drawn on top and sized in
    screen pixels."""
    return server.scene.add_label(name, text, position=np.asarray(local[:3], dtype=np.float64),
                                  anchor="center-center", font_screen_scale=1.4,
                                  depth_test=False)


def mark_pick(server: viser.ViserServer, loaded: LoadedCloud, info: CellInfo,
              local: np.ndarray, cell_size: float) -> list[viser.SceneNodeHandle]:
    """A marker on the picked point (on top, screen-sized) and the outline of its
    cell (lines a few pixels thick)."""
    c = np.asarray(info.centre) - loaded.origin
    return [
        marker(server, "/pick/point", local),
        server.scene.add_line_segments("/pick/cell", box_edges(c, cell_size), PICK_COLOUR,
                                       thickness=LINE_PX, thickness_units="screen"),
    ]


def clear_pick(nodes: list[viser.SceneNodeHandle]) -> None:
    """Remove the scene nodes of a pick."""
    for node in nodes:
        node.remove()


def surface_line(server: viser.ViserServer, name: str, local: np.ndarray, normal: np.ndarray,
                 lift: float, colour: tuple[int, int, int],
                 max_segments: int = 400) -> list[viser.SceneNodeHandle]:
    """A polyline along the surface (``local``: (K, 3) display frame, NaN rows
    skipped) drawn twice, lifted by ``lift`` metres to either side of the surface
    along ``normal``, so the points in front of it on either side cannot hide it."""
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
        seg = np.stack([p[:-1], p[1:]], axis=1).astype(np.float32)
        nodes.append(server.scene.add_line_segments(f"{name}/{side}", seg, colour,
                                                    thickness=LINE_PX + 1,
                                                    thickness_units="screen"))
    return nodes
