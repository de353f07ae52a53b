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


def initial_camera(server: viser.ViserServer, loaded: LoadedCloud) -> None:
    """Set the server's initial camera to look at the cloud (steep faces straight
    on, flat ground from above at an angle), leaving room for the control panel."""
    pts = loaded.display_points.astype(np.float64)
    centre = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    extent = float(np.max(pts.max(axis=0) - pts.min(axis=0))) or 1.0
    normal = loaded.plane.normal
    if abs(normal[2]) > 0.8:  # near-horizontal surface: look down at an angle
        direction = np.array([0.0, -0.6, 0.8])
        right = np.array([1.0, 0.0, 0.0])
    else:  # steep face: look at it straight on, slightly from above
        horiz = np.array([normal[0], normal[1], 0.0])
        horiz /= np.linalg.norm(horiz)
        if horiz[0] - horiz[1] < 0:  # keep +x (or +y) to the right on screen
            horiz = -horiz
        direction = horiz + np.array([0.0, 0.0, 0.35])
        right = np.array([-horiz[1], horiz[0], 0.0])
    direction /= np.linalg.norm(direction)
    # aim right of the centre so the cloud sits left of the control panel
    target = centre + 0.22 * extent * right
    server.initial_camera.look_at = (float(target[0]), float(target[1]), float(target[2]))
    eye = target + 0.8 * extent * direction
    server.initial_camera.position = (float(eye[0]), float(eye[1]), float(eye[2]))
    server.initial_camera.up = (0.0, 0.0, 1.0)


def reset_cameras(server: viser.ViserServer) -> None:
    """Move every connected browser's camera to the initial camera."""
    for client in server.get_clients().values():
        client.camera.position = server.initial_camera.position
        client.camera.look_at = server.initial_camera.look_at


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


def mark_pick(server: viser.ViserServer, loaded: LoadedCloud, info: CellInfo,
              local: np.ndarray, cell_size: float) -> list[viser.SceneNodeHandle]:
    """A marker on the picked point and the outline of its cell."""
    g = cell_size
    c = np.asarray(info.centre) - loaded.origin
    return [
        server.scene.add_icosphere("/pick/point", radius=0.15 * g, color=PICK_COLOUR,
                                   position=(float(local[0]), float(local[1]), float(local[2]))),
        server.scene.add_box("/pick/cell", color=PICK_COLOUR, dimensions=(g, g, g),
                             wireframe=True, position=(float(c[0]), float(c[1]), float(c[2]))),
    ]
