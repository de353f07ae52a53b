"""A scanner's calibration: its range noise, its beam effective radius against range,
and the span of ranges they were measured over (docs/scanner.md).

From the user's numbers (``--noise``, ``--beam-radius``), the JSON that ``rough-viewer
bias noise --json`` and ``bias radius --json`` write (``--calibration FILE``), or the
bias paper's values by default: 1.6 mm of range noise (a Riegl VZ-400, mean over 3 to
45 m) and its calibration span, the 3 to 38 m of its wire scans. The paper shows its
effective radii only in a figure (its Fig. 3A), so the default effective radius is the
toolkit's example value, 4 mm at every range (``bias predict --er 0.004``, the app's
Bias tab); measure yours with ``bias radius``.

>>> c = paper_calibration()
>>> c.noise_sigma_m, float(c.effective_radius(20.0)), c.span_m
(0.0016, 0.004, (3.0, 38.0))
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from rough_viewer.bias.measurement import PiecewiseLinearFit
from rough_viewer.vocabulary import InputError, error_line

#: The bias paper's range noise, metres (a Riegl VZ-400; mean over 3 to 45 m).
PAPER_NOISE_M = 0.0016
#: Effective radius used when none is measured, metres: the toolkit's example value
#: (``bias predict --er 0.004``); the paper shows its measured radii only graphically.
DEFAULT_EFFECTIVE_RADIUS_M = 0.004
#: Ranges of the bias paper's calibration scans (its wire, 3 to 38 m), metres.
PAPER_SPAN_M = (3.0, 38.0)
#: Largest noise or effective radius a calibration takes, metres (exclusive).
MAX_CALIBRATION_M = 1.0


@dataclass(frozen=True)
class Calibration:
    """Range noise and beam effective radius of a scanner, metres."""

    noise_sigma_m: float
    """Range noise (standard deviation along the beam), metres."""
    radius_ranges_m: np.ndarray
    """(K,) ranges of measured effective radii, ascending, metres (one value: a constant)."""
    radii_m: np.ndarray
    """(K,) effective radii at ``radius_ranges_m``, metres."""
    fit: PiecewiseLinearFit | None = None
    """A piecewise-linear fit of radius against range (``bias radius`` with 4+ scans),
    used instead of interpolating ``radii_m``."""
    span_m: tuple[float, float] | None = PAPER_SPAN_M
    """Ranges the calibration holds for, metres; None when unknown (numbers typed in)."""
    noise_source: str = "the bias paper (Riegl VZ-400)"
    """Where the noise came from."""
    radius_source: str = "the toolkit's example value"
    """Where the effective radius came from."""

    def effective_radius(self, range_m: np.ndarray | float) -> np.ndarray:
        """Effective radius at the given range(s), metres: the fit where there is one,
        else the measured radii interpolated (constant beyond the ends); never < 0."""
        r = np.asarray(range_m, dtype=np.float64)
        if self.fit is not None:
            return np.clip(self.fit.predict(r), 0.0, None)
        return np.interp(r, self.radius_ranges_m, self.radii_m)

    def check(self) -> None:
        """Raise InputError unless noise and radii are finite, >= 0 and below 1 m."""
        values = [("range noise", self.noise_sigma_m)]
        values += [("effective radius", float(v)) for v in np.ravel(self.radii_m)]
        for what, v in values:
            if not (math.isfinite(v) and 0.0 <= v < MAX_CALIBRATION_M):
                raise InputError(f"{what} must be a length >= 0 and below 1 m, got {v:g} m")
        if np.size(self.radii_m) == 0 or np.shape(self.radii_m) != np.shape(self.radius_ranges_m):
            raise InputError("a calibration needs at least one effective radius")

    def describe(self, *, per: float = 1.0, unit: str = "m", small_per: float = 1e-3,
                 small_unit: str = "mm") -> str:
        """One line: the noise, the radius (constant, or over its ranges) and the span,
        lengths in ``unit`` (ranges) and ``small_unit`` (noise, radii)."""
        noise = f"range noise {self.noise_sigma_m / small_per:.3g} {small_unit} ({self.noise_source})"
        if self.fit is not None:
            lo, hi = (float(v) for v in self.radius_ranges_m[[0, -1]])
            radius = (f"effective radius {float(self.effective_radius(lo)) / small_per:.3g} to "
                      f"{float(self.effective_radius(hi)) / small_per:.3g} {small_unit} "
                      f"(piecewise fit, {self.radius_source})")
        elif np.size(self.radii_m) > 1:
            radius = (f"effective radius {float(self.radii_m.min()) / small_per:.3g} to "
                      f"{float(self.radii_m.max()) / small_per:.3g} {small_unit} "
                      f"(interpolated, {self.radius_source})")
        else:
            radius = (f"effective radius {float(self.radii_m[0]) / small_per:.3g} {small_unit} "
                      f"({self.radius_source})")
        span = ("calibrated span unknown" if self.span_m is None else
                f"calibrated over {self.span_m[0] / per:g} to {self.span_m[1] / per:g} {unit}")
        return f"{noise}; {radius}; {span}"


def paper_calibration() -> Calibration:
    """The default: the bias paper's noise and span, the toolkit's example radius."""
    return Calibration(noise_sigma_m=PAPER_NOISE_M,
                       radius_ranges_m=np.array([0.0]),
                       radii_m=np.array([DEFAULT_EFFECTIVE_RADIUS_M]))


def _read_json(p: Path) -> dict:
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"calibration file not found: {p}") from None
    except (OSError, ValueError) as exc:
        raise InputError(f"cannot read {p} as calibration JSON: {error_line(exc)}") from None
    if not isinstance(data, dict):
        raise InputError(f"{p} is not the JSON of 'bias noise --json' or 'bias radius --json'")
    return data


def _number(p: Path, value: object, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise InputError(f"{p}: {what} must be a finite number, got {value!r}")
    return float(value)


def read_calibration(path: str | os.PathLike[str], base: Calibration | None = None) -> Calibration:
    """Apply one calibration JSON to ``base`` (default :func:`paper_calibration`).

    ``bias noise --json`` (a ``"sigma"``, metres) sets the range noise; ``bias radius
    --json`` (``"scans"`` with ``effective_radius`` and ``range``, and ``"fit"`` with
    4+ scans) sets the effective radius against range and the calibrated span (the
    scans' ranges).

    Raises
    ------
    InputError
        A missing or unreadable file, JSON of another kind, or values that are not
        lengths (the message names the file).
    """
    p = Path(path)
    data = _read_json(p)
    cal = base or paper_calibration()
    if "scans" in data:
        scans = data["scans"]
        if not isinstance(scans, list) or not scans:
            raise InputError(f"{p}: 'scans' must be a non-empty list (bias radius --json)")
        try:
            pairs = sorted((_number(p, s["range"], "range"),
                            _number(p, s["effective_radius"], "effective_radius"))
                           for s in scans)
        except (KeyError, TypeError):
            raise InputError(f"{p}: every scan needs 'range' and 'effective_radius' "
                             "(bias radius --json)") from None
        ranges = np.array([a for a, _ in pairs])
        radii = np.array([b for _, b in pairs])
        fit = None
        f = data.get("fit")
        if isinstance(f, dict):
            try:
                fit = PiecewiseLinearFit(
                    break_range=_number(p, f["break_range"], "fit.break_range"),
                    intercept=_number(p, f["intercept"], "fit.intercept"),
                    slope_near=_number(p, f["slope_near"], "fit.slope_near"),
                    slope_far=_number(p, f["slope_far"], "fit.slope_far"),
                    rmse=_number(p, f.get("rmse", 0.0), "fit.rmse"),
                    n=int(f.get("n", len(pairs))), break_given=bool(f.get("break_given")))
            except KeyError as exc:
                raise InputError(f"{p}: the fit has no {exc.args[0]!r}") from None
        out = replace(cal, radius_ranges_m=ranges, radii_m=radii, fit=fit,
                      span_m=(float(ranges[0]), float(ranges[-1])),
                      radius_source=f"{p.name}: {len(pairs)} wire scan"
                                    f"{'s' if len(pairs) != 1 else ''}")
    elif "sigma" in data:
        out = replace(cal, noise_sigma_m=_number(p, data["sigma"], "sigma"),
                      noise_source=f"{p.name}: board scan")
    else:
        raise InputError(f"{p} is neither 'bias noise --json' (sigma) nor 'bias radius --json' "
                         "(scans) output")
    try:
        out.check()
    except InputError as exc:
        raise InputError(f"{p}: {exc}") from None
    return out


def calibration(*, noise_sigma_m: float | None = None, effective_radius_m: float | None = None,
                files: Iterable[str | os.PathLike[str]] = ()) -> Calibration:
    """The calibration a run uses: the paper's, then each file in turn, then the
    numbers given (a number replaces what a file said; a typed-in radius has no
    calibrated span).

    >>> c = calibration(noise_sigma_m=0.002, effective_radius_m=0.006)
    >>> c.noise_sigma_m, float(c.effective_radius(50.0)), c.span_m
    (0.002, 0.006, None)
    """
    cal = paper_calibration()
    for f in files:
        cal = read_calibration(f, cal)
    if noise_sigma_m is not None:
        cal = replace(cal, noise_sigma_m=float(noise_sigma_m), noise_source="given")
    if effective_radius_m is not None:
        cal = replace(cal, radius_ranges_m=np.array([0.0]),
                      radii_m=np.array([float(effective_radius_m)]), fit=None, span_m=None,
                      radius_source="given")
    cal.check()
    return cal
