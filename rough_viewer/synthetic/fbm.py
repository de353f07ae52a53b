"""Exact fractional Brownian motion profiles by circulant embedding (Davies-Harte).

Used by the tests and demos of the roughness-length method: a profile of known Hurst
exponent ``H`` has fractal dimension ``D = 2 - H``.

The increments of fBm sampled at a regular spacing are fractional Gaussian noise with
autocovariance ``g(k) = sigma^2 spacing^(2H) / 2 (|k+1|^2H - 2|k|^2H + |k-1|^2H)``.
Embedding that Toeplitz covariance in a circulant matrix of size ``2n`` (whose
eigenvalues are non-negative for fGn at every H in (0, 1)) gives exact Gaussian samples
with one FFT; the cumulative sum of the increments is the fBm.
"""

from __future__ import annotations

import numpy as np

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
    g = fgn_autocovariance(m + 1, hurst)
    row = np.concatenate([g[: m + 1], g[m - 1 : 0 : -1]])  # circulant first row, size 2m
    lam = np.fft.fft(row).real
    lam[lam < 0] = 0.0  # round-off only; exact values are >= 0 for fGn
    size = row.size
    z = gen.standard_normal(size) + 1j * gen.standard_normal(size)
    w = np.fft.fft(np.sqrt(lam / size) * z)
    incr = w.real[:m] * (sigma * spacing**hurst)
    return np.concatenate([[0.0], np.cumsum(incr)])
