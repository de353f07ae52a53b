"""The report as plain numbers (``rough-viewer report --format json``)."""

from __future__ import annotations

from typing import Any

from rough_viewer.grid.maps import face_frame
from rough_viewer.grid.variogram import Semivariogram
from rough_viewer.io.jsonable import to_jsonable
from rough_viewer.report.build import Report
from rough_viewer.vocabulary import HISTOGRAM_BIN, MAPS


def variogram_dict(vg: Semivariogram) -> dict[str, Any]:
    """Plain numbers of a semivariogram (the JSON contract)."""
    return {
        "lag": to_jsonable(vg.lag),
        "gamma": to_jsonable(vg.gamma),
        "gamma_normalised": to_jsonable(vg.gamma_normalised),
        "pairs": to_jsonable(vg.pairs),
        "variance": to_jsonable(vg.variance),
        "n_cells": int(vg.n_cells),
        "bin_width": float(vg.bin_width),
        "max_lag": float(vg.max_lag),
        "lag_limited": bool(vg.lag_limited),
        "space": vg.space,
    }


def report_json(report: Report) -> dict[str, Any]:
    """The report's numbers as a JSON-ready dict (NaN -> null).

    Layout: ``grids`` is a list (in the order asked) of ``{"grid_size", "error",
    "cells", "models": {name: {"summary", "histogram", "semivariogram"}}}`` for the
    names ``odr``, ``ols``, ``hybrid`` and ``e_ols``.
    """
    frame = face_frame(report.plane)
    grids = []
    for s in report.sections:
        entry: dict[str, Any] = {"grid_size": s.grid_size, "error": s.error}
        if s.result is not None:
            entry["cells"] = s.result.cell_report("odr")
            entry["origin"] = [float(v) for v in s.result.grid.origin]
        if s.error is None:
            entry["models"] = {
                name: {
                    "summary": {k: to_jsonable(v) for k, v in s.summaries[name].as_dict().items()},
                    "histogram": {
                        "edges": to_jsonable(s.histograms[name].edges),
                        "fractions": to_jsonable(s.histograms[name].fractions),
                        "counts": to_jsonable(s.histograms[name].counts),
                    },
                    "semivariogram": (variogram_dict(s.variograms[name])
                                      if name in s.variograms else None),
                }
                for name in MAPS
            }
            entry["figure_errors"] = dict(s.figure_errors)
        grids.append(entry)
    return {
        "software": {"name": "rough_viewer", "version": report.version},
        "created": report.created,
        "input": {
            "name": report.name,
            "path": report.source,
            "points": report.n_points,
            "dropped_nonfinite": report.dropped_nonfinite,
            "bounds_min": to_jsonable(report.bounds_min),
            "bounds_max": to_jsonable(report.bounds_max),
        },
        "axis": report.axis,
        "axis_requested": report.axis_requested,
        "threshold": report.threshold,
        "min_points": report.min_points,
        "histogram_bin_width": HISTOGRAM_BIN,
        "face_plane": {
            "centroid": to_jsonable(frame.origin),
            "normal": to_jsonable(frame.normal),
            "u_axis": to_jsonable(frame.u_axis),
            "v_axis": to_jsonable(frame.v_axis),
        },
        "grids": grids,
    }
