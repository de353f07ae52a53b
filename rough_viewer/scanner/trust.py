"""Scanner-aware roughness: how far to trust each cell (docs/scanner.md).

For every cell of a grid result of a cloud whose scanner positions are known
(:mod:`rough_viewer.scanner.positions`), the scanner geometry
(:func:`rough_viewer.scanner.geometry.scan_geometry`: scans, range, incidence, density
ratio, occlusion) and the roughness bias the toolkit's models predict for it:

- noise inflation: range noise ``sigma`` acts along the beam, so ``s = sigma cos(i)``
  across the cell's plane, and adds ``s^2`` to the mean squared orthogonal distance
  ``m2`` of the cell's points (independent noise: exactly, in expectation; the
  signed-residual roughness of ``bias predict`` is ``sqrt(m2)``, and its simulation of
  target A gives 5.07 -> 5.31 mm as the paper). The grid's roughness (the std of the
  absolute distances) keeps its ratio ``q = theta / sqrt(m2)`` to the RMS, so the
  noise adds ``q^2 s^2`` to ``theta^2`` (exact for Gaussian heights, ``q^2 = 1 -
  2/pi``; within 1 % on target A);
- beam smoothing: the fraction the simulated target loses at the cell's ratio of
  effective radius (at its range) to asperity radius (``smoothing_effect_pct`` of
  the prediction); the asperity radius is ``--asperity-radius`` (default target A's
  19 mm), but at most half the grid size, the largest feature a cell can hold;
- measured ``theta = sqrt((theta_true (1 + f_s))^2 + q^2 s^2)``, so
  ``noise_pred = theta - theta sqrt(1 - s^2 / m2)`` (>= 0; all of theta where
  ``s^2 >= m2``),
  ``smoothing_pred`` the (negative) change the smoothing made, and
  ``bias_pred = noise_pred + smoothing_pred = theta - theta_true``.

The smoothing, and the calibration's reference figure on target A, run through
:func:`rough_viewer.bias.simulation.predict_paper_target`, the code path of
``rough-viewer bias predict``. Cells outside the papers'
recommendations are flagged: incidence above 22.5 degrees (the 2012 paper's
half-angle), a range outside the calibrated span, predicted noise above 30 % of the
measured roughness. ``trusted`` = a cell with a value and none of the flags.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rough_viewer.bias.calibration import Calibration, paper_calibration
from rough_viewer.bias.simulation import PAPER_RADIUS_M, BiasPrediction, predict_paper_target
from rough_viewer.grid.roughness import GridRoughness
from rough_viewer.io.cloud import PointCloud
from rough_viewer.scanner.geometry import ScanGeometry, scan_geometry
from rough_viewer.scanner.positions import NO_POSITIONS, cloud_scanners
from rough_viewer.vocabulary import (
    BIAS_TRIALS,
    TRUST_FIELDS,
    TRUST_LABELS,
    InputError,
    ProgressFn,
    Residual,
    roughness_scale,
    unit_scale,
)

#: Largest incidence angle the 2012 paper recommends: "half-angles ... less than
#: 22.5 degrees" (errors within 5 %), degrees.
INCIDENCE_LIMIT_DEG = 22.5
#: Largest share of the measured roughness the predicted noise may make up.
NOISE_SHARE_LIMIT = 0.30
#: Default asperity radius, metres: the bias paper's target A.
DEFAULT_ASPERITY_RADIUS_M = PAPER_RADIUS_M["A"]
#: Ratios of effective radius to asperity radius are simulated up to this (beyond it
#: the beam flattens the hemispheres whole; cells beyond take its prediction).
MAX_ER_RATIO = 3.0
#: Spacing of the simulated ratios, and the most of them one model simulates.
RATIO_STEP = 0.05
MAX_RATIO_SAMPLES = 8

#: Flag bits of :attr:`CellTrust.flags`.
FLAG_INCIDENCE = 1
FLAG_RANGE = 2
FLAG_NOISE = 4
FLAG_NAMES: dict[int, str] = {
    FLAG_INCIDENCE: "incidence above 22.5 degrees (2012 paper)",
    FLAG_RANGE: "range outside the calibrated span",
    FLAG_NOISE: "predicted noise above 30 % of the roughness",
}

#: Columns of :meth:`CellTrust.columns` that are lengths (metres).
LENGTH_FIELDS = ("range", "noise_pred", "smoothing_pred", "bias_pred")


#: Finest angular step accepted, degrees: a thousandth of the finest terrestrial
#: scanners' (about 0.001 deg); finer ones underflow the expected density's square
#: (``--angular-step 1e-300`` ended in ZeroDivisionError).
MIN_ANGULAR_STEP_DEG = 1e-6


@dataclass(frozen=True)
class TrustSettings:
    """What the per-cell trust is computed with (the ``--scanner ...`` options)."""

    calibration: Calibration = field(default_factory=paper_calibration)
    """Range noise, effective radius against range, calibrated span."""
    asperity_radius_m: float = DEFAULT_ASPERITY_RADIUS_M
    """Radius of the features of interest, metres (default target A's 19 mm)."""
    angular_step_rad: float | None = None
    """The scanners' angular step, radians (``N0 = 1 / step^2``); None: fitted."""
    trials: int = BIAS_TRIALS
    """Noise draws each simulation averages."""

    def check(self) -> None:
        """Raise InputError (one line) for a setting that cannot be used."""
        self.calibration.check()
        a = self.asperity_radius_m
        if not (math.isfinite(a) and 0.0 < a < 1.0):
            raise InputError(f"asperity radius must be a length > 0 and below 1 m, got {a:g} m")
        s = self.angular_step_rad
        if s is not None and not (math.isfinite(s) and math.radians(MIN_ANGULAR_STEP_DEG) <= s
                                  < math.radians(10.0)):
            raise InputError(f"angular step must be above 0 and below 10 degrees (at least "
                             f"{MIN_ANGULAR_STEP_DEG:g}: no scanner steps finer), got "
                             f"{math.degrees(s):g} degrees")
        if not 1 <= int(self.trials) <= 1000:
            raise InputError(f"trials must be 1 to 1000, got {self.trials}")


@dataclass(frozen=True)
class BiasModel:
    """The toolkit's predictions for one noise and asperity radius: the noise gain and
    the smoothing against ER / asperity radius, each from
    :func:`~rough_viewer.bias.simulation.predict_paper_target`."""

    predictions: tuple[BiasPrediction, ...]
    """One prediction per simulated ratio (same noise draws: same noise effect)."""
    er_ratio: np.ndarray
    """(K,) ratios of effective radius to asperity radius simulated, ascending."""
    residual: Residual
    """Roughness convention of the simulations (the grid's)."""

    @property
    def noise(self) -> BiasPrediction:
        """The prediction of the noise effect (the first one)."""
        return self.predictions[0]

    @property
    def noise_sigma_m(self) -> float:
        """Range noise simulated, metres."""
        return self.noise.noise_sigma_m

    @property
    def noise_gain(self) -> float:
        """Squared roughness the noise adds to the simulated target, per squared noise
        sigma (1 for signed residuals: the variance adds)."""
        p = self.noise
        if p.noise_sigma_m <= 0:
            return 0.0
        return max(0.0, (p.noise_only_m ** 2 - p.expected_m ** 2) / p.noise_sigma_m ** 2)

    @property
    def smoothing_pct(self) -> np.ndarray:
        """(K,) smoothing effect at each ratio, percent (<= 0)."""
        return np.array([p.smoothing_effect_pct for p in self.predictions])

    def smoothing_fraction(self, er_ratio: np.ndarray) -> np.ndarray:
        """Smoothing effect at the given ratios, a fraction (-0.05 = 5 % lower),
        interpolated linearly between the simulated ratios (their ends beyond)."""
        return np.interp(np.asarray(er_ratio, dtype=np.float64), self.er_ratio,
                         self.smoothing_pct / 100.0)


@functools.lru_cache(maxsize=16)
def _model(noise_sigma_m: float, asperity_radius_m: float, ratios: tuple[float, ...],
           residual: Residual, trials: int) -> BiasModel:
    preds = tuple(predict_paper_target(noise_sigma_m=noise_sigma_m,
                                       effective_radius_m=rho * asperity_radius_m,
                                       asperity_radius_m=asperity_radius_m, trials=trials,
                                       residual=residual)
                  for rho in ratios)
    return BiasModel(predictions=preds, er_ratio=np.array(ratios), residual=residual)


def ratio_samples(er_ratio: np.ndarray) -> tuple[float, ...]:
    """The ratios to simulate for cells of these ratios: the one value when they are
    all equal, else a grid of :data:`RATIO_STEP` (coarser past
    :data:`MAX_RATIO_SAMPLES` values) covering them, within ``[0, MAX_ER_RATIO]``.

    >>> ratio_samples(np.array([0.21, 0.21])), ratio_samples(np.array([0.12, 0.26]))
    ((0.21,), (0.1, 0.15, 0.2, 0.25, 0.3))
    """
    r = np.asarray(er_ratio, dtype=np.float64)
    r = np.clip(r[np.isfinite(r)], 0.0, MAX_ER_RATIO)
    if r.size == 0:
        return (0.0,)
    lo, hi = float(r.min()), float(r.max())
    if hi - lo < 1e-9:
        return (round(lo, 12),)
    step = RATIO_STEP
    while True:
        a, b = math.floor(lo / step + 1e-9), math.ceil(hi / step - 1e-9)
        if b - a + 1 <= MAX_RATIO_SAMPLES:
            return tuple(round(k * step, 12) for k in range(a, b + 1))
        step *= 2.0


def bias_model(noise_sigma_m: float, er_ratios: tuple[float, ...], *,
               asperity_radius_m: float = DEFAULT_ASPERITY_RADIUS_M,
               residual: Residual = "absolute", trials: int = BIAS_TRIALS) -> BiasModel:
    """The toolkit's predictions at these ratios (cached: the same arguments give the
    same object). A ratio takes one :func:`predict_paper_target` run, about 0.4 s a
    trial at the paper's 1 mm raster."""
    return _model(float(noise_sigma_m), float(asperity_radius_m),
                  tuple(float(r) for r in er_ratios), residual, int(trials))


@dataclass(frozen=True)
class CellTrust:
    """Scanner geometry and predicted bias of every cell of a grid result; (M,) arrays
    aligned with the result's cells (NaN where a cell has no value)."""

    geometry: ScanGeometry
    """Scans, range, incidence, density ratio, occlusion."""
    settings: TrustSettings
    """The calibration and options used."""
    model: BiasModel
    """The toolkit's predictions the cells were read from."""
    grid_size_m: float
    """Cell edge of the result, metres."""
    asperity_scale_m: float
    """Asperity radius the smoothing is judged at: the setting, at most half the grid size."""
    theta_m: np.ndarray
    """(M,) the cells' ODR roughness (the result's residual convention), metres."""
    effective_radius_m: np.ndarray
    """(M,) beam effective radius at the cell's range, metres."""
    er_ratio: np.ndarray
    """(M,) effective radius / asperity scale."""
    noise_pred_m: np.ndarray
    """(M,) roughness the range noise adds (>= 0), metres."""
    smoothing_pred_m: np.ndarray
    """(M,) roughness the beam smoothing takes away (<= 0), metres."""
    bias_pred_m: np.ndarray
    """(M,) net predicted bias, measured - true, metres."""
    flags: np.ndarray
    """(M,) uint8 bits :data:`FLAG_INCIDENCE`, :data:`FLAG_RANGE`, :data:`FLAG_NOISE`."""
    known: np.ndarray
    """(M,) bool: the cell has a roughness value and a geometry (its trust is judged)."""

    @property
    def trusted(self) -> np.ndarray:
        """(M,) 1.0 for a trusted cell, 0.0 for a flagged one, NaN where not judged."""
        return np.where(self.known, (self.flags == 0).astype(np.float64), np.nan)

    def layer(self, name: str) -> np.ndarray:
        """(M,) float64 values of one :data:`rough_viewer.vocabulary.TRUST_FIELDS`
        field (lengths in metres, NaN where none): a colour layer of the cells."""
        if name not in TRUST_FIELDS:
            raise ValueError(f"unknown trust field {name!r}; expected one of "
                             f"{', '.join(TRUST_FIELDS)}")
        geo = self.geometry
        values: dict[str, np.ndarray] = {
            "scans": geo.scans.astype(np.float64),
            "range": geo.range_m,
            "incidence_deg": geo.incidence_deg,
            "density_ratio": geo.density_ratio,
            "occlusion": geo.occlusion,
            "noise_pred": self.noise_pred_m,
            "smoothing_pred": self.smoothing_pred_m,
            "bias_pred": self.bias_pred_m,
            "trusted": self.trusted,
        }
        return values[name]

    def columns(self) -> dict[str, np.ndarray]:
        """The :data:`~rough_viewer.vocabulary.TRUST_FIELDS` as (M,) arrays for the
        cell table (lengths in metres): ``scans`` and ``trusted`` integers masked
        where unknown, the others float64 with NaN."""
        out: dict[str, np.ndarray] = {}
        for name in TRUST_FIELDS:
            v = self.layer(name)
            if name in ("scans", "trusted"):
                out[name] = np.ma.masked_array(np.nan_to_num(v).astype(np.int64),
                                               mask=~np.isfinite(v))
            else:
                out[name] = v
        return out

    def lines(self, row: int, unit: str = "m") -> list[str]:
        """A cell's trust figures as text lines (the app's cell report): scans, range
        and incidence, density and occlusion, the predicted bias beside theta, and
        whether it is trusted (or why not). Ranges in ``unit``, roughness in its
        roughness unit (mm for metric input)."""
        per, ul = unit_scale(unit)
        rper, rl = roughness_scale(unit)
        geo = self.geometry
        if not (0 <= row < self.theta_m.shape[0]):
            raise IndexError(f"no cell {row}")
        if not np.isfinite(geo.range_m[row]):
            return [f"seen by {int(geo.scans[row])} scan(s); no plane, so no range, incidence "
                    "or predicted bias"]
        lines = [f"seen by {int(geo.scans[row])} scan{'s' if geo.scans[row] != 1 else ''}: "
                 f"range {geo.range_m[row] / per:.2f} {ul}, incidence "
                 f"{geo.incidence_deg[row]:.1f} degrees"]
        dens = geo.density_ratio[row]
        occ = geo.occlusion[row]
        lines.append(
            (f"point density {dens:.2f} x expected ({geo.n0_source} N0)" if np.isfinite(dens)
             else "point density: no expected value")
            + (f", occlusion {occ:.2f}" if np.isfinite(occ) else ", occlusion: no neighbour "
               "along the beam"))
        th = self.theta_m[row]
        if np.isfinite(th):
            pct = 100.0 * self.bias_pred_m[row] / (th - self.bias_pred_m[row]) \
                if th - self.bias_pred_m[row] > 0 else float("nan")
            lines.append(f"predicted bias {self.bias_pred_m[row] / rper:+.3f} {rl} of ODR "
                         f"{th / rper:.3f} {rl} ({pct:+.1f} %): noise "
                         f"{self.noise_pred_m[row] / rper:+.3f}, beam smoothing "
                         f"{self.smoothing_pred_m[row] / rper:+.3f} {rl} (ER "
                         f"{self.effective_radius_m[row] / rper:.2f} {rl}, ER/r "
                         f"{self.er_ratio[row]:.2f})")
        if self.known[row]:
            f = int(self.flags[row])
            lines.append("trusted" if f == 0 else "not trusted: " + "; ".join(
                text for bit, text in FLAG_NAMES.items() if f & bit))
        return lines

    def summary(self) -> TrustSummary:
        """The figures of all judged cells (the report's section)."""
        return trust_summary(self)


def cell_trust(
    cloud: PointCloud,
    result: GridRoughness,
    settings: TrustSettings | None = None,
    *,
    progress: ProgressFn | None = None,
) -> CellTrust | None:
    """Scanner geometry and predicted bias of every cell of ``result``.

    Parameters
    ----------
    cloud : PointCloud
        The points ``result`` was computed from, with scanner positions
        (:func:`rough_viewer.scanner.positions.cloud_scanners`).
    result : GridRoughness
        The grid result (in memory: its point-to-cell map is needed).
    settings : TrustSettings, optional
        Calibration and options (default: the paper's).
    progress : callable, optional
        ``progress(done, total)`` over 4 stages.

    Returns
    -------
    CellTrust, or None when the cloud has no scanner positions
    (:data:`rough_viewer.scanner.positions.NO_POSITIONS` says what to give).
    """
    settings = settings or TrustSettings()
    settings.check()
    scanners = cloud_scanners(cloud)
    if scanners is None:
        return None
    positions, scan = scanners
    tick = progress or (lambda done, total: None)
    geo = scan_geometry(cloud, result, positions, scan,
                        angular_step_rad=settings.angular_step_rad,
                        progress=lambda d, t: tick(min(d, 2), 4))
    tick(2, 4)
    cal = settings.calibration
    g = result.grid.cell_size
    scale = min(settings.asperity_radius_m, 0.5 * g)
    er = cal.effective_radius(np.where(np.isfinite(geo.range_m), geo.range_m, 0.0))
    er = np.where(np.isfinite(geo.range_m), er, np.nan)
    ratio = er / scale
    model = bias_model(cal.noise_sigma_m, ratio_samples(ratio),
                       asperity_radius_m=settings.asperity_radius_m,
                       residual=result.residual, trials=settings.trials)
    tick(3, 4)
    theta = result.theta_odr
    sigma = cal.noise_sigma_m * np.cos(np.radians(geo.incidence_deg))
    with np.errstate(invalid="ignore", divide="ignore"):
        # the noise adds sigma^2 to the mean squared distance m2; theta keeps its ratio
        # to sqrt(m2) (signed residuals: theta = sqrt(m2))
        keep = np.clip(1.0 - sigma * sigma / geo.plane_variance, 0.0, None)
        smoothed = theta * np.sqrt(np.where(geo.plane_variance > 0, keep, 0.0))
        noise = theta - smoothed
        frac = model.smoothing_fraction(np.clip(ratio, 0.0, MAX_ER_RATIO))
        true = smoothed / (1.0 + frac)
        smoothing = smoothed - true
        bias = theta - true
    known = np.isfinite(theta) & np.isfinite(geo.range_m) & np.isfinite(geo.incidence_deg)
    flags = np.zeros(result.n_cells, dtype=np.uint8)
    with np.errstate(invalid="ignore"):
        flags[geo.incidence_deg > INCIDENCE_LIMIT_DEG] |= FLAG_INCIDENCE
        if cal.span_m is not None:
            lo, hi = cal.span_m
            flags[(geo.range_m < lo) | (geo.range_m > hi)] |= FLAG_RANGE
        flags[noise > NOISE_SHARE_LIMIT * theta] |= FLAG_NOISE
    flags[~known] = 0
    tick(4, 4)
    return CellTrust(geometry=geo, settings=settings, model=model, grid_size_m=float(g),
                     asperity_scale_m=float(scale), theta_m=theta, effective_radius_m=er,
                     er_ratio=ratio, noise_pred_m=noise, smoothing_pred_m=smoothing,
                     bias_pred_m=bias, flags=flags, known=known)


# ----------------------------------------------------------------------------- summary


def _spread(v: np.ndarray) -> tuple[float, float, float]:
    """(median, 5th, 95th percentile) of the finite values, NaN when none."""
    f = v[np.isfinite(v)]
    if f.size == 0:
        return (math.nan, math.nan, math.nan)
    p5, p50, p95 = np.percentile(f, [5, 50, 95])
    return (float(p50), float(p5), float(p95))


@dataclass(frozen=True)
class TrustSummary:
    """The trust figures of one grid (the report's section, the command's lines)."""

    cells: int
    """Cells judged (a roughness value and a geometry)."""
    scans: dict[int, int]
    """Cells by the number of scans seeing them."""
    range_m: tuple[float, float, float]
    """Median, 5th and 95th percentile of the range, metres."""
    incidence_deg: tuple[float, float, float]
    """The same of the incidence, degrees."""
    density_ratio: tuple[float, float, float]
    """The same of the density ratio."""
    occlusion: tuple[float, float, float]
    """The same of the occlusion."""
    noise_pct: tuple[float, float, float]
    """The same of the predicted noise, percent of the measured roughness."""
    smoothing_pct: tuple[float, float, float]
    """The same of the predicted smoothing, percent of the measured roughness."""
    bias_pct: tuple[float, float, float]
    """The same of the net predicted bias, percent of the measured roughness."""
    flagged: dict[str, int]
    """Cells per flag (``incidence``, ``range``, ``noise``)."""
    trusted: int
    """Cells with none of the flags."""
    n0: tuple[float, ...]
    """Rays per steradian of every scan."""
    n0_source: str
    """``"angular step"`` or ``"fitted"``."""
    target_noise_pct: float
    """The calibration's noise inflation of the paper's target (``bias predict``), %."""
    asperity_scale_m: float
    """Asperity radius the smoothing was judged at, metres."""
    calibration: Calibration
    """The calibration used."""

    def as_dict(self, *, per: float = 1.0) -> dict[str, Any]:
        """Plain numbers (JSON): ranges divided by ``per`` (metres per unit); the
        angular step each N0 means, degrees."""
        out: dict[str, Any] = {
            "cells": self.cells, "trusted": self.trusted,
            "scans": {str(k): v for k, v in sorted(self.scans.items())},
            "flagged": dict(self.flagged),
        }
        for name in ("range_m", "incidence_deg", "density_ratio", "occlusion", "noise_pct",
                     "smoothing_pct", "bias_pct"):
            v = getattr(self, name)
            d = per if name == "range_m" else 1.0
            out[name.removesuffix("_m") if name == "range_m" else name] = {
                "median": v[0] / d, "p5": v[1] / d, "p95": v[2] / d}
        out["n0_per_sr"] = list(self.n0)
        out["angular_step_deg"] = [math.degrees(1.0 / math.sqrt(v)) if v > 0 else None
                                   for v in self.n0]
        out["n0_source"] = self.n0_source
        out["target_noise_pct"] = self.target_noise_pct
        out["asperity_radius"] = self.asperity_scale_m / per
        out["noise_sigma"] = self.calibration.noise_sigma_m / per
        out["calibrated_span"] = (None if self.calibration.span_m is None
                                  else [v / per for v in self.calibration.span_m])
        out["incidence_limit_deg"] = INCIDENCE_LIMIT_DEG
        out["noise_share_limit"] = NOISE_SHARE_LIMIT
        return out

    def lines(self, unit: str = "m") -> list[str]:
        """The summary as a few text lines, ranges in ``unit``."""
        per, ul = unit_scale(unit)
        rper, rl = roughness_scale(unit)
        if self.cells == 0:
            return ["scanner: no cell with a value and a geometry"]
        scans = ", ".join(f"{v:,} by {k}" for k, v in sorted(self.scans.items()))
        r, i, d, o = self.range_m, self.incidence_deg, self.density_ratio, self.occlusion
        step = [math.degrees(1.0 / math.sqrt(v)) for v in self.n0 if v > 0]
        steps = (f"{min(step):.4f}" if step and max(step) - min(step) < 1e-4 * max(step)
                 else (f"{min(step):.4f}-{max(step):.4f}" if step else "?"))
        flag = ", ".join(f"{v:,} {k}" for k, v in self.flagged.items())
        return [
            f"scanner: {self.cells:,} cells seen ({scans} scan(s)); range {r[0] / per:.2f} "
            f"{ul} (5-95 %: {r[1] / per:.2f}-{r[2] / per:.2f}), incidence {i[0]:.1f} degrees "
            f"({i[1]:.1f}-{i[2]:.1f})",
            f"  density ratio {d[0]:.2f} ({d[1]:.2f}-{d[2]:.2f}; N0 {self.n0_source}, angular "
            f"step {steps} degrees), occlusion {o[0]:.2f} (95 %: {o[2]:.2f})",
            f"  predicted bias {self.bias_pct[0]:+.1f} % of ODR (noise {self.noise_pct[0]:+.1f} "
            f"%, beam smoothing {self.smoothing_pct[0]:+.1f} % at asperity radius "
            f"{self.asperity_scale_m / rper:.3g} {rl}); "
            + self.calibration.describe(per=per, unit=ul, small_per=rper, small_unit=rl),
            f"  trusted {self.trusted:,} of {self.cells:,} ({100.0 * self.trusted / self.cells:.0f} "
            f"%); flagged: {flag}",
        ]


def trust_summary(trust: CellTrust) -> TrustSummary:
    """Medians, spreads and counts of the judged cells of ``trust``."""
    k = trust.known
    th = trust.theta_m
    with np.errstate(invalid="ignore", divide="ignore"):
        share = lambda v: np.where(k & (th > 0), 100.0 * v / th, np.nan)  # noqa: E731
        noise, smooth, bias = (share(v) for v in (trust.noise_pred_m, trust.smoothing_pred_m,
                                                  trust.bias_pred_m))
    geo = trust.geometry
    scans, counts = np.unique(geo.scans[k], return_counts=True)
    flags = trust.flags[k]
    return TrustSummary(
        cells=int(np.count_nonzero(k)),
        scans={int(a): int(b) for a, b in zip(scans, counts, strict=True)},
        range_m=_spread(np.where(k, geo.range_m, np.nan)),
        incidence_deg=_spread(np.where(k, geo.incidence_deg, np.nan)),
        density_ratio=_spread(np.where(k, geo.density_ratio, np.nan)),
        occlusion=_spread(np.where(k, geo.occlusion, np.nan)),
        noise_pct=_spread(noise), smoothing_pct=_spread(smooth), bias_pct=_spread(bias),
        flagged={"incidence": int(np.count_nonzero(flags & FLAG_INCIDENCE)),
                 "range": int(np.count_nonzero(flags & FLAG_RANGE)),
                 "noise": int(np.count_nonzero(flags & FLAG_NOISE))},
        trusted=int(np.count_nonzero(flags == 0)),
        n0=tuple(float(v) for v in geo.n0 if np.isfinite(v)),
        n0_source=geo.n0_source,
        target_noise_pct=trust.model.noise.noise_effect_pct,
        asperity_scale_m=trust.asperity_scale_m,
        calibration=trust.settings.calibration,
    )


__all__ = [
    "FLAG_INCIDENCE", "FLAG_NAMES", "FLAG_NOISE", "FLAG_RANGE", "INCIDENCE_LIMIT_DEG",
    "NOISE_SHARE_LIMIT", "NO_POSITIONS", "TRUST_LABELS", "BiasModel", "CellTrust",
    "TrustSettings", "TrustSummary", "bias_model", "cell_trust", "ratio_samples",
    "trust_summary",
]
