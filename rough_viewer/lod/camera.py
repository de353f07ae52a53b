"""A browser tab's camera as the level of detail needs it: pose, field of view, the
window's shape, and the pinhole projection they define.

Conventions are viser's (``client.camera``): ``wxyz`` is the camera-to-world
rotation ``R`` (``p_world = R p_camera + position``) in the OpenCV frame, +x right,
+y down, +z forward (the viewing direction); ``fov`` is the vertical field of view in
radians; ``aspect`` is width / height. A point ``p`` is at camera coordinates
``c = R^T (p - position)`` and at pixel ``(u, v) = (f c_x / c_z + W / 2,
f c_y / c_z + H / 2)``, ``f = (H / 2) / tan(fov / 2)``, from the window's top left.

Looking along +y from 10 m: f = 400 / tan(25 deg) = 857.8 px, so 1 m at 10 m is 85.78 px.

>>> cam = ViewCamera.looking_at((0.0, -10.0, 0.0), (0.0, 0.0, 0.0), height_px=800)
>>> u, v, depth = cam.project(np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 1.0]]))
>>> u.round(3).tolist(), v.round(3).tolist(), depth.tolist()
([533.333, 619.114], [400.0, 314.22], [10.0, 10.0])
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from rough_viewer.vocabulary import InputError


def rotation_from_wxyz(wxyz: np.ndarray | tuple[float, ...]) -> np.ndarray:
    """(3, 3) rotation matrix of a unit quaternion ``(w, x, y, z)`` (normalised here)."""
    q = np.asarray(wxyz, dtype=np.float64)
    norm = float(np.linalg.norm(q))
    if q.shape != (4,) or not (math.isfinite(norm) and norm > 0.0):
        raise InputError(f"camera orientation must be a non-zero quaternion (w, x, y, z), "
                         f"got {np.asarray(wxyz).tolist()}")
    w, x, y, z = q / norm
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def wxyz_from_rotation(r: np.ndarray) -> np.ndarray:
    """(4,) unit quaternion ``(w, x, y, z)`` of a rotation matrix (``w >= 0``)."""
    m = np.asarray(r, dtype=np.float64)
    t = np.trace(m)
    if t > 0:
        s = 2.0 * math.sqrt(1.0 + t)
        q = [0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
    else:
        i = int(np.argmax(np.diag(m)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * math.sqrt(max(1.0 + m[i, i] - m[j, j] - m[k, k], 1e-300))
        q = [0.0, 0.0, 0.0, 0.0]
        q[0] = (m[k, j] - m[j, k]) / s
        q[1 + i] = 0.25 * s
        q[1 + j] = (m[j, i] + m[i, j]) / s
        q[1 + k] = (m[k, i] + m[i, k]) / s
    out = np.array(q)
    out /= np.linalg.norm(out)
    return -out if out[0] < 0 else out


@dataclass(frozen=True)
class ViewCamera:
    """A tab's camera in the cloud's frame (metres)."""

    position: np.ndarray
    """(3,) camera centre, metres, the cloud's frame (viser's position plus the app's
    local origin)."""
    wxyz: np.ndarray
    """(4,) camera-to-world rotation, OpenCV axes (x right, y down, z forward)."""
    fov_rad: float
    """Vertical field of view, radians, in (0, pi)."""
    aspect: float
    """Window width / height."""
    height_px: int
    """Window height, pixels."""

    def __post_init__(self) -> None:
        pos = np.asarray(self.position, dtype=np.float64)
        if pos.shape != (3,) or not np.all(np.isfinite(pos)):
            raise InputError(f"camera position must be three finite numbers, got "
                             f"{np.asarray(self.position).tolist()}")
        if not (math.isfinite(self.fov_rad) and 0.0 < self.fov_rad < math.pi):
            raise InputError(f"camera field of view must lie in (0, pi) radians, got {self.fov_rad}")
        if not (math.isfinite(self.aspect) and self.aspect > 0.0):
            raise InputError(f"camera aspect must be positive, got {self.aspect}")
        if int(self.height_px) < 1:
            raise InputError(f"window height must be at least 1 pixel, got {self.height_px}")
        rotation_from_wxyz(self.wxyz)  # checks it
        object.__setattr__(self, "position", pos)
        object.__setattr__(self, "wxyz", np.asarray(self.wxyz, dtype=np.float64))
        object.__setattr__(self, "height_px", int(self.height_px))

    @classmethod
    def from_viser(cls, camera: Any, origin: np.ndarray | tuple[float, float, float] = (0, 0, 0)
                   ) -> ViewCamera:
        """From a viser ``client.camera`` (read, not imported: position, wxyz, fov,
        aspect, image_height), the scene's local ``origin`` (metres, the cloud's
        frame) added back to the position."""
        return cls(position=np.asarray(camera.position, dtype=np.float64)
                   + np.asarray(origin, dtype=np.float64),
                   wxyz=np.asarray(camera.wxyz, dtype=np.float64), fov_rad=float(camera.fov),
                   aspect=float(camera.aspect), height_px=int(camera.image_height))

    @classmethod
    def looking_at(cls, position: Any, target: Any, *, up: Any = (0.0, 0.0, 1.0),
                   fov_rad: float = math.radians(50.0), aspect: float = 4.0 / 3.0,
                   height_px: int = 1000) -> ViewCamera:
        """A camera at ``position`` looking at ``target`` with ``up`` upward on screen."""
        p = np.asarray(position, dtype=np.float64)
        forward = np.asarray(target, dtype=np.float64) - p
        if not np.linalg.norm(forward) > 0:
            raise InputError("a camera cannot look at its own position")
        forward /= np.linalg.norm(forward)
        right = np.cross(forward, np.asarray(up, dtype=np.float64))
        if np.linalg.norm(right) < 1e-12:  # looking along up: any right will do
            right = np.cross(forward, [0.0, 1.0, 0.0] if abs(forward[1]) < 0.9 else [1.0, 0, 0])
        right /= np.linalg.norm(right)
        down = np.cross(forward, right)
        r = np.column_stack([right, down, forward])
        return cls(position=p, wxyz=wxyz_from_rotation(r), fov_rad=fov_rad, aspect=aspect,
                   height_px=height_px)

    @property
    def rotation(self) -> np.ndarray:
        """(3, 3) camera-to-world rotation; columns: right, down, forward."""
        return rotation_from_wxyz(self.wxyz)

    @property
    def focal_px(self) -> float:
        """Focal length in pixels, ``(H / 2) / tan(fov / 2)``."""
        return 0.5 * self.height_px / math.tan(0.5 * self.fov_rad)

    @property
    def width_px(self) -> float:
        """Window width, pixels."""
        return self.aspect * self.height_px

    @property
    def half_tangents(self) -> tuple[float, float]:
        """``tan`` of half the horizontal and half the vertical field of view."""
        ty = math.tan(0.5 * self.fov_rad)
        return self.aspect * ty, ty

    def to_camera(self, xyz: np.ndarray) -> np.ndarray:
        """(n, 3) camera coordinates ``R^T (p - position)`` of (n, 3) points, metres."""
        return (np.asarray(xyz, dtype=np.float64) - self.position) @ self.rotation

    def project(self, xyz: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pixel column ``u``, row ``v`` (from the top left) and depth (metres along
        the viewing direction) of (n, 3) points; ``u, v`` are NaN behind the camera."""
        c = self.to_camera(xyz)
        f = self.focal_px
        with np.errstate(divide="ignore", invalid="ignore"):
            front = c[:, 2] > 0
            u = np.where(front, f * c[:, 0] / c[:, 2] + 0.5 * self.width_px, np.nan)
            v = np.where(front, f * c[:, 1] / c[:, 2] + 0.5 * self.height_px, np.nan)
        return u, v, c[:, 2]


def in_view(camera: ViewCamera, xyz: np.ndarray) -> np.ndarray:
    """(n,) bool: which points are in front of the camera and inside its window."""
    u, v, _ = camera.project(xyz)
    with np.errstate(invalid="ignore"):
        return (u >= 0) & (u <= camera.width_px) & (v >= 0) & (v <= camera.height_px)


def screen_rect_mask(camera: ViewCamera, xyz: np.ndarray, corner_a: tuple[float, float],
                     corner_b: tuple[float, float]) -> np.ndarray:
    """(n,) bool: points in front of the camera whose projection falls in a screen
    rectangle (viser's rectangle selection: two corners in normalised window
    coordinates, ``(0, 0)`` top left, ``(1, 1)`` bottom right)."""
    u, v, _ = camera.project(xyz)
    (ua, va), (ub, vb) = corner_a, corner_b
    u0, u1 = sorted((ua * camera.width_px, ub * camera.width_px))
    v0, v1 = sorted((va * camera.height_px, vb * camera.height_px))
    with np.errstate(invalid="ignore"):
        return (u >= u0) & (u <= u1) & (v >= v0) & (v <= v1)


#: Points projected at a time by :func:`rect_select` (bounds its temporaries).
RECT_CHUNK = 1 << 20


def rect_select(camera: ViewCamera, x: np.ndarray, y: np.ndarray, z: np.ndarray,
                corner_a: tuple[float, float], corner_b: tuple[float, float], *,
                chunk: int = RECT_CHUNK) -> np.ndarray:
    """(n,) bool: the points of columns ``x, y, z`` (the camera's frame, metres) in
    front of the camera whose projection falls in a screen rectangle (through the
    whole depth, as CloudCompare's segment tool selects), projected ``chunk`` points
    at a time (about 100 bytes per point of a chunk, besides the result's byte per
    point).

    >>> cam = ViewCamera.looking_at((0.0, -5.0, 0.0), (0.0, 0.0, 0.0))
    >>> x = np.array([0.0, 0.0, 3.0, 0.0]); y = np.array([0.0, 4.0, 0.0, -9.0])
    >>> rect_select(cam, x, y, np.zeros(4), (0.4, 0.4), (0.6, 0.6)).tolist()  # behind: no
    [True, True, False, False]
    """
    for a, name in ((corner_a, "first"), (corner_b, "second")):
        if len(a) != 2 or not all(math.isfinite(float(v)) for v in a):
            raise InputError(f"the {name} corner of a selection needs two finite numbers")
    n = int(x.shape[0])
    out = np.zeros(n, dtype=bool)
    step = max(1, int(chunk))
    for lo in range(0, n, step):
        hi = min(n, lo + step)
        xyz = np.column_stack([x[lo:hi], y[lo:hi], z[lo:hi]]).astype(np.float64, copy=False)
        out[lo:hi] = screen_rect_mask(camera, xyz, corner_a, corner_b)
    return out


def camera_moved(before: ViewCamera, after: ViewCamera, *, distance_m: float,
                 tolerance_px: float = 2.0) -> bool:
    """Whether a new camera differs enough from the last one to select again.

    The camera moved enough when the scene would shift on screen by more than
    ``tolerance_px`` pixels: a translation ``t`` shifts what lies at ``distance_m``
    by up to ``f |t| / distance_m`` pixels, a turn by angle ``a`` by about ``f a``, a
    zoom by ``(H / 2) |f' / f - 1|``; another window size always counts.

    Parameters
    ----------
    before, after : ViewCamera
    distance_m : float
        Distance to the nearest thing shown (:attr:`rough_viewer.lod.select.Selection.nearest_m`).
    tolerance_px : float
        Largest shift ignored, pixels.
    """
    if before.height_px != after.height_px or not math.isclose(before.aspect, after.aspect,
                                                               rel_tol=1e-6):
        return True
    f = before.focal_px
    shift = f * float(np.linalg.norm(after.position - before.position)) / max(distance_m, 1e-12)
    relative = before.rotation.T @ after.rotation
    angle = math.acos(max(-1.0, min(1.0, 0.5 * (float(np.trace(relative)) - 1.0))))
    zoom = 0.5 * before.height_px * abs(after.focal_px / f - 1.0)
    return max(shift, f * angle, zoom) > tolerance_px
