"""Z2 and the joint roughness coefficient estimated from it (Tse and Cruden 1979).

Definitions:

- ``Z2``, the root mean square of the first derivative of a profile (Myers 1962;
  the form Tse and Cruden used): ``Z2 = sqrt( 1 / (M dx^2) * sum_i (y_{i+1} - y_i)^2 )``
  over the M intervals of a profile sampled every ``dx``. Dimensionless (a slope).
  Here the sum runs over the intervals whose two samples are finite (a gap's NaN
  samples are skipped, never bridged) and M counts them.
- JRC estimate: ``JRC = 32.2 + 32.47 log10(Z2)`` (Tse and Cruden 1979, their
  regression on Barton and Choubey's ten standard profiles). It is an estimate: the
  regression was made on profiles digitised at a fine, fixed interval, and Z2 grows
  as the sampling interval shrinks, so the formula only holds for profiles sampled
  at about 0.5-1 mm (:data:`JRC_SPACING_M`); :func:`jrc_warnings` says so for any
  other spacing. JRC is not clipped to Barton's 0-20 scale: a value outside it says
  the profile is smoother or rougher than any standard profile.

>>> import numpy as np
>>> saw = np.tile([0.0, 1e-3], 50)          # teeth 1 mm high every 2 mm: slope 1
>>> z2(saw, 1e-3)
1.0
>>> round(jrc_from_z2(0.2), 2)
9.5
"""

from __future__ import annotations

import numpy as np

from rough_viewer.vocabulary import InputError

#: Tse and Cruden (1979): JRC = JRC_INTERCEPT + JRC_SLOPE * log10(Z2).
JRC_INTERCEPT = 32.2
JRC_SLOPE = 32.47
#: Sampling intervals (metres) the JRC estimate holds for: about 0.5 to 1 mm.
JRC_SPACING_M = (0.5e-3, 1.0e-3)
#: "About": intervals within this share outside that range give no warning.
JRC_SPACING_TOLERANCE = 0.1


def z2(heights: np.ndarray, spacing: float) -> float:
    """Z2 of a profile: the RMS of ``(y_{i+1} - y_i) / spacing`` over the intervals
    whose two samples are finite (dimensionless); NaN with no such interval.

    Parameters
    ----------
    heights : (K,) array
        Heights at a regular spacing, metres (NaN in gaps).
    spacing : float
        Sample spacing, metres.
    """
    h = np.asarray(heights, dtype=np.float64)
    if h.ndim != 1:
        raise InputError(f"a profile must be one-dimensional, got shape {h.shape}")
    if not (np.isfinite(spacing) and spacing > 0):
        raise InputError(f"spacing must be a positive length in metres, got {spacing}")
    d = np.diff(h)
    d = d[np.isfinite(d)]
    if d.size == 0:
        return float("nan")
    return float(np.sqrt(np.mean(d * d)) / spacing)


def jrc_from_z2(value: float | np.ndarray) -> float | np.ndarray:
    """The JRC estimate of Tse and Cruden (1979), ``32.2 + 32.47 log10(Z2)``
    (NaN where Z2 <= 0 or NaN); a float for a float, an array for an array."""
    z = np.asarray(value, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.where(z > 0, JRC_INTERCEPT + JRC_SLOPE * np.log10(np.where(z > 0, z, 1.0)),
                       np.nan)
    return float(out) if out.ndim == 0 else out


def jrc_warnings(spacing: float) -> tuple[str, ...]:
    """One warning when profiles sampled every ``spacing`` metres lie outside the
    0.5-1 mm the JRC estimate was calibrated for, by more than
    :data:`JRC_SPACING_TOLERANCE` (else none)."""
    lo, hi = JRC_SPACING_M
    if lo * (1 - JRC_SPACING_TOLERANCE) <= spacing <= hi * (1 + JRC_SPACING_TOLERANCE):
        return ()
    return (f"JRC estimates (Tse and Cruden 1979) hold for profiles sampled at about "
            f"{lo * 1e3:g}-{hi * 1e3:g} mm; these are sampled every {spacing * 1e3:.3g} mm, "
            "and Z2 (so JRC) grows as the interval shrinks: read them as indications only",)
