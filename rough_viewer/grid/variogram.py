"""Experimental semivariograms of per-cell maps, exact over all pairs of cells.

Definition (2011 paper, Fig. 4; SCIENCE.md section 1)::

    gamma(k) = 1 / (2 N_k) * sum over unordered cell pairs (i, j) in bin k of (Z_i - Z_j)^2

Default binning: distances between cell centres (metres), bin ``k = 1, 2, ..., K``
holds the pairs whose distance ``d`` lies in ``[(k - 0.5) w, (k + 0.5) w)`` with bin
width ``w`` = the cell size ``g``; its lag is ``k w``. Bins run up to half the largest
extent of the map: ``K = floor(max_lag / w)`` with ``max_lag`` = half the longest
side of the bounding box of the occupied cells (``(i_max - i_min + 1) g`` on the
longest axis). With a bin width above ``2 g`` the pairs closer than ``w / 2`` fall in
no bin and are not counted.

Method. Cells sit on a regular grid, so every pair of cells differs by an integer lag
vector ``h``. With the indicator grid ``I`` (1 where a cell has a value) and the value
grid ``Z`` (0 elsewhere), for every lag vector at once::

    N(h) = sum_x I(x) I(x + h)
    S(h) = sum_x I(x) I(x + h) (Z(x + h) - Z(x))^2
         = C[I, Z^2](h) + C[I, Z^2](-h) - 2 C[Z, Z](h)

where ``C[A, B](h) = sum_x A(x) B(x + h)`` is a cross-correlation, computed with real
FFTs of zero-padded grids (no wrap-around for the lags kept). Ordered pairs are then
summed per bin of ``|h| g``; each unordered pair is seen twice (``h`` and ``-h``),
which cancels in ``gamma`` and is divided out of the pair count. This is exact: the
pair counts are whole numbers recovered by rounding, and ``gamma`` equals a
brute-force loop over all pairs to round-off (the values are centred and scaled
before the transforms to keep that round-off small). Cost: a few FFTs of the
occupied bounding box padded by the largest lag kept, not ``O(M^2)``.

The face-plane variant (:func:`face_semivariogram`) is the 2-D analogue: cell
centres are projected onto the plane of the face, rasterised at the cell size (the
mean of the cells falling into one pixel), and the same estimator runs on that
2-D grid with distances measured in the plane.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from rough_viewer.grid.maps import Plane, face_raster
from rough_viewer.vocabulary import InputError

Space = Literal["3d", "plane"]


@dataclass(frozen=True)
class Semivariogram:
    """An experimental semivariogram (all arrays have one entry per lag bin)."""

    lag: np.ndarray
    """(K,) bin centres ``k * bin_width``, metres, k = 1..K."""
    gamma: np.ndarray
    """(K,) semivariance, in the map's units squared (m^2 for roughness); NaN where
    a bin holds no pair."""
    gamma_normalised: np.ndarray
    """(K,) ``gamma / variance`` (sill near 1 for uncorrelated values); NaN where
    the variance is 0 or the bin is empty."""
    pairs: np.ndarray
    """(K,) int64, number of unordered cell pairs in each bin."""
    variance: float
    """Population variance of the map values (divides by the number of cells)."""
    n_cells: int
    """Number of cells with a finite value that entered the estimate."""
    bin_width: float
    """Width of the lag bins, metres."""
    max_lag: float
    """Largest lag asked for, metres (the last bin centre is <= this)."""
    space: Space
    """``"3d"``: distances between cell centres in space; ``"plane"``: distances in
    the plane of the face after projection and rasterisation."""


def semivariogram(
    ijk: np.ndarray,
    values: np.ndarray,
    cell_size: float,
    *,
    bin_width: float | None = None,
    max_lag: float | None = None,
    space: Space = "3d",
    workers: int | None = None,
) -> Semivariogram:
    """Experimental semivariogram of a map on a regular grid, exact over all pairs.

    Parameters
    ----------
    ijk : (M, D) int array, D = 2 or 3
        Integer cell indices (any origin; only differences matter). Each row must be
        a distinct cell.
    values : (M,) float
        The map value of each cell (e.g. roughness in metres); NaN or inf marks a
        missing value (the cell is left out).
    cell_size : float
        Cell edge ``g``, metres; the distance of two cells is ``g * |ijk_a - ijk_b|``.
    bin_width : float, optional
        Width ``w`` of the lag bins, metres; default ``cell_size``. Bin k holds
        distances in ``[(k - 0.5) w, (k + 0.5) w)``.
    max_lag : float, optional
        Largest bin centre, metres; default half the longest side of the bounding
        box of the cells with a value. Bins ``k = 1 .. floor(max_lag / w)``.
    space : {"3d", "plane"}
        Label stored in the result (say ``"plane"`` when ``ijk`` are face-plane
        pixels); the computation is the same.
    workers : int, optional
        Threads for :mod:`scipy.fft` (default: all cores).

    Returns
    -------
    Semivariogram
        With no bins (K = 0) when fewer than two cells have a value.
    """
    ijk = np.asarray(ijk)
    values = np.asarray(values, dtype=np.float64)
    if ijk.ndim != 2 or ijk.shape[1] not in (2, 3):
        raise InputError(f"ijk must have shape (M, 2) or (M, 3), got {ijk.shape}")
    if values.shape != (ijk.shape[0],):
        raise InputError(f"values must have shape ({ijk.shape[0]},), got {values.shape}")
    if not np.issubdtype(ijk.dtype, np.integer):
        raise InputError("ijk must be an integer array of cell indices")
    g = float(cell_size)
    if not g > 0:
        raise InputError(f"cell_size must be positive, got {cell_size}")
    w = g if bin_width is None else float(bin_width)
    if not w > 0:
        raise InputError(f"bin_width must be positive, got {bin_width}")

    ok = np.isfinite(values)
    idx = ijk[ok].astype(np.int64)
    z = values[ok]
    m = int(z.size)
    variance = float(np.var(z)) if m else float("nan")

    if m:
        lo = idx.min(axis=0)
        idx = idx - lo
        shape = tuple(int(s) for s in idx.max(axis=0) + 1)
    else:
        shape = (1,) * ijk.shape[1]
    if max_lag is None:
        max_lag = 0.5 * max(shape) * g
    n_bins = int(np.floor(max_lag / w + 1e-9)) if m >= 2 else 0

    if n_bins <= 0:
        empty = np.zeros(0)
        return Semivariogram(
            lag=empty, gamma=empty, gamma_normalised=empty,
            pairs=np.zeros(0, dtype=np.int64), variance=variance, n_cells=m,
            bin_width=w, max_lag=float(max_lag), space=space,
        )

    import scipy.fft  # here, not on import: loading it costs 0.2 s of every command's start

    # Largest lag (in cells) along any axis that can fall in a bin.
    reach = int(np.floor((n_bins + 0.5) * w / g))
    lags = tuple(min(n - 1, reach) for n in shape)
    padded = tuple(scipy.fft.next_fast_len(n + lag, real=True) for n, lag in zip(shape, lags, strict=True))

    # Centre and scale so that the FFT round-off is small relative to the differences.
    scale = float(np.std(z))
    if not scale > 0:
        scale = 1.0
    zc = (z - z.mean()) / scale

    flat = np.ravel_multi_index(idx.T, padded)
    grid = np.zeros(padded)
    axes = tuple(range(len(padded)))

    def forward(a: np.ndarray) -> np.ndarray:
        return scipy.fft.rfftn(a, s=padded, axes=axes, workers=workers)

    def backward(spec: np.ndarray) -> np.ndarray:
        return scipy.fft.irfftn(spec, s=padded, axes=axes, workers=workers)

    # Window of lag vectors -lags..lags per axis (negative lags wrap around).
    window = np.ix_(*[np.r_[0 : lag + 1, -lag:0] for lag in lags])
    offsets = np.ix_(*[np.r_[0 : lag + 1, -lag:0].astype(np.float64) for lag in lags])

    grid.flat[flat] = 1.0
    f_ind = forward(grid)
    counts = np.rint(backward(f_ind * f_ind.conj())[window])

    grid.flat[flat] = zc * zc
    cross = f_ind.conj() * forward(grid)
    del f_ind
    grid.flat[flat] = zc
    f_val = forward(grid)
    cross -= f_val * f_val.conj()
    del f_val, grid
    # S(h) + S(-h) over the window; S is symmetric in h, so summing over the
    # symmetric window gives 2 * sum_bin [C_IZ2(h) - C_ZZ(h)] = sum_bin S(h).
    sums = 2.0 * backward(cross)[window]
    del cross

    h2 = sum(o * o for o in offsets)
    k = np.floor(np.sqrt(h2) * (g / w) + 0.5).astype(np.int64)
    keep = (k >= 1) & (k <= n_bins)
    kb = k[keep]
    ordered = np.bincount(kb, weights=counts[keep], minlength=n_bins + 1)[1:]
    ssum = np.bincount(kb, weights=sums[keep], minlength=n_bins + 1)[1:]

    pairs = np.rint(ordered / 2.0).astype(np.int64)
    with np.errstate(invalid="ignore", divide="ignore"):
        gamma_scaled = np.where(ordered > 0, np.maximum(ssum, 0.0) / (2.0 * ordered), np.nan)
    gamma = gamma_scaled * scale * scale
    with np.errstate(invalid="ignore", divide="ignore"):
        gamma_normalised = gamma / variance if variance > 0 else np.full(n_bins, np.nan)
    return Semivariogram(
        lag=np.arange(1, n_bins + 1) * w,
        gamma=gamma,
        gamma_normalised=gamma_normalised,
        pairs=pairs,
        variance=variance,
        n_cells=m,
        bin_width=w,
        max_lag=float(max_lag),
        space=space,
    )


def face_semivariogram(
    centres: np.ndarray,
    values: np.ndarray,
    cell_size: float,
    plane: Plane,
    *,
    bin_width: float | None = None,
    max_lag: float | None = None,
    workers: int | None = None,
) -> Semivariogram:
    """Semivariogram in the plane of the face (the 2-D analogue of :func:`semivariogram`).

    Cell centres are projected onto the 2-D axes of ``plane`` (see
    :func:`rough_viewer.grid.maps.face_raster`) and rasterised at ``cell_size``; where
    several cells fall into one pixel their values are averaged. The estimator then
    runs on the 2-D pixel grid, distances in the plane.

    Parameters
    ----------
    centres : (M, 3) float
        Cell centres, metres.
    values : (M,) float
        Map values; NaN = missing (left out before rasterising).
    cell_size : float
        Cell edge and pixel size, metres.
    plane : Plane
        Anything with ``centroid`` (3,) and unit ``normal`` (3,), e.g. the whole-cloud
        ODR plane (:class:`rough_viewer.grid.planes.PlaneFit`).
    bin_width, max_lag, workers
        As for :func:`semivariogram`.
    """
    values = np.asarray(values, dtype=np.float64)
    ok = np.isfinite(values)
    raster = face_raster(np.asarray(centres, dtype=np.float64)[ok], plane, cell_size)
    pix, inverse = np.unique(raster.pixel, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    total = np.bincount(inverse, weights=values[ok], minlength=len(pix))
    count = np.bincount(inverse, minlength=len(pix))
    mean = total / np.maximum(count, 1)
    return semivariogram(
        pix, mean, cell_size, bin_width=bin_width, max_lag=max_lag, space="plane",
        workers=workers,
    )
