"""Exact fractional Brownian motion profiles by circulant embedding (Davies-Harte),
an exact anisotropic fractional Brownian sheet and isotropic fractal surfaces.

Used by the tests and demos of the roughness-length method: a profile of known Hurst
exponent ``H`` has fractal dimension ``D = 2 - H``; a sheet has one exponent along x
and another along y (:func:`fbm_sheet`), a surface the same in every direction
(:func:`fbm_surface`).

The increments of fBm sampled at a regular spacing are fractional Gaussian noise with
autocovariance ``g(k) = sigma^2 spacing^(2H) / 2 (|k+1|^2H - 2|k|^2H + |k-1|^2H)``.
Embedding that Toeplitz covariance in a circulant matrix of size ``2n`` (whose
eigenvalues are non-negative for fGn at every H in (0, 1)) gives exact Gaussian samples
with one FFT; the cumulative sum of the increments is the fBm.
"""

from __future__ import annotations

import numpy as np

from rough_viewer.memory import require
from rough_viewer.vocabulary import InputError


def fgn_autocovariance(n: int, hurst: float) -> np.ndarray:
    """Autocovariance ``g(0..n-1)`` of unit-variance fractional Gaussian noise."""
    k = np.arange(n, dtype=float)
    two_h = 2.0 * hurst
    return 0.5 * (np.abs(k + 1) ** two_h - 2.0 * k**two_h + np.abs(k - 1) ** two_h)


def fbm_profile(
    n: int,
    hurst: float,
    *,
    spacing: float = 1e-3,
    sigma: float = 1e-3,
    rng: np.random.Generator | int | None = None,
) -> np.ndarray:
    """Sample a fractional Brownian motion profile exactly.

    Parameters
    ----------
    n
        Number of samples (>= 2).
    hurst
        Hurst exponent H, 0 < H < 1.
    spacing
        Sample spacing, metres.
    sigma
        Standard deviation of the height increment over one metre, metres; the
        increment over a lag ``r`` has standard deviation ``sigma * r**H``.
    rng
        NumPy generator or seed.

    Returns
    -------
    np.ndarray
        (n,) heights in metres, starting at 0.
    """
    if not 0.0 < hurst < 1.0:
        raise InputError(f"hurst must be in (0, 1), got {hurst}")
    if n < 2:
        raise InputError(f"need at least 2 samples, got {n}")
    gen = np.random.default_rng(rng)
    m = n - 1  # number of increments
    lam = _circulant_fgn_eigenvalues(m, hurst)
    size = lam.size
    z = gen.standard_normal(size) + 1j * gen.standard_normal(size)
    w = np.fft.fft(np.sqrt(lam / size) * z)
    incr = w.real[:m] * (sigma * spacing**hurst)
    return np.concatenate([[0.0], np.cumsum(incr)])


def _circulant_fgn_eigenvalues(m: int, hurst: float) -> np.ndarray:
    """Eigenvalues (size 2m, all >= 0) of the circulant embedding of the covariance
    of ``m`` unit fractional Gaussian noise increments."""
    g = fgn_autocovariance(m + 1, hurst)
    row = np.concatenate([g[: m + 1], g[m - 1 : 0 : -1]])
    lam = np.fft.fft(row).real
    lam[lam < 0] = 0.0  # round-off only
    return lam


def fbm_sheet(
    shape: tuple[int, int],
    hurst_x: float,
    hurst_y: float,
    *,
    spacing: float = 1e-3,
    sigma: float = 1e-3,
    rng: np.random.Generator | int | None = None,
) -> np.ndarray:
    """An anisotropic fractional Brownian surface: a fractional Brownian sheet with
    Hurst exponent ``hurst_x`` along x (the columns, axis 1) and ``hurst_y`` along y
    (the rows, axis 0), sampled exactly.

    The sheet ``B(x, y)`` has covariance ``prod_i (|s_i|^2H_i + |t_i|^2H_i -
    |s_i - t_i|^2H_i) / 2``: every row is a fractional Brownian motion in x with
    exponent ``hurst_x`` and every column one in y with ``hurst_y``, so profiles along
    x have ``D = 2 - hurst_x`` and profiles along y ``D = 2 - hurst_y``. Its increments
    are the tensor product of two fractional Gaussian noises, sampled by a 2-D
    circulant embedding whose eigenvalues are the products of the two 1-D ones (all
    non-negative: exact), and summed along both axes.

    A sheet is zero along its two axes and its amplitude grows away from them (a row
    at distance ``y`` from the x axis has increments ``sigma_x y^hurst_y`` times
    those of unit fBm), so the surface returned is the far quadrant of a sheet twice
    as large in each direction: across it the amplitude of rows (columns) changes by
    at most a factor ``2^hurst_y`` (``2^hurst_x``), which leaves every exponent as it is.

    Parameters
    ----------
    shape
        ``(rows, columns)`` of the surface returned, each >= 2.
    hurst_x, hurst_y
        Hurst exponents along x and y, each in (0, 1).
    spacing
        Grid spacing along both axes, metres.
    sigma
        Scale, metres: the increment of one grid step along x at unit distance (one
        metre) from the x axis has standard deviation ``sigma spacing^hurst_x``.
    rng
        NumPy generator or seed.

    Returns
    -------
    np.ndarray
        (rows, columns) heights, metres; row ``i`` lies at ``y = i spacing``, column
        ``j`` at ``x = j spacing``.

    Examples
    --------
    >>> z = fbm_sheet((65, 65), 0.3, 0.8, rng=0)
    >>> z.shape
    (65, 65)
    """
    rows, cols = (int(s) for s in shape)
    for name, h in (("hurst_x", hurst_x), ("hurst_y", hurst_y)):
        if not 0.0 < h < 1.0:
            raise InputError(f"{name} must be in (0, 1), got {h}")
    if rows < 2 or cols < 2:
        raise InputError(f"need at least 2 x 2 samples, got {rows} x {cols}")
    my, mx = 2 * rows - 1, 2 * cols - 1  # increments of the sheet twice as large
    require(16.0 * 4 * my * mx * 3, f"an fBm sheet of {2 * rows} x {2 * cols} samples")
    gen = np.random.default_rng(rng)
    lam = np.outer(_circulant_fgn_eigenvalues(my, hurst_y), _circulant_fgn_eigenvalues(mx, hurst_x))
    z = gen.standard_normal(lam.shape) + 1j * gen.standard_normal(lam.shape)
    w = np.fft.fft2(np.sqrt(lam / lam.size) * z).real[:my, :mx]
    w *= sigma * spacing**hurst_x * spacing**hurst_y
    sheet = np.zeros((my + 1, mx + 1))
    sheet[1:, 1:] = np.cumsum(np.cumsum(w, axis=0), axis=1)
    return sheet[rows:, cols:].copy()


def fbm_surface(
    shape: tuple[int, int],
    hurst: float,
    *,
    spacing: float = 1e-3,
    rms: float = 1e-3,
    rng: np.random.Generator | int | None = None,
) -> np.ndarray:
    """An isotropic fractal surface by spectral synthesis (approximate fBm).

    Fourier amplitudes ``|k|^-(hurst + 1)`` (the power spectrum of a 2-D fBm surface,
    ``|k|^-(2 hurst + 2)``) with random phases, transformed back to heights on a
    periodic grid; every direction has the same statistics, so profiles in any
    direction share one exponent, about ``hurst`` (spectral synthesis is not exact:
    use :func:`fbm_profile` or :func:`fbm_sheet` where the exponent itself is tested).

    Parameters
    ----------
    shape
        ``(rows, columns)``, each >= 2.
    hurst
        Hurst exponent, in (0, 1).
    spacing
        Grid spacing, metres (the heights do not depend on it: ``rms`` sets them).
    rms
        Root mean square height of the surface returned, metres.
    rng
        NumPy generator or seed.

    Returns
    -------
    np.ndarray
        (rows, columns) heights, metres, mean zero.
    """
    rows, cols = (int(s) for s in shape)
    if not 0.0 < hurst < 1.0:
        raise InputError(f"hurst must be in (0, 1), got {hurst}")
    if rows < 2 or cols < 2:
        raise InputError(f"need at least 2 x 2 samples, got {rows} x {cols}")
    require(16.0 * 4 * rows * cols, f"a fractal surface of {rows} x {cols} samples")
    gen = np.random.default_rng(rng)
    ky = np.fft.fftfreq(rows, d=spacing)[:, None]
    kx = np.fft.fftfreq(cols, d=spacing)[None, :]
    k = np.hypot(kx, ky)
    k[0, 0] = np.inf  # no mean
    amp = k ** -(hurst + 1.0)
    coef = amp * (gen.standard_normal((rows, cols)) + 1j * gen.standard_normal((rows, cols)))
    z = np.fft.ifft2(coef).real
    z -= z.mean()
    return z * (rms / float(np.sqrt(np.mean(z * z))))
