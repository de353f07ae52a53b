"""The 2012 paper's experiment: a 1 m board with 132 hemispheres, scanned by ray casting.

Pollyea and Fairley (2012) built a 1 m x 1 m board, put hemispherical roughness
elements (table-tennis balls, radius 0.019 m) on 132 randomly chosen nodes of a
0.05 m grid, and scanned it from 4.5 m at 2 mm spacing for 25 dual-axis rotations.
This module rebuilds that experiment in software:

- :func:`hemisphere_board` places the hemispheres (fixed seed);
- :func:`board_theoretical_roughness` gives the board's roughness in closed form
  (the paper found 3.60756e-3 m by Monte Carlo; the closed form gives the same);
- :func:`board_scan` "scans" the board rotated by (alpha, beta): one ray per cell of
  a regular angular grid, each intersected analytically with the board plane and
  the spheres, nearest hit wins. Point counts therefore fall as
  ``cos(alpha) cos(beta)`` and hemispheres shadow the board behind them, as in a
  real scan.

Frame: the scanner sits at ``(0, 0, 1.75)`` looking along +y; the board centre is at
``(0, range_m, 1.75)``. At (0, 0) the board is parallel to the xz plane, facing the
scanner, so the dependent axis of the paper's OLS and hybrid models is ``y``.
``alpha`` turns the board about the vertical (z) axis, ``beta`` about the board's
own horizontal axis (the pipe it was mounted on).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from rough_viewer.io.cloud import PointCloud
from rough_viewer.synthetic._scan import directions, ray_grid
from rough_viewer.vocabulary import InputError

#: Height of the scanner mirror and of the board centre above the ground (m), as in the paper.
MOUNT_HEIGHT_M = 1.75

#: The paper's published theoretical roughness of its board (m).
PAPER_THEORETICAL_ROUGHNESS_M = 3.60756e-3

#: The 25 rotations of the paper (degrees), for alpha and for beta.
PAPER_ROTATIONS_DEG = (0.0, 11.25, 22.5, 33.75, 45.0)


@dataclass(frozen=True)
class HemisphereBoard:
    """A square board with hemispheres standing on some nodes of a square grid.

    Board-local frame: ``u`` horizontal, ``v`` up, ``w`` the board normal (towards the
    scanner); the board face is ``w = 0`` with centre ``u = v = 0``.
    """

    size_m: float
    """Edge of the square board (m)."""
    radius_m: float
    """Hemisphere radius (m)."""
    node_spacing_m: float
    """Spacing of the node grid (m)."""
    node_ij: np.ndarray
    """(K, 2) int grid indices of the occupied nodes (node ``i`` at ``u = -size/2 + i * spacing``)."""
    centres_uv: np.ndarray
    """(K, 2) hemisphere centres in board coordinates (m)."""
    seed: int
    """Seed of the node selection."""

    @property
    def n_spheres(self) -> int:
        """Number of hemispheres."""
        return int(self.node_ij.shape[0])


def hemisphere_board(
    *,
    n_spheres: int = 132,
    radius_m: float = 0.019,
    node_spacing_m: float = 0.05,
    size_m: float = 1.0,
    seed: int = 2012,
) -> HemisphereBoard:
    """Place ``n_spheres`` hemispheres on distinct random interior nodes of the grid.

    Only interior nodes (at least one spacing from every edge) are used, so no
    hemisphere overhangs the board edge and the closed-form roughness is exact.
    The paper's board (132 of the 19 x 19 interior nodes) is the default.
    """
    n_nodes = int(round(size_m / node_spacing_m))
    interior = np.arange(1, n_nodes)
    ii, jj = np.meshgrid(interior, interior, indexing="ij")
    nodes = np.column_stack([ii.ravel(), jj.ravel()])
    if not 0 <= n_spheres <= nodes.shape[0]:
        raise InputError(f"n_spheres must be in 0..{nodes.shape[0]}, got {n_spheres}")
    if 2 * radius_m >= node_spacing_m:
        raise InputError("hemispheres would touch: need 2 * radius_m < node_spacing_m")
    pick = np.random.default_rng(seed).choice(nodes.shape[0], size=n_spheres, replace=False)
    node_ij = nodes[np.sort(pick)]
    centres = -size_m / 2 + node_ij * node_spacing_m
    return HemisphereBoard(
        size_m=float(size_m),
        radius_m=float(radius_m),
        node_spacing_m=float(node_spacing_m),
        node_ij=node_ij.astype(np.int64),
        centres_uv=centres.astype(np.float64),
        seed=int(seed),
    )


def hemisphere_roughness(
    n_spheres: int,
    radius_m: float,
    area_m2: float,
    *,
    residual: Literal["absolute", "signed"] = "absolute",
) -> float:
    """Closed-form roughness (m) of a flat area carrying non-overlapping hemispheres.

    The surface height over a uniformly sampled area is ``z = sqrt(r^2 - d^2)`` on a
    fraction ``f = n pi r^2 / A`` of it and 0 elsewhere. Over one hemisphere's base,
    ``z^2`` is uniform on ``[0, r^2]``, so ``E z = 2r/3`` and ``E z^2 = r^2 / 2``. With
    ``m = f 2r/3`` the mean height,

    - ``E (z - m)^2 = f r^2 / 2 - m^2`` (its square root is the ``signed`` roughness),
    - ``E |z - m| = (1 - f) m + f (2r/3 - m + 2 m^3 / (3 r^2))``,

    and the ``absolute`` roughness (docs/science.md section 1: standard deviation of the
    absolute distances) is ``sqrt(E (z - m)^2 - (E |z - m|)^2)``. For the paper's
    board (132 spheres, r = 0.019 m, 1 m^2) this is 3.6076e-3 m, the published
    Monte Carlo value 3.60756e-3 m.
    """
    r = float(radius_m)
    f = n_spheres * np.pi * r * r / float(area_m2)
    if not 0.0 <= f <= 1.0:
        raise InputError("hemispheres cover more than the area")
    m = f * 2.0 * r / 3.0
    var_signed = f * r * r / 2.0 - m * m
    if residual == "signed":
        return float(np.sqrt(var_signed))
    if residual != "absolute":
        raise InputError(f"residual must be 'absolute' or 'signed', got {residual!r}")
    mean_abs = (1.0 - f) * m + f * (2.0 * r / 3.0 - m + 2.0 * m**3 / (3.0 * r * r))
    return float(np.sqrt(var_signed - mean_abs * mean_abs))


def board_theoretical_roughness(
    board: HemisphereBoard, *, residual: Literal["absolute", "signed"] = "absolute"
) -> float:
    """Closed-form roughness (m) of ``board``: see :func:`hemisphere_roughness`.

    Examples
    --------
    The 2012 paper's board (132 hemispheres of radius 0.019 m on 1 m^2) has a
    published theoretical roughness of 3.60756e-3 m:

    >>> round(board_theoretical_roughness(hemisphere_board()) * 1e3, 4)  # mm
    3.6076
    """
    return hemisphere_roughness(
        board.n_spheres, board.radius_m, board.size_m**2, residual=residual
    )


def board_rotation(alpha_deg: float, beta_deg: float) -> np.ndarray:
    """Columns: the board's u, v, w axes in the world frame after the rotation.

    At (0, 0): u = +x, v = +z, w = -y (facing the scanner at the origin). ``beta``
    tilts the board about its own horizontal axis u, then ``alpha`` turns it about
    the vertical axis z.
    """
    a, b = np.radians(alpha_deg), np.radians(beta_deg)
    base = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # columns u, v, w
    rx = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(b), -np.sin(b)], [0.0, np.sin(b), np.cos(b)]])
    rz = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
    # beta about the board's u axis (= world x before alpha), then alpha about world z.
    return rz @ rx @ base


@dataclass(frozen=True)
class BoardScan:
    """One simulated scan of the hemisphere board at one rotation."""

    cloud: PointCloud
    """The scanned points (m), in scan order."""
    on_sphere: np.ndarray
    """(N,) bool: the point lies on a hemisphere (else on the flat board)."""
    alpha_deg: float
    """Rotation about the vertical axis (degrees)."""
    beta_deg: float
    """Rotation about the board's horizontal axis (degrees)."""
    scanner: np.ndarray
    """(3,) scanner position (m)."""
    centre: np.ndarray
    """(3,) board centre (m)."""
    axes: np.ndarray
    """(3, 3) columns u, v, w of the board in the world frame; w is the board normal."""
    n_rays: int
    """Rays of the angular grid that were cast (hits and misses)."""
    theoretical_roughness: float
    """Closed-form roughness of the board (m), the value every model should report."""
    angular_step_rad: float
    """Angular step of the scanner's ray grid (radians): ``spacing / range_m``."""
    board: HemisphereBoard = field(repr=False)
    """The board that was scanned."""

    @property
    def normal(self) -> np.ndarray:
        """(3,) unit board normal, towards the scanner."""
        return self.axes[:, 2].copy()


def board_scan(
    alpha_deg: float,
    beta_deg: float,
    *,
    spacing: float = 0.002,
    range_m: float = 4.5,
    noise: float = 0.0,
    seed: int = 0,
    board: HemisphereBoard | None = None,
) -> BoardScan:
    """Scan the hemisphere board rotated by (``alpha_deg``, ``beta_deg``).

    Parameters
    ----------
    alpha_deg, beta_deg : rotation about the vertical and the board's horizontal axis (degrees).
    spacing : point spacing (m) at ``range_m`` straight ahead; the angular step of the
        scanner is ``spacing / range_m`` radians (paper: 2 mm at 4.5 m).
    range_m : distance from the scanner to the board centre (m).
    noise : standard deviation of Gaussian range noise (m) added along each ray.
    seed : seed of the range noise.
    board : the board; default the paper's (:func:`hemisphere_board`).

    Results are cached in memory per argument set (the board arrays are read-only).
    """
    b = board if board is not None else _default_board()
    return _board_scan_cached(
        float(alpha_deg), float(beta_deg), float(spacing), float(range_m), float(noise),
        int(seed), _BoardKey(b),
    )


class _BoardKey:
    """Hashable wrapper so a board can key the cache (by identity of its content)."""

    def __init__(self, board: HemisphereBoard) -> None:
        self.board = board
        self._key = (
            board.size_m, board.radius_m, board.node_spacing_m, board.node_ij.tobytes()
        )

    def __hash__(self) -> int:
        return hash(self._key)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, _BoardKey) and self._key == other._key


@functools.lru_cache(maxsize=1)
def _default_board() -> HemisphereBoard:
    return hemisphere_board()


@dataclass(frozen=True)
class _Pose:
    """Where the board and the scanner stand (world frame, metres)."""

    scanner: np.ndarray
    centre: np.ndarray
    axes: np.ndarray
    """(3, 3) board axes u, v, w as columns."""


def _ray_window(board: HemisphereBoard, pose: _Pose, step: float) -> np.ndarray:
    """(R, 3) unit ray directions on a regular angular grid of ``step`` radians over
    the board's corners, raised by r towards the scanner, plus a margin."""
    eu, ev, ew = pose.axes[:, 0], pose.axes[:, 1], pose.axes[:, 2]
    half, r = board.size_m / 2, board.radius_m
    corners = np.array(
        [pose.centre + su * half * eu + sv * half * ev + sw * r * ew
         for su in (-1, 1) for sv in (-1, 1) for sw in (0, 1)]
    )
    rel = corners - pose.scanner
    phi_c = np.arctan2(rel[:, 0], rel[:, 1])
    theta_c = np.arctan2(rel[:, 2], np.hypot(rel[:, 0], rel[:, 1]))
    phi, theta = ray_grid(
        (phi_c.min() - 2 * step, phi_c.max() + 2 * step),
        (theta_c.min() - 2 * step, theta_c.max() + 2 * step),
        step,
    )
    return directions(phi, theta)


def _hit_hemispheres(
    board: HemisphereBoard, pose: _Pose, d: np.ndarray, t_best: np.ndarray,
    sphere_id: np.ndarray, u: np.ndarray, v: np.ndarray,
) -> None:
    """Lower ``t_best`` (in place) where a ray meets a hemisphere first, and record
    which one in ``sphere_id``.

    A ray can only meet hemispheres near the stretch of it between w = r and w = 0;
    the nodes around that stretch's midpoint are tested one node offset at a time.
    """
    eu, ev, ew = pose.axes[:, 0], pose.axes[:, 1], pose.axes[:, 2]
    half, r, g = board.size_m / 2, board.radius_m, board.node_spacing_m
    du, dv, dw = d @ eu, d @ ev, d @ ew
    back = r / (2.0 * -dw)
    mu, mv = u - back * du, v - back * dv
    half_seg = np.max(back * np.hypot(du, dv))
    reach = int(np.ceil((r + half_seg) / g + 0.5))
    n_nodes = int(round(board.size_m / g))
    occupied = np.full((n_nodes + 1, n_nodes + 1), -1, dtype=np.int64)
    occupied[board.node_ij[:, 0], board.node_ij[:, 1]] = np.arange(board.n_spheres)
    i0 = np.rint((mu + half) / g).astype(np.int64)
    j0 = np.rint((mv + half) / g).astype(np.int64)
    centres_world = (
        pose.centre + board.centres_uv[:, :1] * eu + board.centres_uv[:, 1:] * ev
    )
    for di in range(-reach, reach + 1):
        for dj in range(-reach, reach + 1):
            ii, jj = i0 + di, j0 + dj
            inside = (ii >= 0) & (ii <= n_nodes) & (jj >= 0) & (jj <= n_nodes)
            cand = np.flatnonzero(inside)
            sid = occupied[ii[cand], jj[cand]]
            cand, sid = cand[sid >= 0], sid[sid >= 0]
            if cand.size == 0:
                continue
            oc = pose.scanner - centres_world[sid]
            dc = d[cand]
            bq = np.einsum("ij,ij->i", dc, oc)
            cq = np.einsum("ij,ij->i", oc, oc) - r * r
            disc = bq * bq - cq
            ok = disc >= 0
            t = -bq - np.sqrt(np.where(ok, disc, 0.0))
            w_hit = (pose.scanner + t[:, None] * dc - pose.centre) @ ew
            ok &= w_hit >= 0.0
            better = ok & (t < t_best[cand])
            t_best[cand[better]] = t[better]
            sphere_id[cand[better]] = sid[better]


@functools.lru_cache(maxsize=32)
def _board_scan_cached(
    alpha_deg: float,
    beta_deg: float,
    spacing: float,
    range_m: float,
    noise: float,
    seed: int,
    key: _BoardKey,
) -> BoardScan:
    board = key.board
    if spacing <= 0 or range_m <= 0 or noise < 0:
        raise InputError("spacing and range_m must be > 0 and noise >= 0")
    scanner = np.array([0.0, 0.0, MOUNT_HEIGHT_M])
    centre = np.array([0.0, range_m, MOUNT_HEIGHT_M])
    axes = board_rotation(alpha_deg, beta_deg)
    pose = _Pose(scanner=scanner, centre=centre, axes=axes)
    d = _ray_window(board, pose, spacing / range_m)

    # Board plane w = 0: every ray of the window meets it in front of the scanner.
    eu, ev, ew = axes[:, 0], axes[:, 1], axes[:, 2]
    half = board.size_m / 2
    t_plane = ((centre - scanner) @ ew) / (d @ ew)
    hit = scanner + t_plane[:, None] * d - centre
    u = hit @ eu
    v = hit @ ev
    t_best = np.where((np.abs(u) <= half) & (np.abs(v) <= half), t_plane, np.inf)
    sphere_id = np.full(d.shape[0], -1, dtype=np.int64)
    _hit_hemispheres(board, pose, d, t_best, sphere_id, u, v)

    seen = np.isfinite(t_best)
    t_seen = t_best[seen]
    if noise > 0:
        t_seen = t_seen + np.random.default_rng(seed).normal(0.0, noise, t_seen.shape[0])
    xyz = scanner + t_seen[:, None] * d[seen]
    on_sphere = sphere_id[seen] >= 0
    # one scan from a known position: the per-cell scanner geometry needs no option
    cloud = PointCloud.from_xyz(xyz, source="", scan_index=np.zeros(xyz.shape[0], np.int32),
                                scanner_positions=scanner[None, :])
    for arr in (on_sphere, axes, scanner, centre):
        arr.setflags(write=False)
    return BoardScan(
        cloud=cloud,
        on_sphere=on_sphere,
        alpha_deg=alpha_deg,
        beta_deg=beta_deg,
        scanner=scanner,
        centre=centre,
        axes=axes,
        n_rays=int(d.shape[0]),
        theoretical_roughness=board_theoretical_roughness(board),
        angular_step_rad=spacing / range_m,
        board=board,
    )
