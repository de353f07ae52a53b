"""Orientation of planes and lines, and the lower-hemisphere equal-area stereonet.

Conventions (docs/zones.md; the issue's, and those of structural geology):

- ``z`` is up; azimuths (dip direction, trend) are degrees clockwise from ``+y``
  (grid north) in [0, 360); ``+x`` is east (azimuth 90).
- A plane is given by its normal. Normals are oriented **upward** (``n_z > 0``); a
  plane that is vertical to within :data:`VERTICAL_TOL` keeps the side of a
  reference vector ``toward`` (the viewer's side; rough_viewer does not know where
  the scanner stood, so callers pass the whole-cloud normal, whose largest component
  is positive: :func:`rough_viewer.grid.planes.orient_normal`).
- Dip: angle of the plane below horizontal, degrees in [0, 90]. Dip direction: the
  azimuth of the down-dip direction, which is the azimuth of the horizontal part of
  the upward normal (0 for a horizontal plane).
- A line (a zone's trace) is given by a direction vector, oriented **downward**;
  plunge = angle below horizontal in [0, 90], trend = azimuth of the downward
  direction. A horizontal line (``|v_z| <= VERTICAL_TOL``) has its trend in
  [0, 180).
- The pole of a plane is its downward normal: trend ``dip direction + 180``, plunge
  ``90 - dip``.
- Stereonet: lower hemisphere, equal area (Schmidt), primitive radius 1, north up
  (``+y``), east right (``+x``). A line of trend ``t`` and plunge ``p`` projects to
  ``r = sqrt(2) sin((90 - p) / 2)``, ``(x, y) = (r sin t, r cos t)``.
- Density contours: an axial Fisher kernel ``exp(kappa (|p . d| - 1))`` with
  ``kappa = 1 / sigma^2`` (``sigma`` = ``smoothing_deg`` in radians), in multiples of
  a uniform distribution (MUD: 1 everywhere for poles spread evenly over the
  hemisphere). Poles are first counted in small bins of the projection plane (mean
  direction per bin), so the cost does not grow with the number of cells.

>>> import numpy as np
>>> dip, dd = dip_and_direction(np.array([[0.0, -0.5, np.sqrt(0.75)]]))  # dips 30 deg south
>>> dip.round(6), dd.round(6)
(array([30.]), array([180.]))
>>> trend, plunge = trend_and_plunge(np.array([[1.0, 0.0, 1.0]]))  # up to the east
>>> trend.round(6), plunge.round(6)
(array([270.]), array([45.]))
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from rough_viewer.memory import require
from rough_viewer.vocabulary import InputError

if TYPE_CHECKING:
    from rough_viewer.grid.roughness import GridRoughness

#: ``|n_z|`` (or ``|v_z|`` of a line) at or below which a plane counts as vertical
#: (a line as horizontal): ties are broken by the conventions above.
VERTICAL_TOL = 1e-9
#: Default angular smoothing of stereonet density contours, degrees.
DEFAULT_SMOOTHING_DEG = 6.0
#: Default number of density nodes along each axis of the projection plane.
DEFAULT_NET_NODES = 61
#: Bins per axis of the projection plane in which poles are counted before the
#: kernel sum (about 1.3 to 1.8 degrees each, well below the smoothing).
POLE_BINS = 96


def _unit_rows(v: np.ndarray) -> np.ndarray:
    """(M, 3) float64 copy of ``v`` with rows scaled to unit length (NaN rows stay)."""
    a = np.array(v, dtype=np.float64, ndmin=2)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"expected an (M, 3) array of vectors, got shape {np.shape(v)}")
    with np.errstate(invalid="ignore", divide="ignore"):
        return a / np.linalg.norm(a, axis=1, keepdims=True)


def _azimuth(east: np.ndarray, north: np.ndarray) -> np.ndarray:
    """Degrees clockwise from +y in [0, 360)."""
    az = np.degrees(np.arctan2(east, north)) % 360.0
    az[az >= 360.0] -= 360.0  # a tiny negative angle % 360 rounds to 360
    az[(east == 0.0) & (north == 0.0)] = 0.0  # arctan2(-0.0, -0.0) is -180
    return az


def orient_normals(normals: np.ndarray, toward: np.ndarray | None = None) -> np.ndarray:
    """Unit normals made upward (``n_z > 0``); vertical ones (``|n_z| <=``
    :data:`VERTICAL_TOL`) turned to the side of ``toward`` (a (3,) vector; kept as
    given when None).

    Parameters
    ----------
    normals : (M, 3) array_like
        Plane normals (any length, either sign); NaN rows stay NaN.
    toward : (3,) array_like, optional
        The viewer's side, for vertical planes only.

    Returns
    -------
    (M, 3) float64 array
    """
    n = _unit_rows(normals)
    nz = n[:, 2]
    with np.errstate(invalid="ignore"):
        flip = nz < -VERTICAL_TOL
        if toward is not None:
            t = np.asarray(toward, dtype=np.float64)
            vertical = np.abs(nz) <= VERTICAL_TOL
            flip |= vertical & (n[:, :2] @ t[:2] < 0)
    n[flip] *= -1.0
    return n


def dip_and_direction(
    normals: np.ndarray, toward: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Dip and dip direction of planes given by their normals.

    Parameters
    ----------
    normals : (M, 3) array_like
        Plane normals (any sign; oriented by :func:`orient_normals`).
    toward : (3,) array_like, optional
        The viewer's side, which decides the dip direction of vertical planes.

    Returns
    -------
    dip_deg : (M,) array
        Degrees below horizontal, [0, 90]; NaN where the normal is NaN.
    dip_direction_deg : (M,) array
        Azimuth of the down-dip direction, degrees clockwise from +y, [0, 360).
    """
    n = orient_normals(normals, toward)
    horizontal = np.hypot(n[:, 0], n[:, 1])
    dip = np.degrees(np.arctan2(horizontal, np.abs(n[:, 2])))
    return dip, _azimuth(n[:, 0], n[:, 1])


def trend_and_plunge(vectors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Trend and plunge of lines given by direction vectors (either sense).

    Parameters
    ----------
    vectors : (M, 3) array_like
        Line directions, any length.

    Returns
    -------
    trend_deg : (M,) array
        Azimuth of the downward direction, degrees clockwise from +y in [0, 360);
        [0, 180) for horizontal lines; 0 for vertical ones.
    plunge_deg : (M,) array
        Degrees below horizontal, [0, 90].
    """
    v = _unit_rows(vectors)
    with np.errstate(invalid="ignore"):
        v[v[:, 2] > VERTICAL_TOL] *= -1.0
    horizontal = np.hypot(v[:, 0], v[:, 1])
    plunge = np.degrees(np.arctan2(np.abs(v[:, 2]), horizontal))
    trend = _azimuth(v[:, 0], v[:, 1])
    with np.errstate(invalid="ignore"):
        level = (np.abs(v[:, 2]) <= VERTICAL_TOL) & (trend >= 180.0)
    trend[level] -= 180.0
    return trend, plunge


def line_vectors(trend_deg: np.ndarray, plunge_deg: np.ndarray) -> np.ndarray:
    """(M, 3) downward unit vectors of lines of trend and plunge (degrees)."""
    t = np.radians(np.asarray(trend_deg, dtype=np.float64))
    p = np.radians(np.asarray(plunge_deg, dtype=np.float64))
    return np.column_stack([np.cos(p) * np.sin(t), np.cos(p) * np.cos(t), -np.sin(p)])


def plane_normals(dip_deg: np.ndarray, dip_direction_deg: np.ndarray) -> np.ndarray:
    """(M, 3) upward unit normals of planes of dip and dip direction (degrees): the
    inverse of :func:`dip_and_direction`.

    >>> np.round(plane_normals(np.array([30.0]), np.array([180.0])), 6) + 0.0
    array([[ 0.      , -0.5     ,  0.866025]])
    """
    dip = np.asarray(dip_deg, dtype=np.float64).reshape(-1)
    dd = np.asarray(dip_direction_deg, dtype=np.float64).reshape(-1)
    return -line_vectors(dd + 180.0, 90.0 - dip)


def dip_strike_axes(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit down-dip and strike directions (each (M, 3)) of planes with the given
    normals (either sign): the dip axis points down the dip direction, the strike
    axis is horizontal, at the dip direction minus 90 degrees (right-hand rule), and
    ``dip axis x strike axis`` is the upward normal. A horizontal plane takes north
    (+y) as its dip axis and east as its strike.

    >>> d, s = dip_strike_axes(np.array([[0.0, -0.5, np.sqrt(0.75)]]))
    >>> np.round(d, 6) + 0.0, np.round(s, 6) + 0.0
    (array([[ 0.      , -0.866025, -0.5     ]]), array([[1., 0., 0.]]))
    """
    n = orient_normals(normals)
    h = np.hypot(n[:, 0], n[:, 1])
    flat = h < VERTICAL_TOL
    hs = np.where(flat, 1.0, h)
    dip = np.column_stack([n[:, 0] * n[:, 2] / hs, n[:, 1] * n[:, 2] / hs, -h])
    dip[flat] = (0.0, 1.0, 0.0)
    strike = np.cross(n, dip)
    strike /= np.linalg.norm(strike, axis=1, keepdims=True)
    return dip, strike


def poles(normals: np.ndarray, toward: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Trend and plunge (degrees) of the poles (downward normals) of planes:
    ``dip direction + 180`` and ``90 - dip``."""
    dip, dd = dip_and_direction(normals, toward)
    return (dd + 180.0) % 360.0, 90.0 - dip


def schmidt(trend_deg: np.ndarray, plunge_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lower-hemisphere equal-area (Schmidt) projection of lines, primitive radius 1.

    ``r = sqrt(2) sin((90 - plunge) / 2)``, ``x = r sin(trend)``, ``y = r cos(trend)``:
    a vertical line projects to the centre, a horizontal one onto the unit circle;
    equal areas of the hemisphere map to equal areas of the disc.

    >>> x, y = schmidt(np.array([90.0, 0.0]), np.array([0.0, 90.0]))
    >>> x.round(6) + 0.0, y.round(6) + 0.0
    (array([1., 0.]), array([0., 0.]))
    """
    t = np.radians(np.asarray(trend_deg, dtype=np.float64))
    half = np.radians(90.0 - np.asarray(plunge_deg, dtype=np.float64)) / 2.0
    r = np.sqrt(2.0) * np.sin(half)
    return r * np.sin(t), r * np.cos(t)


def schmidt_inverse(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """(..., 3) downward unit vectors of the points ``(x, y)`` of the Schmidt net
    (NaN outside the primitive circle)."""
    xa = np.asarray(x, dtype=np.float64)
    ya = np.asarray(y, dtype=np.float64)
    r = np.hypot(xa, ya)
    with np.errstate(invalid="ignore"):
        inside = r <= 1.0 + 1e-12
        angle = 2.0 * np.arcsin(np.clip(r / np.sqrt(2.0), 0.0, 1.0))  # from the downward vertical
        s = np.where(r > 0, np.sin(angle) / np.where(r > 0, r, 1.0), 0.0)
    out = np.stack([xa * s, ya * s, -np.cos(angle)], axis=-1)
    out[~inside] = np.nan
    return out


@dataclass(frozen=True, eq=False)
class Stereonet:
    """Poles of planes on a lower-hemisphere equal-area net, with density contours."""

    x: np.ndarray
    """(K,) projected x (east) of every pole, primitive radius 1."""
    y: np.ndarray
    """(K,) projected y (north) of every pole."""
    rows: np.ndarray
    """(K,) int64: the input row (cell) of every pole (rows with a NaN normal have none)."""
    nodes: np.ndarray
    """(G,) coordinates of the density nodes along x and along y (the same), [-1, 1]."""
    density: np.ndarray
    """(G, G) pole density in multiples of a uniform distribution (MUD), row = y,
    column = x; NaN outside the primitive circle (all NaN when there are no poles)."""
    smoothing_deg: float
    """Angular smoothing of the density (kernel ``sigma``), degrees."""
    weights: np.ndarray | None = None
    """(K,) weight of every pole in the density (e.g. its cell's points), or None:
    every pole counts once."""

    @property
    def n_poles(self) -> int:
        """Number of poles."""
        return int(self.x.shape[0])


def kernel_peak(smoothing_deg: float) -> float:
    """Density (MUD) at a point where all poles coincide: ``kappa / (1 - exp(-kappa))``."""
    kappa = kernel_kappa(smoothing_deg)
    return float(kappa / -np.expm1(-kappa))


def kernel_kappa(smoothing_deg: float) -> float:
    """Concentration ``kappa = 1 / sigma^2`` of the density kernel (``sigma`` in radians)."""
    return float(1.0 / np.radians(smoothing_deg) ** 2)


def kernel_density(
    directions: np.ndarray,
    poles: np.ndarray,
    weights: np.ndarray | None = None,
    *,
    smoothing_deg: float = DEFAULT_SMOOTHING_DEG,
) -> np.ndarray:
    """Axial Fisher-kernel density of ``poles`` at ``directions``, in multiples of a
    uniform distribution (MUD), summed exactly over every pole.

    ``density(d) = sum_i w_i exp(kappa (|p_i . d| - 1)) / (U sum_i w_i)`` with
    ``U = (1 - exp(-kappa)) / kappa``, the mean of the kernel over uniformly spread
    directions, so poles spread evenly give 1 everywhere. The stereonet's contours
    and the joint sets' peaks (:mod:`rough_viewer.structure.sets`) both come from this
    formula.

    Parameters
    ----------
    directions : (G, 3) array
        Unit vectors where the density is wanted (either sense).
    poles : (K, 3) array
        Unit pole vectors (either sense: the kernel is axial).
    weights : (K,) array, optional
        Weight of every pole (default 1 each).
    smoothing_deg : float
        Kernel ``sigma``, degrees.

    Returns
    -------
    (G,) float64 array (NaN when the weights sum to 0)

    Examples
    --------
    >>> d = np.array([[0.0, 0.0, -1.0]])
    >>> bool(np.isclose(kernel_density(d, np.array([[0.0, 0.0, 1.0]]))[0], kernel_peak(6.0)))
    True
    """
    d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    p = np.asarray(poles, dtype=np.float64).reshape(-1, 3)
    w = np.ones(p.shape[0]) if weights is None else np.asarray(weights, dtype=np.float64)
    kappa = kernel_kappa(smoothing_deg)
    uniform = -np.expm1(-kappa) / kappa  # mean of exp(kappa (|c| - 1)), c uniform in [-1, 1]
    total = float(w.sum())
    out = np.full(d.shape[0], np.nan)
    if total <= 0.0 or d.shape[0] == 0:
        return out
    chunk = max(1, (1 << 22) // max(1, p.shape[0]))
    require(8.0 * min(chunk, d.shape[0]) * p.shape[0] * 3, "stereonet density")
    for s in range(0, d.shape[0], chunk):
        k = np.exp(kappa * (np.abs(d[s:s + chunk] @ p.T) - 1.0))
        out[s:s + chunk] = (k @ w) / (total * uniform)
    return out


def stereonet(
    normals: np.ndarray,
    *,
    toward: np.ndarray | None = None,
    smoothing_deg: float = DEFAULT_SMOOTHING_DEG,
    nodes: int = DEFAULT_NET_NODES,
    weights: np.ndarray | None = None,
) -> Stereonet:
    """Poles of planes on the lower-hemisphere Schmidt net and their density.

    Parameters
    ----------
    normals : (M, 3) array_like
        Plane normals (e.g. every cell's ODR normal); NaN rows are skipped.
    toward : (3,) array_like, optional
        The viewer's side, deciding the pole of vertical planes (see
        :func:`orient_normals`); the two choices are the same point of the primitive.
    smoothing_deg : float
        Kernel ``sigma``, degrees (default 6).
    nodes : int
        Density nodes along each axis of the net (default 61).
    weights : (M,) array_like, optional
        Weight of every plane in the density (e.g. its cell's points; default 1 each).

    Returns
    -------
    Stereonet

    Examples
    --------
    Every pole vertical (horizontal planes): the density peaks at the centre with
    the kernel's peak value.

    >>> net = stereonet(np.tile([0.0, 0.0, 1.0], (50, 1)), nodes=21)
    >>> bool(np.isclose(net.density[10, 10], kernel_peak(6.0)))
    True
    """
    if not (np.isfinite(smoothing_deg) and 0.0 < smoothing_deg <= 90.0):
        raise InputError(f"smoothing must be in (0, 90] degrees, got {smoothing_deg}")
    g_nodes = int(nodes)
    if g_nodes < 3:
        raise InputError(f"a stereonet needs at least 3 nodes per axis, got {nodes}")
    n = np.array(normals, dtype=np.float64, ndmin=2)
    if n.ndim != 2 or n.shape[1] != 3:
        raise ValueError(f"expected an (M, 3) array of normals, got shape {np.shape(normals)}")
    rows = np.flatnonzero(np.all(np.isfinite(n), axis=1) & np.any(n != 0.0, axis=1))
    w = None
    if weights is not None:
        w_all = np.asarray(weights, dtype=np.float64).reshape(-1)
        if w_all.shape[0] != n.shape[0] or not np.all(np.isfinite(w_all) & (w_all >= 0)):
            raise ValueError(f"expected {n.shape[0]} finite weights >= 0, got shape "
                             f"{np.shape(weights)}")
        w = w_all[rows]
    trend, plunge = poles(n[rows], toward)
    x, y = schmidt(trend, plunge)
    grid = np.linspace(-1.0, 1.0, g_nodes)
    density = _density(x, y, grid, smoothing_deg, w)
    return Stereonet(x=x, y=y, rows=rows.astype(np.int64), nodes=grid, density=density,
                     smoothing_deg=float(smoothing_deg), weights=w)


def cell_orientation(result: GridRoughness) -> tuple[np.ndarray, np.ndarray]:
    """Dip and dip direction (degrees) of every cell's ODR plane (NaN where none);
    vertical cells take the side of the whole-cloud normal."""
    return dip_and_direction(result.normal, result.whole_plane.normal)


def cell_stereonet(
    result: GridRoughness,
    cells: np.ndarray | None = None,
    *,
    smoothing_deg: float = DEFAULT_SMOOTHING_DEG,
    nodes: int = DEFAULT_NET_NODES,
    weighted: bool = False,
) -> Stereonet:
    """The stereonet of the poles of ``result``'s cells (all, or the rows ``cells``:
    an index array or a boolean mask); :attr:`Stereonet.rows` are cell rows. With
    ``weighted`` every pole counts in the density by its cell's points."""
    rows = np.arange(result.n_cells) if cells is None else np.arange(result.n_cells)[cells]
    net = stereonet(result.normal[rows], toward=result.whole_plane.normal,
                    smoothing_deg=smoothing_deg, nodes=nodes,
                    weights=result.n_points[rows] if weighted else None)
    return Stereonet(x=net.x, y=net.y, rows=rows[net.rows], nodes=net.nodes,
                     density=net.density, smoothing_deg=net.smoothing_deg, weights=net.weights)


def _density(x: np.ndarray, y: np.ndarray, grid: np.ndarray, smoothing_deg: float,
             weights: np.ndarray | None = None) -> np.ndarray:
    """Axial Fisher-kernel density (MUD) of the poles at ``(x, y)`` (weighted by
    ``weights``, default 1 each) on the node grid."""
    g = grid.shape[0]
    gx, gy = np.meshgrid(grid, grid)
    d = schmidt_inverse(gx, gy).reshape(-1, 3)
    out = np.full(g * g, np.nan)
    if x.shape[0] == 0:
        return out.reshape(g, g)
    # Count the poles in small bins of the projection plane; the mean direction of a
    # bin stands for its poles (bins are far smaller than the kernel).
    nb = POLE_BINS
    ix = np.clip(((x + 1.0) * 0.5 * nb).astype(np.int64), 0, nb - 1)
    iy = np.clip(((y + 1.0) * 0.5 * nb).astype(np.int64), 0, nb - 1)
    b = iy * nb + ix
    v = schmidt_inverse(x, y)
    wt = np.ones(x.shape[0]) if weights is None else np.asarray(weights, dtype=np.float64)
    count = np.bincount(b, weights=wt, minlength=nb * nb)
    occupied = np.flatnonzero(count > 0)
    if occupied.shape[0] == 0:
        return out.reshape(g, g)
    sums = np.column_stack([np.bincount(b, weights=wt * v[:, a], minlength=nb * nb)[occupied]
                            for a in range(3)])
    pv = sums / np.linalg.norm(sums, axis=1, keepdims=True)
    inside = np.flatnonzero(np.isfinite(d[:, 0]))
    out[inside] = kernel_density(d[inside], pv, count[occupied], smoothing_deg=smoothing_deg)
    return out.reshape(g, g)
