"""Plane fits: orthogonal distance regression (ODR) and ordinary least squares (OLS).

Two flavours of the same two ideas:

- :func:`fit_plane` fits one point set (an (N, 3) array), for profiles, targets
  and the whole-cloud orientation.
- :func:`odr_from_covariance` and :func:`ols_from_covariance` fit many cells at once
  from their 3x3 covariance matrices (batched, no loop over cells).

The ODR plane passes through the centroid with normal = eigenvector of the
smallest eigenvalue of the population covariance (docs/science.md section 1; this is the
orthogonal regression of the 2011 paper's Eq. 2 without its inability to represent
a vertical face). The OLS plane takes one coordinate axis ``a`` as the dependent
variable: ``p_a = b0 + b1 p_u + b2 p_v``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from rough_viewer.io.cloud import PointCloud, as_columns
from rough_viewer.memory import require
from rough_viewer.vocabulary import AXES, Axis, InputError

#: A covariance eigenvalue (square metres) counts as zero below this share of the
#: cell's absolute squared length scale (the squared cell size on a grid, else the
#: total variance, the trace of the covariance): a spread under 1e-6 of the scale.
#: Round-off leaves a constant coordinate a variance of ~1e-21 m^2 (UTM-sized
#: coordinates), far below this for any cell larger than a micrometre, while each
#: axis's own variance is no yardstick: it is itself round-off when the axis is
#: constant.
DEGENERATE_RTOL = 1e-12


def _scale2(cov: np.ndarray, scale2: np.ndarray | float | None) -> np.ndarray:
    """Squared length scale per cell: ``scale2`` when given (at least the trace),
    else the trace of the covariance (total variance)."""
    trace = np.trace(cov, axis1=1, axis2=2)
    if scale2 is None:
        return trace
    return np.maximum(np.broadcast_to(np.asarray(scale2, dtype=np.float64), trace.shape), trace)


@dataclass(frozen=True)
class PlaneFit:
    """ODR plane of one point set."""

    centroid: np.ndarray
    """(3,) mean of the points, metres."""
    normal: np.ndarray
    """(3,) unit normal (eigenvector of the smallest covariance eigenvalue)."""
    eigenvalues: np.ndarray
    """(3,) population covariance eigenvalues, descending, square metres."""
    axes: np.ndarray
    """(3, 3) principal axes as columns, in the order of ``eigenvalues`` (the last
    column is ``normal``)."""


def axis_index(axis: Axis) -> int:
    """Index 0, 1, 2 of the coordinate axis named ``"x"``, ``"y"`` or ``"z"``."""
    try:
        return AXES.index(axis)
    except ValueError:
        raise InputError(f"axis must be one of x, y, z, got {axis!r}") from None


def plane_from_scatter(centroid: np.ndarray, covariance: np.ndarray) -> PlaneFit:
    """The ODR plane of a point set given its centroid and population covariance.

    The one place where a plane comes from an eigen-decomposition: :func:`fit_plane`
    and :func:`whole_cloud_plane` (and the grid's moment sums) all end here.

    Parameters
    ----------
    centroid : (3,) array_like
        Mean of the points, metres.
    covariance : (3, 3) array_like
        Population covariance of the points, square metres.
    """
    w, v = np.linalg.eigh(np.asarray(covariance, dtype=np.float64))
    axes = v[:, ::-1].copy()
    return PlaneFit(centroid=np.asarray(centroid, dtype=np.float64).copy(),
                    normal=axes[:, 2].copy(), eigenvalues=w[::-1].copy(), axes=axes)


def orient_normal(normal: np.ndarray) -> np.ndarray:
    """``normal`` with its largest component made positive: the sign convention of the
    whole-cloud plane (for a vertical face parallel to xz the normal points to +y;
    for a horizontal surface, up)."""
    n = np.asarray(normal, dtype=np.float64)
    return -n if n[int(np.argmax(np.abs(n)))] < 0 else n.copy()


def fit_plane(xyz: np.ndarray) -> PlaneFit:
    """ODR plane of an (N, 3) point set (N >= 3).

    Parameters
    ----------
    xyz : (N, 3) array_like
        Points in metres.

    Returns
    -------
    PlaneFit
        Centroid, unit normal, covariance eigenvalues (descending) and principal axes.

    Examples
    --------
    >>> import numpy as np
    >>> pts = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.0]])
    >>> fit = fit_plane(pts)
    >>> np.abs(fit.normal).round(6) + 0.0, fit.centroid
    (array([0., 0., 1.]), array([0.5, 0.5, 0. ]))
    """
    pts = np.asarray(xyz, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3 or pts.shape[0] < 3:
        raise InputError("fit_plane needs an (N, 3) array with N >= 3")
    centroid = pts.mean(axis=0)
    d = pts - centroid
    return plane_from_scatter(centroid, d.T @ d / pts.shape[0])


#: Points per chunk of :func:`whole_cloud_plane` (bounds its temporaries).
_PLANE_CHUNK = 1 << 21


def whole_cloud_plane(points: PointCloud | np.ndarray) -> PlaneFit:
    """The ODR plane of a whole cloud: the face plane of maps, the reference of the
    ``auto`` dependent axis and of the app's camera.

    Sums are taken in chunks relative to the first point, so no (N, 3) temporary is
    made and UTM-sized coordinates lose no precision. The normal follows
    :func:`orient_normal`.

    Parameters
    ----------
    points : PointCloud or (N, 3) array
        Points, metres (N >= 3).

    Returns
    -------
    PlaneFit

    Examples
    --------
    >>> import numpy as np
    >>> xz = np.random.default_rng(0).uniform(0, 4, (1000, 2))
    >>> face = np.column_stack([xz[:, 0], np.full(1000, 7.0), xz[:, 1]])  # a wall facing y
    >>> whole_cloud_plane(face).normal.round(6) + 0.0
    array([0., 1., 0.])
    """
    x, y, z = as_columns(points)
    n = int(x.shape[0])
    if n < 3:
        raise InputError(f"a plane needs at least 3 points, got {n}")
    ref = np.array([x[0], y[0], z[0]])
    s1 = np.zeros(3)
    s2 = np.zeros((3, 3))
    for start in range(0, n, _PLANE_CHUNK):
        sl = slice(start, min(n, start + _PLANE_CHUNK))
        d = np.column_stack([x[sl] - ref[0], y[sl] - ref[1], z[sl] - ref[2]])
        s1 += d.sum(axis=0)
        s2 += d.T @ d
    mean = s1 / n
    plane = plane_from_scatter(ref + mean, s2 / n - np.outer(mean, mean))
    return replace(plane, normal=orient_normal(plane.normal))


def signed_distance(points: PointCloud | np.ndarray, plane: PlaneFit) -> np.ndarray:
    """Signed orthogonal distance of every point to a plane, metres.

    ``(p - centroid) . normal``: positive on the side the plane's normal points to
    (for :func:`whole_cloud_plane`, the :func:`orient_normal` convention: the normal's
    largest component is positive, e.g. +y for a face parallel to xz). Computed in
    chunks from the columns, so the only full-length array is the result.

    Parameters
    ----------
    points : PointCloud or (N, 3) array
        Points, metres.
    plane : PlaneFit
        Any object with ``centroid`` (3,) and ``normal`` (3,) (a unit vector or not:
        it is normalised here).

    Returns
    -------
    (N,) float64 array, metres.

    Examples
    --------
    >>> import numpy as np
    >>> face = whole_cloud_plane(np.array([[0, 0, 0], [1, 0, 0], [0, 0, 1], [1, 0, 1.0]]))
    >>> signed_distance(np.array([[0.5, 0.25, 0.5], [3.0, -0.1, 9.0]]), face)
    array([ 0.25, -0.1 ])
    """
    x, y, z = as_columns(points)
    n = int(x.shape[0])
    require(8.0 * (n + 2 * min(n, _PLANE_CHUNK)), f"distances of {n:,} points to a plane")
    normal = np.asarray(plane.normal, dtype=np.float64)
    length = float(np.linalg.norm(normal))
    if not (np.isfinite(length) and length > 0):
        raise InputError("the plane has no normal")
    normal = normal / length
    c = np.asarray(plane.centroid, dtype=np.float64)
    out = np.empty(n)
    for start in range(0, n, _PLANE_CHUNK):
        sl = slice(start, min(n, start + _PLANE_CHUNK))
        o = out[sl]
        np.subtract(x[sl], c[0], out=o)
        o *= normal[0]
        o += (y[sl] - c[1]) * normal[1]
        o += (z[sl] - c[2]) * normal[2]
    return out


def dominant_axis(normal: np.ndarray) -> Axis:
    """The coordinate axis closest to ``normal`` (largest absolute component)."""
    return AXES[int(np.argmax(np.abs(np.asarray(normal, dtype=np.float64))))]


def odr_from_covariance(
    cov: np.ndarray, scale2: np.ndarray | float | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Batched ODR normals from per-cell covariance matrices.

    Parameters
    ----------
    cov : (M, 3, 3) array
        Population covariance of each cell's points (square metres).
    scale2 : float or (M,) array, optional
        Absolute squared length scale, square metres (the squared cell size on a
        grid); default the total variance of each cell.

    Returns
    -------
    normal : (M, 3) array
        Unit normal per cell (eigenvector of the smallest eigenvalue).
    eigenvalues : (M, 3) array
        Eigenvalues, descending.
    valid : (M,) bool array
        False where the plane is not unique: points coincident or collinear (the
        middle eigenvalue vanishes against ``scale2``).
    """
    w, v = np.linalg.eigh(cov)
    normal = v[:, :, 0]
    eig = w[:, ::-1]
    scale = _scale2(cov, scale2)
    valid = (scale > 0) & (eig[:, 1] > DEGENERATE_RTOL * scale)
    return normal, eig, valid


def ols_from_covariance(
    cov: np.ndarray, axis: Axis, scale2: np.ndarray | float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Batched OLS planes along a dependent axis, from per-cell covariances.

    The fitted plane through the centroid is ``w . (p - c) = 0`` with ``w_a = 1`` and
    ``w_u = -b1``, ``w_v = -b2``; the residual along ``a`` of a point is
    ``w . (p - c)``.

    Parameters
    ----------
    cov : (M, 3, 3) array
        Population covariance of each cell's points (square metres).
    axis : {"x", "y", "z"}
        Dependent axis.
    scale2 : float or (M,) array, optional
        Absolute squared length scale, square metres (the squared cell size on a
        grid); default the total variance of each cell.

    Returns
    -------
    w : (M, 3) array
        Residual vector per cell (dimensionless).
    valid : (M,) bool array
        False where the two independent coordinates are degenerate (collinear or
        coincident in the u-v plane), so the regression has no unique solution:
        the smaller eigenvalue of their 2x2 covariance vanishes against ``scale2``
        (not against each axis's own variance, which round-off makes ~1e-21 m^2 for
        a constant coordinate, e.g. one column of a DEM lattice).
    """
    a = axis_index(axis)
    u, v = [i for i in range(3) if i != a]
    cuu = cov[:, u, u]
    cvv = cov[:, v, v]
    cuv = cov[:, u, v]
    cua = cov[:, u, a]
    cva = cov[:, v, a]
    det = cuu * cvv - cuv * cuv
    half_gap = np.sqrt((0.5 * (cuu - cvv)) ** 2 + cuv * cuv)
    smallest = 0.5 * (cuu + cvv) - half_gap  # smaller eigenvalue of the u-v covariance
    scale = _scale2(cov, scale2)
    valid = (det > 0) & (smallest > DEGENERATE_RTOL * scale)
    safe = np.where(valid, det, 1.0)
    b1 = (cvv * cua - cuv * cva) / safe
    b2 = (cuu * cva - cuv * cua) / safe
    w = np.zeros((cov.shape[0], 3))
    w[:, a] = 1.0
    w[:, u] = -b1
    w[:, v] = -b2
    w[~valid] = np.nan
    return w, valid
