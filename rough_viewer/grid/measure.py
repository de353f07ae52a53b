"""Measuring on the rock: the distance between two picked points, and the ODR plane of
a selected set of points with its dip, dip direction and RMS residual.

Orientations follow docs/zones.md through :mod:`rough_viewer.grid.orientation` (z up,
azimuths clockwise from +y, the upward normal, a vertical plane turned to the
``toward`` side); planes are fitted by :func:`rough_viewer.grid.planes.fit_plane`.

>>> import numpy as np
>>> d = point_distance((0.0, 0.0, 10.0), (3.0, 4.0, 22.0))
>>> d.distance_m, d.horizontal_m, d.vertical_m, round(d.trend_deg, 2), round(d.plunge_deg, 2)
(13.0, 5.0, 12.0, 216.87, 67.38)
>>> rng = np.random.default_rng(0)
>>> uv = rng.uniform(-1, 1, (500, 2))
>>> plane = np.column_stack([uv[:, 0], uv[:, 1], 0.5 * uv[:, 1]])  # rises to the north
>>> m = region_plane(plane)
>>> round(m.dip_deg, 3), round(m.dip_direction_deg, 3), m.n_points
(26.565, 180.0, 500)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rough_viewer.grid.orientation import dip_and_direction, orient_normals, trend_and_plunge
from rough_viewer.grid.planes import fit_plane
from rough_viewer.io.cloud import PointCloud, as_columns
from rough_viewer.memory import require
from rough_viewer.vocabulary import InputError


@dataclass(frozen=True)
class Distance:
    """The line between two points."""

    a: np.ndarray
    """(3,) first point, metres."""
    b: np.ndarray
    """(3,) second point, metres."""
    distance_m: float
    """Straight-line distance, metres."""
    horizontal_m: float
    """Horizontal part (in the xy plane), metres."""
    vertical_m: float
    """``b_z - a_z``, metres (positive when b is higher)."""
    trend_deg: float
    """Trend of the line (azimuth of its downward direction), degrees clockwise from
    +y; [0, 180) for a horizontal line."""
    plunge_deg: float
    """Plunge of the line below horizontal, degrees [0, 90]."""


def point_distance(a: tuple[float, float, float] | np.ndarray,
                   b: tuple[float, float, float] | np.ndarray) -> Distance:
    """The distance between two points (metres), with its horizontal and vertical
    parts and the line's trend and plunge."""
    p = np.asarray(a, dtype=np.float64)
    q = np.asarray(b, dtype=np.float64)
    if p.shape != (3,) or q.shape != (3,) or not (np.all(np.isfinite(p)) and np.all(np.isfinite(q))):
        raise InputError("a distance needs two points of three finite coordinates")
    d = q - p
    length = float(np.linalg.norm(d))
    if length > 0:
        trend, plunge = trend_and_plunge(d[None])
        t, pl = float(trend[0]), float(plunge[0])
    else:
        t = pl = math.nan
    return Distance(a=p, b=q, distance_m=length, horizontal_m=float(math.hypot(d[0], d[1])),
                    vertical_m=float(d[2]), trend_deg=t, plunge_deg=pl)


@dataclass(frozen=True)
class PlaneMeasure:
    """The ODR plane of a set of points."""

    centroid: np.ndarray
    """(3,) mean of the points, metres."""
    normal: np.ndarray
    """(3,) unit normal, upward (a vertical plane: toward the viewer's side)."""
    dip_deg: float
    """Dip below horizontal, degrees [0, 90]."""
    dip_direction_deg: float
    """Azimuth of the down-dip direction, degrees clockwise from +y, [0, 360)."""
    rms_m: float
    """Root mean square of the points' orthogonal distances to the plane, metres."""
    max_abs_m: float
    """Largest orthogonal distance of a point to the plane, metres."""
    n_points: int
    """Points fitted."""


def plane_orientation(normal: np.ndarray | tuple[float, float, float],
                      toward: np.ndarray | None = None) -> tuple[float, float]:
    """Dip and dip direction (degrees) of the plane with ``normal`` (any sign); a
    vertical plane takes the side of ``toward`` (docs/zones.md)."""
    dip, dd = dip_and_direction(np.asarray(normal, dtype=np.float64)[None], toward)
    return float(dip[0]), float(dd[0])


def region_plane(points: PointCloud | np.ndarray, which: np.ndarray | None = None, *,
                 toward: np.ndarray | None = None) -> PlaneMeasure:
    """The ODR plane of a cloud's points (those selected by ``which``: a boolean mask
    or an index array), with its dip, dip direction and RMS residual.

    Parameters
    ----------
    points : PointCloud or (N, 3) array
        Metres.
    which : array, optional
        The selected points (all when None); at least 3, not all on one line.
    toward : (3,) array, optional
        The viewer's side, for a vertical plane (the whole-cloud normal, as the cell
        and zone tables use: ``result.whole_plane.normal``).

    Returns
    -------
    PlaneMeasure
    """
    x, y, z = as_columns(points)
    if which is not None:
        sel = np.asarray(which)
        x, y, z = x[sel], y[sel], z[sel]
    n = int(x.shape[0])
    if n < 3:
        raise InputError(f"a plane needs at least 3 selected points, got {n}")
    require(8.0 * 7 * n, f"the plane of {n:,} selected points")
    xyz = np.column_stack([x, y, z])
    ref = xyz[0].copy()  # UTM-sized coordinates: fit relative to a point of the set
    fit = fit_plane(xyz - ref)
    if not fit.eigenvalues[1] > 1e-12 * max(float(fit.eigenvalues[0]), 1e-300):
        raise InputError(f"the {n:,} selected points lie on a line (or one spot): no plane")
    normal = orient_normals(fit.normal[None], toward)[0]
    residual = (xyz - ref - fit.centroid) @ normal
    dip, dd = plane_orientation(normal, toward)
    return PlaneMeasure(centroid=fit.centroid + ref, normal=normal, dip_deg=dip,
                        dip_direction_deg=dd, rms_m=float(np.sqrt(np.mean(residual**2))),
                        max_abs_m=float(np.max(np.abs(residual))), n_points=n)
