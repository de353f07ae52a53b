"""Roughness-length method (Malinverno 1990) for profiles and patches.

Definitions (``SCIENCE.md`` section 2, with the details the paper leaves open fixed
here):

- A window of ``m`` consecutive samples spans ``w = (m - 1) * spacing`` metres (the
  distance from its first to its last sample). Patches use square windows of
  ``m x m`` samples, also of side ``w = (m - 1) * spacing``.
- In every window the heights are detrended by least squares (a line for a profile, a
  plane for a patch) and their standard deviation is taken as the root mean square of
  the residuals (population form, dividing by the number of samples in the window).
- ``s(w)`` is the mean of that standard deviation over ALL windows of that size at
  every sample offset (sliding windows, step one sample); windows that contain a NaN
  sample are left out.
- ``s = A w^H`` is fitted by least squares on ``ln s`` against ``ln w``; ``H`` is the
  slope, ``A = exp(intercept)`` (so ``A`` is in metres^(1-H): it depends on the length
  unit, ``H`` does not); ``D = 2 - H`` for a profile and ``3 - H`` for a patch; ``r2``
  is the coefficient of determination of that fit.
- Default windows: 8 lengths evenly spaced from 3 % to 10 % of the profile length
  ``(K - 1) * spacing`` (for a patch, of its shorter side), each rounded to a whole
  number of samples (at least 3); duplicates after rounding are dropped.

No value is clipped: heavily smoothed profiles can give ``H > 1`` and ``D < 1``, as in
the paper's tables.

Windowed sums come from cumulative sums (summed-area tables for patches), so the cost
is O(samples) per window size.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from rough_viewer.vocabulary import InputError

DEFAULT_FRACTIONS = np.linspace(0.03, 0.10, 8)


@dataclass(frozen=True)
class RoughnessLength:
    """Result of the roughness-length method."""

    hurst: float
    """Hurst exponent H (slope of ln s against ln w)."""
    dimension: float
    """Fractal dimension D = 2 - H (profile) or 3 - H (patch)."""
    amplitude: float
    """Amplitude A of ``s = A w^H`` with w and s in metres (unit metres^(1-H))."""
    r2: float
    """Coefficient of determination of the log-log fit."""
    windows: np.ndarray
    """(M,) window lengths w actually used, metres: ``(m - 1) * spacing``."""
    window_samples: np.ndarray
    """(M,) window sizes m in samples (per side for a patch)."""
    s: np.ndarray
    """(M,) mean detrended standard deviation s(w), metres."""
    n_windows: np.ndarray
    """(M,) number of windows averaged for each size."""
    spacing: float
    """Sample spacing, metres."""
    ndim: Literal[1, 2]
    """1 for a profile, 2 for a patch."""
    warnings: tuple[str, ...] = ()
    """Plausibility warnings, one line each: a dimension outside ``[1, 2]`` (profile)
    or ``[2, 3]`` (patch) says the fit measured something else than roughness."""


# ----------------------------------------------------------------------------- windows


def _window_samples(
    length: float, spacing: float, windows: Sequence[float] | np.ndarray | None, n_max: int
) -> np.ndarray:
    if windows is None:
        targets = DEFAULT_FRACTIONS * length
    else:
        targets = np.asarray(windows, dtype=float).ravel()
        if targets.size == 0 or not np.all(np.isfinite(targets)) or np.any(targets <= 0):
            raise InputError("windows must be positive lengths in metres")
    m = np.rint(targets / spacing).astype(np.int64) + 1
    m = np.unique(np.clip(m, 3, None))
    m = m[m <= n_max]
    if m.size < 2:
        raise InputError(
            f"need at least 2 distinct window sizes of 3..{n_max} samples; got {m.tolist()} "
            "(profile too short for these windows?)"
        )
    return m


def _fit(
    m: np.ndarray,
    s: np.ndarray,
    counts: np.ndarray,
    spacing: float,
    ndim: Literal[1, 2],
    scale: float,
) -> RoughnessLength:
    w = (m - 1) * spacing
    # s below round-off of the input's magnitude counts as zero (e.g. a straight line)
    ok = (counts > 0) & np.isfinite(s) & (s > 1e-12 * scale)
    if ok.sum() < 2:
        raise InputError("fewer than 2 window sizes with a positive s(w): cannot fit s = A w^H")
    x = np.log(w[ok])
    y = np.log(s[ok])
    slope, intercept = np.polyfit(x, y, 1)
    pred = intercept + slope * x
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    r2 = 1.0 - float(np.sum((y - pred) ** 2)) / ss_tot if ss_tot > 0 else 1.0
    top = 2.0 if ndim == 1 else 3.0
    return RoughnessLength(
        hurst=float(slope),
        dimension=float(top - slope),
        warnings=plausibility(float(top - slope), float(slope), ndim, int(m[ok].min()),
                              int(m[ok].max())),
        amplitude=float(np.exp(intercept)),
        r2=r2,
        windows=w,
        window_samples=m,
        s=s,
        n_windows=counts,
        spacing=float(spacing),
        ndim=ndim,
    )


def plausibility(dimension: float, hurst: float, ndim: Literal[1, 2], m_min: int,
                 m_max: int) -> tuple[str, ...]:
    """Warnings for a fractal dimension outside its range (``[1, 2]`` for a profile,
    ``[2, 3]`` for a patch), with the likely cause and what to do."""
    lo = 1.0 if ndim == 1 else 2.0
    what = "profile" if ndim == 1 else "patch"
    if dimension < lo:
        return (f"fractal dimension D = {dimension:.2f} is below {lo:g} (H = {hurst:.2f} > 1): "
                f"s(w) grows faster than the window, the mark of a trend or curvature in the "
                f"{what} that each window's linear detrending does not remove (remove the trend "
                "first: profiles.fractal.detrend, or --detrend 2 on the command line), or of "
                f"a {what} smoother than its windows ({m_min}-{m_max} samples; a mesh or an "
                "over-sampled scan): use larger windows",)
    if dimension > lo + 1.0:
        return (f"fractal dimension D = {dimension:.2f} is above {lo + 1:g} (H = {hurst:.2f} < 0): "
                f"s(w) falls as the window grows, so the {what} is too short for these windows "
                f"({m_min}-{m_max} samples) or noise dominates it; use a longer {what}, larger "
                "windows or de-noise it first",)
    return ()


def detrend(heights: np.ndarray, spacing: float, *, degree: int = 2) -> np.ndarray:
    """Heights minus their least-squares polynomial trend of ``degree`` along the
    profile (NaN samples ignored in the fit and kept as NaN), metres.

    >>> x = np.arange(50) * 0.01
    >>> bool(np.allclose(detrend(3 + 2 * x + 5 * x**2, 0.01), 0.0))
    True
    """
    h = np.asarray(heights, dtype=float)
    if h.ndim != 1:
        raise InputError(f"a profile must be one-dimensional, got shape {h.shape}")
    if degree < 0:
        raise InputError(f"detrend degree must be >= 0, got {degree}")
    spacing = _check_spacing(spacing)
    x = np.arange(h.size) * spacing
    ok = np.isfinite(h)
    if np.count_nonzero(ok) <= degree:
        raise InputError(f"need more than {degree} finite samples to remove a degree-{degree} trend")
    centre, width = x[ok].mean(), max(float(np.ptp(x[ok])), spacing)
    coef = np.polynomial.polynomial.polyfit((x[ok] - centre) / width, h[ok], degree)
    return h - np.polynomial.polynomial.polyval((x - centre) / width, coef)


def _scale(a: np.ndarray) -> float:
    finite = a[np.isfinite(a)]
    return float(np.max(np.abs(finite))) if finite.size else 0.0


def _check_spacing(spacing: float) -> float:
    try:
        spacing = float(spacing)
    except (TypeError, ValueError):  # e.g. the distances array given as the spacing
        raise InputError("spacing must be one number (the sample spacing in metres), got "
                         f"{type(spacing).__name__}"
                         f"{f' of shape {np.shape(spacing)}' if np.ndim(spacing) else ''}"
                         ) from None
    if not np.isfinite(spacing) or spacing <= 0:
        raise InputError(f"spacing must be a positive length in metres, got {spacing}")
    return spacing


# ----------------------------------------------------------------------------- 1-D


def _detrend_global_1d(h: np.ndarray) -> np.ndarray:
    """Remove the least-squares line over the finite samples (conditioning only: a
    global linear trend does not change any window's detrended residuals)."""
    i = np.arange(h.size, dtype=float)
    ok = np.isfinite(h)
    if ok.sum() >= 2:
        b, a = np.polyfit(i[ok], h[ok], 1)
        return h - (a + b * i)
    return h - np.nanmean(h)


def window_std_1d(heights: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Linearly detrended RMS residual of every window of ``m`` consecutive samples.

    Returns ``(std, valid)``: (K - m + 1,) arrays; ``valid`` is False for windows
    containing a NaN (their std is NaN).
    """
    h = _detrend_global_1d(np.asarray(heights, dtype=float))
    nan = ~np.isfinite(h)
    z = np.where(nan, 0.0, h)
    idx = np.arange(z.size, dtype=float)

    def wsum(a: np.ndarray) -> np.ndarray:
        c = np.concatenate(([0.0], np.cumsum(a)))
        return c[m:] - c[:-m]

    s_h = wsum(z)
    s_hh = wsum(z * z)
    s_ih = wsum(idx * z)
    n_nan = wsum(nan.astype(float))
    start = np.arange(s_h.size, dtype=float)
    s_xh = s_ih - start * s_h  # local abscissa x = 0..m-1
    mean_h = s_h / m
    var_h = s_hh / m - mean_h**2
    cov = s_xh / m - 0.5 * (m - 1) * mean_h
    var_x = (m * m - 1) / 12.0
    res = np.clip(var_h - cov**2 / var_x, 0.0, None)
    valid = n_nan < 0.5
    std = np.where(valid, np.sqrt(res), np.nan)
    return std, valid


def roughness_length(
    heights: np.ndarray,
    spacing: float,
    *,
    windows: Sequence[float] | np.ndarray | None = None,
) -> RoughnessLength:
    """Fractal dimension of a profile by the roughness-length method.

    Parameters
    ----------
    heights
        (K,) heights at a regular spacing, metres; NaN samples (gaps) exclude the
        windows that contain them.
    spacing
        Sample spacing, metres.
    windows
        Window lengths in metres (rounded to whole samples, see the module docstring);
        default 8 lengths from 3 % to 10 % of the profile length.

    Returns
    -------
    RoughnessLength
        H, D = 2 - H, A, r2 and the s(w) points of the fit.

    Examples
    --------
    A straight line has no roughness; Brownian motion (H = 0.5) has D near 1.5.

    >>> import numpy as np
    >>> walk = np.cumsum(np.random.default_rng(0).standard_normal(20_000)) * 1e-4
    >>> round(roughness_length(walk, 0.001).dimension, 1)
    1.5
    """
    h = np.asarray(heights, dtype=float)
    if h.ndim != 1:
        raise InputError(f"a profile must be one-dimensional, got shape {h.shape}")
    spacing = _check_spacing(spacing)
    m_all = _window_samples((h.size - 1) * spacing, spacing, windows, h.size)
    s = np.full(m_all.size, np.nan)
    counts = np.zeros(m_all.size, dtype=np.int64)
    for k, m in enumerate(m_all):  # a loop over the window sizes only
        std, valid = window_std_1d(h, int(m))
        counts[k] = int(valid.sum())
        if counts[k]:
            s[k] = float(std[valid].mean())
    return _fit(m_all, s, counts, spacing, 1, _scale(h))


# ----------------------------------------------------------------------------- 2-D


def _summed(a: np.ndarray, m: int) -> np.ndarray:
    """Sums over every m x m window of a 2-D array (summed-area table)."""
    p = np.zeros((a.shape[0] + 1, a.shape[1] + 1))
    p[1:, 1:] = np.cumsum(np.cumsum(a, axis=0), axis=1)
    return p[m:, m:] - p[:-m, m:] - p[m:, :-m] + p[:-m, :-m]


def _detrend_global_2d(z: np.ndarray) -> np.ndarray:
    yy, xx = np.indices(z.shape, dtype=float)
    ok = np.isfinite(z)
    if ok.sum() >= 3:
        a = np.column_stack([np.ones(ok.sum()), xx[ok], yy[ok]])
        coef, *_ = np.linalg.lstsq(a, z[ok], rcond=None)
        return z - (coef[0] + coef[1] * xx + coef[2] * yy)
    return z - np.nanmean(z)


def window_std_2d(heights_grid: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Plane-detrended RMS residual of every m x m window of a grid.

    Returns ``(std, valid)``: (R - m + 1, C - m + 1) arrays; ``valid`` is False for
    windows containing a NaN.
    """
    z = _detrend_global_2d(np.asarray(heights_grid, dtype=float))
    nan = ~np.isfinite(z)
    z = np.where(nan, 0.0, z)
    yy, xx = np.indices(z.shape, dtype=float)
    n = float(m * m)
    s_z = _summed(z, m)
    s_zz = _summed(z * z, m)
    s_xz = _summed(xx * z, m)
    s_yz = _summed(yy * z, m)
    n_nan = _summed(nan.astype(float), m)
    r0 = np.arange(s_z.shape[0], dtype=float)[:, None]
    c0 = np.arange(s_z.shape[1], dtype=float)[None, :]
    mean_z = s_z / n
    var_z = s_zz / n - mean_z**2
    half = 0.5 * (m - 1)
    cov_x = (s_xz - c0 * s_z) / n - half * mean_z
    cov_y = (s_yz - r0 * s_z) / n - half * mean_z
    var_x = (m * m - 1) / 12.0  # = var_y; cov(x, y) = 0 on a full square window
    res = np.clip(var_z - (cov_x**2 + cov_y**2) / var_x, 0.0, None)
    valid = n_nan < 0.5
    return np.where(valid, np.sqrt(res), np.nan), valid


def roughness_length_2d(
    heights_grid: np.ndarray,
    spacing: float,
    *,
    windows: Sequence[float] | np.ndarray | None = None,
) -> RoughnessLength:
    """Fractal dimension of a gridded patch by the roughness-length method.

    Parameters
    ----------
    heights_grid
        (R, C) residual heights on a square grid of the given spacing, metres; NaN
        cells exclude the windows that contain them.
    spacing
        Grid spacing (both axes), metres.
    windows
        Square-window side lengths in metres; default 8 from 3 % to 10 % of the
        shorter side ``(min(R, C) - 1) * spacing``.

    Returns
    -------
    RoughnessLength
        H, D = 3 - H, A, r2 and the s(w) points of the fit (``ndim == 2``).
    """
    z = np.asarray(heights_grid, dtype=float)
    if z.ndim != 2:
        raise InputError(f"a patch must be a 2-D grid, got shape {z.shape}")
    spacing = _check_spacing(spacing)
    side = min(z.shape)
    m_all = _window_samples((side - 1) * spacing, spacing, windows, side)
    s = np.full(m_all.size, np.nan)
    counts = np.zeros(m_all.size, dtype=np.int64)
    for k, m in enumerate(m_all):
        std, valid = window_std_2d(z, int(m))
        counts[k] = int(valid.sum())
        if counts[k]:
            s[k] = float(std[valid].mean())
    return _fit(m_all, s, counts, spacing, 2, _scale(z))
