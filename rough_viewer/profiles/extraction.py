"""Roughness profile along a line picked on a point cloud (Khoshelham & Altundag, sec. 2).

Steps, with every choice the paper leaves open fixed here:

1. Local patch: the points within ``frame_radius`` (default a quarter of the line's
   length, at least 3 band half-widths) of the 3-D segment from ``start`` to ``end``.
2. Local principal axes (PCA) of the patch: ``normal`` = eigenvector of the smallest
   covariance eigenvalue (the ODR plane normal), signed so that its largest component
   is positive; ``along`` = the direction ``end - start`` projected into that plane;
   ``across = normal x along``. Coordinates: distance along the line measured from
   ``start``, offset across it, and height along ``normal``.
3. Band: the patch points with ``|across| <= band_half_width`` whose distance along the
   line rounds to a sample (``-spacing/2 <= along < L + spacing/2``, L = projected line
   length). Their number is ``n_points``.
4. Plane removal: the heights are the signed distances of the band points from the
   patch's ODR plane (through the patch centroid, along ``normal``). That is the
   plane the principal axes define; a least-squares plane refitted to the patch in
   this frame is zero up to round-off, and one fitted to the band alone would be
   worse: a band a few points wide cannot fix the across slope, the roughness itself
   would leak into it.
5. Resampling at ``distance = 0, spacing, 2 spacing, ...`` up to the sample nearest
   to the end point (``round(L / spacing) + 1`` samples): the band points are
   binned to their nearest sample; each occupied bin gives its mean distance and mean
   residual height; the samples are linearly interpolated between consecutive bin
   means. A stretch between bin means longer than ``max_gap`` (default 3 spacings) is
   NOT interpolated: its samples are NaN (except within half a spacing of a bin mean,
   which take that bin's height; at the two ends of the data, the line through the two
   outermost bin means) and the data-free interval is listed in ``gaps``;
   so are the ends of the line that lie more than half a spacing beyond the first or
   last bin mean.

Defaults from the local point spacing ``point_spacing`` = the median distance from the
patch points to their 4th nearest neighbour, measured in the patch plane (along and
across coordinates, so range noise does not inflate it; for large patches, among the
50000 points closest to the line; about the grid step of a regular scan,
``1.08 / sqrt(density)`` for randomly placed points): ``spacing = point_spacing`` and
``band_half_width = point_spacing``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from rough_viewer.grid.planes import fit_plane
from rough_viewer.grid.spacing import neighbour_distance
from rough_viewer.io.cloud import as_xyz
from rough_viewer.memory import require
from rough_viewer.vocabulary import InputError

_SPACING_NEIGHBOUR = 4
_SPACING_SAMPLE = 5000
_STRIP_POINTS = 50000
DEFAULT_MAX_GAP_SPACINGS = 3.0

#: Bytes per profile sample at the peak of resampling (positions, heights, counts,
#: bin sums and the interpolation's temporaries; measured with tracemalloc: 85-88).
#: What is done with the profile afterwards costs more: see
#: :data:`rough_viewer.profiles.comparison.COMPARISON_BYTES_PER_SAMPLE` and
#: :data:`rough_viewer.profiles.profile_sets.DIRECTION_BYTES_PER_SAMPLE`.
PROFILE_BYTES_PER_SAMPLE = 12 * 8


@dataclass(frozen=True)
class LocalFrame:
    """Principal axes of the patch around the line (file frame, metres)."""

    origin: np.ndarray
    """(3,) centroid of the patch points."""
    along: np.ndarray
    """(3,) unit vector along the line, in the patch plane."""
    across: np.ndarray
    """(3,) unit vector ``normal x along``."""
    normal: np.ndarray
    """(3,) unit normal of the patch's ODR plane (height direction)."""
    eigenvalues: np.ndarray
    """(3,) covariance eigenvalues of the patch, descending, m^2."""
    n_points: int
    """Number of points in the patch."""
    radius: float
    """Patch radius around the segment, metres."""

    def rotation(self) -> np.ndarray:
        """(3, 3) matrix whose rows are ``along, across, normal``."""
        return np.vstack([self.along, self.across, self.normal])


@dataclass(frozen=True)
class Profile:
    """A roughness profile: residual heights at a regular spacing along a line."""

    distance: np.ndarray
    """(K,) distance of each sample from ``start`` along the line, metres."""
    heights: np.ndarray
    """(K,) residual heights (plane removed), metres; NaN inside gaps."""
    counts: np.ndarray
    """(K,) number of band points binned to each sample."""
    spacing: float
    """Sample spacing, metres."""
    band_half_width: float
    """Half-width of the band of points around the line, metres."""
    max_gap: float
    """Longest stretch without points that is interpolated across, metres."""
    point_spacing: float
    """Estimated local point spacing (median 4th-neighbour distance in the patch
    plane), metres."""
    n_points: int
    """Number of points in the band (used for the profile)."""
    point_index: np.ndarray
    """(n_points,) indices of those points in the input array."""
    gaps: tuple[tuple[float, float], ...]
    """Data-free intervals (from, to) along the line, metres, whose samples are NaN."""
    start: np.ndarray
    """(3,) line start as given, file frame, metres."""
    end: np.ndarray
    """(3,) line end as given, file frame, metres."""
    length: float
    """Length of the line projected into the patch plane, metres."""
    frame: LocalFrame
    """Local principal axes used; heights are measured from the plane through
    ``frame.origin`` with normal ``frame.normal``."""

    def sample_xyz(self, heights: np.ndarray | None = None) -> np.ndarray:
        """(K, 3) file-frame positions of the samples on the surface, metres.

        ``heights`` (K,) replaces the profile's residual heights (e.g. a de-noised
        version); NaN heights give NaN rows. Inverse of the extraction's mapping: the
        point at ``distance`` on the line, across offset 0, ``height`` above the plane.
        """
        h = self.heights if heights is None else np.asarray(heights, dtype=float)
        if h.shape != self.distance.shape:
            raise ValueError(f"heights must have shape {self.distance.shape}, got {h.shape}")
        f = self.frame
        offset = float((self.start - f.origin) @ f.normal)
        return self.start + self.distance[:, None] * f.along + (h - offset)[:, None] * f.normal

    @property
    def n_gap_samples(self) -> int:
        """Number of NaN samples."""
        return int(np.count_nonzero(~np.isfinite(self.heights)))


# ----------------------------------------------------------------------------- helpers


def _as_point(p: Any, name: str) -> np.ndarray:
    a = np.asarray(p, dtype=float).ravel()
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise InputError(f"{name} must be three finite coordinates, got {p!r}")
    return a


def positive_length(value: float | None, name: str) -> float | None:
    """``value`` as a float, or None; InputError unless it is a finite length > 0
    (``name`` the setting, for the message)."""
    if value is None:
        return None
    v = float(value)
    if not np.isfinite(v) or v <= 0:
        raise InputError(f"{name} must be a positive length in metres, got {value!r}")
    return v


def segment_distance(xyz: np.ndarray, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """Euclidean distance (metres) of each point to the segment ``start``-``end``."""
    d = end - start
    t = np.clip(((xyz - start) @ d) / float(d @ d), 0.0, 1.0)
    return np.linalg.norm(xyz - start - t[:, None] * d, axis=1)


def point_spacing(xyz: np.ndarray, *, k: int = _SPACING_NEIGHBOUR) -> float:
    """Median distance from the points (N, 2 or 3) to their ``k``-th nearest neighbour,
    metres (:func:`rough_viewer.grid.spacing.neighbour_distance`, the one definition).

    At most 5000 evenly strided points are queried (against all points).
    """
    return neighbour_distance(xyz, k=k)


def _strip_spacing(along: np.ndarray, across: np.ndarray) -> float:
    """Point spacing near the line: with more than 50000 patch points, the neighbour
    search uses the 50000 closest to the line (a strip tens of spacings wide) and
    queries the inner half of them, so the cost does not grow with the patch."""
    xy = np.column_stack([along, across])
    if xy.shape[0] <= _STRIP_POINTS:
        return point_spacing(xy)
    dist = np.abs(across)
    strip = np.argpartition(dist, _STRIP_POINTS - 1)[:_STRIP_POINTS]
    tree = cKDTree(xy[strip])
    inner = strip[dist[strip] <= np.median(dist[strip])]
    step = max(1, inner.size // _SPACING_SAMPLE)
    d, _ = tree.query(xy[inner[::step]], k=_SPACING_NEIGHBOUR + 1)
    value = float(np.median(d[:, _SPACING_NEIGHBOUR]))
    if not value > 0:
        raise InputError("points are coincident: cannot estimate the point spacing")
    return value


def local_frame(patch: np.ndarray, start: np.ndarray, end: np.ndarray, radius: float) -> LocalFrame:
    """Principal axes of ``patch`` with ``along`` following ``end - start`` (see module doc)."""
    fit = fit_plane(patch)
    centroid = fit.centroid
    normal = fit.normal
    normal = normal * (1.0 if normal[np.argmax(np.abs(normal))] > 0 else -1.0)
    d = end - start
    along = d - (d @ normal) * normal
    norm = float(np.linalg.norm(along))
    if norm < 0.1 * float(np.linalg.norm(d)):
        angle = np.degrees(np.arccos(min(1.0, norm / float(np.linalg.norm(d)))))
        raise InputError(
            f"the line is nearly perpendicular to the local surface ({angle:.0f} degrees "
            "from it): no profile along it"
        )
    along = along / norm
    across = np.cross(normal, along)
    return LocalFrame(
        origin=centroid,
        along=along,
        across=across,
        normal=normal,
        eigenvalues=fit.eigenvalues,
        n_points=int(patch.shape[0]),
        radius=float(radius),
    )


def resample_band(
    along: np.ndarray, height: np.ndarray, n_samples: int, spacing: float, max_gap: float
) -> tuple[np.ndarray, np.ndarray, tuple[tuple[float, float], ...]]:
    """Bin, average and interpolate band points onto ``n_samples`` samples at
    ``0, spacing, ...`` (step 5 of the module docstring).

    ``along`` (M,) are the points' distances along the line from its start, metres,
    each rounding to a sample (``-spacing/2 <= along < (n_samples - 1/2) spacing``);
    ``height`` (M,) their residual heights. Returns ``(heights, counts, gaps)``:
    (n_samples,) heights (NaN in gaps longer than ``max_gap``), points per sample
    and the data-free intervals.
    """
    bins = np.rint(along / spacing).astype(np.int64)
    counts = np.bincount(bins, minlength=n_samples)
    occupied = np.flatnonzero(counts)
    mean_a = np.bincount(bins, weights=along, minlength=n_samples)[occupied] / counts[occupied]
    mean_h = np.bincount(bins, weights=height, minlength=n_samples)[occupied] / counts[occupied]
    s = np.arange(n_samples) * spacing
    out = np.interp(s, mean_a, mean_h)
    j = np.searchsorted(mean_a, s, side="right")  # mean_a[j-1] <= s < mean_a[j]
    inside = (j > 0) & (j < mean_a.size)
    jl = np.clip(j - 1, 0, mean_a.size - 1)
    jr = np.clip(j, 0, mean_a.size - 1)
    bridged = inside & (mean_a[jr] - mean_a[jl] <= max_gap)
    bridged |= (j == mean_a.size) & (s == mean_a[-1])
    nearest = np.where(np.abs(s - mean_a[jl]) <= np.abs(mean_a[jr] - s), jl, jr)
    near = np.abs(s - mean_a[nearest]) <= 0.5 * spacing
    # beyond the first / last bin mean (by at most half a spacing): extend the line
    # through the two outermost bin means when they are close enough, else hold the value
    held = mean_h[nearest]
    if mean_a.size >= 2:
        for i, k in ((0, 1), (-1, -2)):
            run = mean_a[k] - mean_a[i]
            if abs(run) <= max_gap:
                side = (s < mean_a[0]) if i == 0 else (s > mean_a[-1])
                slope = (mean_h[k] - mean_h[i]) / run
                held = np.where(side, mean_h[i] + slope * (s - mean_a[i]), held)
    out = np.where(bridged, out, np.where(near, held, np.nan))
    gaps: list[tuple[float, float]] = []
    if not (np.isfinite(out[0])):
        gaps.append((0.0, float(mean_a[0])))
    wide = np.flatnonzero(np.diff(mean_a) > max_gap)
    gaps.extend((float(mean_a[i]), float(mean_a[i + 1])) for i in wide)
    if not (np.isfinite(out[-1])):
        gaps.append((float(mean_a[-1]), float(s[-1])))
    return out, counts, tuple(gaps)


# ----------------------------------------------------------------------------- public


def patch_radius(length: float, band_half_width: float | None = None,
                 frame_radius: float | None = None) -> float:
    """Radius (metres) around a line of ``length`` metres of the patch
    :func:`extract_profile` reads: ``frame_radius``, by default ``max(L / 4, 3
    band_half_width)``.

    >>> patch_radius(8.0), patch_radius(8.0, 1.0), patch_radius(8.0, 1.0, 0.5)
    (2.0, 3.0, 0.5)
    """
    if frame_radius is not None:
        return float(frame_radius)
    return max(0.25 * float(length), 3.0 * band_half_width if band_half_width is not None else 0.0)


def patch_box(start: Any, end: Any, *, band_half_width: float | None = None,
              frame_radius: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The box (lowest and highest corners, metres) that holds every point
    :func:`extract_profile` may use for the line from ``start`` to ``end``: the
    line's box grown by :func:`patch_radius` (a cloud too big to hold gives only
    these points; the profile is the same).

    >>> lo, hi = patch_box([0, 0, 0], [4, 0, 0])
    >>> lo.tolist(), hi.tolist()
    ([-1.0, -1.0, -1.0], [5.0, 1.0, 1.0])
    """
    p0, p1 = _as_point(start, "start"), _as_point(end, "end")
    radius = patch_radius(float(np.linalg.norm(p1 - p0)),
                          positive_length(band_half_width, "band_half_width"),
                          positive_length(frame_radius, "frame_radius"))
    return np.minimum(p0, p1) - radius, np.maximum(p0, p1) + radius


def extract_profile(
    points: Any,
    start: Any,
    end: Any,
    *,
    band_half_width: float | None = None,
    spacing: float | None = None,
    max_gap: float | None = None,
    frame_radius: float | None = None,
) -> Profile:
    """Extract a roughness profile between two points picked on a cloud.

    Parameters
    ----------
    points
        (N, 3) coordinates in metres, or a PointCloud (anything with ``.xyz()``).
    start, end
        Line end points (3,), metres, file frame; normally picked on the surface.
    band_half_width
        Points within this distance across the line are used, metres; default the
        local point spacing.
    spacing
        Sample spacing along the line, metres; default the local point spacing.
    max_gap
        Longest stretch without points that is interpolated across, metres; default
        3 sample spacings. Longer gaps give NaN samples and are listed in ``gaps``.
    frame_radius
        Radius around the segment of the patch that defines the local principal axes,
        metres; default ``max(L / 4, 3 band_half_width)``.

    Returns
    -------
    Profile
        Regularly spaced residual heights with the frame, band and gaps used.

    Raises
    ------
    ValueError
        Degenerate line, or too few points near it.

    Examples
    --------
    A tilted plane with a 1 mm sine ripple along x: the profile along x recovers the
    ripple once the plane is removed.

    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> x, y = rng.uniform(0.0, 1.0, (2, 200_000))
    >>> z = 0.3 * x + 0.001 * np.sin(2 * np.pi * x / 0.1)
    >>> prof = extract_profile(np.column_stack([x, y, z]), (0.1, 0.5, 0.03), (0.9, 0.5, 0.27))
    >>> # heights are normal to the plane: rms of the ripple = cos(atan(0.3)) / sqrt(2) mm
    >>> round(float(np.nanstd(prof.heights)) * 1e3, 2)
    0.67
    """
    xyz = as_xyz(points)
    p0 = _as_point(start, "start")
    p1 = _as_point(end, "end")
    length3 = float(np.linalg.norm(p1 - p0))
    if length3 <= 0:
        raise InputError("start and end are the same point")
    band = positive_length(band_half_width, "band_half_width")
    step = positive_length(spacing, "spacing")
    gap = positive_length(max_gap, "max_gap")
    radius = patch_radius(length3, band, positive_length(frame_radius, "frame_radius"))

    # Patch: cheap bounding-box cut, then exact distance to the segment.
    lo = np.minimum(p0, p1) - radius
    hi = np.maximum(p0, p1) + radius
    box = np.flatnonzero(np.all((xyz >= lo) & (xyz <= hi), axis=1))
    near = segment_distance(xyz[box], p0, p1) <= radius
    patch_index = box[near]
    if patch_index.size < _SPACING_NEIGHBOUR + 1:
        raise InputError(
            f"only {patch_index.size} points within {radius:.4g} m of the line: "
            "pick the line on the surface"
        )
    patch = xyz[patch_index]
    frame = local_frame(patch, p0, p1, radius)
    rel = patch - p0
    along = rel @ frame.along
    across = rel @ frame.across
    spacing_est = _strip_spacing(along, across)
    step = spacing_est if step is None else step
    band = spacing_est if band is None else band
    gap = DEFAULT_MAX_GAP_SPACINGS * step if gap is None else gap

    height = (patch - frame.origin) @ frame.normal
    length = float((p1 - p0) @ frame.along)
    n_samples = int(np.rint(length / step)) + 1
    if n_samples < 2:
        raise InputError(f"line ({length:.4g} m) shorter than one sample spacing ({step:.4g} m)")
    require(n_samples * PROFILE_BYTES_PER_SAMPLE, f"a profile of {n_samples:,} samples at "
            f"{step:.4g} m", hint="choose a larger spacing or a shorter line")
    in_band = (np.abs(across) <= band) & (along >= -0.5 * step)
    in_band &= np.rint(along / step) <= n_samples - 1
    if np.count_nonzero(in_band) < 3:
        raise InputError(
            f"only {np.count_nonzero(in_band)} points within {band:.4g} m of the line: "
            "widen the band"
        )
    a = along[in_band]
    resid = height[in_band]  # distance from the patch's ODR plane: the plane removed
    heights, counts, gaps = resample_band(a, resid, n_samples, step, gap)
    return Profile(
        distance=np.arange(n_samples) * step,
        heights=heights,
        counts=counts,
        spacing=float(step),
        band_half_width=float(band),
        max_gap=float(gap),
        point_spacing=spacing_est,
        n_points=int(a.size),
        point_index=patch_index[in_band],
        gaps=gaps,
        start=p0,
        end=p1,
        length=length,
        frame=frame,
    )


def regular_samples(
    distance: np.ndarray,
    heights: np.ndarray,
    *,
    spacing: float | None = None,
    max_gap: float | None = None,
) -> tuple[np.ndarray, np.ndarray, tuple[tuple[float, float], ...]]:
    """Put a measured profile (e.g. from a profile gauge) on a regular spacing.

    Parameters
    ----------
    distance
        (K,) strictly increasing distances along the profile, metres.
    heights
        (K,) heights, metres; rows with NaN heights are dropped.
    spacing
        Output spacing, metres; default the median step of ``distance``.
    max_gap
        Longest step interpolated across, metres; default 3 spacings.

    Returns
    -------
    (distance, heights, gaps)
        A profile already regular at ``spacing`` (every step within 1e-6 relative) is
        returned unchanged; otherwise it is resampled exactly like an extracted
        profile (nearest-sample bins, linear interpolation, NaN and a listed gap where
        a step exceeds ``max_gap``), starting at the first distance.
    """
    d = np.asarray(distance, dtype=float).ravel()
    h = np.asarray(heights, dtype=float).ravel()
    if d.shape != h.shape:
        raise InputError("distance and heights differ in length")
    if not np.all(np.isfinite(d)):
        raise InputError("distances must be finite")
    keep = np.isfinite(h)
    d, h = d[keep], h[keep]
    if d.size < 2:
        raise InputError("a profile needs at least 2 samples with a finite height")
    steps = np.diff(d)
    if np.any(steps <= 0):
        raise InputError("distances must be strictly increasing")
    step = positive_length(spacing, "spacing") or float(np.median(steps))
    gap = positive_length(max_gap, "max_gap") or DEFAULT_MAX_GAP_SPACINGS * step
    if keep.all() and np.all(np.abs(steps - step) <= 1e-6 * step):
        return d, h, ()
    rel = d - d[0]
    n_samples = int(np.rint(rel[-1] / step)) + 1
    inside = np.rint(rel / step) <= n_samples - 1
    out, _, gaps = resample_band(rel[inside], h[inside], n_samples, step, gap)
    shifted = tuple((a + d[0], b + d[0]) for a, b in gaps)
    return d[0] + np.arange(n_samples) * step, out, shifted
