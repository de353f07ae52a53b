"""The report as plain numbers (``rough-viewer report --format json``)."""

from __future__ import annotations

from typing import Any

from rough_viewer.grid.maps import face_frame
from rough_viewer.grid.orientation import Stereonet
from rough_viewer.grid.variogram import Semivariogram
from rough_viewer.io.jsonable import to_jsonable
from rough_viewer.report.build import Report
from rough_viewer.report.directions import directions_dict
from rough_viewer.structure.joints import RQD_FORMULA
from rough_viewer.structure.sets import PLANE_COLUMNS, SET_COLUMNS, JointSets
from rough_viewer.structure.zones import ZONE_COLUMNS, Zones
from rough_viewer.vocabulary import HISTOGRAM_BIN, MAPS, UNIT_METRES


def variogram_dict(vg: Semivariogram, per: float = 1.0) -> dict[str, Any]:
    """Plain numbers of a semivariogram (the JSON contract); lengths divided by
    ``per`` (metres per display unit)."""
    return {
        "lag": to_jsonable(vg.lag / per),
        "gamma": to_jsonable(vg.gamma / per**2),
        "gamma_normalised": to_jsonable(vg.gamma_normalised),
        "pairs": to_jsonable(vg.pairs),
        "variance": to_jsonable(vg.variance / per**2),
        "n_cells": int(vg.n_cells),
        "bin_width": float(vg.bin_width / per),
        "max_lag": float(vg.max_lag / per),
        "lag_limited": bool(vg.lag_limited),
        "space": vg.space,
        # "fft" / "pairs": exact over every pair; "sample": estimated from a random
        # sample of pairs ("pairs" then estimated), with the standard error of gamma
        "method": vg.method,
        "gamma_se": None if vg.gamma_se is None else to_jsonable(vg.gamma_se / per**2),
        "gamma_normalised_se": (None if vg.gamma_normalised_se is None
                                else to_jsonable(vg.gamma_normalised_se)),
        "sampled_pairs": None if vg.sampled is None else to_jsonable(vg.sampled),
    }


def _summary(summary: dict[str, float | int], per: float) -> dict[str, Any]:
    """Table-1 numbers with lengths divided by ``per`` (variance by its square)."""
    out: dict[str, Any] = {}
    for k, v in summary.items():
        if k in ("min", "max", "mean", "std"):
            v = v / per
        elif k == "variance":
            v = v / per**2
        out[k] = to_jsonable(v)
    return out


def zones_dict(zones: Zones, net: Stereonet | None) -> dict[str, Any]:
    """Plain numbers of one grid size's zones and the stereonet of its cell poles (the
    JSON contract): the zone table as ``columns`` (:data:`ZONE_COLUMNS`) and ``rows``,
    and the pole density on the net's nodes (multiples of a uniform distribution,
    null outside the primitive circle)."""
    table = zones.table()
    out: dict[str, Any] = {
        "map": zones.map_name,
        "threshold": zones.threshold,
        "connectivity": zones.connectivity,
        "min_cells": zones.min_cells,
        "count": zones.n_zones,
        "cells_in_zones": int(zones.cells.sum()),
        "columns": list(ZONE_COLUMNS),
        "rows": [[to_jsonable(table[c][k]) for c in ZONE_COLUMNS] for k in range(zones.n_zones)],
    }
    if net is not None:
        out["stereonet"] = {
            "projection": "lower hemisphere, equal area (Schmidt), radius 1, x east, y north",
            "poles": net.n_poles,
            "smoothing_deg": net.smoothing_deg,
            "nodes": to_jsonable(net.nodes),
            "density_mud": to_jsonable(net.density),
        }
    return out


def sets_dict(sets: JointSets, per: float = 1.0) -> dict[str, Any]:
    """Plain numbers of one grid size's joint sets (the JSON contract): the settings,
    the set and plane tables as ``columns`` (SETS.csv's and PLANES.csv's) and
    ``rows``, lengths divided by ``per`` (metres per display unit, areas by its
    square), ``note`` (why there is no set, else empty), the rock-mass figures
    (``jv`` per display unit, ``jv_per_m3``, ``block_size_index``, ``rqd_estimate``)
    and the warnings of the sets' roughness."""
    o = sets.options
    sets_t, planes_t = sets.set_table(per), sets.plane_table(per)
    return {
        "max_roughness": sets.max_roughness / per,
        "min_planar_points": o.min_planar_points,
        "planar_cells": int(sets.planar.sum()),
        "cone_deg": o.cone_deg,
        "min_angle_deg": o.min_angle_deg,
        "max_sets": o.max_sets,
        "smoothing_deg": o.smoothing_deg,
        "min_density": o.min_density,
        "plane_tolerance": sets.plane_tolerance / per,
        "count": sets.n_sets,
        "note": sets.note,
        "columns": list(SET_COLUMNS),
        "rows": [[to_jsonable(sets_t[c][k]) for c in SET_COLUMNS] for k in range(sets.n_sets)],
        "plane_columns": list(PLANE_COLUMNS),
        "plane_rows": [[to_jsonable(planes_t[c][k]) for c in PLANE_COLUMNS]
                       for k in range(sets.planes.n_planes)],
        "peak_density_mud": to_jsonable(sets.peak_density),
        "joints": sets.joints.n_joints,
        # the rock-mass figures (Jv per cubic display unit, as sum 1 / spacing in it)
        "jv": to_jsonable(sets.figures.jv * per),
        "jv_per_m3": to_jsonable(sets.figures.jv),
        "block_size_index": to_jsonable(sets.figures.block_size_index / per),
        "rqd_estimate": to_jsonable(sets.figures.rqd_estimate),
        "rqd_estimate_formula": RQD_FORMULA,
        "roughness_warnings": list(sets.roughness.warnings),
    }


def report_json(report: Report) -> dict[str, Any]:
    """The report's numbers as a JSON-ready dict (NaN -> null).

    Layout: ``grids`` is a list (in the order asked) of ``{"grid_size", "error",
    "cells", "models": {name: {"summary", "histogram", "semivariogram"}}, "zones",
    "sets", "figure_errors"}`` for the names ``odr``, ``ols``, ``hybrid`` and ``e_ols``;
    ``zones`` is :func:`zones_dict`, ``sets`` :func:`sets_dict`. Every length and
    roughness is in ``unit`` (the report's display unit; variances and areas in its
    square); the zone table keeps its own units (metres, square metres, degrees).
    """
    frame = face_frame(report.plane)
    per = UNIT_METRES[report.unit]
    grids = []
    for s in report.sections:
        entry: dict[str, Any] = {"grid_size": s.grid_size / per, "error": s.error}
        if s.result is not None:
            entry["cells"] = s.result.cell_report("odr")
            entry["origin"] = [float(v) / per for v in s.result.grid.origin]
        if s.error is None:
            entry["models"] = {
                name: {
                    "summary": _summary(s.summaries[name].as_dict(), per),
                    "histogram": {
                        "edges": to_jsonable(s.histograms[name].edges),
                        "fractions": to_jsonable(s.histograms[name].fractions),
                        "counts": to_jsonable(s.histograms[name].counts),
                    },
                    "semivariogram": (variogram_dict(s.variograms[name], per)
                                      if name in s.variograms else None),
                }
                for name in MAPS
            }
            entry["figure_errors"] = dict(s.figure_errors)
            entry["threshold_advice"] = {name: to_jsonable(a.as_dict())
                                         for name, a in s.advice.items()}
            if s.zones is not None:
                entry["zones"] = zones_dict(s.zones, s.stereonet)
            entry["scanner"] = (None if s.trust is None
                                else to_jsonable(s.trust.summary().as_dict(per=per)))
            if s.sets is not None:
                entry["sets"] = sets_dict(s.sets, per)
        grids.append(entry)
    return {
        "software": {"name": "rough_viewer", "version": report.version},
        "created": report.created,
        "input": {
            "name": report.name,
            "path": report.source,
            "points": report.n_points,
            "dropped_nonfinite": report.dropped_nonfinite,
            "bounds_min": to_jsonable(report.bounds_min / per),
            "bounds_max": to_jsonable(report.bounds_max / per),
        },
        "unit": report.unit,
        "grids_chosen": report.grids_chosen,
        "warnings": list(report.warnings),
        "scanner_note": report.scanner_note,
        "axis": report.axis,
        "axis_requested": report.axis_requested,
        "threshold": report.threshold,
        "keep_outliers": report.keep_outliers,
        "min_points": report.min_points,
        "min_cells": report.min_cells,
        "connectivity": report.connectivity,
        "histogram_bin_width": HISTOGRAM_BIN,
        "face_plane": {
            "centroid": to_jsonable(frame.origin / per),
            "normal": to_jsonable(frame.normal),
            "u_axis": to_jsonable(frame.u_axis),
            "v_axis": to_jsonable(frame.v_axis),
        },
        "grids": grids,
        "directions": [directions_dict(d, unit=report.unit) for d in report.directions],
    }
