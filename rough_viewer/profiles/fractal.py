"""Roughness-length method (Malinverno 1990) for profiles and patches.

Definitions (docs/science.md section 2, with the details the paper leaves open fixed
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
- Default windows: 8 lengths spaced evenly in log from 3 % to 30 % of the profile
  length ``(K - 1) * spacing`` (for a patch, of its shorter side), each rounded to a
  whole number of samples (at least 3); duplicates after rounding are dropped. The
  paper's windows (8 lengths evenly spaced from 3 % to 10 %) are ``windows="paper"``.
  Why a decade rather than the paper's factor of 3.3: on the fault DEM's profiles
  (388 x 537 grid at 5.7 mm, Hurst exponents of the paper's own estimators H = 0.50
  along x and 0.76 along y, i.e. D = 1.50 and 1.24) the extracted profiles are
  smoother than the grid below a few samples (the band averages neighbouring lattice
  columns and the resampling interpolates), which steepens the short windows: with
  the paper's windows 7 of 44 extracted columns gave D < 1 (mean 1.09), with 3-30 %
  2 of 44 (mean 1.15); on the grid's own 386 rows and 536 columns 3-30 % gives mean
  D = 1.51 and 1.24 (the paper's windows 1.56 and 1.23); and on exact fractional
  Brownian motion (2048 samples) the log spacing keeps the bias (+0.01 to +0.03) and
  spread (0.05 to 0.09) of the paper's windows (``benchmarks/fault_dem_windows.py``).

No value is clipped: heavily smoothed profiles can give ``H > 1`` and ``D < 1``, as in
the paper's tables.

Windowed sums come from cumulative sums (summed-area tables for patches), so the cost
is O(samples) per window size.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from rough_viewer.vocabulary import InputError

#: Default window lengths as shares of the profile length: 8, evenly in log, 3-30 %.
DEFAULT_FRACTIONS = np.geomspace(0.03, 0.30, 8)
#: The paper's window lengths (Khoshelham & Altundag, sec. 4.3): 8, evenly, 3-10 %.
PAPER_FRACTIONS = np.linspace(0.03, 0.10, 8)
#: Named window rules, for ``windows=`` and the ``--windows`` option.
WINDOW_RULES: dict[str, np.ndarray] = {"default": DEFAULT_FRACTIONS, "paper": PAPER_FRACTIONS}

Windows = Sequence[float] | np.ndarray | str | None
"""Window lengths in metres, a rule name (``"default"``, ``"paper"``) or None (the
default)."""


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


def window_lengths(length: float, windows: Windows = None) -> np.ndarray:
    """The window lengths asked for, metres, before rounding to samples: the given
    lengths, or a rule's shares of ``length`` (the profile's length, or a patch's
    shorter side, metres).

    >>> np.round(window_lengths(1.0, "paper"), 3)
    array([0.03, 0.04, 0.05, 0.06, 0.07, 0.08, 0.09, 0.1 ])
    >>> np.round(window_lengths(1.0)[[0, -1]], 3)
    array([0.03, 0.3 ])
    """
    if windows is None or isinstance(windows, str):
        rule = "default" if windows is None else windows
        if rule not in WINDOW_RULES:
            raise InputError(f"unknown window rule {rule!r}; expected "
                             f"{' or '.join(WINDOW_RULES)} or window lengths")
        return WINDOW_RULES[rule] * float(length)
    targets = np.asarray(windows, dtype=float).ravel()
    if targets.size == 0 or not np.all(np.isfinite(targets)) or np.any(targets <= 0):
        raise InputError("windows must be positive lengths")
    return targets


def parse_windows(text: str, metres_per_unit: float = 1.0) -> Windows:
    """Windows typed by a user (the ``--windows`` option, a text field): lengths
    separated by commas in a unit of ``metres_per_unit`` metres, returned in metres,
    or ``default`` / ``paper``.

    >>> parse_windows("10, 20,40", 1e-3), parse_windows("paper")
    ((0.01, 0.02, 0.04), 'paper')
    """
    t = text.strip().lower()
    if t in WINDOW_RULES:
        return t
    try:
        values = [float(p) for p in t.replace(";", ",").split(",") if p.strip()]
    except ValueError:
        values = []
    if len(values) < 2 or not all(math.isfinite(v) and v > 0 for v in values):
        raise InputError(f"windows {text!r}: give two or more positive lengths separated by "
                         "commas (e.g. 0.05,0.1,0.2), or 'default' (3-30 % of the profile) or "
                         "'paper' (3-10 %)")
    return tuple(v * metres_per_unit for v in values)


def _window_samples(length: float, spacing: float, windows: Windows, n_max: int) -> np.ndarray:
    targets = window_lengths(length, windows)
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


def plausibility(dimension: float, hurst: float, ndim: Literal[1, 2], m_min: int = 0,
                 m_max: int = 0) -> tuple[str, ...]:
    """One line, in the words of the app's controls, for a fractal dimension outside
    its range (``[1, 2]`` for a profile, ``[2, 3]`` for a patch): what it means and
    what to try. The command line and the app show the same line. (``hurst``,
    ``m_min`` and ``m_max`` are kept for callers; the line does not need them.)

    >>> plausibility(0.93, 1.07, 1)[0]
    'D = 0.93 is below 1: the profile is smoother than rough rock at these window lengths (a mesh, an over-sampled scan or a curved profile); try larger windows or remove the trend'
    """
    del hurst, m_min, m_max
    lo = 1.0 if ndim == 1 else 2.0
    what = "profile" if ndim == 1 else "patch"
    if dimension < lo:
        return (f"D = {dimension:.2f} is below {lo:g}: the {what} is smoother than rough rock "
                f"at these window lengths (a mesh, an over-sampled scan or a curved {what}); "
                "try larger windows or remove the trend",)
    if dimension > lo + 1.0:
        return (f"D = {dimension:.2f} is above {lo + 1:g}: the {what} is too short or too noisy "
                f"for these window lengths; try larger windows, a longer {what} or de-noising",)
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


def _cumulative_1d(heights: np.ndarray) -> tuple[np.ndarray, ...]:
    """Cumulative sums (heights, squares, index x heights, NaN count; each with a
    leading 0) of a profile after the global detrend, for every window size."""
    h = _detrend_global_1d(np.asarray(heights, dtype=float))
    nan = ~np.isfinite(h)
    z = np.where(nan, 0.0, h)
    idx = np.arange(z.size, dtype=float)
    return tuple(np.concatenate(([0.0], np.cumsum(a)))
                 for a in (z, z * z, idx * z, nan.astype(float)))


def _window_std_from(sums: tuple[np.ndarray, ...], m: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`window_std_1d` from :func:`_cumulative_1d`'s sums."""
    s_h, s_hh, s_ih, n_nan = (c[m:] - c[:-m] for c in sums)
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


def window_std_1d(heights: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Linearly detrended RMS residual of every window of ``m`` consecutive samples.

    Returns ``(std, valid)``: (K - m + 1,) arrays; ``valid`` is False for windows
    containing a NaN (their std is NaN).
    """
    return _window_std_from(_cumulative_1d(heights), m)


def roughness_length(
    heights: np.ndarray,
    spacing: float,
    *,
    windows: Windows = None,
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
        Window lengths in metres (rounded to whole samples, see the module docstring),
        or a rule: ``"default"`` (also None: 8 lengths evenly in log from 3 % to 30 % of
        the profile length) or ``"paper"`` (8 lengths evenly from 3 % to 10 %).

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
    sums = _cumulative_1d(h)  # once for every window size
    for k, m in enumerate(m_all):  # a loop over the window sizes only
        std, valid = _window_std_from(sums, int(m))
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
    windows: Windows = None,
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
        Square-window side lengths in metres, or a rule as for :func:`roughness_length`
        (shares of the shorter side ``(min(R, C) - 1) * spacing``).

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
