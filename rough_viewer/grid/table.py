"""A grid result as tables: the per-cell table of ``rough-viewer compute`` (CSV or
Parquet through :func:`rough_viewer.io.table.write_table`) and the per-point fields
that LAS/LAZ and PLY exports attach to every point.

The one definition of both, used by the command line, the zones command and the app.
"""

from __future__ import annotations

import numpy as np

from rough_viewer.grid.roughness import GridRoughness
from rough_viewer.io.point_fields import CellField, PointFields
from rough_viewer.vocabulary import UNIT_METRES, InputError

#: Columns of the per-cell table, in order (the ``compute`` contract).
CELL_COLUMNS: tuple[str, ...] = (
    "ix", "iy", "iz", "cx", "cy", "cz", "n_points",
    "theta_odr", "theta_ols", "theta_hybrid", "e_ols",
    "normal_x", "normal_y", "normal_z", "outlier",
)

#: Per-point fields of LAS/LAZ and PLY exports, in order.
POINT_FIELD_NAMES: tuple[str, ...] = (
    "theta_odr", "theta_ols", "theta_hybrid", "e_ols",
    "cell_ix", "cell_iy", "cell_iz", "cell_points",
)

#: ``cell_ix``/``iy``/``iz`` of a point that is in no cell (an input row with a
#: non-finite coordinate); ``cell_points`` is 0 there and the roughness NaN.
NO_CELL = np.iinfo(np.int32).min


def cell_columns(result: GridRoughness, *, unit: str = "m") -> dict[str, np.ndarray]:
    """The per-cell table: one row per cell with at least ``min_points`` points.

    Columns :data:`CELL_COLUMNS`: cell index (``ix, iy, iz``), cell centre (``cx, cy,
    cz``), points in the cell, the roughness of each model and ``e_ols`` (NaN where
    the cell has no value) and the cell's ODR unit normal, and ``outlier``: 0, or
    the sum of 1 (OLS) and 2 (hybrid) for the models whose roughness is larger than
    the cell (:func:`rough_viewer.grid.outliers.outlier_flags`; the values stay in
    their columns). Lengths in ``unit`` (default metres;
    ``rough_viewer.vocabulary.UNITS``).
    """
    from rough_viewer.grid.outliers import outlier_flags

    keep = result.n_points >= result.min_points
    per = UNIT_METRES[unit]

    def length(v: np.ndarray) -> np.ndarray:
        return v[keep] / per if per != 1.0 else v[keep]

    return {
        "ix": result.ijk[keep, 0], "iy": result.ijk[keep, 1], "iz": result.ijk[keep, 2],
        "cx": length(result.centre[:, 0]), "cy": length(result.centre[:, 1]),
        "cz": length(result.centre[:, 2]),
        "n_points": result.n_points[keep],
        "theta_odr": length(result.theta_odr), "theta_ols": length(result.theta_ols),
        "theta_hybrid": length(result.theta_hybrid), "e_ols": length(result.e_ols),
        "normal_x": result.normal[keep, 0], "normal_y": result.normal[keep, 1],
        "normal_z": result.normal[keep, 2],
        "outlier": outlier_flags(result)[keep],
    }


def table_metadata(result: GridRoughness, source: str = "", *, unit: str = "m") -> dict[str, str]:
    """Notes stored with a Parquet cell table: units and the grid's settings."""
    return {
        "rough_viewer.units": f"{'metres' if unit == 'm' else unit} (theta_*, e_ols, cx, cy, cz)",
        "rough_viewer.grid_size_m": repr(float(result.grid.cell_size)),
        "rough_viewer.origin_m": ",".join(repr(float(v)) for v in result.grid.origin),
        "rough_viewer.axis": result.axis,
        "rough_viewer.min_points": str(result.min_points),
        "rough_viewer.residual": result.residual,
        "rough_viewer.input": source,
    }


def point_fields(result: GridRoughness) -> PointFields:
    """The per-point fields of a result, for LAS/LAZ and PLY export.

    Each point gets its cell's values: ``theta_odr``, ``theta_ols``,
    ``theta_hybrid``, ``e_ols`` (float32, metres, NaN where the cell has no value),
    ``cell_ix``, ``cell_iy``, ``cell_iz`` (int32 cell index) and ``cell_points``
    (uint32, points in the cell).
    """
    ijk = result.ijk
    lo, hi = np.iinfo(np.int32).min + 1, np.iinfo(np.int32).max
    if ijk.size and (ijk.min() < lo or ijk.max() > hi):
        raise InputError("cell indices do not fit in 32 bits; use a larger grid size "
                         "or an origin nearer the points")
    g = f"{result.grid.cell_size:g}"
    axis = result.axis
    f32 = np.float32
    nan = f32(np.nan)
    fields = (
        CellField("theta_odr", result.theta_odr.astype(f32), "ODR roughness (m)", nan),
        CellField("theta_ols", result.theta_ols.astype(f32), f"OLS roughness along {axis} (m)",
                  nan),
        CellField("theta_hybrid", result.theta_hybrid.astype(f32),
                  f"hybrid roughness along {axis} (m)", nan),
        CellField("e_ols", result.e_ols.astype(f32), "OLS error |OLS - ODR| (m)", nan),
        CellField("cell_ix", ijk[:, 0].astype(np.int32), f"cell index x, grid {g} m"[:32],
                  np.int32(NO_CELL)),
        CellField("cell_iy", ijk[:, 1].astype(np.int32), f"cell index y, grid {g} m"[:32],
                  np.int32(NO_CELL)),
        CellField("cell_iz", ijk[:, 2].astype(np.int32), f"cell index z, grid {g} m"[:32],
                  np.int32(NO_CELL)),
        CellField("cell_points", result.n_points.astype(np.uint32), "points in the cell",
                  np.uint32(0)),
    )
    return PointFields(fields=fields, point_cell=result.point_cell)
