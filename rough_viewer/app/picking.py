"""Match a click ray from the browser to the displayed point it hit (pure numpy)."""

from __future__ import annotations

import numpy as np

from rough_viewer.io import PointCloud


def ray_distances(
    points: np.ndarray, origin: np.ndarray, direction: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Distance of each point from a ray, and its position along the ray.

    Parameters
    ----------
    points
        ``(N, 3)`` positions (any float dtype), same frame as the ray.
    origin, direction
        Ray start (the camera) and direction (need not be unit length).

    Returns
    -------
    perp, along
        ``(N,)`` perpendicular distance to the ray's line and signed distance
        along the unit direction (negative: behind the camera), both float64.
    """
    o = np.asarray(origin, dtype=np.float64)
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    v = np.asarray(points, dtype=np.float64) - o
    along = v @ d
    perp2 = np.einsum("ij,ij->i", v, v) - along * along
    return np.sqrt(np.maximum(perp2, 0.0)), along


def pick_point(
    points: np.ndarray,
    origin: np.ndarray,
    direction: np.ndarray,
    *,
    tolerance_rad: float = 0.004,
) -> int | None:
    """Index of the point a click ray hit, or None if the ray misses the cloud.

    The ray hits the points whose angular distance from it (perpendicular
    distance / distance along the ray) is within ``tolerance_rad`` of the
    smallest one; of those, the ones nearest the camera (within a depth slack
    of ``10 * tolerance_rad`` times their distance) form the visible surface, and
    the one closest to the ray among them is returned. So a click picks the
    visible surface, not a point behind it.

    Parameters
    ----------
    points
        ``(N, 3)`` displayed point positions, same frame as the ray.
    origin, direction
        Click ray (viser's ``ray_origin``, ``ray_direction``).
    tolerance_rad
        Angular slack in radians (0.004 rad is about 3 pixels at a 50 degree
        field of view on an 800 pixel high view).
    """
    if len(points) == 0:
        return None
    perp, along = ray_distances(points, origin, direction)
    front = along > 0
    if not front.any():
        return None
    angle = np.full(len(points), np.inf)
    angle[front] = perp[front] / along[front]
    best = float(angle.min())
    if best > 10 * tolerance_rad:
        return None
    near = np.flatnonzero(angle <= best + tolerance_rad)
    depth = float(along[near].min())
    front_layer = near[along[near] <= depth * (1.0 + 10.0 * tolerance_rad)]
    return int(front_layer[np.argmin(angle[front_layer])])


#: Points a pick looks at per chunk (the temporaries of one chunk: about 80 bytes a point).
PICK_CHUNK = 1 << 20


def pick_cloud_point(
    cloud: PointCloud,
    origin: np.ndarray,
    direction: np.ndarray,
    *,
    tolerance_rad: float = 0.004,
) -> int | None:
    """:func:`pick_point` on every point of ``cloud`` (its frame, metres), in chunks
    of :data:`PICK_CHUNK` points: a click picks at full resolution, whatever a browser
    tab shows. Returns an index into the cloud, or None."""
    n = cloud.n
    keep_i, keep_p = [], []
    o = np.asarray(origin, dtype=np.float64)
    for start in range(0, n, PICK_CHUNK):
        stop = min(n, start + PICK_CHUNK)
        pts = np.column_stack([cloud.x[start:stop], cloud.y[start:stop], cloud.z[start:stop]])
        perp, along = ray_distances(pts, o, direction)
        front = along > 0
        with np.errstate(divide="ignore", invalid="ignore"):
            close = front & (perp <= 10 * tolerance_rad * along + 1e-300)
        idx = np.flatnonzero(close)
        keep_i.append(idx + start)
        keep_p.append(pts[idx])
    if not keep_i:
        return None
    rows = np.concatenate(keep_i)
    if rows.size == 0:
        return None
    hit = pick_point(np.concatenate(keep_p), o, direction, tolerance_rad=tolerance_rad)
    return None if hit is None else int(rows[hit])
