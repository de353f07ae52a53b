"""Sets of parallel profiles across a face, in several directions: roughness by
direction (Hurst exponent and fractal dimension, raw and de-noised, profile RMS,
Z2 and its JRC estimate).

Definitions (``docs/directions.md`` gives them with their sources):

- Face frame: the ODR plane of the points (or of a given region of them, or a
  plane given), with the axes ``u`` ("along the face") and ``v`` ("up the face", or
  the world y axis for a near-horizontal face) of
  :func:`rough_viewer.grid.maps.face_frame`; heights are distances from that plane
  along its normal ``n`` (signed as :func:`rough_viewer.grid.planes.orient_normal`).
- Azimuth ``alpha`` (degrees): the profiles run along ``t = cos(alpha) u +
  sin(alpha) v``, counter-clockwise from ``u`` towards ``v``; 0 = along ``u``, 90 =
  along ``v``. ``alpha`` and ``alpha + 180`` are the same lines run the other way:
  every number here is the same for both (the TIN parameters of
  :mod:`rough_viewer.tin` are not).
- Profiles: centre lines at ``across = c_min + k * spacing``, k = 0, 1, ... up to
  the largest ``across`` (``across = (p - origin) . (n x t)``, ``c_min`` its lowest
  value over the points: on a grid whose row step divides the spacing, every line
  runs along a row), each taking the points within ``band_half_width`` of its line
  (bands overlap when ``spacing < 2 band_half_width``); a profile runs from its
  band's first point to its last along ``t``. The points are projected once per direction and sorted by ``across``, so
  every band is a slice of one sorted array (no pass over the cloud per profile).
- Each profile is resampled exactly as a picked profile is
  (:func:`rough_viewer.profiles.extraction.resample_band`: nearest-sample bins,
  linear interpolation, NaN across gaps longer than ``max_gap``), then its
  least-squares line is removed (the plane of a set is the face's, so the line
  takes the profile's own mean slope off; the roughness length detrends each window
  anyway). From those heights: ``rms`` (root mean square), ``z2``
  (:func:`rough_viewer.profiles.jrc.z2`) and its JRC estimate
  (:func:`rough_viewer.profiles.jrc.jrc_from_z2`); H and D by the roughness-length
  method (:func:`rough_viewer.profiles.fractal.roughness_length`) of the heights
  and of their wavelet de-noised version
  (:func:`rough_viewer.profiles.wavelets.denoise_result`, default DWT, fixed-form
  threshold, hard: the app's default).
- A profile is used when it has at least ``min_samples`` samples with data and its
  roughness-length fit succeeds; the others are counted, by reason.
- Per direction: the number of profiles used and the mean and standard deviation
  (sample form, n - 1) over them of each value (:class:`DirectionSummary`).

Defaults: ``band_half_width`` and the sample spacing = the point spacing (median
distance to the 4th nearest neighbour in the face plane, as for a picked
profile); ``spacing`` = the larger of ``2 band_half_width`` (bands that do not
overlap) and the face's larger extent / :data:`DEFAULT_MAX_PROFILES`; roughness-
length windows: the default rule of :mod:`rough_viewer.profiles.fractal` (shares of
each profile's length), or the lengths or rule given.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from rough_viewer.grid.maps import FaceFrame, Plane, face_frame
from rough_viewer.grid.planes import whole_cloud_plane
from rough_viewer.grid.spacing import neighbour_distance
from rough_viewer.io.cloud import PointCloud, as_xyz
from rough_viewer.memory import require
from rough_viewer.profiles.extraction import (
    DEFAULT_MAX_GAP_SPACINGS,
    positive_length,
    resample_band,
)
from rough_viewer.profiles.fractal import Windows, roughness_length
from rough_viewer.profiles.jrc import jrc_from_z2, jrc_warnings, z2
from rough_viewer.profiles.wavelets import denoise_result, min_run_length
from rough_viewer.vocabulary import (
    Decomposition,
    InputError,
    Mode,
    ProgressFn,
    ThresholdRule,
    error_line,
)

#: Profiles per direction at most by default (the default spacing is the face's
#: larger extent divided by this).
DEFAULT_MAX_PROFILES = 100
#: Fewest samples with data a profile needs by default.
DEFAULT_MIN_SAMPLES = 64
#: Bytes per point of one direction's projection (three coordinates, the sort).
PROJECTION_BYTES = 5 * 8
#: Bytes per band point (index, along, height, profile, bins).
BAND_BYTES = 6 * 8
#: Bytes per sample of the profile being measured, at its peak: its heights, the
#: line removed, the de-noised heights, the wavelet coefficients and the
#: roughness-length windows' temporaries (measured with tracemalloc: 167 on
#: 200,000 samples).
DIRECTION_BYTES_PER_SAMPLE = 22 * 8

#: The per-profile values, in the order of :class:`DirectionSummary`'s fields.
VALUES = ("hurst", "dimension", "hurst_denoised", "dimension_denoised", "rms", "z2", "jrc")


@dataclass(frozen=True)
class DenoiseSettings:
    """How each profile is de-noised (:func:`rough_viewer.profiles.wavelets.denoise_result`)."""

    wavelet: str = "db3"
    level: int = 3
    decomposition: Decomposition = "dwt"
    threshold: ThresholdRule = "fixed"
    mode: Mode = "hard"


@dataclass(frozen=True)
class DirectionSummary:
    """Mean and standard deviation (n - 1) of the used profiles' values in one
    direction; NaN where no (or, for a deviation, one) profile has the value."""

    azimuth_deg: float
    profiles: int
    """Profiles used."""
    hurst_mean: float
    hurst_std: float
    dimension_mean: float
    dimension_std: float
    hurst_denoised_mean: float
    hurst_denoised_std: float
    dimension_denoised_mean: float
    dimension_denoised_std: float
    rms_mean: float
    """Metres."""
    rms_std: float
    z2_mean: float
    z2_std: float
    jrc_mean: float
    """Mean of the profiles' JRC estimates (Tse and Cruden 1979)."""
    jrc_std: float


@dataclass(frozen=True)
class ProfileSet:
    """Parallel profiles in one direction across a face, and their roughness."""

    azimuth_deg: float
    """Degrees from the face's ``u`` axis towards ``v``."""
    frame: FaceFrame
    """Face plane and axes (metres, file frame)."""
    direction: np.ndarray
    """(3,) unit vector along the profiles."""
    across: np.ndarray
    """(3,) unit vector ``n x direction``: the offsets between profiles."""
    spacing: float
    """Distance between neighbouring profile lines, metres."""
    band_half_width: float
    """Points within this distance of a line make its profile, metres."""
    sample_spacing: float
    """Sample spacing along the profiles, metres."""
    max_gap: float
    """Longest stretch without points interpolated across, metres."""
    windows: np.ndarray | str | None
    """Roughness-length window lengths given, metres, or a rule (``"default"``,
    ``"paper"``); None: the default rule, shares of each profile's length
    (:func:`rough_viewer.profiles.fractal.window_lengths`)."""
    offsets: np.ndarray
    """(P,) ``across`` position of each profile line, metres from the frame origin
    (lines without points are left out)."""
    starts: np.ndarray
    """(P, 3) first sample of each profile on its fitted line, file frame, metres."""
    ends: np.ndarray
    """(P, 3) last sample, likewise: ``starts``/``ends`` are the lines to draw."""
    n_points: np.ndarray
    """(P,) band points of each profile."""
    n_samples: np.ndarray
    """(P,) samples of each profile (with data or not)."""
    used: np.ndarray
    """(P,) bool: the profile's roughness was measured."""
    values: dict[str, np.ndarray]
    """(P,) arrays named :data:`VALUES` (NaN where not measured): ``hurst``,
    ``dimension`` (2 - H), the same ``_denoised``, ``rms`` (metres), ``z2``, ``jrc``."""
    skipped: tuple[tuple[str, int], ...]
    """Why profiles were not used: (reason, count), most common first."""
    warnings: tuple[str, ...]
    """What the reader should know (JRC outside its sampling); implausible fits are
    counted in ``implausible`` and said once for all sets by :func:`set_warnings`."""
    denoise: DenoiseSettings = DenoiseSettings()
    implausible: int = 0
    """Used profiles whose raw fractal dimension lies outside [1, 2]
    (:func:`rough_viewer.profiles.fractal.plausibility`)."""

    @property
    def n_profiles(self) -> int:
        """Profile lines laid across the face (used or not)."""
        return int(self.offsets.size)

    def summary(self) -> DirectionSummary:
        """Mean and standard deviation of every value over the used profiles."""
        stats: dict[str, float] = {}
        for name in VALUES:
            v = self.values[name][self.used]
            v = v[np.isfinite(v)]
            stats[f"{name}_mean"] = float(v.mean()) if v.size else float("nan")
            stats[f"{name}_std"] = float(v.std(ddof=1)) if v.size > 1 else float("nan")
        return DirectionSummary(azimuth_deg=self.azimuth_deg,
                                profiles=int(np.count_nonzero(self.used)), **stats)

    def reversed(self, azimuth_deg: float) -> ProfileSet:
        """The same profiles run the other way (``azimuth_deg`` = this one + 180)."""
        return replace(self, azimuth_deg=float(azimuth_deg), direction=-self.direction,
                       across=-self.across, offsets=-self.offsets, starts=self.ends,
                       ends=self.starts)


@dataclass(frozen=True)
class _Prepared:
    """What every direction of one analysis shares."""

    rel: np.ndarray
    """(N, 3) points minus the frame origin, metres."""
    frame: FaceFrame
    spacing: float
    band: float
    step: float
    gap: float


def crop(xyz: np.ndarray, region: tuple[Sequence[float], Sequence[float]] | None) -> np.ndarray:
    """The points (N, 3) inside the box ``region = (lo, hi)`` (file frame, metres,
    bounds included); all of them for None."""
    if region is None:
        return xyz
    lo, hi = (np.asarray(b, dtype=np.float64).ravel() for b in region)
    if lo.shape != (3,) or hi.shape != (3,) or not np.all(lo < hi):
        raise InputError(f"a region is two corners (x, y, z) with lo < hi, got {region!r}")
    inside = np.all((xyz >= lo) & (xyz <= hi), axis=1)
    if np.count_nonzero(inside) < 3:
        raise InputError(f"only {np.count_nonzero(inside)} points inside the region "
                         f"{lo.tolist()} - {hi.tolist()}")
    return xyz[inside]


def _prepare(
    points: PointCloud | np.ndarray,
    *,
    plane: Plane | None,
    region: tuple[Sequence[float], Sequence[float]] | None,
    spacing: float | None,
    band_half_width: float | None,
    sample_spacing: float | None,
    max_gap: float | None,
) -> _Prepared:
    xyz = crop(as_xyz(points), region)
    n = xyz.shape[0]
    require(n * (PROJECTION_BYTES + 24.0), f"profiles across {n:,} points")
    frame = face_frame(plane if plane is not None else whole_cloud_plane(xyz))
    rel = xyz - frame.origin
    uv = np.column_stack([rel @ frame.u_axis, rel @ frame.v_axis])
    step = positive_length(sample_spacing, "sample_spacing")
    band = positive_length(band_half_width, "band_half_width")
    if step is None or band is None:
        spacing_est = neighbour_distance(uv, k=4)
        step = spacing_est if step is None else step
        band = spacing_est if band is None else band
    gap = positive_length(max_gap, "max_gap") or DEFAULT_MAX_GAP_SPACINGS * step
    between = positive_length(spacing, "spacing")
    if between is None:
        extent = float(np.max(uv.max(axis=0) - uv.min(axis=0)))
        between = max(2.0 * band, extent / DEFAULT_MAX_PROFILES)
    return _Prepared(rel=rel, frame=frame, spacing=between, band=band, step=step, gap=gap)


def _fit_line(heights: np.ndarray) -> tuple[np.ndarray, float, float]:
    """(heights minus their least-squares line over the finite samples, the line's
    value at the first and at the last sample)."""
    i = np.arange(heights.size, dtype=np.float64)
    ok = np.isfinite(heights)
    slope, icpt = np.polyfit(i[ok], heights[ok], 1)
    return heights - (icpt + slope * i), float(icpt), float(icpt + slope * (heights.size - 1))


def _measure(heights: np.ndarray, step: float, windows: np.ndarray | str | None,
             denoise: DenoiseSettings) -> dict[str, float]:
    """Every value of one profile (heights with the line removed); InputError when
    its roughness length cannot be fitted. The de-noised values are NaN where the
    de-noising or its fit fails."""
    ok = np.isfinite(heights)
    rms = float(np.sqrt(np.mean(heights[ok] ** 2)))
    slope = z2(heights, step)
    raw = roughness_length(heights, step, windows=windows)
    out = {"hurst": raw.hurst, "dimension": raw.dimension, "rms": rms, "z2": slope,
           "jrc": float(jrc_from_z2(slope)), "hurst_denoised": float("nan"),
           "dimension_denoised": float("nan"), "implausible": float(bool(raw.warnings))}
    try:
        den = denoise_result(heights, wavelet=denoise.wavelet, level=denoise.level,
                             decomposition=denoise.decomposition,
                             threshold=denoise.threshold, mode=denoise.mode)
        fit = roughness_length(den.heights, step, windows=windows)
    except InputError:
        return out
    out["hurst_denoised"], out["dimension_denoised"] = fit.hurst, fit.dimension
    return out


def _bands(prep: _Prepared, w: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The bands of the profiles across unit ``w``: every ``prep.spacing`` from the
    lowest point along ``w``, ``prep.band`` either side (metres), those with points:
    their offsets along ``w`` (metres), point counts, first rows in ``idx`` and
    ``idx`` the points of every band one band after the other (a point in two bands
    twice)."""
    c = prep.rel @ w
    order = np.argsort(c, kind="stable")
    cs = c[order]
    del c
    s, band = prep.spacing, prep.band
    centres = cs[0] + s * np.arange(int(np.floor((cs[-1] - cs[0]) / s + 1e-9)) + 1)
    lo = np.searchsorted(cs, centres - band, side="left")
    hi = np.searchsorted(cs, centres + band, side="right")
    keep = hi > lo
    centres, lo, hi = centres[keep], lo[keep], hi[keep]
    count = hi - lo
    total = int(count.sum())
    require(total * BAND_BYTES, f"{centres.size:,} profiles of {total:,} band points",
            hint="choose a larger spacing or a narrower band")
    first = np.cumsum(count) - count
    pos = np.arange(total) - np.repeat(first, count) + np.repeat(lo, count)
    return centres, count, first, order[pos]


def _one_direction(
    prep: _Prepared,
    azimuth_deg: float,
    *,
    windows: np.ndarray | str | None,
    min_samples: int,
    denoise: DenoiseSettings,
    progress: ProgressFn | None = None,
) -> ProfileSet:
    f = prep.frame
    alpha = np.radians(azimuth_deg)
    t = np.cos(alpha) * f.u_axis + np.sin(alpha) * f.v_axis
    w = np.cross(f.normal, t)
    s, band = prep.spacing, prep.band
    centres, count, first, idx = _bands(prep, w)
    along = prep.rel[idx] @ t
    height = prep.rel[idx] @ f.normal
    amin = np.minimum.reduceat(along, first)
    amax = np.maximum.reduceat(along, first)
    n_samples = (np.rint((amax - amin) / prep.step) + 1).astype(np.int64)
    longest = int(n_samples.max()) if n_samples.size else 0
    require(longest * DIRECTION_BYTES_PER_SAMPLE,
            f"a profile of {longest:,} samples at {prep.step:.4g} m (azimuth {azimuth_deg:g})",
            hint="choose a larger sample spacing")
    p = centres.size
    values = {name: np.full(p, np.nan) for name in VALUES}
    used = np.zeros(p, dtype=bool)
    starts = np.zeros((p, 3))
    ends = np.zeros((p, 3))
    reasons: Counter[str] = Counter()
    implausible = 0
    need = max(int(min_samples), min_run_length(denoise.wavelet, denoise.level), 4)
    for j in range(p):
        sl = slice(int(first[j]), int(first[j] + count[j]))
        base = f.origin + centres[j] * w + amin[j] * t
        starts[j] = base
        ends[j] = base + (n_samples[j] - 1) * prep.step * t
        if progress is not None:
            progress(j, p)
        if n_samples[j] < need:
            reasons[f"shorter than {need} samples"] += 1
            continue
        heights, _, _ = resample_band(along[sl] - amin[j], height[sl], int(n_samples[j]),
                                      prep.step, prep.gap)
        if np.count_nonzero(np.isfinite(heights)) < need:
            reasons[f"fewer than {need} samples with data"] += 1
            continue
        resid, h0, h1 = _fit_line(heights)
        starts[j] += h0 * f.normal
        ends[j] += h1 * f.normal
        try:
            got = _measure(resid, prep.step, windows, denoise)
        except InputError as exc:
            reasons[f"no roughness-length fit ({error_line(exc)})"] += 1
            continue
        used[j] = True
        implausible += int(got.pop("implausible"))
        for name in VALUES:
            values[name][j] = got[name]
    if progress is not None:
        progress(p, p)
    warnings = list(jrc_warnings(prep.step)) if used.any() else []
    return ProfileSet(
        azimuth_deg=float(azimuth_deg), frame=f, direction=t, across=w, spacing=s,
        band_half_width=band, sample_spacing=prep.step, max_gap=prep.gap, windows=windows,
        offsets=centres, starts=starts, ends=ends, n_points=count.astype(np.int64),
        n_samples=n_samples, used=used, values=values,
        skipped=tuple(reasons.most_common()), warnings=tuple(warnings), denoise=denoise,
        implausible=implausible,
    )


def _windows(windows: Windows) -> np.ndarray | str | None:
    if windows is None or isinstance(windows, str):
        return windows
    w = np.asarray(windows, dtype=np.float64).ravel()
    if w.size < 2 or not np.all(np.isfinite(w)) or np.any(w <= 0):
        raise InputError("roughness-length windows must be at least 2 positive lengths "
                         "in metres")
    return w


def profile_sets(
    points: PointCloud | np.ndarray,
    azimuth_deg: Sequence[float] | np.ndarray,
    *,
    spacing: float | None = None,
    band_half_width: float | None = None,
    sample_spacing: float | None = None,
    windows: Windows = None,
    max_gap: float | None = None,
    region: tuple[Sequence[float], Sequence[float]] | None = None,
    plane: Plane | None = None,
    min_samples: int = DEFAULT_MIN_SAMPLES,
    denoise: DenoiseSettings | None = None,
    progress: ProgressFn | None = None,
) -> tuple[ProfileSet, ...]:
    """Parallel profiles across a face in each direction, and their roughness.

    Parameters
    ----------
    points : PointCloud or (N, 3) array
        The cloud, metres.
    azimuth_deg : sequence of float
        Directions, degrees from the face's ``u`` axis towards ``v`` (module
        docstring); ``alpha`` and ``alpha + 180`` are measured once.
    spacing : float, optional
        Distance between profile lines, metres (default in the module docstring).
    band_half_width : float, optional
        Half-width of each profile's band of points, metres (default: the point
        spacing).
    sample_spacing : float, optional
        Sample spacing along the profiles, metres (default: the point spacing).
    windows : sequence of float or str, optional
        Roughness-length window lengths, metres, for every profile, or a rule
        (``"default"``: 8 evenly in log from 3 % to 30 % of each profile's length;
        ``"paper"``: 8 from 3 % to 10 %); default the default rule.
    max_gap : float, optional
        Longest stretch without points interpolated across, metres (default: 3
        sample spacings).
    region : (lo, hi), optional
        Only the points inside this box (file frame, metres), whose own plane is
        then the face.
    plane : Plane, optional
        The face plane (default: the ODR plane of the points used).
    min_samples : int
        Fewest samples with data a profile needs (default 64; never fewer than
        the de-noising's shortest run, 40 for db3 at level 3).
    denoise : DenoiseSettings, optional
        De-noising of each profile (default DWT, fixed threshold, hard).
    progress : callable, optional
        ``progress(done, total)`` in directions measured, called at each profile too
        (it may raise to stop the work).

    Returns
    -------
    tuple of ProfileSet
        One per azimuth, in the order given.

    Examples
    --------
    Ripples along x (wavelength 50 mm, amplitude 2 mm) on a random 0.4 x 0.4 m
    face: profiles along x see them (RMS 1.4 mm), profiles along y hardly do (what
    they see comes from the ripples' slope across their 2-point-spacing-wide band).

    >>> rng = np.random.default_rng(1)
    >>> xy = rng.uniform(0.0, 0.4, (40_000, 2))
    >>> z = 0.002 * np.sin(2 * np.pi * xy[:, 0] / 0.05)
    >>> sets = profile_sets(np.column_stack([xy, z]), [0, 90], spacing=0.02)
    >>> [round(s.summary().rms_mean * 1e3, 1) for s in sets]
    [1.4, 0.1]
    """
    az = np.asarray(azimuth_deg, dtype=np.float64).ravel()
    if az.size == 0 or not np.all(np.isfinite(az)):
        raise InputError("give at least one finite azimuth, in degrees")
    if int(min_samples) < 2:
        raise InputError(f"min_samples must be at least 2, got {min_samples}")
    den = denoise or DenoiseSettings()
    prep = _prepare(points, plane=plane, region=region, spacing=spacing,
                    band_half_width=band_half_width, sample_spacing=sample_spacing,
                    max_gap=max_gap)
    wins = _windows(windows)
    lines = np.mod(az, 180.0)
    distinct = list(dict.fromkeys(np.round(lines, 9).tolist()))
    done: dict[float, ProfileSet] = {}
    for i, line in enumerate(distinct):
        # called at each profile too, so a progress that raises stops the work soon
        each = None if progress is None else (
            lambda _j, _p, i=i: progress(i, len(distinct)))
        done[line] = _one_direction(prep, line, windows=wins, min_samples=int(min_samples),
                                    denoise=den, progress=each)
        if progress is not None:
            progress(i + 1, len(distinct))
    out = []
    for a, line in zip(az, np.round(lines, 9), strict=True):
        base = done[float(line)]
        same = np.isclose(np.mod(a - base.azimuth_deg, 360.0), 0.0) or np.isclose(
            np.mod(a - base.azimuth_deg, 360.0), 360.0)
        out.append(replace(base, azimuth_deg=float(a)) if same else base.reversed(float(a)))
    return tuple(out)


def summaries(sets: Sequence[ProfileSet]) -> list[DirectionSummary]:
    """:meth:`ProfileSet.summary` of each set."""
    return [s.summary() for s in sets]


def set_warnings(sets: Sequence[ProfileSet]) -> tuple[str, ...]:
    """Every set's warnings once, in order, and one line for the profiles of all
    directions whose fractal dimension is implausible (each line direction counted
    once)."""
    out = list(dict.fromkeys(w for s in sets for w in s.warnings))
    lines = {round(s.azimuth_deg % 180.0, 9): s for s in sets}.values()
    bad = sum(s.implausible for s in lines)
    used = sum(int(np.count_nonzero(s.used)) for s in lines)
    if bad:
        out.append(f"{bad} of {used} profiles have a fractal dimension outside [1, 2]: a "
                   "trend or curvature their windows do not remove, or a surface smoother "
                   "(D < 1) or noisier (D > 2) than its windows; try larger roughness-length "
                   "windows (directions --windows)")
    return tuple(out)

