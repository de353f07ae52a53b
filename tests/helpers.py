"""Synthetic clouds shared by the tests (made here: the suite never reads ../shared).

A normal module: test files import what they need from ``tests.helpers``.
"""

from __future__ import annotations

import math

import numpy as np

from rough_viewer.io import PointCloud
from rough_viewer.vocabulary import PAPER_GRIDS

#: Range noise of the synthetic board and wire scans, metres (the bias paper's 1.6 mm).
NOISE = 0.0016


def rough_surface(n: int, seed: int = 0, *, size: float = 4.0, noise: float = 0.003) -> np.ndarray:
    """(n, 3) points of a wavy, noisy surface z = f(x, y), metres."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0.0, size, (n, 2))
    z = (
        0.05 * np.sin(3.1 * xy[:, 0]) * np.cos(2.3 * xy[:, 1])
        + 0.02 * np.sin(11.0 * xy[:, 0] + 1.0)
        + rng.normal(0.0, noise, n)
    )
    return np.column_stack([xy, z])


def random_rotation(seed: int) -> np.ndarray:
    """A random proper rotation matrix (3x3)."""
    rng = np.random.default_rng(seed)
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] *= -1
    return q



UTM = np.array([512_000.0, 4_170_000.0, 100.0])


def face_cloud(n: int = 40_000, *, seed: int = 0) -> PointCloud:
    """A vertical face 4 m x 2 m facing -y at UTM-like coordinates, gently waved,
    whose noise grows from 0.5 mm at the left edge to 10.5 mm at the right."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.0, 4.0, n)
    z = rng.uniform(0.0, 2.0, n)
    sigma = 0.0005 + 0.0025 * x
    y = 0.02 * np.sin(1.5 * x) + sigma * rng.standard_normal(n)
    return PointCloud.from_xyz(np.column_stack([x, y, z]) + UTM, source="synthetic-face")


def board_rotation(seed: int) -> np.ndarray:
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def board_points(*, n: int, noise: float, sag: float, seed: int, grid: bool = False,
           long_m: float = 1.244, short_m: float = 0.609) -> tuple[np.ndarray, np.ndarray]:
    """A board scanned at ~10 m: in its own frame u (long), v (short), w (normal),
    bowed by ``w = k u^2`` with ``sag`` at the ends, rotated into a random pose.

    Returns the points and the scanner position (the origin)."""
    rng = np.random.default_rng(seed)
    if grid:
        m = int(round(math.sqrt(n * long_m / short_m)))
        u, v = np.meshgrid((np.arange(m) + 0.5) / m - 0.5,
                           (np.arange(n // m) + 0.5) / (n // m) - 0.5)
        u = u.ravel() * long_m
        v = v.ravel() * short_m
    else:
        u = rng.uniform(-long_m / 2, long_m / 2, n)
        v = rng.uniform(-short_m / 2, short_m / 2, n)
    k = sag / (long_m / 2) ** 2
    w = k * u**2 + rng.normal(0.0, noise, u.size)
    rot = board_rotation(seed)
    local = np.column_stack((u, v, w))
    centre = np.array([3.0, 9.0, 1.0])
    # Board normal (third column of rot) faces the scanner at the origin.
    if np.dot(rot[:, 2], -centre) < 0:
        rot[:, 2] *= -1
        rot[:, 0] *= -1
    return local @ rot.T + centre, np.zeros(3)


def wire_points(*, er: float, wire_r: float, range_m: float, n: int, seed: int) -> np.ndarray:
    """Scan of a taut wire at 45 degrees across the view: every beam whose footprint
    (radius ``er``) touches the wire (radius ``wire_r``) returns the wire's range."""
    rng = np.random.default_rng(seed)
    view = np.array([0.3, 0.9, 0.2])
    view /= np.linalg.norm(view)
    centre = range_m * view
    a = np.cross(view, [0.0, 0.0, 1.0])
    a /= np.linalg.norm(a)
    b = np.cross(view, a)
    direction = (a + b) / math.sqrt(2.0)
    across = np.cross(direction, view)
    t = rng.uniform(-0.4, 0.4, n)
    s = rng.uniform(-(er + wire_r), er + wire_r, n)
    target = centre + t[:, None] * direction + s[:, None] * across
    rng_to_wire = np.linalg.norm(centre + t[:, None] * direction, axis=1)
    rays = target / np.linalg.norm(target, axis=1)[:, None]
    return rays * (rng_to_wire + rng.normal(0.0, NOISE, n))[:, None]


def face_axes(dip_deg: float, dip_direction_deg: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit vectors of a plane of given dip and dip direction (z up, azimuth clockwise
    from +y): strike (azimuth dip direction - 90), down-dip, and the upward normal."""
    d, a = math.radians(dip_deg), math.radians(dip_direction_deg)
    strike = np.array([-math.cos(a), math.sin(a), 0.0])
    down = np.array([math.cos(d) * math.sin(a), math.cos(d) * math.cos(a), -math.sin(d)])
    normal = np.array([math.sin(d) * math.sin(a), math.sin(d) * math.cos(a), math.cos(d)])
    return strike, down, normal


def banded_face(
    dip_deg: float,
    dip_direction_deg: float,
    bands: list[tuple[float, float, float, float, float]],
    *,
    size: tuple[float, float] = (8.0, 6.0),
    n: int = 150_000,
    smooth: float = 0.001,
    rough: float = 0.03,
    seed: int = 0,
    offset: np.ndarray = UTM,
) -> tuple[np.ndarray, np.ndarray]:
    """A planar face of known orientation with planted rough bands, metres.

    Points are uniform over a ``size`` (along strike, down dip) rectangle and
    displaced along the normal by Gaussian noise of ``smooth``; inside a band by
    ``rough``. Each band is ``(s, t, length, width, angle_deg)``: centre at ``s``
    along strike and ``t`` down dip from the face's centre, its long axis turned
    ``angle_deg`` from the strike towards the down-dip direction.

    Returns the (n, 3) points (shifted by ``offset``) and the (n,) band index of
    every point (-1 outside every band).
    """
    rng = np.random.default_rng(seed)
    strike, down, normal = face_axes(dip_deg, dip_direction_deg)
    s = rng.uniform(-size[0] / 2, size[0] / 2, n)
    t = rng.uniform(-size[1] / 2, size[1] / 2, n)
    band = np.full(n, -1)
    for k, (bs, bt, length, width, angle) in enumerate(bands):
        ang = math.radians(angle)
        along = (s - bs) * math.cos(ang) + (t - bt) * math.sin(ang)
        across = -(s - bs) * math.sin(ang) + (t - bt) * math.cos(ang)
        band[(np.abs(along) <= length / 2) & (np.abs(across) <= width / 2)] = k
    h = rng.standard_normal(n) * np.where(band >= 0, rough, smooth)
    pts = s[:, None] * strike + t[:, None] * down + h[:, None] * normal
    return pts + offset, band


def write_las_with_colours(path, cloud: PointCloud, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """A LAS (point format 3) of ``cloud`` with 16-bit RGB (8-bit values times 257, as
    most writers scale) and intensity; red grows with x, green and blue are random.
    Returns the 8-bit colours and the intensity."""
    import laspy

    rng = np.random.default_rng(seed)
    rgb8 = rng.integers(0, 256, (cloud.n, 3)).astype(np.uint16)
    rgb8[:, 0] = np.clip(np.round(255 * (cloud.x - cloud.x.min()) / np.ptp(cloud.x)), 0, 255)
    intensity = rng.integers(100, 4000, cloud.n).astype(np.uint16)
    hdr = laspy.LasHeader(point_format=3, version="1.2")
    hdr.scales = np.array([1e-4] * 3)
    hdr.offsets = np.floor(cloud.xyz().min(axis=0))
    las = laspy.LasData(hdr)
    las.x, las.y, las.z = cloud.xyz().T
    las.red, las.green, las.blue = (rgb8 * 257).T
    las.intensity = intensity
    las.write(str(path))
    return rgb8.astype(np.uint8), intensity


#: The 2011 paper's grid sizes, metres: tests about other things than the grid pass
#: them as the app's presets (``build_app(..., presets=PAPER_PRESETS)``) instead of the
#: presets the app derives from each cloud's point spacing.
PAPER_PRESETS = PAPER_GRIDS


def repeated_points_cloud(seed: int = 8) -> np.ndarray:
    """(N, 3) points, metres: three 1 m cells (x 0..3) of 6 points holding only 3
    distinct ones (as clouds that repeat points have; they fit their plane exactly)
    beside three rough cells (x 3..6), all in one layer of 1 m cells from (0, 0, 0)."""
    rng = np.random.default_rng(seed)
    # the cloud's minimum is (0, 0, 0), so the default origin is the grid's too
    tri = np.array([[0.0, 0.0, 0.0], [0.6, 0.1, 0.05], [0.2, 0.7, 0.02]])
    blocks = [np.vstack([tri, tri]) + [i, 0, 0] for i in range(3)]
    rough = np.column_stack([rng.uniform(3, 6, 600), rng.uniform(0, 1, 600),
                             0.5 + 0.02 * rng.standard_normal(600)])
    return np.vstack([*blocks, rough])


def ray_grid(scanner: np.ndarray, centre: np.ndarray, half_angle: float, step: float = 1e-3):
    """Unit ray directions on a levelled scanner's azimuth-elevation grid around the
    direction to ``centre`` (azimuth from +y towards +x, elevation from horizontal)."""
    d = centre - scanner
    phi0 = np.arctan2(d[0], d[1])
    th0 = np.arctan2(d[2], np.hypot(d[0], d[1]))
    k = np.arange(-int(half_angle / step), int(half_angle / step) + 1) * step
    phi, th = np.meshgrid(phi0 + k, th0 + k, indexing="ij")
    phi, th = phi.ravel(), th.ravel()
    return np.column_stack([np.cos(th) * np.sin(phi), np.cos(th) * np.cos(phi), np.sin(th)])


def scan_plane(scanner, point, normal, rays, *, extent, noise=0.0, seed=0):
    """Points where the rays meet the plane (``point``, ``normal``) within ``extent``
    of ``point``, with Gaussian range noise along each ray."""
    t = ((point - scanner) @ normal) / (rays @ normal)
    hit = scanner + t[:, None] * rays
    keep = (t > 0) & (np.abs(hit - point).max(axis=1) < extent)
    t = t[keep] + np.random.default_rng(seed).normal(0.0, noise, int(keep.sum()))
    return scanner + t[:, None] * rays[keep]


def axis_angle(a: np.ndarray, b: np.ndarray) -> float:
    """Degrees between two axes (either sense)."""
    c = abs(float(np.dot(a, b))) / (np.linalg.norm(a) * np.linalg.norm(b))
    return math.degrees(math.acos(min(1.0, c)))
