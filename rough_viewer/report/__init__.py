"""The grid-roughness report: the 2011 paper's Table 1 and Figs. 2-4 for one cloud.

:func:`build_report` computes everything (roughness maps at each grid size, Table-1
summaries, histograms, semivariograms, face-plane maps); :func:`report_json` turns it
into plain numbers; :func:`report_html` into one self-contained HTML page (plotly.js
inlined, works offline); :func:`report_figures` gives the plotly figures, e.g. for
PNG export.
"""

from __future__ import annotations

import datetime as _dt
import html
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rough_viewer import __version__
from rough_viewer.grid.maps import FaceMaps, face_frame, face_maps, face_raster
from rough_viewer.grid.planes import PlaneFit, dominant_axis, whole_cloud_plane
from rough_viewer.grid.roughness import GridRoughness, grid_roughness
from rough_viewer.grid.summary import Histogram, Summary, histogram, normalise, summarise
from rough_viewer.grid.variogram import Semivariogram, semivariogram
from rough_viewer.io import PointCloud
from rough_viewer.io.jsonable import to_jsonable
from rough_viewer.vocabulary import MAPS, InputError, ProgressFn

PAPER_GRIDS: tuple[float, ...] = (1.0, 0.5, 0.25, 0.125)
"""The 2011 paper's grid sizes, metres."""
MIN_CELLS = 10
"""A grid size leaving fewer cells with an ODR value than this is reported, not drawn."""
HISTOGRAM_BIN = 0.05
"""Bin width of the normalised-roughness histograms (2011 Fig. 3)."""
VARIOGRAM_FIGURE_MAPS = ("odr", "ols", "e_ols")
"""Maps overlaid in the semivariogram figure (2011 Fig. 4); the numbers cover all maps."""
FACE_MAP_ORDER = ("ols", "odr", "hybrid", "e_ols")
"""Panel order of the face-map figures (2011 Fig. 2: A = OLS, B = ODR)."""
ROUGHNESS_STAGES = 4
"""Progress stages reported by ``grid_roughness``."""
STEPS_PER_GRID = ROUGHNESS_STAGES + len(MAPS) + 1


@dataclass(frozen=True)
class GridSection:
    """Everything the report shows for one grid size."""

    grid_size: float
    """Cell edge, metres."""
    error: str | None = None
    """Why this grid size has no results (e.g. too few cells), else None."""
    result: GridRoughness | None = None
    summaries: dict[str, Summary] = field(default_factory=dict)
    histograms: dict[str, Histogram] = field(default_factory=dict)
    variograms: dict[str, Semivariogram] = field(default_factory=dict)
    maps: dict[str, FaceMaps] = field(default_factory=dict)


@dataclass(frozen=True)
class Report:
    """A whole report: the input, the options and one section per grid size."""

    name: str
    """File name of the input (or "in-memory cloud")."""
    source: str
    """Path of the input as given."""
    n_points: int
    dropped_nonfinite: int
    bounds_min: np.ndarray
    """(3,) metres."""
    bounds_max: np.ndarray
    axis: str
    """Dependent axis used by OLS and hybrid."""
    axis_requested: str
    threshold: float
    """Binary-transform threshold on normalised roughness."""
    min_points: int
    plane: PlaneFit
    """The whole-cloud ODR plane (centroid = mean point), the frame of the face maps."""
    sections: tuple[GridSection, ...]
    version: str = __version__
    created: str = ""
    """UTC time the report was made (ISO 8601)."""


def _section(
    cloud: PointCloud,
    g: float,
    *,
    axis: str,
    threshold: float,
    min_points: int,
    plane: PlaneFit,
    tick: Callable[[], None],
    stage: ProgressFn,
) -> GridSection:
    try:
        result = grid_roughness(cloud, g, min_points=min_points, axis=axis,  # type: ignore[arg-type]
                                progress=stage)
    except InputError as exc:
        return GridSection(grid_size=g, error=str(exc))
    n_valid = int(np.count_nonzero(np.isfinite(result.theta_odr)))
    if n_valid < MIN_CELLS:
        return GridSection(
            grid_size=g,
            error=(f"too few cells: {n_valid} cell{'s' if n_valid != 1 else ''} with a "
                   f"roughness value, at least {MIN_CELLS} needed (cells need {min_points} "
                   "points); use a smaller grid size"),
            result=result,
        )
    raster = face_raster(result.centre, plane, g)
    summaries, histograms, variograms, maps = {}, {}, {}, {}
    for name in MAPS:
        values = result.values(name)
        norm = normalise(values)
        summaries[name] = summarise(result, name)
        histograms[name] = histogram(norm, HISTOGRAM_BIN)
        try:
            variograms[name] = semivariogram(result.ijk, values, g)
        except MemoryError:
            shape = tuple(int(v) for v in np.ptp(result.ijk, axis=0) + 1)
            return GridSection(
                grid_size=g, result=result,
                error=(f"not enough memory for the semivariogram of the occupied box "
                       f"{shape[0]} x {shape[1]} x {shape[2]} cells; use a larger grid size"),
            )
        maps[name] = face_maps(raster, norm, threshold=threshold)
        tick()
    tick()
    return GridSection(grid_size=g, result=result, summaries=summaries, histograms=histograms,
                       variograms=variograms, maps=maps)


def build_report(
    cloud: PointCloud,
    grid_sizes: Sequence[float] = PAPER_GRIDS,
    *,
    axis: str = "auto",
    threshold: float = 0.05,
    min_points: int = 3,
    progress: ProgressFn | None = None,
) -> Report:
    """Compute every number of the report.

    Parameters
    ----------
    cloud : PointCloud
        The points, metres.
    grid_sizes : sequence of float
        Cell edges, metres (default the paper's 1, 0.5, 0.25, 0.125).
    axis : {"auto", "x", "y", "z"}
        Dependent axis of OLS and hybrid.
    threshold : float
        Binary transform threshold on normalised roughness (paper: 0.05).
    min_points : int
        Cells with fewer points get no value.
    progress : callable, optional
        ``progress(done, total)`` over all steps of all grid sizes.

    Returns
    -------
    Report
        One section per grid size; a grid size that fails (too few cells, too many
        cells for memory) has ``error`` set and the others go on.
    """
    if cloud.n < 3:
        raise InputError(f"need at least 3 points, got {cloud.n} ({cloud.source or 'cloud'})")
    sizes = list(dict.fromkeys(float(g) for g in grid_sizes))
    total = STEPS_PER_GRID * len(sizes)
    done = base = 0
    shown = -1

    def show(value: int) -> None:
        nonlocal shown
        value = min(value, total)
        if progress is not None and value > shown:
            shown = value
            progress(value, total)

    def tick() -> None:
        nonlocal done
        done += 1
        show(done)

    def stage(stage_done: int, stage_total: int) -> None:
        # grid_roughness's own stages, mapped onto the first steps of this grid size
        if stage_total > 0:
            show(base + round(ROUGHNESS_STAGES * min(stage_done, stage_total) / stage_total))

    show(0)
    plane = whole_cloud_plane(cloud)
    used_axis = dominant_axis(plane.normal) if axis == "auto" else axis
    sections = []
    for i, g in enumerate(sizes):
        base = STEPS_PER_GRID * i
        done = base + ROUGHNESS_STAGES
        sections.append(_section(cloud, g, axis=used_axis, threshold=threshold,
                                 min_points=min_points, plane=plane, tick=tick, stage=stage))
        done = STEPS_PER_GRID * (i + 1)
        show(done)
    lo, hi = cloud.bounds()
    return Report(
        name=Path(cloud.source).name if cloud.source else "in-memory cloud",
        source=cloud.source,
        n_points=cloud.n,
        dropped_nonfinite=cloud.dropped_nonfinite,
        bounds_min=lo,
        bounds_max=hi,
        axis=used_axis,
        axis_requested=axis,
        threshold=float(threshold),
        min_points=int(min_points),
        plane=plane,
        sections=tuple(sections),
        created=_dt.datetime.now(_dt.UTC).replace(microsecond=0).isoformat(),
    )


# ----------------------------------------------------------------------------- numbers


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
                    "semivariogram": variogram_dict(s.variograms[name]),
                }
                for name in MAPS
            }
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


# ----------------------------------------------------------------------------- figures


def report_figures(report: Report, section: GridSection) -> dict[str, Any]:
    """The plotly figures of one grid section, keyed by a short file-name-safe name:
    ``summary``, ``maps_normalised``, ``maps_binary``, ``histogram``, ``variogram``.
    Empty when the section has an error."""
    from rough_viewer.visual.grid import (
        face_map_figure,
        histogram_figure,
        summary_table_figure,
        variogram_figure,
    )

    if section.error is not None:
        return {}
    kw = {"grid_size": section.grid_size, "axis": report.axis, "n_points": report.n_points}
    maps = {n: section.maps[n] for n in FACE_MAP_ORDER if n in section.maps}
    return {
        "summary": summary_table_figure(section.summaries, **kw),
        "maps_normalised": face_map_figure(maps, kind="normalised", **kw),
        "maps_binary": face_map_figure(maps, kind="binary", **kw),
        "histogram": histogram_figure(
            {n: section.histograms[n] for n in ("ols", "odr", "hybrid", "e_ols")}, **kw),
        "variogram": variogram_figure(
            {n: section.variograms[n] for n in VARIOGRAM_FIGURE_MAPS}, **kw),
    }


def png_name(grid_size: float, figure: str) -> str:
    """File name of one exported figure: ``g<G>_<figure>.png``."""
    return f"g{grid_size:g}_{figure}.png"


FIGURE_NAMES = ("summary", "maps_normalised", "maps_binary", "histogram", "variogram")


# ----------------------------------------------------------------------------- HTML

_CSS = """
body { font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 1100px; color: #222; }
h1 { font-size: 1.5em; } h2 { border-bottom: 1px solid #ccc; margin-top: 2em; }
table.meta td { padding: 2px 12px 2px 0; vertical-align: top; }
.error { color: #a00; font-weight: bold; }
.figure { margin: 1em 0; }
.note { color: #555; font-size: 0.9em; }
"""


def _fmt_xyz(v: np.ndarray) -> str:
    return ", ".join(f"{float(c):.3f}" for c in v)


def report_html(report: Report) -> str:
    """One self-contained HTML page (plotly.js inlined: no network needed)."""
    from plotly.offline import get_plotlyjs

    esc = html.escape
    frame = face_frame(report.plane)
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>Roughness report: {esc(report.name)}</title>",
        f"<style>{_CSS}</style>",
        f'<script type="text/javascript">{get_plotlyjs()}</script>',
        "</head><body>",
        f"<h1>Surface roughness report: {esc(report.name)}</h1>",
        '<table class="meta">',
        f"<tr><td>input</td><td>{esc(report.source or report.name)}</td></tr>",
        f"<tr><td>points</td><td>{report.n_points:,}"
        + (f" ({report.dropped_nonfinite:,} non-finite rows dropped)"
           if report.dropped_nonfinite else "") + "</td></tr>",
        f"<tr><td>bounding box (m)</td><td>min ({_fmt_xyz(report.bounds_min)})<br>"
        f"max ({_fmt_xyz(report.bounds_max)})<br>size "
        f"({_fmt_xyz(report.bounds_max - report.bounds_min)})</td></tr>",
        f"<tr><td>dependent axis (OLS, hybrid)</td><td>{esc(report.axis)}"
        f" (requested: {esc(report.axis_requested)})</td></tr>",
        f"<tr><td>face plane (whole-cloud ODR)</td><td>normal ({_fmt_xyz(frame.normal)}); "
        f"u axis ({_fmt_xyz(frame.u_axis)}); v axis ({_fmt_xyz(frame.v_axis)})</td></tr>",
        f"<tr><td>grid sizes (m)</td><td>"
        f"{', '.join(f'{s.grid_size:g}' for s in report.sections)}</td></tr>",
        f"<tr><td>binary threshold</td><td>{report.threshold:g} (normalised roughness)</td></tr>",
        f"<tr><td>min points per cell</td><td>{report.min_points}</td></tr>",
        f"<tr><td>software</td><td>rough_viewer {esc(report.version)}</td></tr>",
        f"<tr><td>created (UTC)</td><td>{esc(report.created)}</td></tr>",
        "</table>",
        '<p class="note">Roughness: population standard deviation of the absolute '
        "point-to-plane distances per cell (ODR: orthogonal; OLS: along the dependent axis; "
        "hybrid: ODR plane, distance along the dependent axis); e_OLS = |OLS - ODR|. "
        "Face maps: cells projected onto the whole-cloud ODR plane, pixel = cell size, "
        "max of the cells in a pixel. Semivariograms: all pairs of cells, 3-D distances "
        "between cell centres, bins of one cell size up to half the largest extent, "
        "divided by the map's variance.</p>",
    ]
    for s in report.sections:
        sid = f"grid-{s.grid_size:g}".replace(".", "_")
        parts.append(f'<section id="{sid}" class="grid-section"><h2>Grid {s.grid_size:g} m</h2>')
        if s.error is not None:
            parts.append(f'<p class="error">{esc(s.error)}</p></section>')
            continue
        cells = s.result.cell_report("odr") if s.result is not None else {}
        if cells:
            parts.append(
                f'<p class="note">{cells["occupied"]:,} occupied cells, '
                f'{cells["with_value"]:,} with an ODR value, '
                f'{cells["below_min_points"]:,} below {report.min_points} points, '
                f'{cells["degenerate"]:,} degenerate.</p>'
            )
        for key, fig in report_figures(report, s).items():
            div = fig.to_html(full_html=False, include_plotlyjs=False,
                              div_id=f"{sid}-{key}", config={"displaylogo": False})
            parts.append(f'<div class="figure" data-figure="{key}">{div}</div>')
        parts.append("</section>")
    parts.append("</body></html>")
    return "\n".join(parts)


def check_png_export() -> None:
    """Raise InputError (one line) unless the optional kaleido package is installed."""
    import importlib.util

    if importlib.util.find_spec("kaleido") is None:
        raise InputError("PNG export needs the optional package kaleido "
                         "(pip install kaleido); the HTML and JSON reports do not")


def png_figures(report: Report) -> list[tuple[str, Any]]:
    """``(file name, figure)`` for every figure of every grid section, for PNG export
    (``fig.to_image(format="png")`` needs kaleido: see :func:`check_png_export`)."""
    return [
        (png_name(s.grid_size, key), fig)
        for s in report.sections
        for key, fig in report_figures(report, s).items()
    ]
