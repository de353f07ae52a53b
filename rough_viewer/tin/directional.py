"""Directional roughness of a triangulated surface: Grasselli's ``theta*max/(C+1)``
and ``Delta-T``, for the whole surface and as a map of circular windows.

Definitions (the sources are in ``docs/directions.md``, "Definitions"):

- Reference plane and axes: the ODR plane of the surface's vertices (for the whole
  surface: :func:`rough_viewer.grid.planes.whole_cloud_plane`; for a window: the
  ODR plane of that window's vertices), seen from the side its normal ``n`` points
  to, with the in-plane axes ``u``, ``v`` of :func:`rough_viewer.grid.maps.face_frame`
  (a window uses ``u`` projected into its own plane, and ``v = n_w x u_w``).
- Azimuth ``alpha`` (degrees, 0-360): the analysis (shear) direction
  ``t = cos(alpha) u + sin(alpha) v`` in the plane, counter-clockwise from ``u``
  towards ``v``.
- Apparent dip of a triangle of unit normal ``m`` (turned to ``n``'s side) in
  direction ``t``: the slope angle of its plane along ``t``,
  ``theta* = atan2(-(m . t), m . n)`` in degrees, in (-90, 90); positive when the
  facet rises along ``t``, i.e. faces the shear and resists it (Grasselli 2001).
- ``A*(theta*)``: the area of the triangles whose apparent dip is at least
  ``theta*``, as a share of the whole (window's) area; ``A0 = A*(0)``; ``theta*max``
  the largest apparent dip. Grasselli's law ``A*(theta*) = A0 ((theta*max -
  theta*) / theta*max)^C`` is fitted by least squares on ``A*/A0`` at the
  thresholds ``theta* = k * dip_step`` (k = 1, 2, ... below ``theta*max``; default
  step 1 degree), with ``C >= 0``; ``theta*max / (C + 1)`` (degrees) is the
  roughness parameter of Tatone and Grasselli (2009): the area under the fitted
  curve ``A*/A0`` against ``theta*``. NaN where no facet faces the direction or no
  threshold lies below ``theta*max`` (a surface smoother than one step); 0 where
  the facing facets are parallel to the direction (apparent dips within
  :data:`FLAT_DEG` of 0 are round-off and count as 0).
- ``Delta-T`` (Babanouri and Karami Nasab 2017): the area-weighted mean apparent
  dip of the triangles facing the direction (``theta* >= 0``), degrees.
- Windows: centres on a square grid of ``step`` in the face plane, from the
  surface's lowest ``u`` and ``v``; a window holds the triangles whose three
  corners lie within ``radius`` of its centre in the face plane, and is kept when
  their projected area covers at least ``min_coverage`` of the disc (default half).
  A window's row gives the area-weighted centroid of its triangles (``cx, cy,
  cz``) and their area.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from rough_viewer.grid.maps import FaceFrame, Plane, face_frame
from rough_viewer.grid.planes import whole_cloud_plane
from rough_viewer.io.formats.mesh import TriangleMesh
from rough_viewer.memory import require
from rough_viewer.tin.surface import Facets, facets
from rough_viewer.vocabulary import InputError, ProgressFn

#: Default step of the apparent-dip thresholds the C fit uses, degrees.
DEFAULT_DIP_STEP_DEG = 1.0
#: Default share of a window's disc its triangles must cover (projected area).
DEFAULT_MIN_COVERAGE = 0.5
#: Candidate values of C of the first, coarse search (then refined by golden section
#: between the neighbours of the best one).
C_GRID = np.concatenate([[0.0], np.geomspace(1e-3, 1e4, 71)])
#: Golden-section steps of the refinement (the bracket shrinks by 0.618 each).
GOLDEN_STEPS = 48
#: Relative round-off allowed at the thresholds: a dip within it below a threshold
#: counts as reaching it, a threshold within it below theta*max as not below it.
ROUND_OFF = 1e-9
#: An apparent dip of at most this size (degrees) is round-off on a facet parallel
#: to the direction: it counts as 0 (facing), and a largest dip of 0 gives
#: ``theta*max/(C+1) = 0`` (C taken as 0).
FLAT_DEG = 1e-6
#: Triangle-window pairs handled at a time by :func:`window_roughness`.
PAIRS_PER_CHUNK = 1_000_000
#: Peak bytes per triangle-window pair (indices, dot products, dips, bins).
PAIR_BYTES = 16 * 8
#: Seconds of work per triangle-window pair and azimuth (apparent dips, sums), and
#: per window, azimuth and dip threshold (the C fit), measured on a 2-core machine:
#: 0.32-1.0 microseconds a pair, 0.52-0.62 ms a window at 91 thresholds.
PAIR_SECONDS = 0.35e-6
WINDOW_THRESHOLD_SECONDS = 6e-6
#: Longest window map :func:`window_roughness` starts, in seconds estimated at the
#: rates above (``--window-step 0.001`` on the demo was days of work).
MAX_WINDOW_MAP_SECONDS = 1800.0


@dataclass(frozen=True)
class DirectionalRoughness:
    """The directional roughness of a whole surface, one value per azimuth."""

    azimuth_deg: np.ndarray
    """(A,) analysis directions, degrees counter-clockwise from the face's ``u`` axis."""
    theta_max_c1: np.ndarray
    """(A,) ``theta*max / (C + 1)``, degrees."""
    delta_t: np.ndarray
    """(A,) ``Delta-T``, degrees."""
    theta_max: np.ndarray
    """(A,) largest apparent dip, degrees."""
    c: np.ndarray
    """(A,) fitted exponent C (dimensionless)."""
    a0: np.ndarray
    """(A,) share of the area facing the direction (apparent dip >= 0)."""
    facing: np.ndarray
    """(A,) number of triangles facing the direction."""
    n_triangles: int
    """Triangles measured (zero-area ones left out)."""
    area: float
    """Their total area, square metres."""
    frame: FaceFrame
    """Reference plane and axes."""
    dip_step_deg: float


@dataclass(frozen=True)
class WindowRoughness:
    """Directional roughness in circular windows: one row per window."""

    azimuth_deg: np.ndarray
    """(A,) analysis directions, degrees."""
    centre: np.ndarray
    """(W, 3) area-weighted centroid of each window's triangles, metres, file frame."""
    centre_uv: np.ndarray
    """(W, 2) the window's grid centre in the face plane (``u``, ``v``), metres."""
    area: np.ndarray
    """(W,) area of the window's triangles, square metres."""
    n_triangles: np.ndarray
    """(W,) triangles in each window."""
    normal: np.ndarray
    """(W, 3) unit normal of each window's ODR plane."""
    theta_max_c1: np.ndarray
    """(W, A) degrees."""
    delta_t: np.ndarray
    """(W, A) degrees."""
    theta_max: np.ndarray
    """(W, A) degrees."""
    c: np.ndarray
    """(W, A)."""
    a0: np.ndarray
    """(W, A)."""
    radius: float
    """Window radius, metres."""
    step: float
    """Spacing of the window centres, metres."""
    min_coverage: float
    frame: FaceFrame
    """The face plane the windows are laid out in."""
    dip_step_deg: float
    candidates: int = 0
    """Window centres tried (kept or not)."""

    @property
    def n_windows(self) -> int:
        """Windows kept."""
        return int(self.centre.shape[0])

    def table(self, per: float = 1.0) -> dict[str, np.ndarray]:
        """The ``--windows-out`` columns, one row per window and azimuth (window-major):
        ``cx, cy, cz`` and ``area`` in units of ``per`` metres (and its square),
        ``azimuth_deg, delta_t, theta_max_c1`` in degrees."""
        a = self.azimuth_deg.size
        return {
            "cx": np.repeat(self.centre[:, 0] / per, a),
            "cy": np.repeat(self.centre[:, 1] / per, a),
            "cz": np.repeat(self.centre[:, 2] / per, a),
            "area": np.repeat(self.area / per**2, a),
            "azimuth_deg": np.tile(self.azimuth_deg, self.n_windows),
            "delta_t": self.delta_t.ravel(),
            "theta_max_c1": self.theta_max_c1.ravel(),
        }


# ----------------------------------------------------------------------------- helpers


#: Finest azimuth step, degrees (360 directions, the app's least step): finer ones
#: asked for work without bound (``--step 1e-300`` tried to allocate 3.6e302 azimuths;
#: ``--step 0.01``, 36,000 directions, ran about an hour).
MIN_AZIMUTH_STEP_DEG = 1.0


def azimuths(step_deg: float) -> np.ndarray:
    """Azimuths ``0, step, 2 step, ...`` below 360 degrees.

    >>> azimuths(90.0)
    array([  0.,  90., 180., 270.])
    """
    step = float(step_deg)
    if not (np.isfinite(step) and MIN_AZIMUTH_STEP_DEG <= step <= 360):
        raise InputError(f"the azimuth step must be from {MIN_AZIMUTH_STEP_DEG:g} to 360 "
                         f"degrees (each direction is a set of profiles), got {step_deg:g}")
    return np.arange(0.0, 360.0 - 1e-9, step)


def _check_azimuths(azimuth_deg: Sequence[float] | np.ndarray) -> np.ndarray:
    az = np.asarray(azimuth_deg, dtype=np.float64).ravel()
    if az.size == 0 or not np.all(np.isfinite(az)):
        raise InputError("give at least one finite azimuth, in degrees")
    return az


def _check_step(dip_step_deg: float) -> float:
    step = float(dip_step_deg)
    if not (np.isfinite(step) and 0 < step <= 45):
        raise InputError(f"the dip step must be in (0, 45] degrees, got {dip_step_deg}")
    return step


def apparent_dips(
    normals: np.ndarray,
    plane_normal: np.ndarray,
    u_axis: np.ndarray,
    v_axis: np.ndarray,
    azimuth_deg: Sequence[float] | np.ndarray,
) -> np.ndarray:
    """Apparent dips (T, A), degrees, of facets of unit ``normals`` (T, 3) in the
    directions ``cos(a) u + sin(a) v`` (module docstring); a normal on the far side
    of ``plane_normal`` is turned first.

    >>> s = np.sin(np.radians(30.0)); c = np.cos(np.radians(30.0))
    >>> up, u, v = np.eye(3)[2], np.eye(3)[0], np.eye(3)[1]
    >>> apparent_dips(np.array([[-s, 0.0, c]]), up, u, v, [0, 90, 180]).round(6) + 0.0
    array([[ 30.,   0., -30.]])
    """
    m = np.asarray(normals, dtype=np.float64)
    az = np.radians(_check_azimuths(azimuth_deg))
    mn = m @ np.asarray(plane_normal, dtype=np.float64)
    sign = np.where(mn < 0, -1.0, 1.0)
    mu = (m @ np.asarray(u_axis, dtype=np.float64)) * sign
    mv = (m @ np.asarray(v_axis, dtype=np.float64)) * sign
    mt = np.cos(az)[None, :] * mu[:, None] + np.sin(az)[None, :] * mv[:, None]
    return np.degrees(np.arctan2(-mt, np.abs(mn)[:, None]))


def _sse(c: np.ndarray, log_x: np.ndarray, y: np.ndarray, valid: np.ndarray) -> np.ndarray:
    r = np.where(valid, np.exp(c[:, None] * log_x) - y, 0.0)
    return np.sum(r * r, axis=1)


def fit_c(x: np.ndarray, y: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Least-squares ``C >= 0`` of ``y = x^C`` for each row of (G, K) arrays, over the
    entries where ``valid`` (``0 < x < 1``); NaN for a row without one.

    A coarse search over :data:`C_GRID` picks the best candidate, then golden-section
    search refines it between its two neighbours (:data:`GOLDEN_STEPS` steps); the
    better of the two is returned, so a perfect fit at ``C = 0`` stays exactly 0.

    >>> x = np.linspace(0.1, 0.9, 9)[None, :]
    >>> float(fit_c(x, x**2.5, np.ones_like(x, bool))[0].round(6))
    2.5
    """
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    valid = np.asarray(valid, dtype=bool) & (x > 0) & (x < 1) & np.isfinite(y)
    g = x.shape[0]
    log_x = np.where(valid, np.log(np.where(valid, x, 0.5)), 0.0)
    y = np.where(valid, y, 0.0)
    grid_sse = np.stack([_sse(np.full(g, cand), log_x, y, valid) for cand in C_GRID], axis=1)
    best = np.argmin(grid_sse, axis=1)
    lo = C_GRID[np.clip(best - 1, 0, C_GRID.size - 1)]
    hi = C_GRID[np.clip(best + 1, 0, C_GRID.size - 1)]
    ratio = (np.sqrt(5.0) - 1.0) / 2.0
    a, b = lo.copy(), hi.copy()
    c1, c2 = b - ratio * (b - a), a + ratio * (b - a)
    f1, f2 = _sse(c1, log_x, y, valid), _sse(c2, log_x, y, valid)
    for _ in range(GOLDEN_STEPS):  # one new evaluation per row and step
        left = f1 < f2  # the minimum lies in [a, c2]: c2 becomes b, c1 becomes c2
        b = np.where(left, c2, b)
        a = np.where(left, a, c1)
        c1, c2 = (np.where(left, b - ratio * (b - a), c2),
                  np.where(left, c1, a + ratio * (b - a)))
        new = _sse(np.where(left, c1, c2), log_x, y, valid)
        f1, f2 = np.where(left, new, f2), np.where(left, f1, new)
    refined = 0.5 * (a + b)
    c = np.where(_sse(refined, log_x, y, valid) <= grid_sse[np.arange(g), best],
                 refined, C_GRID[best])
    return np.where(valid.any(axis=1), c, np.nan)


def _grouped(
    group: np.ndarray,
    n_groups: int,
    normals: np.ndarray,
    areas: np.ndarray,
    plane_normal: np.ndarray,
    u_axis: np.ndarray,
    v_axis: np.ndarray,
    azimuth_deg: np.ndarray,
    dip_step: float,
    progress: ProgressFn | None = None,
) -> dict[str, np.ndarray]:
    """The parameters of every group (the whole surface, or each window) at every
    azimuth. ``group`` (P,) names the group of each facet entry, ``normals`` (P, 3)
    and ``areas`` (P,) its facet; ``plane_normal``, ``u_axis``, ``v_axis`` (G, 3)
    each group's reference frame; ``progress(done, total)`` after each azimuth.
    Returns (G, A) arrays."""
    n_th = int(np.floor(90.0 / dip_step + 1e-9)) + 1  # thresholds 0, step, ... <= 90
    mn = np.einsum("ij,ij->i", normals, plane_normal[group])
    sign = np.where(mn < 0, -1.0, 1.0)
    mu = np.einsum("ij,ij->i", normals, u_axis[group]) * sign
    mv = np.einsum("ij,ij->i", normals, v_axis[group]) * sign
    mn = np.abs(mn)
    total = np.bincount(group, weights=areas, minlength=n_groups)
    shape = (n_groups, azimuth_deg.size)
    out = {k: np.full(shape, np.nan) for k in ("theta_max_c1", "delta_t", "theta_max", "c", "a0")}
    out["facing"] = np.zeros(shape, dtype=np.int64)
    k = np.arange(n_th, dtype=np.float64) * dip_step
    for j, alpha in enumerate(np.radians(azimuth_deg)):
        dip = np.degrees(np.arctan2(-(np.cos(alpha) * mu + np.sin(alpha) * mv), mn))
        dip[np.abs(dip) <= FLAT_DEG] = 0.0  # parallel to t up to round-off: flat, facing
        facing = dip >= 0.0
        gf, df, af = group[facing], dip[facing], areas[facing]
        out["facing"][:, j] = np.bincount(gf, minlength=n_groups)
        a_facing = np.bincount(gf, weights=af, minlength=n_groups)
        with np.errstate(invalid="ignore", divide="ignore"):
            out["delta_t"][:, j] = np.bincount(gf, weights=af * df, minlength=n_groups) / a_facing
        top = np.full(n_groups, -np.inf)
        np.maximum.at(top, gf, df)
        top[~np.isfinite(top)] = np.nan
        out["theta_max"][:, j] = top
        # a dip a round-off short of a threshold reaches it (facets of one slope)
        bins = np.minimum(np.floor(df / dip_step + ROUND_OFF).astype(np.int64), n_th - 1)
        hist = np.bincount(gf * n_th + bins, weights=af, minlength=n_groups * n_th)
        above = np.cumsum(hist.reshape(n_groups, n_th)[:, ::-1], axis=1)[:, ::-1]  # A(>= k step)
        with np.errstate(invalid="ignore", divide="ignore"):
            out["a0"][:, j] = above[:, 0] / total
            y = above / above[:, :1]
            x = 1.0 - k[None, :] / top[:, None]
        valid = (k[None, :] > 0) & (k[None, :] < top[:, None] * (1 - ROUND_OFF)) \
            & (above[:, :1] > 0)
        c = fit_c(np.where(valid, x, 0.5), np.where(valid, y, 0.0), valid)
        c = np.where(top <= FLAT_DEG, 0.0, c)  # facets flat along t: theta*max/(C+1) = 0
        out["c"][:, j] = c
        out["theta_max_c1"][:, j] = top / (c + 1.0)
        if progress is not None:
            progress(j + 1, azimuth_deg.size)
    return out


def _frame(mesh: TriangleMesh, plane: Plane | None) -> FaceFrame:
    """The given plane's frame, else that of the ODR plane of the vertices the
    triangles use (a vertex no triangle uses is no part of the surface)."""
    if plane is not None:
        return face_frame(plane)
    used = np.unique(mesh.faces)
    vertices = mesh.vertices if used.size == mesh.n_vertices else mesh.vertices[used]
    return face_frame(whole_cloud_plane(vertices))


# ----------------------------------------------------------------------------- public


def directional_roughness(
    mesh: TriangleMesh,
    azimuth_deg: Sequence[float] | np.ndarray,
    *,
    dip_step_deg: float = DEFAULT_DIP_STEP_DEG,
    plane: Plane | None = None,
    progress: ProgressFn | None = None,
) -> DirectionalRoughness:
    """``theta*max/(C+1)`` and ``Delta-T`` of a whole surface at each azimuth.

    Parameters
    ----------
    mesh : TriangleMesh
        The surface, metres (a mesh read from a file, or
        :func:`rough_viewer.tin.surface.triangulate_cloud`).
    azimuth_deg : sequence of float
        Analysis directions, degrees from the face's ``u`` axis towards ``v``
        (:func:`azimuths` gives a full circle at a step).
    dip_step_deg : float
        Step of the apparent-dip thresholds of the C fit, degrees (default 1).
    plane : Plane, optional
        Reference plane (default: the ODR plane of the vertices).
    progress : callable, optional
        ``progress(done, total)`` in azimuths (it may raise to stop the work).

    Returns
    -------
    DirectionalRoughness

    Examples
    --------
    A sawtooth of 30-degree facets along x has ``theta*max/(C+1) = Delta-T = 30``
    degrees along and against the teeth, and 0 along the ridges:

    >>> from rough_viewer.io.formats.mesh import TriangleMesh
    >>> x = np.arange(9.0); z = np.tan(np.radians(30.0)) * (x % 2)
    >>> xx, yy = np.meshgrid(x, np.arange(3.0))
    >>> zz = np.broadcast_to(z, xx.shape)
    >>> i = np.arange(xx.size).reshape(xx.shape)
    >>> a, b, c, d = i[:-1, :-1].ravel(), i[:-1, 1:].ravel(), i[1:, :-1].ravel(), i[1:, 1:].ravel()
    >>> mesh = TriangleMesh(np.column_stack([xx.ravel(), yy.ravel(), zz.ravel()]),
    ...                     np.concatenate([np.column_stack([a, b, d]), np.column_stack([a, d, c])]))
    >>> r = directional_roughness(mesh, [0, 90, 180])
    >>> r.theta_max_c1.round(6) + 0.0, r.delta_t.round(6) + 0.0
    (array([30.,  0., 30.]), array([30.,  0., 30.]))
    """
    az = _check_azimuths(azimuth_deg)
    step = _check_step(dip_step_deg)
    frame = _frame(mesh, plane)
    f = facets(mesh, toward=frame.normal)
    if f.areas.size == 0:
        raise InputError("the surface has no triangle of non-zero area")
    n = f.areas.size
    require(n * PAIR_BYTES, f"the apparent dips of {n:,} triangles")
    one = np.zeros(n, dtype=np.int64)
    res = _grouped(one, 1, f.normals, f.areas, frame.normal[None], frame.u_axis[None],
                   frame.v_axis[None], az, step, progress=progress)
    return DirectionalRoughness(
        azimuth_deg=az,
        theta_max_c1=res["theta_max_c1"][0],
        delta_t=res["delta_t"][0],
        theta_max=res["theta_max"][0],
        c=res["c"][0],
        a0=res["a0"][0],
        facing=res["facing"][0],
        n_triangles=n,
        area=float(f.areas.sum()),
        frame=frame,
        dip_step_deg=step,
    )


def facet_roughness(
    normals: np.ndarray,
    areas: np.ndarray,
    group: np.ndarray,
    n_groups: int,
    azimuth_deg: Sequence[float] | np.ndarray,
    *,
    dip_step_deg: float = DEFAULT_DIP_STEP_DEG,
) -> dict[str, np.ndarray]:
    """``theta*max/(C+1)``, ``Delta-T`` (and ``theta_max``, ``c``, ``a0``,
    ``facing``) of groups of facets whose normals are given in their own reference
    frame: the reference plane ``z = 0`` (normal ``+z``), ``u = +x``, ``v = +y``.

    Facets of several surfaces, each turned into its own plane's frame first (the
    joints of a set, :mod:`rough_viewer.structure.set_roughness`), are pooled into one
    distribution of apparent dips per group, exactly as :func:`directional_roughness`
    pools the facets of one surface.

    Parameters
    ----------
    normals : (T, 3) array
        Unit facet normals in the frame above (either sense: turned to ``+z``).
    areas : (T,) array
        Facet areas, square metres (only their ratios matter).
    group : (T,) int array
        Group 0..G-1 of every facet.
    n_groups : int
        ``G``.
    azimuth_deg : sequence of float
        Analysis directions, degrees from ``+x`` towards ``+y``.

    Returns
    -------
    dict of (G, A) arrays
        ``theta_max_c1``, ``delta_t``, ``theta_max`` (degrees), ``c``, ``a0`` and
        ``facing`` (int); NaN for a group without facets facing a direction.

    Examples
    --------
    A sawtooth of 30-degree facets along x, as in :func:`directional_roughness`:

    >>> s, c = np.sin(np.radians(30.0)), np.cos(np.radians(30.0))
    >>> n = np.array([[-s, 0.0, c], [s, 0.0, c]])
    >>> r = facet_roughness(n, np.ones(2), np.zeros(2, dtype=int), 1, [0, 90])
    >>> r["theta_max_c1"].round(6) + 0.0, r["delta_t"].round(6) + 0.0
    (array([[30.,  0.]]), array([[30.,  0.]]))
    """
    az = _check_azimuths(azimuth_deg)
    step = _check_step(dip_step_deg)
    m = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    a = np.asarray(areas, dtype=np.float64).ravel()
    g = np.asarray(group, dtype=np.int64).ravel()
    if not (m.shape[0] == a.shape[0] == g.shape[0]):
        raise ValueError("facet normals, areas and groups must have one row per facet")
    if g.size and (g.min() < 0 or g.max() >= n_groups):
        raise ValueError(f"facet groups must lie in 0..{n_groups - 1}")
    require(m.shape[0] * PAIR_BYTES, f"the apparent dips of {m.shape[0]:,} triangles")
    k = int(n_groups)
    eye = np.eye(3)
    return _grouped(g, k, m, a, np.tile(eye[2], (k, 1)), np.tile(eye[0], (k, 1)),
                    np.tile(eye[1], (k, 1)), az, step)


def _window_planes(
    vertices: np.ndarray, faces: np.ndarray, pair_w: np.ndarray, pair_t: np.ndarray,
    centres: np.ndarray, frame: FaceFrame,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(normal, u, v), each (W, 3), of the ODR plane of each window's distinct
    vertices, the normal on the face normal's side, ``u`` the face's ``u`` projected."""
    n_win = centres.shape[0]
    corner_w = np.repeat(pair_w, 3)
    corner_v = faces[pair_t].ravel()
    key = np.unique(corner_w * np.int64(vertices.shape[0]) + corner_v)
    w = key // vertices.shape[0]
    p = vertices[key % vertices.shape[0]] - centres[w]
    count = np.bincount(w, minlength=n_win).astype(np.float64)
    mean = np.stack([np.bincount(w, weights=p[:, i], minlength=n_win) for i in range(3)],
                    1) / count[:, None]
    cov = np.empty((n_win, 3, 3))
    for i in range(3):
        for j in range(i, 3):
            s = np.bincount(w, weights=p[:, i] * p[:, j], minlength=n_win) / count
            cov[:, i, j] = cov[:, j, i] = s - mean[:, i] * mean[:, j]
    _, vec = np.linalg.eigh(cov)
    normal = vec[:, :, 0]
    normal *= np.where(normal @ frame.normal < 0, -1.0, 1.0)[:, None]
    u = frame.u_axis[None, :] - (normal @ frame.u_axis)[:, None] * normal
    u /= np.linalg.norm(u, axis=1)[:, None]
    v = np.cross(normal, u)
    v *= np.where(v @ frame.v_axis < 0, -1.0, 1.0)[:, None]
    return normal, u, v


def window_map_seconds(n_windows: float, per_window: float, n_azimuths: int,
                       dip_step_deg: float) -> float:
    """Estimated seconds of a window map: ``n_windows`` windows of ``per_window``
    triangles each, at ``n_azimuths`` azimuths and thresholds ``dip_step_deg``
    apart (:data:`PAIR_SECONDS`, :data:`WINDOW_THRESHOLD_SECONDS`).

    >>> round(window_map_seconds(1000, 1000, 24, 1.0), 1)
    21.5
    """
    n_th = np.floor(90.0 / dip_step_deg + 1e-9) + 1
    return float(n_azimuths * n_windows * (per_window * PAIR_SECONDS
                                           + n_th * WINDOW_THRESHOLD_SECONDS))


def require_window_work(n_windows: float, per_window: float, n_azimuths: int,
                        dip_step_deg: float, *, radius: float, step: float) -> None:
    """Raise InputError when the window map's estimated work
    (:func:`window_map_seconds`) is over :data:`MAX_WINDOW_MAP_SECONDS`; the
    message gives the figures (windows, triangles each, azimuths, minutes)."""
    seconds = window_map_seconds(n_windows, per_window, n_azimuths, dip_step_deg)
    if seconds > MAX_WINDOW_MAP_SECONDS:
        raise InputError(
            f"a window map of {n_windows:,.0f} windows (radius {radius:.4g} m, step "
            f"{step:.4g} m) of about {per_window:,.0f} triangles each at {n_azimuths} "
            f"azimuths is about {seconds / 60:,.0f} minutes of work, more than the "
            f"{MAX_WINDOW_MAP_SECONDS / 60:.0f} allowed; choose a larger window step "
            "(default: the radius), a radius of fewer triangles or a larger azimuth step")


def _windows_of(cu: np.ndarray, tree: Any, uv: np.ndarray, faces: np.ndarray, f: Facets,
                projected: np.ndarray, vert: np.ndarray, frame: FaceFrame, *, radius: float,
                min_coverage: float, az: np.ndarray, dstep: float
                ) -> dict[str, np.ndarray] | None:
    """The windows about the candidate centres ``cu`` ((K, 2) in the face plane,
    metres) whose triangles (those wholly inside the disc, found with ``tree`` of the
    triangles' centres ``uv``) cover ``min_coverage`` of it: each measured in its own
    plane (:func:`window_roughness`'s columns); None where no window is kept."""
    from scipy.spatial import cKDTree

    disc = np.pi * radius * radius
    pairs = cKDTree(cu).sparse_distance_matrix(tree, radius, output_type="ndarray")
    pw, pt = pairs["i"].astype(np.int64), pairs["j"].astype(np.int64)
    corner = uv[faces[pt]] - cu[pw][:, None, :]  # (P, 3, 2)
    inside = np.all(np.sum(corner * corner, axis=2) <= radius * radius, axis=1)
    pw, pt = pw[inside], pt[inside]
    cover = np.bincount(pw, weights=projected[pt], minlength=cu.shape[0])
    ntri = np.bincount(pw, minlength=cu.shape[0])
    ok = (cover >= min_coverage * disc) & (ntri >= 3)
    if not ok.any():
        return None
    renum = np.cumsum(ok) - 1
    sel = ok[pw]
    pw, pt = renum[pw[sel]], pt[sel]
    wuv = cu[ok]
    centre3 = frame.origin + wuv[:, :1] * frame.u_axis + wuv[:, 1:] * frame.v_axis
    normal, u_w, v_w = _window_planes(vert, faces, pw, pt, centre3, frame)
    res = _grouped(pw, int(ok.sum()), f.normals[pt], f.areas[pt], normal, u_w, v_w, az, dstep)
    area = np.bincount(pw, weights=f.areas[pt], minlength=wuv.shape[0])
    centroid = np.stack([np.bincount(pw, weights=f.areas[pt] * f.centroids[pt, i],
                                     minlength=wuv.shape[0]) for i in range(3)], 1)
    return {"centre": centroid / area[:, None], "centre_uv": wuv, "area": area,
            "n_triangles": np.bincount(pw, minlength=wuv.shape[0]), "normal": normal, **res}


def window_roughness(
    mesh: TriangleMesh,
    azimuth_deg: Sequence[float] | np.ndarray,
    *,
    radius: float,
    step: float,
    dip_step_deg: float = DEFAULT_DIP_STEP_DEG,
    min_coverage: float = DEFAULT_MIN_COVERAGE,
    plane: Plane | None = None,
    progress: ProgressFn | None = None,
) -> WindowRoughness:
    """``theta*max/(C+1)`` and ``Delta-T`` in circular windows over a surface.

    Parameters
    ----------
    mesh : TriangleMesh
        The surface, metres.
    azimuth_deg : sequence of float
        Analysis directions, degrees (as :func:`directional_roughness`).
    radius : float
        Window radius, metres (in the face plane).
    step : float
        Spacing of the window centres, metres.
    dip_step_deg : float
        Step of the apparent-dip thresholds of the C fit, degrees.
    min_coverage : float
        Share of the window's disc (projected area) its triangles must cover, in
        (0, 1]; windows at the surface's edge covering less are dropped.
    plane : Plane, optional
        The face plane the windows are laid out in (default: the ODR plane of the
        vertices); each window is measured in its own ODR plane.
    progress : callable, optional
        ``progress(done, total)`` in window centres.

    Returns
    -------
    WindowRoughness
    """
    az = _check_azimuths(azimuth_deg)
    dstep = _check_step(dip_step_deg)
    for name, value in (("radius", radius), ("step", step)):
        if not (np.isfinite(value) and value > 0):
            raise InputError(f"window {name} must be a positive length in metres, got {value}")
    if not (np.isfinite(min_coverage) and 0 < min_coverage <= 1):
        raise InputError(f"min_coverage must be in (0, 1], got {min_coverage}")
    from scipy.spatial import cKDTree

    frame = _frame(mesh, plane)
    f = facets(mesh, toward=frame.normal)
    if f.areas.size == 0:
        raise InputError("the surface has no triangle of non-zero area")
    vert = mesh.vertices
    faces = mesh.faces[f.index]
    rel = vert - frame.origin
    uv = np.column_stack([rel @ frame.u_axis, rel @ frame.v_axis])
    del rel
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    counts = np.floor(np.minimum((hi - lo) / step + 1e-9, 2.0**62)).astype(np.int64) + 1
    n_cand = float(counts[0]) * float(counts[1])
    projected = f.areas * np.abs(f.normals @ frame.normal)
    disc = np.pi * radius * radius
    density = f.areas.size / max(float(projected.sum()), 1e-300)  # triangles per m^2
    per_window = max(1.0, 1.5 * density * disc)
    require_window_work(n_cand, per_window, az.size, dstep, radius=radius, step=step)
    require(n_cand * 10 * 8.0, f"{n_cand:,.0f} window centres (step {step:.4g} m)",
            hint="choose a larger window step")
    n_cand = int(n_cand)
    gu, gv = np.meshgrid(lo[0] + step * np.arange(counts[0]), lo[1] + step * np.arange(counts[1]))
    cand_uv = np.column_stack([gu.ravel(), gv.ravel()])
    chunk = int(max(1, PAIRS_PER_CHUNK // per_window))
    require(min(n_cand, chunk) * per_window * PAIR_BYTES,
            f"windows of radius {radius:.4g} m ({per_window:,.0f} triangles each)",
            hint="choose a smaller window radius")
    tri_uv = uv[faces].mean(axis=1)
    tree = cKDTree(tri_uv)
    kept: list[dict[str, np.ndarray]] = []
    for start in range(0, n_cand, chunk):
        got = _windows_of(cand_uv[start:start + chunk], tree, uv, faces, f, projected,
                          vert, frame, radius=radius, min_coverage=min_coverage, az=az,
                          dstep=dstep)
        if got is not None:
            kept.append(got)
        if progress is not None:
            progress(min(start + chunk, n_cand), n_cand)
    if not kept:
        raise InputError(f"no window of radius {radius:.4g} m has triangles covering "
                         f"{min_coverage:.0%} of it: choose a larger radius or a smaller "
                         "minimum coverage")

    def cat(key: str) -> np.ndarray:
        return np.concatenate([k[key] for k in kept])

    return WindowRoughness(
        azimuth_deg=az, centre=cat("centre"), centre_uv=cat("centre_uv"), area=cat("area"),
        n_triangles=cat("n_triangles"), normal=cat("normal"),
        theta_max_c1=cat("theta_max_c1"), delta_t=cat("delta_t"), theta_max=cat("theta_max"),
        c=cat("c"), a0=cat("a0"), radius=float(radius), step=float(step),
        min_coverage=float(min_coverage), frame=frame, dip_step_deg=dstep, candidates=n_cand,
    )
