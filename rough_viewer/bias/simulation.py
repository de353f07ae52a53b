"""Simulated rough targets: hemispherical asperities, range noise and beam smoothing.

After the instrument-bias paper (docs/science.md section 3): a flat board sampled on a
regular raster (default 1 mm), hemispheres of radius ``r`` on chosen nodes (height
``sqrt(r^2 - d^2)`` inside, 0 outside), then

- beam smoothing: every sample is the mean height of the surface over a disc of the
  beam's effective radius (ER) around it (an FFT convolution with a disc kernel);
- range noise: independent Gaussian heights of standard deviation ``sigma``.

:func:`predict_bias` compares the roughness of the true surface ("expected") with
that of the noisy, smoothed surface ("measured") on population-normalised clouds;
:func:`smoothing_curve` gives the error against ER / asperity radius (the paper's
Fig. 4). The paper's targets are :func:`paper_target` ("A": r = 19 mm, "B": 32.5 mm).
All lengths are metres.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Literal

import numpy as np

from rough_viewer.bias.measurement import normalise_population, target_roughness
from rough_viewer.memory import require
from rough_viewer.vocabulary import BIAS_RESIDUAL, BIAS_TRIALS, InputError, ProgressFn, Residual

PaperTarget = Literal["A", "B"]
Normalisation = Literal["known", "none"]

#: The paper's board: 0.609 m x 1.244 m.
PAPER_BOARD_M = (0.609, 1.244)
#: Asperity radii of the paper's targets A and B, metres.
PAPER_RADIUS_M = {"A": 0.019, "B": 0.0325}
#: Edge of the squares of the paper's node grid (6 x 13 squares), metres.
PAPER_PITCH_M = 0.085
#: Asperities on the paper's targets (at randomly chosen nodes).
PAPER_N_ASPERITIES = 36

__all__ = [
    "BiasPrediction",
    "PAPER_BOARD_M",
    "PAPER_RADIUS_M",
    "SimulatedTarget",
    "SmoothingCurve",
    "TargetLayout",
    "disc_kernel",
    "kernel_half_width",
    "paper_target",
    "predict_bias",
    "predict_paper_target",
    "raster_heights",
    "raster_shape",
    "simulate_target",
    "smooth_heights",
    "smoothing_bytes",
    "smoothing_curve",
]

#: Bytes per raster node held at the peak of a simulation (heights, labels, noise,
#: the smoothing convolution and the scanned points).
RASTER_BYTES_PER_NODE = 12 * 8
#: Bytes per node of the padded raster held at the peak of the FFT smoothing (the two
#: padded inputs, their half spectra, their product and the result, float64).
FFT_BYTES_PER_NODE = 8 * 8
#: Sub-samples per cell side of :func:`disc_kernel`.
KERNEL_SUPERSAMPLE = 8


def _check_lengths(named: Iterable[tuple[str, float]], *, positive: bool = False) -> None:
    """Raise InputError unless every value is finite and >= 0 (> 0 if ``positive``)."""
    for name, value in named:
        v = float(value)
        if not (math.isfinite(v) and (v > 0 if positive else v >= 0)):
            sign = "> 0" if positive else ">= 0"
            raise InputError(f"{name} must be a finite length {sign}, got {value!r}")


@dataclass(frozen=True)
class TargetLayout:
    """A flat board with hemispherical asperities."""

    width_m: float
    """Board extent along x, metres."""
    height_m: float
    """Board extent along y, metres."""
    centres: np.ndarray
    """(K, 2) asperity centres (x, y) on the board, metres from its corner."""
    asperity_radius_m: float
    """Hemisphere radius, metres."""


def paper_target(
    which: PaperTarget = "A",
    *,
    asperity_radius_m: float | None = None,
    seed: int | None = 0,
) -> TargetLayout:
    """The paper's target A or B: a 0.609 m x 1.244 m board, 36 hemispheres.

    The nodes are the 7 x 14 corners of a 6 x 13 grid of 85 mm squares centred on
    the board; 36 of them are drawn at random (the paper's own draw is not
    published; with population normalisation the roughness hardly depends on it).

    Parameters
    ----------
    which : {"A", "B"}
        Target A (r = 19 mm) or B (r = 32.5 mm).
    asperity_radius_m : float, optional
        Another radius on the same layout, metres.
    seed : int, optional
        Seed of the node draw (the same for A and B: identical node patterns).
    """
    if which not in PAPER_RADIUS_M:
        raise InputError(f"paper target must be 'A' or 'B', got {which!r}")
    r = PAPER_RADIUS_M[which] if asperity_radius_m is None else float(asperity_radius_m)
    w, h = PAPER_BOARD_M
    gx = (w - 6 * PAPER_PITCH_M) / 2 + PAPER_PITCH_M * np.arange(7)
    gy = (h - 13 * PAPER_PITCH_M) / 2 + PAPER_PITCH_M * np.arange(14)
    nodes = np.stack(np.meshgrid(gx, gy), axis=-1).reshape(-1, 2)
    pick = np.random.default_rng(seed).choice(nodes.shape[0], size=PAPER_N_ASPERITIES,
                                              replace=False)
    return TargetLayout(width_m=w, height_m=h, centres=nodes[np.sort(pick)],
                        asperity_radius_m=r)


def raster_heights(
    layout: TargetLayout, *, spacing_m: float = 1e-3
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """True heights of a target on a regular raster.

    Raster nodes sit at the centres of ``spacing_m`` squares covering the board:
    ``x_i = (i + 0.5) * spacing_m``.

    Returns
    -------
    x : (nx,) array, metres
    y : (ny,) array, metres
    z : (ny, nx) array
        Heights above the board, metres: ``sqrt(r^2 - d^2)`` within ``r`` of an
        asperity centre (the highest where two overlap), 0 elsewhere.
    asperity : (ny, nx) bool array
        True within ``r`` of an asperity centre (the known class).
    """
    _check_lengths([("asperity radius", layout.asperity_radius_m)], positive=True)
    ny, nx = raster_shape(layout, spacing_m)
    # heights, noise, smoothed heights, labels and the simulated points all live on
    # this raster at once (about 12 float64 per node, FFT convolution included)
    require(nx * ny * RASTER_BYTES_PER_NODE, f"a simulated target raster of {nx:,} x {ny:,} "
            f"nodes at {spacing_m * 1e3:g} mm", hint="choose a larger raster spacing")
    x = (np.arange(nx) + 0.5) * spacing_m
    y = (np.arange(ny) + 0.5) * spacing_m
    z = np.zeros((ny, nx))
    asperity = np.zeros((ny, nx), dtype=bool)
    r = float(layout.asperity_radius_m)
    r2 = r * r
    # One window per asperity (a loop over asperities, not over points).
    for cx, cy in np.asarray(layout.centres, dtype=np.float64).reshape(-1, 2):
        i0 = max(0, int(math.floor((cx - r) / spacing_m - 0.5)))
        i1 = min(nx, int(math.ceil((cx + r) / spacing_m + 0.5)) + 1)
        j0 = max(0, int(math.floor((cy - r) / spacing_m - 0.5)))
        j1 = min(ny, int(math.ceil((cy + r) / spacing_m + 0.5)) + 1)
        if i0 >= i1 or j0 >= j1:
            continue
        d2 = (x[None, i0:i1] - cx) ** 2 + (y[j0:j1, None] - cy) ** 2
        inside = d2 < r2
        h = np.sqrt(np.where(inside, r2 - d2, 0.0))
        z[j0:j1, i0:i1] = np.maximum(z[j0:j1, i0:i1], h)
        asperity[j0:j1, i0:i1] |= inside
    return x, y, z, asperity


def kernel_half_width(radius_m: float, spacing_m: float) -> int:
    """Half width, in raster nodes, of the :func:`disc_kernel` of ``radius_m``."""
    _check_lengths([("effective radius", radius_m)])
    _check_lengths([("spacing", spacing_m)], positive=True)
    return int(math.floor(radius_m / spacing_m + 0.5))


def smoothing_bytes(shape: tuple[int, int], effective_radius_m: float, spacing_m: float,
                    *, raster: bool = False) -> float:
    """Peak bytes of the beam smoothing of a ``shape`` raster: the padded FFT raster
    (:data:`FFT_BYTES_PER_NODE` a node) and the kernel building (:func:`disc_kernel`),
    plus the simulated raster itself (:data:`RASTER_BYTES_PER_NODE` a node) when
    ``raster``."""
    ny, nx = shape
    n = 2 * kernel_half_width(effective_radius_m, spacing_m) + 1
    smooth = 0.0 if n == 1 else (float(ny + n - 1) * (nx + n - 1) * FFT_BYTES_PER_NODE
                                 + float(n) * n * (9 * KERNEL_SUPERSAMPLE + 24))
    return smooth + (float(ny) * nx * RASTER_BYTES_PER_NODE if raster else 0.0)


def _require_smoothing(shape: tuple[int, int], effective_radius_m: float, spacing_m: float,
                       *, raster: bool = False) -> None:
    ny, nx = shape
    n = 2 * kernel_half_width(effective_radius_m, spacing_m) + 1
    what = "the simulation and beam smoothing" if raster else "the beam smoothing"
    require(smoothing_bytes(shape, effective_radius_m, spacing_m, raster=raster),
            f"{what} of a {ny:,} x {nx:,} raster with a {n:,} x {n:,} kernel (effective "
            f"radius {effective_radius_m * 1e3:g} mm at {spacing_m * 1e3:g} mm)",
            hint="choose a smaller effective radius or a larger raster spacing")


def raster_shape(layout: TargetLayout, spacing_m: float) -> tuple[int, int]:
    """(ny, nx): nodes of the raster of ``layout`` at ``spacing_m`` (see
    :func:`raster_heights`)."""
    _check_lengths([("spacing", spacing_m), ("board width", layout.width_m),
                    ("board height", layout.height_m)], positive=True)
    nx = int(round(layout.width_m / spacing_m))
    ny = int(round(layout.height_m / spacing_m))
    if nx < 1 or ny < 1:
        raise InputError("the board is smaller than one raster cell")
    return ny, nx


def disc_kernel(radius_m: float, spacing_m: float, *,
                supersample: int = KERNEL_SUPERSAMPLE) -> np.ndarray:
    """Averaging kernel of a disc on a raster, weights summing to 1.

    Each weight is the fraction of the raster cell (a ``spacing_m`` square centred
    on the node) inside the disc, estimated on a ``supersample`` x ``supersample``
    sub-grid, so radii that are not whole multiples of the spacing are honoured.
    Its memory (about ``n^2 (9 q + 24)`` bytes for ``n = 2 round(radius / spacing) + 1``
    nodes a side and ``q = supersample``) is checked before it is built.

    Parameters
    ----------
    radius_m : float
        Disc radius (the effective radius), metres; 0 gives the identity kernel.
    spacing_m : float
        Raster spacing, metres.
    supersample : int
        Sub-samples per cell side.
    """
    half = kernel_half_width(radius_m, spacing_m)
    if half == 0:
        return np.ones((1, 1))
    rp = radius_m / spacing_m
    q = int(supersample)
    n = 2 * half + 1
    # one (n, n, q) slab of squared distances and its mask at a time, the counts and
    # the weights
    require(float(n) * n * (9 * q + 24), f"the beam kernel of effective radius "
            f"{radius_m * 1e3:g} mm ({n:,} x {n:,} nodes at {spacing_m * 1e3:g} mm)",
            hint="choose a smaller effective radius or a larger raster spacing")
    sub = (np.arange(q) + 0.5) / q - 0.5
    off = np.arange(-half, half + 1)
    dx2 = (off[:, None] + sub[None, :]) ** 2              # (n, q) sub-sample x^2
    counts = np.zeros((n, n), dtype=np.int64)
    # A loop over the q sub-rows of every cell (not over points): (n, n, q) each.
    for s in sub:
        dy2 = (off + s) ** 2
        counts += np.count_nonzero(dy2[:, None, None] + dx2[None, :, :] <= rp * rp, axis=2)
    w = counts.astype(np.float64)
    return w / w.sum()


def smooth_heights(z: np.ndarray, *, effective_radius_m: float, spacing_m: float) -> np.ndarray:
    """Beam smoothing: each sample becomes the mean height over a disc around it.

    FFT convolution of the height raster with :func:`disc_kernel`; outside the
    raster the board is taken as flat at height 0.

    Parameters
    ----------
    z : (ny, nx) array
        Heights, metres.
    effective_radius_m : float
        Beam effective radius, metres.
    spacing_m : float
        Raster spacing, metres.

    The padded FFT raster (``(ny + n - 1) x (nx + n - 1)`` nodes for a kernel of
    ``n`` nodes a side, :data:`FFT_BYTES_PER_NODE` bytes each) is checked against the
    available memory before the kernel is built.
    """
    half = kernel_half_width(effective_radius_m, spacing_m)
    if half == 0:
        return np.array(z, dtype=np.float64, copy=True)
    ny, nx = np.shape(z)
    _require_smoothing((ny, nx), effective_radius_m, spacing_m)
    k = disc_kernel(effective_radius_m, spacing_m)
    from scipy.signal import fftconvolve  # here: 0.4 s of import, needed by simulations only

    return fftconvolve(np.asarray(z, dtype=np.float64), k, mode="same")


@dataclass(frozen=True)
class SimulatedTarget:
    """A simulated scan of a rough target on a regular raster."""

    x: np.ndarray
    """(nx,) raster x coordinates, metres."""
    y: np.ndarray
    """(ny,) raster y coordinates, metres."""
    true_height: np.ndarray
    """(ny, nx) heights of the real surface, metres."""
    height: np.ndarray
    """(ny, nx) "measured" heights: smoothed by the beam, plus range noise, metres."""
    asperity: np.ndarray
    """(ny, nx) bool: the known class (True = asperity point)."""
    spacing_m: float
    """Raster spacing, metres."""
    noise_sigma_m: float
    """Range noise standard deviation, metres."""
    effective_radius_m: float
    """Beam effective radius, metres."""

    def xyz(self, *, true: bool = False) -> np.ndarray:
        """(ny * nx, 3) points, metres (the board in the xy plane, the scanner on +z)."""
        z = self.true_height if true else self.height
        gx, gy = np.meshgrid(self.x, self.y)
        return np.column_stack((gx.ravel(), gy.ravel(), z.ravel()))

    def labels(self) -> np.ndarray:
        """(ny * nx,) bool known classes in the order of :meth:`xyz`."""
        return self.asperity.ravel().copy()


def simulate_target(
    layout: TargetLayout,
    *,
    spacing_m: float = 1e-3,
    noise_sigma_m: float = 0.0,
    effective_radius_m: float = 0.0,
    seed: int | np.random.Generator | None = 0,
) -> SimulatedTarget:
    """Simulate the scan of a rough target: true raster, beam smoothing, range noise.

    Parameters
    ----------
    layout : TargetLayout
        Board and asperities (e.g. :func:`paper_target`).
    spacing_m : float
        Raster spacing, metres (the paper: 1 mm). Keep it well below the effective
        radius, or the smoothing cannot be represented.
    noise_sigma_m : float
        Range noise standard deviation, metres (the paper: 1.6 mm).
    effective_radius_m : float
        Beam effective radius, metres (0 = no smoothing).
    seed : int or numpy Generator, optional
        Randomness of the noise.
    """
    _check_lengths([("noise sigma", noise_sigma_m), ("effective radius", effective_radius_m)])
    x, y, z, asperity = raster_heights(layout, spacing_m=spacing_m)
    h = smooth_heights(z, effective_radius_m=effective_radius_m, spacing_m=spacing_m)
    if noise_sigma_m > 0:
        rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        h = h + rng.normal(0.0, noise_sigma_m, size=h.shape)
    return SimulatedTarget(x=x, y=y, true_height=z, height=h, asperity=asperity,
                           spacing_m=float(spacing_m), noise_sigma_m=float(noise_sigma_m),
                           effective_radius_m=float(effective_radius_m))


@dataclass(frozen=True)
class BiasPrediction:
    """Expected against "measured" roughness of a simulated target (means over trials)."""

    noise_sigma_m: float
    """Range noise, metres."""
    effective_radius_m: float
    """Beam effective radius, metres."""
    asperity_radius_m: float
    """Hemisphere radius, metres."""
    er_ratio: float
    """Effective radius / asperity radius."""
    expected_m: float
    """Roughness of the true surface, metres."""
    noise_only_m: float
    """Roughness with range noise, no smoothing, metres."""
    smoothing_only_m: float
    """Roughness with beam smoothing, no noise, metres."""
    measured_m: float
    """Roughness with both (what the scanner would give), metres."""
    measured_std_m: float
    """Standard deviation of ``measured_m`` over the trials, metres."""
    noise_effect_pct: float
    """``100 (noise_only / expected - 1)``: the over-estimate from noise."""
    smoothing_effect_pct: float
    """``100 (smoothing_only / expected - 1)``: the under-estimate from smoothing."""
    total_effect_pct: float
    """``100 (measured / expected - 1)``."""
    vs_noisy_pct: float
    """``100 (measured / noise_only - 1)``: against a simulation that includes the
    noise (the paper's Fig. 4 axis)."""
    trials: int
    """Noise and thinning draws averaged."""
    normalisation: Normalisation
    """``"known"``: thinned to ``ratio`` with the known classes; ``"none"``: all points."""
    ratio: float
    """Background : asperity ratio after normalisation (or the native one)."""
    residual: Residual
    """Roughness convention (see :func:`rough_viewer.bias.measurement.target_roughness`)."""


def _check_ratio(ratio: float) -> None:
    if not (math.isfinite(float(ratio)) and ratio > 0):
        raise InputError(f"ratio must be a finite number > 0, got {ratio!r}")


def _roughness_variants(
    xy: np.ndarray, heights: list[np.ndarray], keep: np.ndarray, residual: Residual
) -> list[float]:
    out = []
    for h in heights:
        pts = np.column_stack((xy[keep], h.ravel()[keep]))
        out.append(target_roughness(pts, residual=residual))
    return out


def predict_bias(
    *,
    noise_sigma_m: float,
    effective_radius_m: float,
    asperity_radius_m: float | None = None,
    layout: TargetLayout | None = None,
    spacing_m: float = 1e-3,
    ratio: float = 5.0,
    normalisation: Normalisation = "known",
    trials: int = 1,
    seed: int | None = 0,
    residual: Residual = BIAS_RESIDUAL,
    progress: ProgressFn | None = None,
) -> BiasPrediction:
    """Predict the roughness over- or under-estimate of a scanner on a rough target.

    Simulates the true target, the target with noise, with smoothing and with both,
    thins every version with the same known-class draw to ``ratio`` background
    points per asperity point, and compares their roughness.

    Parameters
    ----------
    noise_sigma_m : float
        Range noise, metres.
    effective_radius_m : float
        Beam effective radius, metres.
    asperity_radius_m : float, optional
        Hemisphere radius, metres, on the paper's layout (default: target A, 19 mm).
        Ignored when ``layout`` is given.
    layout : TargetLayout, optional
        Another target.
    spacing_m : float
        Raster spacing, metres.
    ratio : float
        Background : asperity ratio of the normalisation (the paper: 5).
    normalisation : {"known", "none"}
        Thin with the known classes, or keep every point.
    trials : int
        Independent noise / thinning draws to average.
    seed : int, optional
        Seed of all draws.
    residual : {"signed", "absolute"}
        Roughness convention (default signed, the bias paper's definition; see
        :func:`rough_viewer.bias.measurement.target_roughness`).
    progress : callable, optional
        ``progress(done, total)`` in trials: ``(0, trials)`` once the target is
        simulated, then after each trial up to ``(trials, trials)``. A trial takes
        about 0.1 s on the paper's target at 1 mm.
    """
    if trials < 1:
        raise InputError(f"trials must be >= 1, got {trials}")
    _check_lengths([("noise sigma", noise_sigma_m), ("effective radius", effective_radius_m)])
    _check_ratio(ratio)
    if normalisation not in ("known", "none"):
        raise InputError(f"normalisation must be 'known' or 'none', got {normalisation!r}")
    if layout is None:
        layout = paper_target("A", asperity_radius_m=asperity_radius_m)
    # the whole peak (raster and smoothing) is checked before anything is allocated
    _require_smoothing(raster_shape(layout, spacing_m), effective_radius_m, spacing_m,
                       raster=True)
    base = simulate_target(layout, spacing_m=spacing_m)
    smooth = smooth_heights(base.true_height, effective_radius_m=effective_radius_m,
                            spacing_m=spacing_m)
    xy = base.xyz(true=True)[:, :2]
    labels = base.labels()
    rng = np.random.default_rng(seed)
    rows = []
    ratios = []
    if progress is not None:
        progress(0, trials)
    for t in range(trials):
        noise = rng.normal(0.0, noise_sigma_m, size=smooth.shape) if noise_sigma_m > 0 else 0.0
        if normalisation == "known":
            pts0 = np.column_stack((xy, base.true_height.ravel()))
            pop = normalise_population(pts0, labels, ratio=ratio, seed=rng, residual=residual)
            keep = pop.keep
            ratios.append(pop.ratio)
        else:
            keep = np.arange(labels.size)
            n_asp = max(int(labels.sum()), 1)
            ratios.append((labels.size - n_asp) / n_asp)
        rows.append(_roughness_variants(
            xy, [base.true_height, base.true_height + noise, smooth, smooth + noise],
            keep, residual))
        if progress is not None:
            progress(t + 1, trials)
    v = np.asarray(rows)
    mean = v.mean(axis=0)
    exp_, noisy, smoothed, measured = (float(m) for m in mean)
    r = float(layout.asperity_radius_m)
    return BiasPrediction(
        noise_sigma_m=float(noise_sigma_m), effective_radius_m=float(effective_radius_m),
        asperity_radius_m=r, er_ratio=float(effective_radius_m) / r if r > 0 else float("nan"),
        expected_m=exp_, noise_only_m=noisy, smoothing_only_m=smoothed, measured_m=measured,
        measured_std_m=float(v[:, 3].std()),
        noise_effect_pct=100.0 * (noisy / exp_ - 1.0),
        smoothing_effect_pct=100.0 * (smoothed / exp_ - 1.0),
        total_effect_pct=100.0 * (measured / exp_ - 1.0),
        vs_noisy_pct=100.0 * (measured / noisy - 1.0),
        trials=int(trials), normalisation=normalisation, ratio=float(np.mean(ratios)),
        residual=residual,
    )


def predict_paper_target(
    *,
    noise_sigma_m: float,
    effective_radius_m: float,
    target: PaperTarget = "A",
    asperity_radius_m: float | None = None,
    spacing_m: float = 1e-3,
    ratio: float = 5.0,
    trials: int = BIAS_TRIALS,
    seed: int = 0,
    residual: Residual = BIAS_RESIDUAL,
    progress: ProgressFn | None = None,
) -> BiasPrediction:
    """The bias prediction of ``rough-viewer bias predict``: :func:`predict_bias` on
    the paper's target layout (:func:`paper_target`, nodes drawn with ``seed``).

    The one code path of every prediction on the paper's targets: the command, and
    the per-cell predictions of a scan (:mod:`rough_viewer.scanner.trust`), so the same
    noise, effective radius and asperity radius give the same numbers in both.

    Parameters
    ----------
    noise_sigma_m, effective_radius_m : float
        Range noise and beam effective radius, metres.
    target : {"A", "B"}
        The paper's target (r = 19 mm or 32.5 mm).
    asperity_radius_m : float, optional
        Another hemisphere radius on the same layout, metres.
    spacing_m, ratio, trials, residual, progress
        As :func:`predict_bias`.
    seed : int
        Seed of the node draw and of every noise and thinning draw.

    Examples
    --------
    The paper's target A with 1.6 mm of noise and no beam smoothing: 5.07 -> 5.31 mm
    in the paper (+4.7 %):

    >>> p = predict_paper_target(noise_sigma_m=0.0016, effective_radius_m=0.0, trials=1)
    >>> round(p.expected_m * 1e3, 2), round(p.noise_only_m * 1e3, 2)
    (5.07, 5.31)
    """
    return predict_bias(
        noise_sigma_m=noise_sigma_m, effective_radius_m=effective_radius_m,
        layout=paper_target(target, asperity_radius_m=asperity_radius_m, seed=seed),
        spacing_m=spacing_m, ratio=ratio, trials=trials, seed=seed, residual=residual,
        progress=progress)


@dataclass(frozen=True)
class SmoothingCurve:
    """Roughness error against ER / asperity radius (the paper's Fig. 4)."""

    asperity_radius_m: float
    """Hemisphere radius, metres."""
    effective_radius_m: np.ndarray
    """(K,) effective radii, metres."""
    er_ratio: np.ndarray
    """(K,) effective radius / asperity radius."""
    expected_m: float
    """Roughness of the true surface, metres."""
    noise_only_m: float
    """Roughness with noise and no smoothing, metres."""
    measured_m: np.ndarray
    """(K,) roughness with noise and smoothing, metres."""
    error_pct: np.ndarray
    """(K,) ``100 (measured / expected - 1)``."""
    vs_noisy_pct: np.ndarray
    """(K,) ``100 (measured / noise_only - 1)``."""
    noise_sigma_m: float
    """Range noise, metres."""


def smoothing_curve(
    effective_radii_m: np.ndarray,
    *,
    asperity_radius_m: float | None = None,
    layout: TargetLayout | None = None,
    noise_sigma_m: float = 0.0,
    spacing_m: float = 1e-3,
    ratio: float = 5.0,
    normalisation: Normalisation = "known",
    seed: int | None = 0,
    residual: Residual = BIAS_RESIDUAL,
    progress: ProgressFn | None = None,
) -> SmoothingCurve:
    """Roughness error for a series of effective radii on one target.

    One noise draw and one known-class thinning are shared by all radii, so the
    curve is smooth. See :func:`predict_bias` for the parameters; ``progress(done,
    total)`` counts the effective radii (``(0, K)`` first, then one call per radius).
    The radii are smoothed one at a time, so memory does not grow with their number.
    """
    ers = np.asarray(effective_radii_m, dtype=np.float64).ravel()
    if ers.size == 0 or not np.all(np.isfinite(ers)) or np.any(ers < 0):
        raise InputError("effective radii must be a non-empty list of finite values >= 0")
    _check_lengths([("noise sigma", noise_sigma_m)])
    _check_ratio(ratio)
    if layout is None:
        layout = paper_target("A", asperity_radius_m=asperity_radius_m)
    # the whole peak (raster and the largest smoothing) before anything is allocated
    _require_smoothing(raster_shape(layout, spacing_m), float(ers.max()), spacing_m,
                       raster=True)
    base = simulate_target(layout, spacing_m=spacing_m)
    xy = base.xyz(true=True)[:, :2]
    labels = base.labels()
    rng = np.random.default_rng(seed)
    noise = rng.normal(0.0, noise_sigma_m, size=base.true_height.shape) if noise_sigma_m > 0 \
        else np.zeros_like(base.true_height)
    if normalisation == "known":
        keep = normalise_population(np.column_stack((xy, base.true_height.ravel())), labels,
                                    ratio=ratio, seed=rng, residual=residual).keep
    elif normalisation == "none":
        keep = np.arange(labels.size)
    else:
        raise InputError(f"normalisation must be 'known' or 'none', got {normalisation!r}")
    expected, noisy = _roughness_variants(xy, [base.true_height, base.true_height + noise],
                                          keep, residual)
    if progress is not None:
        progress(0, int(ers.size))
    measured = np.empty(ers.size)
    for i, e in enumerate(ers):  # one smoothed raster alive at a time
        h = smooth_heights(base.true_height, effective_radius_m=float(e), spacing_m=spacing_m)
        measured[i] = _roughness_variants(xy, [h + noise], keep, residual)[0]
        if progress is not None:
            progress(i + 1, int(ers.size))
    r = float(layout.asperity_radius_m)
    return SmoothingCurve(
        asperity_radius_m=r, effective_radius_m=ers, er_ratio=ers / r,
        expected_m=expected, noise_only_m=noisy, measured_m=measured,
        error_pct=100.0 * (measured / expected - 1.0),
        vs_noisy_pct=100.0 * (measured / noisy - 1.0),
        noise_sigma_m=float(noise_sigma_m),
    )
