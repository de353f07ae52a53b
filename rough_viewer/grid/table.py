"""A grid result as tables: the per-cell table of ``rough-viewer compute`` (CSV or
Parquet through :func:`rough_viewer.io.table.write_table`) and the per-point fields
that LAS/LAZ and PLY exports attach to every point.

The one definition of both, used by the command line, the zones command and the app.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from rough_viewer.grid.outliers import outlier_flags
from rough_viewer.grid.roughness import GridRoughness
from rough_viewer.io.formats.point_fields import CellField, PointFields
from rough_viewer.vocabulary import TRUST_FIELDS, UNIT_METRES, InputError

#: The scanner columns of the per-cell table (docs/scanner.md), after the roughness
#: ones; empty where a cloud has no scanner positions.
TRUST_COLUMNS: tuple[str, ...] = TRUST_FIELDS
#: Scanner columns that are lengths (written in the table's unit).
TRUST_LENGTHS: tuple[str, ...] = ("range", "noise_pred", "smoothing_pred", "bias_pred")
#: Scanner columns that are whole numbers (masked where unknown).
TRUST_INTEGERS: tuple[str, ...] = ("scans", "trusted")

#: Columns of the per-cell table, in order (the ``compute`` contract).
CELL_COLUMNS: tuple[str, ...] = (
    "ix", "iy", "iz", "cx", "cy", "cz", "n_points",
    "theta_odr", "theta_ols", "theta_hybrid", "e_ols",
    "normal_x", "normal_y", "normal_z", "outlier",
    *TRUST_COLUMNS,
)

#: Per-point fields of LAS/LAZ and PLY exports, in order.
POINT_FIELD_NAMES: tuple[str, ...] = (
    "theta_odr", "theta_ols", "theta_hybrid", "e_ols",
    "cell_ix", "cell_iy", "cell_iz", "cell_points",
)

#: Per-point fields that are lengths (metres in the cells' arrays; written in the
#: output's unit where a format takes one, e.g. PLY).
POINT_LENGTH_FIELDS: frozenset[str] = frozenset(
    {"theta_odr", "theta_ols", "theta_hybrid", "e_ols", *TRUST_LENGTHS})

#: ``cell_ix``/``iy``/``iz`` of a point that is in no cell (an input row with a
#: non-finite coordinate); ``cell_points`` is 0 there and the roughness NaN.
NO_CELL = np.iinfo(np.int32).min


def cell_columns(result: GridRoughness, *, unit: str = "m",
                 trust: Mapping[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
    """The per-cell table: one row per cell with at least ``min_points`` points.

    Columns :data:`CELL_COLUMNS`: cell index (``ix, iy, iz``), cell centre (``cx, cy,
    cz``), points in the cell, the roughness of each model and ``e_ols`` (NaN where
    the cell has no value), the cell's ODR unit normal, ``outlier``: 0, or the sum of
    1 (OLS) and 2 (hybrid) for the models whose roughness is larger than the cell
    (:func:`rough_viewer.grid.outliers.outlier_flags`; the values stay in their
    columns), and the scanner columns :data:`TRUST_COLUMNS` from ``trust`` (per-cell
    arrays aligned with the result's cells, lengths in metres:
    :meth:`rough_viewer.scanner.trust.CellTrust.columns`), all empty without it. Lengths
    in ``unit`` (default metres;
    ``rough_viewer.vocabulary.UNITS``).
    """
    keep = result.n_points >= result.min_points
    per = UNIT_METRES[unit]

    def length(v: np.ndarray) -> np.ndarray:
        return v[keep] / per if per != 1.0 else v[keep]

    return {**_roughness_columns(result, keep, length),
            **_trust_columns(trust, keep, int(np.count_nonzero(keep)), per)}


def _trust_columns(trust: Mapping[str, np.ndarray] | None, keep: np.ndarray, rows: int,
                   per: float) -> dict[str, np.ndarray]:
    """The scanner columns of the kept cells (masked / NaN without ``trust``)."""
    out: dict[str, np.ndarray] = {}
    for name in TRUST_COLUMNS:
        if trust is None:
            out[name] = (np.ma.masked_all(rows, dtype=np.int64) if name in TRUST_INTEGERS
                         else np.full(rows, np.nan))
            continue
        v = np.ma.asanyarray(trust[name]) if name in TRUST_INTEGERS else np.asarray(trust[name])
        if v.shape[0] != keep.shape[0]:
            raise ValueError(f"scanner column {name!r} has {v.shape[0]:,} cells, the result "
                             f"{keep.shape[0]:,}")
        v = v[keep]
        out[name] = v / per if name in TRUST_LENGTHS and per != 1.0 else v
    return out


def _roughness_columns(result: GridRoughness, keep: np.ndarray,
                       length: Callable[[np.ndarray], np.ndarray]) -> dict[str, np.ndarray]:
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
        "rough_viewer.units": f"{'metres' if unit == 'm' else unit} (theta_*, e_ols, cx, cy, cz, "
                             "range, noise_pred, smoothing_pred, bias_pred)",
        "rough_viewer.grid_size_m": repr(float(result.grid.cell_size)),
        "rough_viewer.origin_m": ",".join(repr(float(v)) for v in result.grid.origin),
        "rough_viewer.axis": result.axis,
        "rough_viewer.min_points": str(result.min_points),
        "rough_viewer.residual": result.residual,
        "rough_viewer.input": source,
    }


def point_fields(result: GridRoughness,
                 trust: Mapping[str, np.ndarray] | None = None) -> PointFields:
    """The per-point fields of a result, for LAS/LAZ and PLY export.

    Each point gets its cell's values: ``theta_odr``, ``theta_ols``,
    ``theta_hybrid``, ``e_ols`` (float32, metres, NaN where the cell has no value),
    ``cell_ix``, ``cell_iy``, ``cell_iz`` (int32 cell index) and ``cell_points``
    (uint32, points in the cell); with ``trust`` (the scanner columns,
    :meth:`rough_viewer.scanner.trust.CellTrust.columns`) also :data:`TRUST_COLUMNS`:
    ``scans`` (uint16), ``trusted`` (int8: 1 trusted, 0 flagged, -1 not judged) and
    the others float32 (lengths in metres, NaN where none).
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
    fields: tuple[CellField, ...] = (
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
    if trust is not None:
        fields += _trust_fields(trust)
    return PointFields(fields=fields, point_cell=result.point_cell)


#: Descriptions of the scanner fields (LAS extra bytes: at most 32 characters).
TRUST_DESCRIPTIONS: dict[str, str] = {
    "scans": "scans seeing the cell",
    "range": "range to the scanner (m)",
    "incidence_deg": "incidence angle (degrees)",
    "density_ratio": "point density / expected",
    "occlusion": "points missing vs along-beam",
    "noise_pred": "predicted noise inflation (m)",
    "smoothing_pred": "predicted beam smoothing (m)",
    "bias_pred": "net predicted bias (m)",
    "trusted": "1 trusted 0 flagged -1 unjudged",
}


def _trust_fields(trust: Mapping[str, np.ndarray]) -> tuple[CellField, ...]:
    f32 = np.float32
    out = []
    for name in TRUST_COLUMNS:
        v = trust[name]
        if name == "scans":
            cells = np.clip(np.ma.filled(np.ma.asanyarray(v), 0), 0, 65535).astype(np.uint16)
            out.append(CellField(name, cells, TRUST_DESCRIPTIONS[name], np.uint16(0)))
        elif name == "trusted":
            cells = np.ma.filled(np.ma.asanyarray(v).astype(np.int8), -1)
            out.append(CellField(name, cells, TRUST_DESCRIPTIONS[name], np.int8(-1)))
        else:
            out.append(CellField(name, np.asarray(v).astype(f32), TRUST_DESCRIPTIONS[name],
                                 f32(np.nan)))
    return tuple(out)
