"""The ``DIRECTIONS.csv`` contract: one row per azimuth of a
:class:`~rough_viewer.directions.analysis.DirectionsResult`, the one table every output
shows (the command's CSV and text, the report, the app's table and rose)."""

from __future__ import annotations

import numpy as np

from rough_viewer.directions.analysis import DirectionsResult
from rough_viewer.vocabulary import UNIT_METRES

#: The ``DIRECTIONS.csv`` contract: these columns first, in this order (``delta_t``
#: only where the surface has triangles), then :data:`EXTRA_COLUMNS`.
TABLE_COLUMNS = ("azimuth_deg", "profiles", "h_mean", "h_std", "d_mean", "d_std", "rms_mean",
                 "z2_mean", "jrc_mean", "theta_max_c1", "delta_t")
#: Columns after the contracted ones.
EXTRA_COLUMNS = ("h_denoised_mean", "h_denoised_std", "d_denoised_mean", "d_denoised_std",
                 "rms_std", "z2_std", "jrc_std", "theta_max", "c", "a0")
#: Table columns of the profile sets: (column, :class:`DirectionSummary` field), in
#: the table's order (the TIN columns follow ``jrc_mean`` and close the table).
_PROFILE_COLUMNS = (
    ("h_mean", "hurst_mean"), ("h_std", "hurst_std"), ("d_mean", "dimension_mean"),
    ("d_std", "dimension_std"), ("rms_mean", "rms_mean"), ("z2_mean", "z2_mean"),
    ("jrc_mean", "jrc_mean"), ("h_denoised_mean", "hurst_denoised_mean"),
    ("h_denoised_std", "hurst_denoised_std"), ("d_denoised_mean", "dimension_denoised_mean"),
    ("d_denoised_std", "dimension_denoised_std"), ("rms_std", "rms_std"), ("z2_std", "z2_std"),
    ("jrc_std", "jrc_std"),
)


def directions_table(result: DirectionsResult, *, unit: str = "m") -> dict[str, np.ndarray]:
    """The ``DIRECTIONS.csv`` table: one row per azimuth, :data:`TABLE_COLUMNS` (without
    ``delta_t`` when there are no triangles) then :data:`EXTRA_COLUMNS`; ``rms`` in
    ``unit``, angles in degrees, Z2, H, D, C and JRC dimensionless."""
    per = UNIT_METRES[unit]
    s = [x.summary() for x in result.sets]
    nan = np.full(result.azimuth_deg.size, np.nan)
    tin = result.tin

    def profiles(attr: str, scale: float = 1.0) -> np.ndarray:
        return np.array([getattr(x, attr) for x in s], dtype=np.float64) * scale

    def triangles(attr: str) -> np.ndarray:
        return getattr(tin, attr).copy() if tin is not None else nan

    cols: dict[str, np.ndarray] = {
        "azimuth_deg": result.azimuth_deg.copy(),
        "profiles": np.array([x.profiles for x in s], dtype=np.int64)}
    for name, attr in _PROFILE_COLUMNS:
        cols[name] = profiles(attr, 1.0 / per if name.startswith("rms") else 1.0)
        if name == "jrc_mean":
            cols["theta_max_c1"] = triangles("theta_max_c1")
            if tin is not None:
                cols["delta_t"] = triangles("delta_t")
    for name in ("theta_max", "c", "a0"):
        cols[name] = triangles(name)
    return cols
