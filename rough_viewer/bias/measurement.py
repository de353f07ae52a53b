"""Scanner bias: range noise, beam effective radius, point-population normalisation.

Measurements from scans of calibration objects (docs/science.md section 3, after the
TLS instrument-bias paper in ``papers/tls-instrument-bias-roughness.txt``):

- :func:`range_noise`: a flat board split into equal segments (default 8), a plane
  per segment, standard deviation of all residuals; per-segment values expose a
  curved board.
- :func:`effective_radius`: a thin taut wire; a line fit, residuals orthogonal to
  the plane through the line and the scanner, mean of the top 2 % magnitudes.
- :func:`fit_piecewise_linear`: effective radius against range, two linear
  pieces joined at a break point (least squares, or given).
- :func:`classify_population`, :func:`normalise_population`: asperity / background
  classes from 1-D K-means on plane residuals with the 3-sigma reclassification,
  then random removal of background points to a fixed ratio before the roughness.
- :func:`target_roughness`: roughness of a whole target as one cell (ODR plane).

The simulation of rough targets lives in :mod:`rough_viewer.bias.simulation`.
All lengths are metres. Functions raise ``ValueError`` for unusable input.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from rough_viewer.grid.planes import fit_plane
from rough_viewer.vocabulary import BIAS_RESIDUAL, InputError, Residual

ClassMethod = Literal["kmeans", "kmeans-3sigma"]

__all__ = [
    "BoardSegment",
    "ClassMethod",
    "Classification",
    "ClassificationScores",
    "EffectiveRadius",
    "NormalisedPopulation",
    "PiecewiseLinearFit",
    "RangeNoise",
    "Residual",
    "classification_scores",
    "classify_population",
    "effective_radius",
    "fit_piecewise_linear",
    "kmeans_1d",
    "normalise_population",
    "range_noise",
    "segment_layout",
    "target_roughness",
]


def _as_points(xyz: np.ndarray, *, minimum: int, what: str) -> np.ndarray:
    pts = np.asarray(xyz, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise InputError(f"{what} needs an (N, 3) array of points, got shape {pts.shape}")
    if pts.shape[0] < minimum:
        raise InputError(f"{what} needs at least {minimum} points, got {pts.shape[0]}")
    if not np.all(np.isfinite(pts)):
        raise InputError(f"{what} got non-finite coordinates")
    return pts


def _orient(normal: np.ndarray, centroid: np.ndarray, scanner: np.ndarray | None,
            residuals: np.ndarray | None = None) -> np.ndarray:
    """Flip ``normal`` to point toward the scanner.

    Without a scanner position: toward the side with the longer residual tail
    (positive third moment), where asperities stand out of a flat background;
    without residuals either, toward the positive side of its largest component.
    """
    if scanner is not None:
        s = float(np.dot(np.asarray(scanner, dtype=np.float64) - centroid, normal))
        return normal if s >= 0 else -normal
    if residuals is not None and residuals.size:
        skew = float(np.mean((residuals - residuals.mean()) ** 3))
        if skew != 0.0:
            return normal if skew > 0 else -normal
    return normal if normal[int(np.argmax(np.abs(normal)))] >= 0 else -normal


# --------------------------------------------------------------------------------------
# Roughness of a whole target


def target_roughness(xyz: np.ndarray, *, residual: Residual = BIAS_RESIDUAL) -> float:
    """Roughness of a whole target treated as one cell, metres.

    The ODR plane of all points (:func:`rough_viewer.grid.planes.fit_plane`), then the
    population standard deviation of the orthogonal distances to it.

    Parameters
    ----------
    xyz : (N, 3) array
        Points, metres.
    residual : {"signed", "absolute"}
        ``"signed"`` (default, :data:`rough_viewer.vocabulary.BIAS_RESIDUAL`): standard
        deviation of the signed distances (their RMS, as the mean is zero), the
        instrument-bias paper's own definition (5.07 mm for its target A).
        ``"absolute"``: standard deviation of the absolute distances
        ``|n . (p - c)|``, the grid-roughness convention of docs/science.md section 1.

    Returns
    -------
    float
        Roughness, metres.
    """
    pts = _as_points(xyz, minimum=3, what="target_roughness")
    fit = fit_plane(pts)
    d = (pts - fit.centroid) @ fit.normal
    if residual == "absolute":
        return float(np.abs(d).std())
    if residual == "signed":
        return float(d.std())
    raise InputError(f"residual must be 'absolute' or 'signed', got {residual!r}")


# --------------------------------------------------------------------------------------
# Range noise from a flat board


@dataclass(frozen=True)
class BoardSegment:
    """One segment of a board scan and its own plane."""

    row: int
    """Index along the board's long in-plane axis (0 .. rows-1)."""
    col: int
    """Index along the board's short in-plane axis (0 .. cols-1)."""
    n_points: int
    """Points in the segment."""
    sigma: float
    """Standard deviation of the residuals to the segment's plane, metres."""
    offset: float
    """Mean signed distance of the segment's points to the whole-board plane, metres
    (positive toward the scanner). A bowed board shows a pattern: centre segments on
    one side, edge segments on the other."""
    tilt_deg: float
    """Angle between the segment's normal and the whole-board normal, degrees."""
    centre: np.ndarray
    """(3,) centroid of the segment's points, metres."""


@dataclass(frozen=True)
class RangeNoise:
    """Rangefinder noise measured on a flat board."""

    sigma: float
    """Standard deviation of all residuals, each point to its own segment's plane,
    metres: the range noise."""
    sigma_single_plane: float
    """Standard deviation of the residuals to one plane through the whole board,
    metres. Well above ``sigma`` means the board is curved."""
    n_points: int
    """Points used (after any random subsample)."""
    shape: tuple[int, int]
    """Segments along the long and the short in-plane axis (rows, cols)."""
    segments: tuple[BoardSegment, ...]
    """Per-segment values, row-major."""
    normal: np.ndarray
    """(3,) unit normal of the whole-board plane, toward the scanner when known."""
    warnings: tuple[str, ...] = ()
    """Plausibility warnings (one line each) when the scan does not look like a flat
    board: the range noise of a rough or curved surface measures its shape."""


def segment_layout(n_segments: int, long_m: float, short_m: float) -> tuple[int, int]:
    """Split ``n_segments`` equal segments into rows x cols with the squarest cells.

    Parameters
    ----------
    n_segments : int
        Number of segments (the paper: 8).
    long_m, short_m : float
        Extents of the board along its long and short in-plane axes, metres.

    Returns
    -------
    (rows, cols)
        ``rows * cols == n_segments``; rows along the long axis.
    """
    if n_segments < 1:
        raise InputError(f"segments must be >= 1, got {n_segments}")
    best: tuple[float, int, int] | None = None
    # every divisor pair (d, n / d) with d <= sqrt(n), both ways round: O(sqrt(n))
    small = [d for d in range(1, math.isqrt(n_segments) + 1) if n_segments % d == 0]
    divisors = sorted(set(small + [n_segments // d for d in small]))
    for rows in divisors:
        cols = n_segments // rows
        a = long_m / rows
        b = short_m / cols
        score = abs(math.log(a / b)) if a > 0 and b > 0 else float(rows == 1)
        if best is None or score < best[0] - 1e-12:
            best = (score, rows, cols)
    assert best is not None
    return best[1], best[2]


def range_noise(
    xyz: np.ndarray,
    *,
    segments: int | tuple[int, int] = 8,
    scanner: np.ndarray | tuple[float, float, float] | None = None,
    max_points: int | None = None,
    seed: int | None = 0,
) -> RangeNoise:
    """Range noise from the scan of a flat board (the paper found 1.6 mm).

    The points are put in the board's own frame (principal axes of the whole-board
    fit), split into equal rectangles over the board's extent, an ODR plane is fitted
    to each, and the standard deviation of all signed residuals (each to its own
    segment's plane) is the noise. Segmenting removes the effect of a slight,
    long-radius curvature of the board.

    Parameters
    ----------
    xyz : (N, 3) array
        Board points, metres, cropped to the board.
    segments : int or (rows, cols)
        Number of equal segments (laid out as the squarest grid, see
        :func:`segment_layout`), or the grid itself (rows along the long axis).
    scanner : (3,) array, optional
        Scanner position, metres; orients normals and offsets toward it.
    max_points : int, optional
        Use a random subsample of this many points (the paper: 180 000).
    seed : int, optional
        Seed of the subsample.

    Returns
    -------
    RangeNoise
    """
    pts = _as_points(xyz, minimum=3, what="range_noise")
    n_seg = (int(segments[0]) * int(segments[1]) if isinstance(segments, tuple)
             else int(segments))
    if n_seg < 1:
        raise InputError(f"segments must be positive, got {segments}")
    n_use = pts.shape[0] if max_points is None else min(pts.shape[0], int(max_points))
    # checked before the per-segment arrays (which grow with the segment count) exist
    if 3 * n_seg > n_use:
        raise InputError(f"{n_seg:,} segments need at least {3 * n_seg:,} points, 3 each "
                         f"(a plane needs at least 3), but there are {n_use:,}; use fewer "
                         "segments")
    if max_points is not None and pts.shape[0] > max_points:
        rng = np.random.default_rng(seed)
        pts = pts[rng.choice(pts.shape[0], size=max_points, replace=False)]
    whole = fit_plane(pts)
    axes = whole.axes
    d_whole = (pts - whole.centroid) @ whole.normal
    normal = _orient(whole.normal, whole.centroid,
                     None if scanner is None else np.asarray(scanner, dtype=np.float64))
    if not np.array_equal(normal, whole.normal):
        d_whole = -d_whole
    u = (pts - whole.centroid) @ axes[:, 0]
    v = (pts - whole.centroid) @ axes[:, 1]
    lu = float(u.max() - u.min())
    lv = float(v.max() - v.min())
    if isinstance(segments, tuple):
        rows, cols = (int(segments[0]), int(segments[1]))
        if rows < 1 or cols < 1:
            raise InputError(f"segments must be positive, got {segments}")
    else:
        rows, cols = segment_layout(int(segments), lu, lv)
    iu = np.clip(((u - u.min()) / (lu if lu > 0 else 1.0) * rows).astype(np.int64), 0, rows - 1)
    iv = np.clip(((v - v.min()) / (lv if lv > 0 else 1.0) * cols).astype(np.int64), 0, cols - 1)
    seg = iu * cols + iv
    order = np.argsort(seg, kind="stable")
    counts = np.bincount(seg, minlength=rows * cols)
    if np.any(counts < 3):
        bad = int(np.argmin(counts))
        raise InputError(
            f"segment {bad // cols},{bad % cols} has {counts[bad]} points; "
            "a plane needs at least 3 (use fewer segments)"
        )
    residual = np.empty(pts.shape[0])
    centred = np.empty(pts.shape[0])
    parts: list[BoardSegment] = []
    bounds = np.concatenate(([0], np.cumsum(counts)))
    # One plane per segment: a loop over the (few) segments, not over points.
    for k in range(rows * cols):
        idx = order[bounds[k]:bounds[k + 1]]
        sp = pts[idx]
        fit = fit_plane(sp)
        n_k = fit.normal if np.dot(fit.normal, normal) >= 0 else -fit.normal
        r = (sp - fit.centroid) @ n_k
        residual[idx] = r
        centred[idx] = r - np.median(r)  # for the MAD sigma: a board's flat part sits at
        # one offset from a plane that objects on it pull away
        cosang = min(1.0, abs(float(np.dot(n_k, normal))))
        parts.append(BoardSegment(
            row=k // cols, col=k % cols, n_points=int(idx.size), sigma=float(r.std()),
            offset=float(d_whole[idx].mean()), tilt_deg=math.degrees(math.acos(cosang)),
            centre=fit.centroid,
        ))
    return RangeNoise(
        sigma=float(residual.std()),
        sigma_single_plane=float(d_whole.std()),
        n_points=int(pts.shape[0]),
        shape=(rows, cols),
        segments=tuple(parts),
        normal=normal,
        warnings=flatness_warnings(float(residual.std()), whole.eigenvalues,
                                   max(p.tilt_deg for p in parts),
                                   robust_sigma=float(np.median(np.abs(centred))) / 0.6745),
    )


#: A board is called flat when the residual std stays under this share of its
#: shorter in-plane extent (std), and no segment tilts more than FLAT_MAX_TILT_DEG.
FLAT_MAX_THICKNESS = 0.02
FLAT_MAX_TILT_DEG = 10.0
#: Range noise is near normal (std / MAD sigma about 1); above this ratio the residuals
#: are a spike and a tail, a board carrying objects.
HEAVY_TAIL_RATIO = 2.0
#: A wire is called thin when its second extent (std) stays under this share of its
#: length (std).
WIRE_MAX_WIDTH = 0.1


def flatness_warnings(sigma: float, eigenvalues: np.ndarray, max_tilt_deg: float, *,
                      robust_sigma: float | None = None) -> tuple[str, ...]:
    """Why a range-noise scan may not be a flat board (empty when it looks like one).

    ``sigma`` is the segmented residual std (metres), ``eigenvalues`` the whole
    cloud's covariance eigenvalues (descending, m^2), ``max_tilt_deg`` the largest
    segment tilt against the whole plane, ``robust_sigma`` the residuals' MAD sigma
    (``median |r - median_segment(r)| / 0.6745``, metres). The paper's board (0.61 x 1.24 m, 1.6 mm
    noise) gives a thickness ratio of about 0.01 and tilts of a degree or two; range
    noise is close to normal, so its std and MAD sigma agree (a ratio near 1), while
    a board carrying objects has most residuals near 0 and a tail of large ones.

    >>> flatness_warnings(0.0048, np.array([0.083, 0.083, 2e-5]), 0.5, robust_sigma=0.0001)[0][:40]
    'the residuals (std 4.80 mm) are 48 times'
    >>> flatness_warnings(0.0016, np.array([0.13, 0.031, 3e-6]), 1.5, robust_sigma=0.0016)
    ()
    """
    out = []
    if robust_sigma is not None and sigma > HEAVY_TAIL_RATIO * max(robust_sigma, 0.0):
        times = sigma / robust_sigma if robust_sigma > 0 else math.inf
        out.append(f"the residuals (std {sigma * 1e3:.2f} mm) are {times:.0f} times their "
                   f"median spread (MAD sigma {robust_sigma * 1e3:.3g} mm): not the normal "
                   "noise of a flat board but a surface carrying objects (asperities, "
                   "hemispheres) or several surfaces; crop it to the bare board")
    short = math.sqrt(max(float(eigenvalues[1]), 0.0))
    ratio = sigma / short if short > 0 else math.inf
    if ratio > FLAT_MAX_THICKNESS:
        out.append(f"the residuals ({sigma * 1e3:.2f} mm) are {ratio * 100:.1f} % of the "
                   f"scan's shorter in-plane extent (std {short * 1e3:.1f} mm): this does not "
                   "look like a flat board, and its 'noise' measures the surface's shape")
    if max_tilt_deg > FLAT_MAX_TILT_DEG:
        out.append(f"segment planes tilt up to {max_tilt_deg:.1f} degrees against the whole "
                   "plane: the scan is not flat (a rough or folded surface, or more than one "
                   "object); crop it to the board")
    return tuple(out)


def wire_warnings(eigenvalues: np.ndarray) -> tuple[str, ...]:
    """Why an effective-radius scan may not be a thin wire (empty when it looks like
    one): its second principal extent should be a small share of its length."""
    length = math.sqrt(max(float(eigenvalues[0]), 0.0))
    width = math.sqrt(max(float(eigenvalues[1]), 0.0))
    ratio = width / length if length > 0 else math.inf
    if ratio > WIRE_MAX_WIDTH:
        return (f"the points are not a thin line: their second extent (std "
                f"{width * 1e3:.1f} mm) is {ratio * 100:.0f} % of their length (std "
                f"{length * 1e3:.1f} mm); the effective radius of a surface measures its "
                "width, not the beam; crop the scan to the wire",)
    return ()


# --------------------------------------------------------------------------------------
# Effective radius from a wire


@dataclass(frozen=True)
class EffectiveRadius:
    """Beam effective radius measured on the scan of a thin wire."""

    effective_radius: float
    """Mean of the top ``top_fraction`` of the residual magnitudes, minus the wire
    radius if one was given, metres."""
    range: float
    """Distance from the scanner to the centroid of the wire points, metres."""
    top_fraction: float
    """Fraction of the largest residuals averaged (the paper: 0.02)."""
    n_points: int
    """Wire points."""
    n_top: int
    """Points in the top fraction."""
    residual_std: float
    """Standard deviation of the residuals, metres."""
    wire_radius: float
    """Wire radius subtracted, metres (0 = the paper's raw value)."""
    centroid: np.ndarray
    """(3,) centroid of the wire points, metres."""
    direction: np.ndarray
    """(3,) unit direction of the fitted line."""
    plane_normal: np.ndarray
    """(3,) unit normal of the plane through the line and the scanner."""
    warnings: tuple[str, ...] = ()
    """Plausibility warnings (one line each) when the points do not look like a thin
    wire: the effective radius of a surface measures its width, not the beam."""


def effective_radius(
    xyz: np.ndarray,
    *,
    scanner: np.ndarray | tuple[float, float, float] = (0.0, 0.0, 0.0),
    top_fraction: float = 0.02,
    wire_radius: float = 0.0,
) -> EffectiveRadius:
    """Beam effective radius (ER) from the scan of a thin taut wire.

    A 3-D line is fitted to the points (least squares: through the centroid along
    the principal axis); the residuals are the distances of the points to the plane
    through that line and the scanner, i.e. across both the wire and the view
    direction; ER is the mean of the largest ``top_fraction`` of their magnitudes.

    Parameters
    ----------
    xyz : (N, 3) array
        Wire points, metres, cropped to the wire.
    scanner : (3,) array
        Scanner position in the same frame, metres (the origin for a scan in its
        own frame).
    top_fraction : float
        Fraction of largest residual magnitudes averaged, in (0, 1]; the paper: 0.02.
    wire_radius : float
        Subtracted from the result, metres; the paper subtracted nothing.

    Returns
    -------
    EffectiveRadius
    """
    pts = _as_points(xyz, minimum=3, what="effective_radius")
    if not 0.0 < top_fraction <= 1.0:
        raise InputError(f"top_fraction must be in (0, 1], got {top_fraction}")
    s = np.asarray(scanner, dtype=np.float64).reshape(3)
    line = fit_plane(pts)
    centroid = line.centroid
    direction = line.axes[:, 0]
    to_line = centroid - s
    m = np.cross(direction, to_line)
    norm = float(np.linalg.norm(m))
    if norm <= 1e-9 * max(1.0, float(np.linalg.norm(to_line))):
        raise InputError("the scanner lies on the wire's line; no plane through both")
    m = m / norm
    r = (pts - centroid) @ m
    mag = np.abs(r)
    n_top = max(1, int(math.ceil(top_fraction * mag.size - 1e-9)))
    top = np.partition(mag, mag.size - n_top)[mag.size - n_top:]
    return EffectiveRadius(
        effective_radius=float(top.mean()) - float(wire_radius),
        range=float(np.linalg.norm(to_line)),
        top_fraction=float(top_fraction),
        n_points=int(pts.shape[0]),
        n_top=int(n_top),
        residual_std=float(r.std()),
        wire_radius=float(wire_radius),
        centroid=centroid,
        direction=direction,
        plane_normal=m,
        warnings=wire_warnings(line.eigenvalues),
    )


# --------------------------------------------------------------------------------------
# Piecewise-linear radius against range


@dataclass(frozen=True)
class PiecewiseLinearFit:
    """Two linear pieces joined at a break point: ``y = a + b x + c max(x - x_b, 0)``."""

    break_range: float
    """Break point, metres of range."""
    intercept: float
    """Value of the near piece at range 0, metres."""
    slope_near: float
    """Slope below the break (metres of radius per metre of range)."""
    slope_far: float
    """Slope above the break."""
    rmse: float
    """Root mean square residual, metres."""
    n: int
    """Number of (range, radius) pairs."""
    break_given: bool
    """True if the break was given, False if chosen by least squares."""

    def predict(self, range_m: np.ndarray | float) -> np.ndarray:
        """Radius at the given range(s), metres."""
        x = np.asarray(range_m, dtype=np.float64)
        return (self.intercept + self.slope_near * x
                + (self.slope_far - self.slope_near) * np.maximum(x - self.break_range, 0.0))


def _hinge_sse(x: np.ndarray, y: np.ndarray, breaks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares hinge fits for many break points at once: (SSE (K,), coef (K, 3))."""
    k = breaks.size
    a = np.empty((k, x.size, 3))
    a[:, :, 0] = 1.0
    a[:, :, 1] = x
    a[:, :, 2] = np.maximum(x[None, :] - breaks[:, None], 0.0)
    coef = np.einsum("kij,j->ki", np.linalg.pinv(a), y)
    res = y[None, :] - np.einsum("kij,kj->ki", a, coef)
    return (res * res).sum(axis=1), coef


def fit_piecewise_linear(
    range_m: np.ndarray,
    radius_m: np.ndarray,
    *,
    break_range: float | None = None,
    candidates: int = 200,
) -> PiecewiseLinearFit:
    """Continuous two-piece linear fit of radius against range.

    Parameters
    ----------
    range_m, radius_m : (N,) arrays
        Pairs of scan range and measured effective radius, metres (N >= 4).
    break_range : float, optional
        Break point, metres. Without it the break minimising the sum of squared
        residuals is searched between the second-smallest and second-largest range
        (a grid of ``candidates`` values plus every data range, then refined).
    candidates : int
        Grid size of the search.

    Returns
    -------
    PiecewiseLinearFit
    """
    x = np.asarray(range_m, dtype=np.float64).ravel()
    y = np.asarray(radius_m, dtype=np.float64).ravel()
    if x.size != y.size:
        raise InputError("range and radius must have the same length")
    if x.size < 4:
        raise InputError(f"a piecewise-linear fit needs at least 4 ranges, got {x.size}")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise InputError("range and radius must be finite")
    xs = np.sort(x)
    given = break_range is not None
    if given:
        xb = float(break_range)  # type: ignore[arg-type]
    else:
        lo, hi = float(xs[1]), float(xs[-2])
        if not hi > lo:
            raise InputError("ranges too few distinct values to place a break point")
        grid = np.unique(np.concatenate((np.linspace(lo, hi, candidates), xs[1:-1])))
        sse, _ = _hinge_sse(x, y, grid)
        i = int(np.argmin(sse))
        left = grid[max(i - 1, 0)]
        right = grid[min(i + 1, grid.size - 1)]
        xb = float(grid[i])
        if right > left:
            from scipy.optimize import minimize_scalar  # here: not on every import of bias

            opt = minimize_scalar(lambda b: float(_hinge_sse(x, y, np.array([b]))[0][0]),
                                  bounds=(float(left), float(right)), method="bounded",
                                  options={"xatol": 1e-6 * max(1.0, hi - lo)})
            if opt.fun <= sse[i]:
                xb = float(opt.x)
    sse_b, coef = _hinge_sse(x, y, np.array([xb]))
    a, b, c = coef[0]
    return PiecewiseLinearFit(
        break_range=xb, intercept=float(a), slope_near=float(b), slope_far=float(b + c),
        rmse=float(math.sqrt(sse_b[0] / x.size)), n=int(x.size), break_given=given,
    )


# --------------------------------------------------------------------------------------
# Classification of asperity and background points


def kmeans_1d(values: np.ndarray) -> tuple[float, float, float]:
    """Two-cluster K-means of 1-D values, solved exactly.

    In one dimension the two clusters of an optimum are split by a threshold, so
    every split of the sorted values is scored at once with cumulative sums and the
    best one (least within-cluster sum of squares) is taken: the global optimum,
    which iterative K-means reaches from a good start.

    Parameters
    ----------
    values : (N,) array
        N >= 2 values.

    Returns
    -------
    (threshold, low_mean, high_mean)
        Values ``> threshold`` form the high cluster; ``threshold`` is midway
        between the two clusters' nearest members.
    """
    v = np.sort(np.asarray(values, dtype=np.float64).ravel())
    n = v.size
    if n < 2:
        raise InputError("kmeans_1d needs at least 2 values")
    if v[0] == v[-1]:
        raise InputError("kmeans_1d: all values are equal, no two clusters")
    c = np.cumsum(v)
    k = np.arange(1, n)
    left = c[:-1]
    right = c[-1] - left
    score = left * left / k + right * right / (n - k)
    # Only splits between distinct values are real splits.
    score[v[1:] == v[:-1]] = -np.inf
    i = int(np.argmax(score))
    threshold = 0.5 * (v[i] + v[i + 1])
    return float(threshold), float(left[i] / (i + 1)), float(right[i] / (n - i - 1))


@dataclass(frozen=True)
class Classification:
    """Asperity / background classes of the points of a rough target."""

    asperity: np.ndarray
    """(N,) bool: True for asperity (node) points."""
    residual: np.ndarray
    """(N,) signed distance to the ODR plane of all points, positive toward the
    scanner, metres."""
    threshold: float
    """K-means split of ``residual``, metres."""
    n_reclassified: int
    """Background points moved to the asperity class by the n-sigma step."""
    noise_sigma: float
    """Range noise used by the n-sigma step, metres (NaN for plain K-means)."""
    method: ClassMethod
    """``"kmeans"`` or ``"kmeans-3sigma"``."""


def classify_population(
    xyz: np.ndarray,
    *,
    noise_sigma: float | None = None,
    method: ClassMethod = "kmeans-3sigma",
    n_sigma: float = 3.0,
    scanner: np.ndarray | tuple[float, float, float] | None = None,
) -> Classification:
    """Split a target's points into asperity and background by their plane residuals.

    1-D K-means with two clusters (:func:`kmeans_1d`) on the signed residuals to the
    ODR plane of all points; the cluster toward the scanner is the asperity class.
    With ``method="kmeans-3sigma"`` a plane is then fitted to the background cluster
    and every background point more than ``n_sigma`` noise sigmas from it toward the
    scanner moves to the asperity class (the paper's reclassification).

    Parameters
    ----------
    xyz : (N, 3) array
        Target points, metres.
    noise_sigma : float, optional
        Range noise, metres (the paper: 0.0016). Without it, the robust sigma of the
        background cluster's residuals (1.4826 x median absolute deviation).
    method : {"kmeans", "kmeans-3sigma"}
    n_sigma : float
        Reclassification distance in noise sigmas (the paper: 3).
    scanner : (3,) array, optional
        Scanner position, metres; without it "toward the scanner" is the side of the
        longer residual tail (asperities stand out of a flat board).

    Returns
    -------
    Classification
    """
    pts = _as_points(xyz, minimum=4, what="classify_population")
    if method not in ("kmeans", "kmeans-3sigma"):
        raise InputError(f"method must be 'kmeans' or 'kmeans-3sigma', got {method!r}")
    sc = None if scanner is None else np.asarray(scanner, dtype=np.float64).reshape(3)
    fit = fit_plane(pts)
    r = (pts - fit.centroid) @ fit.normal
    normal = _orient(fit.normal, fit.centroid, sc, r)
    if not np.array_equal(normal, fit.normal):
        r = -r
    threshold, _, _ = kmeans_1d(r)
    asperity = r > threshold
    moved = 0
    sigma = float("nan")
    if method == "kmeans-3sigma":
        bg = np.flatnonzero(~asperity)
        if bg.size >= 3:
            bfit = fit_plane(pts[bg])
            bn = bfit.normal if np.dot(bfit.normal, normal) >= 0 else -bfit.normal
            rb = (pts[bg] - bfit.centroid) @ bn
            if noise_sigma is None:
                sigma = float(1.4826 * np.median(np.abs(rb - np.median(rb))))
            else:
                sigma = float(noise_sigma)
            if not (math.isfinite(sigma) and sigma >= 0):
                raise InputError(f"noise sigma must be a finite value >= 0, got {noise_sigma}")
            # A floor of 1 nm keeps rounding error of a noise-free board in place.
            up = bg[rb > max(n_sigma * sigma, 1e-9)]
            asperity[up] = True
            moved = int(up.size)
    return Classification(asperity=asperity, residual=r, threshold=threshold,
                          n_reclassified=moved, noise_sigma=sigma, method=method)


@dataclass(frozen=True)
class ClassificationScores:
    """The paper's classification scores against known (a priori) classes."""

    x_score: float
    """Percentage of the a-priori asperity points assigned to the asperity class."""
    y_score: float
    """Percentage of the points assigned to the asperity class that are a-priori
    background."""


def classification_scores(truth: np.ndarray, predicted: np.ndarray) -> ClassificationScores:
    """X and Y scores (percent) of a classification against known classes.

    Parameters
    ----------
    truth, predicted : (N,) bool arrays
        True = asperity (node) point.
    """
    t = np.asarray(truth, dtype=bool).ravel()
    p = np.asarray(predicted, dtype=bool).ravel()
    if t.shape != p.shape:
        raise InputError("truth and predicted must have the same length")
    nt = int(t.sum())
    npred = int(p.sum())
    x = 100.0 * int((t & p).sum()) / nt if nt else float("nan")
    y = 100.0 * int((~t & p).sum()) / npred if npred else float("nan")
    return ClassificationScores(x_score=x, y_score=y)


# --------------------------------------------------------------------------------------
# Point-population normalisation


@dataclass(frozen=True)
class NormalisedPopulation:
    """A target's points thinned to a fixed background : asperity ratio."""

    keep: np.ndarray
    """(M,) int64 indices of the kept points (all asperity points and a random
    subset of background points), ascending."""
    n_asperity: int
    """Asperity points (all kept)."""
    n_background: int
    """Background points kept."""
    native_ratio: float
    """Background : asperity ratio before thinning."""
    ratio: float
    """Ratio after thinning (the target ratio, or less if there were too few
    background points)."""
    roughness: float
    """Roughness of the kept points (refitted plane), metres."""
    roughness_before: float
    """Roughness of all points, metres."""
    residual: Residual
    """Residual convention of both roughness values."""


def normalise_population(
    xyz: np.ndarray,
    asperity: np.ndarray,
    *,
    ratio: float = 5.0,
    seed: int | np.random.Generator | None = 0,
    residual: Residual = BIAS_RESIDUAL,
) -> NormalisedPopulation:
    """Remove background points at random to a fixed background : asperity ratio, refit.

    Parameters
    ----------
    xyz : (N, 3) array
        Target points, metres.
    asperity : (N,) bool array
        Class of each point (known, or from :func:`classify_population`).
    ratio : float
        Background points kept per asperity point (the paper: 5).
    seed : int or numpy Generator, optional
        Randomness of the removal.
    residual : {"signed", "absolute"}
        See :func:`target_roughness` (default signed, the bias paper's definition).

    Returns
    -------
    NormalisedPopulation
    """
    pts = _as_points(xyz, minimum=3, what="normalise_population")
    a = np.asarray(asperity, dtype=bool).ravel()
    if a.size != pts.shape[0]:
        raise InputError("asperity must have one value per point")
    if not (math.isfinite(float(ratio)) and ratio > 0):
        raise InputError(f"ratio must be a finite number > 0, got {ratio}")
    n_asp = int(a.sum())
    bg = np.flatnonzero(~a)
    if n_asp == 0:
        raise InputError("no asperity points: nothing to normalise against")
    if bg.size == 0:
        raise InputError("no background points: nothing to normalise")
    n_keep = min(bg.size, int(round(ratio * n_asp)))
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    kept_bg = rng.choice(bg, size=n_keep, replace=False)
    keep = np.sort(np.concatenate((np.flatnonzero(a), kept_bg)))
    return NormalisedPopulation(
        keep=keep, n_asperity=n_asp, n_background=int(n_keep),
        native_ratio=bg.size / n_asp, ratio=n_keep / n_asp,
        roughness=target_roughness(pts[keep], residual=residual),
        roughness_before=target_roughness(pts, residual=residual),
        residual=residual,
    )
