"""Scanner geometry shared by the synthetic scans: rays on a regular angular grid.

A terrestrial laser scanner sends rays on a regular grid of azimuth and elevation
angles with a fixed angular step. Here the azimuth ``phi`` is measured in the
horizontal plane from the +y axis towards +x, and the elevation ``theta`` from the
horizontal plane upwards, so a scanner looking along +y at a face parallel to the xz
plane sees ``phi = theta = 0`` straight ahead.
"""

from __future__ import annotations

import numpy as np


def angles_of(points: np.ndarray, scanner: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Azimuth and elevation (radians) and range (metres) of points seen from ``scanner``.

    Parameters
    ----------
    points : (N, 3) array, metres.
    scanner : (3,) array, metres.
    """
    d = np.asarray(points, dtype=np.float64) - np.asarray(scanner, dtype=np.float64)
    horiz = np.hypot(d[:, 0], d[:, 1])
    phi = np.arctan2(d[:, 0], d[:, 1])
    theta = np.arctan2(d[:, 2], horiz)
    rng = np.sqrt(horiz * horiz + d[:, 2] * d[:, 2])
    return phi, theta, rng


def directions(phi: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Unit ray directions (N, 3) for azimuth ``phi`` and elevation ``theta`` (radians)."""
    ct = np.cos(theta)
    return np.column_stack([ct * np.sin(phi), ct * np.cos(phi), np.sin(theta)])


def ray_grid(
    phi_range: tuple[float, float], theta_range: tuple[float, float], step_rad: float
) -> tuple[np.ndarray, np.ndarray]:
    """Every ray of the scanner's angular grid inside the given angle ranges.

    The grid is anchored at zero (angles ``k * step_rad`` for integers ``k``), so the
    same ray always has the same angles whatever window is asked for. Rays come in
    scan order: one vertical scan line (all elevations, bottom to top) per azimuth.

    Returns
    -------
    phi, theta : (M,) arrays of ray angles in radians.
    """
    k0 = int(np.floor(phi_range[0] / step_rad))
    k1 = int(np.ceil(phi_range[1] / step_rad))
    j0 = int(np.floor(theta_range[0] / step_rad))
    j1 = int(np.ceil(theta_range[1] / step_rad))
    kk, jj = np.meshgrid(np.arange(k0, k1 + 1), np.arange(j0, j1 + 1), indexing="ij")
    return kk.ravel() * step_rad, jj.ravel() * step_rad


def nearest_per_pixel(key: np.ndarray, rng: np.ndarray) -> np.ndarray:
    """Index of the nearest sample (smallest range) for every distinct pixel key.

    This is a z-buffer: of all surface samples falling in one scanner pixel, only the
    one closest to the scanner is seen; the others are in its shadow. The result is
    sorted by key, i.e. in scan order.
    """
    order = np.lexsort((rng, key))
    k = key[order]
    first = np.ones(k.shape[0], dtype=bool)
    first[1:] = k[1:] != k[:-1]
    return order[first]


def intensity_of(
    rng: np.ndarray, cos_incidence: np.ndarray, *, reflectance: float | np.ndarray, noise: np.ndarray
) -> np.ndarray:
    """A plausible 16-bit return intensity: reflectance x cos(incidence) / range^0.5.

    Real scanners compress the 1/R^2 fall-off; this keeps a visible, gentle fall-off
    with range and incidence. ``noise`` is a multiplicative factor array (~1).
    """
    val = reflectance * np.clip(cos_incidence, 0.05, 1.0) / np.sqrt(np.maximum(rng, 1.0))
    val = val * noise
    return np.clip(np.round(val * 65535.0 / 0.25), 0, 65535).astype(np.uint16)
