"""The report as one self-contained HTML page (plotly.js inlined: works offline), and
its figures for PNG export."""

from __future__ import annotations

import html
from collections.abc import Mapping
from typing import Any

import numpy as np

from rough_viewer.grid.maps import face_frame
from rough_viewer.grid.outliers import outlier_mask
from rough_viewer.grid.variogram import Semivariogram, sampling_note
from rough_viewer.report.build import (
    FACE_MAP_ORDER,
    VARIOGRAM_BUDGET,
    VARIOGRAM_FIGURE_MAPS,
    GridSection,
    Report,
    report_raster,
)
from rough_viewer.report.directions import directions_html
from rough_viewer.visual.colormaps import zone_colour
from rough_viewer.vocabulary import (
    MAP_LABELS,
    UNIT_LABELS,
    UNIT_METRES,
    InputError,
    roughness_scale,
)


def report_figures(report: Report, section: GridSection) -> dict[str, Any]:
    """The plotly figures of one grid section, keyed by a short file-name-safe name:
    ``summary``, ``maps_normalised``, ``maps_binary``, ``histogram``, ``variogram``,
    ``zones_table``, ``zones_map``, ``stereonet``, ``sets_stereonet``, ``sets_table``,
    ``planes_table``. Empty when the section has an
    error; a figure that cannot be drawn (memory) is left out
    (:func:`figures_and_errors` says why)."""
    return figures_and_errors(report, section)[0]


def figures_and_errors(report: Report, section: GridSection, *,
                       timings: dict[str, float] | None = None,
                       ) -> tuple[dict[str, Any], dict[str, str]]:
    """The figures of :func:`report_figures` and, for each one that could not be
    drawn, why (an InputError from a memory check, or MemoryError): one figure never
    takes the others with it. ``timings``, when given, receives the seconds each
    figure took (``benchmarks/bench_report.py``)."""
    import time

    from rough_viewer.visual.grid import (
        face_map_figure,
        histogram_figure,
        summary_table_figure,
        variogram_figure,
    )
    from rough_viewer.visual.sets import (
        planes_table_figure,
        sets_stereonet_figure,
        sets_table_figure,
    )
    from rough_viewer.visual.trust import trust_map_figure
    from rough_viewer.visual.zones import stereonet_figure, zones_map_figure, zones_table_figure

    if section.error is not None:
        return {}, {}
    errors: dict[str, str] = {}

    def draw(key: str, make: Any) -> None:
        start = time.perf_counter()
        try:
            figures[key] = make()
        except InputError as exc:
            errors[key] = str(exc)
        except MemoryError:
            errors[key] = f"not enough memory to draw the {key} figure"
        if timings is not None:
            timings[key] = time.perf_counter() - start

    kw: dict[str, Any] = {"grid_size": section.grid_size, "axis": report.axis,
                          "n_points": report.n_points, "unit": report.unit}
    maps = {n: section.maps[n] for n in FACE_MAP_ORDER if n in section.maps}
    figures: dict[str, Any] = {}
    draw("summary", lambda: summary_table_figure(section.summaries, **kw))
    if maps:  # absent when the face maps could not be made (section.figure_errors)
        draw("maps_normalised", lambda: face_map_figure(maps, kind="normalised", **kw))
        draw("maps_binary", lambda: face_map_figure(maps, kind="binary", **kw))
    draw("histogram", lambda: histogram_figure(
        {n: section.histograms[n] for n in ("ols", "odr", "hybrid", "e_ols")},
        threshold=report.threshold,
        suggestions={n: a.suggested for n, a in section.advice.items()}, **kw))
    if section.variograms:
        draw("variogram", lambda: variogram_figure(
            {n: section.variograms[n] for n in VARIOGRAM_FIGURE_MAPS}, **kw))
    zones, net, result = section.zones, section.stereonet, section.result
    if zones is not None and net is not None and result is not None:
        shown = range(1, min(zones.n_zones, STEREONET_ZONES) + 1)
        draw("zones_table", lambda: zones_table_figure(zones, **kw))
        draw("zones_map", lambda: zones_map_figure(zones, result, plane=report.plane,
                                                   raster=report_raster(result, report.plane),
                                                   unit=report.unit))
        draw("stereonet", lambda: stereonet_figure(
            net, highlight={f"zone {k}": zones.labels == k for k in shown},
            colours={f"zone {k}": zone_colour(k) for k in shown}, **kw))
    trust = section.trust
    if trust is not None and result is not None:
        draw(SCANNER_FIGURE, lambda: trust_map_figure(
            trust, report_raster(result, report.plane), **kw))
    sets = section.sets
    if sets is not None:
        own: dict[str, Any] = {"axis": report.axis, "n_points": report.n_points,
                               "unit": report.unit}
        draw("sets_stereonet", lambda: sets_stereonet_figure(sets, **own))
        draw("sets_table", lambda: sets_table_figure(sets, **own))
        draw("planes_table", lambda: planes_table_figure(sets, **own))
    return figures, errors


def png_name(grid_size: float, figure: str, unit: str = "m") -> str:
    """File name of one exported figure: ``g<G>_<figure>.png``, the grid size (metres)
    in ``unit`` and named as everywhere (:func:`rough_viewer.vocabulary.grid_tag`:
    ``g2.5mm_summary.png`` for a 2.5 mm grid).

    >>> png_name(0.0025, "summary", "mm")
    'g2.5mm_summary.png'
    """
    from rough_viewer.vocabulary import UNIT_METRES, grid_tag

    return f"{grid_tag(grid_size / UNIT_METRES[unit], unit)}_{figure}.png"


FIGURE_NAMES = ("summary", "maps_normalised", "maps_binary", "histogram", "variogram",
                "zones_table", "zones_map", "stereonet", "sets_stereonet", "sets_table",
                "planes_table")
#: The figure of a section whose cloud has scanner positions (after FIGURE_NAMES).
SCANNER_FIGURE = "scanner_map"
STEREONET_ZONES = 6
"""The largest zones whose poles the report's stereonet highlights."""


_CSS = """
body { font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 1100px; color: #222; }
h1 { font-size: 1.5em; } h2 { border-bottom: 1px solid #ccc; margin-top: 2em; }
table.meta td { padding: 2px 12px 2px 0; vertical-align: top; }
.error { color: #a00; font-weight: bold; }
.figure { margin: 1em 0; }
.note { color: #555; font-size: 0.9em; }
"""


def _fmt_xyz(v: np.ndarray, per: float = 1.0) -> str:
    return ", ".join(f"{float(c) / per:.3f}" for c in v)


def report_html(report: Report) -> str:
    """One self-contained HTML page (plotly.js inlined: no network needed)."""
    esc = html.escape
    parts = [
        f"<h1>Surface roughness report: {esc(report.name)}</h1>",
        *_meta_table(report),
        _method_note(report),
    ]
    for line in report.warnings:
        parts.append(f'<p class="error">warning: {esc(line)}</p>')
    for s in report.sections:
        parts += _section_html(report, s)
    for i, d in enumerate(report.directions):
        parts += directions_html(d, unit=report.unit, sid=f"directions-{i}")
    return html_page(f"Roughness report: {report.name}", parts)


def html_page(title: str, body: list[str], *, css: str = "") -> str:
    """One self-contained HTML page: ``title`` (plain text, escaped), the report's
    style (and ``css``), plotly.js inlined (figures work offline), then ``body``
    (HTML fragments). The one page writer of the report and the lesson handouts."""
    from plotly.offline import get_plotlyjs

    head = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{html.escape(title)}</title>",
        f"<style>{_CSS}{css}</style>",
        f'<script type="text/javascript">{get_plotlyjs()}</script>',
        "</head><body>",
    ]
    return "\n".join([*head, *body, "</body></html>"])


def figure_html(fig: Any, div_id: str, key: str) -> str:
    """A plotly figure as a ``<div class="figure" data-figure="key">`` of a page made
    by :func:`html_page` (plotly.js is in the page's head)."""
    div = fig.to_html(full_html=False, include_plotlyjs=False, div_id=div_id,
                      config={"displaylogo": False})
    return f'<div class="figure" data-figure="{html.escape(key)}">{div}</div>'


def _meta_table(report: Report) -> list[str]:
    """The table of what was measured and how: input, points, box, axis, plane, grids."""
    esc = html.escape
    frame = face_frame(report.plane)
    per, u = UNIT_METRES[report.unit], UNIT_LABELS[report.unit]
    return [
        '<table class="meta">',
        f"<tr><td>input</td><td>{esc(report.source or report.name)}</td></tr>",
        f"<tr><td>points</td><td>{report.n_points:,}"
        + (f" ({report.dropped_nonfinite:,} non-finite rows dropped)"
           if report.dropped_nonfinite else "") + "</td></tr>",
        f"<tr><td>bounding box ({u})</td><td>min ({_fmt_xyz(report.bounds_min, per)})<br>"
        f"max ({_fmt_xyz(report.bounds_max, per)})<br>size "
        f"({_fmt_xyz(report.bounds_max - report.bounds_min, per)})</td></tr>",
        f"<tr><td>dependent axis (OLS, hybrid)</td><td>{esc(report.axis)}"
        f" (requested: {esc(report.axis_requested)})</td></tr>",
        f"<tr><td>face plane (whole-cloud ODR)</td><td>normal ({_fmt_xyz(frame.normal)}); "
        f"u axis ({_fmt_xyz(frame.u_axis)}); v axis ({_fmt_xyz(frame.v_axis)})</td></tr>",
        f"<tr><td>grid sizes ({u})</td><td>"
        f"{', '.join(f'{s.grid_size / per:g}' for s in report.sections)}"
        + (" (default: from the point spacing, the typical occupied cell holds 16 points)"
           if report.grids_chosen == "default" else "") + "</td></tr>",
        f"<tr><td>binary threshold</td><td>{report.threshold:g} (normalised roughness; "
        "each grid gives the share it flags and the data's own threshold, Otsu's method on "
        "log roughness)</td></tr>",
        "<tr><td>outlier cells</td><td>"
        + ("kept in every statistic and figure (--keep-outliers)" if report.keep_outliers
           else "cells whose OLS or hybrid roughness is larger than the cell are left out of "
           "Table 1, the normalisation, histograms, semivariograms, face maps and zones "
           "(their values stay in the cell table)") + "</td></tr>",
        f"<tr><td>min points per cell</td><td>{report.min_points}</td></tr>",
        f"<tr><td>scanner</td><td>{esc(_scanner_meta(report))}</td></tr>",
        f"<tr><td>software</td><td>rough_viewer {esc(report.version)}</td></tr>",
        f"<tr><td>created (UTC)</td><td>{esc(report.created)}</td></tr>",
        "</table>",
    ]


def _method_note(report: Report) -> str:
    """One paragraph on how every number and figure of the page was made."""
    return (
        '<p class="note">Roughness: population standard deviation of the absolute '
        "point-to-plane distances per cell (ODR: orthogonal; OLS: along the dependent axis; "
        "hybrid: ODR plane, distance along the dependent axis); e_OLS = |OLS - ODR|. "
        "Face maps: cells projected onto the whole-cloud ODR plane, pixel = cell size, "
        "max of the cells in a pixel. Semivariograms: 3-D distances "
        "between cell centres, bins of one cell size up to half the largest extent, "
        "divided by the map's variance; exact over all pairs of cells (FFT or direct "
        "count) where the cost model puts that within "
        f"{VARIOGRAM_BUDGET:g} s for a grid's maps, else estimated from a random sample "
        "of cell pairs (uniform pairs, and lag vectors for the short lags), drawn with "
        "bars of ±1 standard error (each grid size says which). Zones: connected cells (" + html.escape(report.connectivity)
        + f" connectivity) whose normalised ODR roughness is at or above {report.threshold:g}, "
        f"groups of fewer than {report.min_cells} cells dropped, ids by size; area on the "
        "whole-cloud ODR plane; trace = long axis of the cell centres as azimuth/plunge, "
        "orientation = point-weighted mean ODR normal as dip/dip direction (z up, azimuths "
        "clockwise from +y); stereonet: poles of every cell's ODR plane, lower hemisphere, "
        "equal area, contours in multiples of a uniform distribution (MUD). Joint sets: "
        "poles of the planar cells (ODR roughness at most 2 % of the cell, 10 points or "
        "more) weighted by their points, Fisher-kernel density peaks (at least 3 MUD, 30° "
        "apart), cells within 20° of the nearest peak; Fisher mean, kappa and alpha95 per "
        "set; planes (patches) = touching cells of a set within half a cell of offset along "
        "its normal; joints = the coplanar patches of one discontinuity, touching or not; "
        "spacing between consecutive joints along the set's normal where they overlap, and "
        "on scanlines along it; persistence = longest chord of a plane's points along dip "
        "and along strike; Jv, block size index and RQD estimate from the joint spacings; "
        "the roughness of each set from its cells and from profiles and triangles on its "
        "joints' own planes (docs/sets.md).</p>"
    )


def _variogram_line(variograms: Mapping[str, Semivariogram]) -> str:
    """How this grid's semivariograms were computed (exact or sampled, and how)."""
    note = sampling_note(variograms.values())
    if note:
        return f"Semivariograms {note}."
    methods = sorted({"FFT" if vg.method == "fft" else "direct count"
                      for vg in variograms.values()})
    return f"Semivariograms exact over every pair of cells ({', '.join(methods)})."


def _section_html(report: Report, s: GridSection) -> list[str]:
    """One grid size: its cell counts, what could not be drawn, and its figures."""
    esc = html.escape
    per, u = UNIT_METRES[report.unit], UNIT_LABELS[report.unit]
    sid = f"grid-{s.grid_size:g}".replace(".", "_")
    parts = [f'<section id="{sid}" class="grid-section">'
             f'<h2>Grid {s.grid_size / per:g} {u}</h2>']
    if s.error is not None:
        return parts + [f'<p class="error">{esc(s.error)}</p></section>']
    cells = s.result.cell_report("odr") if s.result is not None else {}
    if cells:
        outliers = int(outlier_mask(s.result, "hybrid").sum()) if s.result is not None else 0
        parts.append(
            f'<p class="note">{cells["occupied"]:,} occupied cells, '
            f'{cells["with_value"]:,} with an ODR value, '
            f'{cells["below_min_points"]:,} below {report.min_points} points, '
            f'{cells["degenerate"]:,} degenerate'
            + (f'; {outliers:,} hybrid outliers (larger than the cell), '
               + ("kept" if report.keep_outliers else "left out") if outliers else "")
            + ".</p>"
        )
    for name, advice in s.advice.items():
        if name in ("odr", "ols", "hybrid"):
            parts.append(f'<p class="{"error" if advice.most else "note"}">'
                         f'{esc(MAP_LABELS[name])}: {esc(advice.text(report.unit))}.</p>')
    parts += _scanner_html(report, s)
    figures, drawing_errors = figures_and_errors(report, s)
    for key, why in {**s.figure_errors, **drawing_errors}.items():
        parts.append(f'<p class="error">no {esc(key)} figure: {esc(why)}</p>')
    limited = sorted({f"{vg.max_lag / per:g} {u}" for vg in s.variograms.values()
                      if vg.lag_limited})
    if limited:
        parts.append(f'<p class="note">Semivariogram lags shortened to {", ".join(limited)} '
                     "to fit in memory (default: half the largest extent).</p>")
    if s.variograms:
        parts.append(f'<p class="note">{esc(_variogram_line(s.variograms))}</p>')
    for key, fig in figures.items():
        if key == "sets_stereonet" and s.sets is not None:
            parts.append("<h3>Joint sets</h3>")
            parts.append(f'<p class="note">{esc(_sets_line(s.sets))}</p>')
            parts += rock_mass_html(s.sets, report.unit)
        if key == "zones_table":
            z = s.zones
            parts.append(f"<h3>Zones at threshold {report.threshold:g}</h3>")
            if z is not None:
                flagged = s.advice.get(z.map_name)
                valued = flagged.cells if flagged is not None else 0
                parts.append(f'<p class="note">{z.n_zones:,} zone{"s" if z.n_zones != 1 else ""} '
                             f'holding {int(z.cells.sum()):,} cells'
                             + (f' ({100 * int(z.cells.sum()) / valued:.0f} % of the cells with a '
                                'value)' if valued else "") + ".</p>")
                if flagged is not None and flagged.most:
                    parts.append(f'<p class="error">{esc(flagged.text(report.unit))}.</p>')
        parts.append(figure_html(fig, f"{sid}-{key}", key))
    parts.append("</section>")
    return parts


def _scanner_meta(report: Report) -> str:
    """The meta table's scanner line: the calibration used, or why there is none."""
    if report.scanner_note is not None:
        return report.scanner_note
    trust = next((s.trust for s in report.sections if s.trust is not None), None)
    if trust is None:
        return "scanner positions given; no grid size has a scanner section"
    per, u = UNIT_METRES[report.unit], UNIT_LABELS[report.unit]
    rper, ru = roughness_scale(report.unit)
    return (f"{trust.geometry.positions.shape[0]} position(s); "
            + trust.settings.calibration.describe(per=per, unit=u, small_per=rper, small_unit=ru))


def _scanner_html(report: Report, s: GridSection) -> list[str]:
    """One grid size's scanner figures (docs/scanner.md) as a small table."""
    if s.trust is None:
        return []
    esc = html.escape
    per, u = UNIT_METRES[report.unit], UNIT_LABELS[report.unit]
    rper, ru = roughness_scale(report.unit)
    t = s.trust.summary()
    if t.cells == 0:
        return ['<h3>Scanner</h3><p class="note">No cell has both a value and a scanner '
                "geometry.</p>"]

    def spread(v: tuple[float, float, float], d: float = 1.0, fmt: str = ".2f") -> str:
        return f"{v[0] / d:{fmt}} ({v[1] / d:{fmt}} to {v[2] / d:{fmt}})"

    steps = ", ".join(f"{np.degrees(1.0 / np.sqrt(n)):.4f}°" for n in t.n0 if n > 0)
    rows = [
        ("cells judged", f"{t.cells:,}; seen by " + ", ".join(
            f"{k} scan{'s' if k != 1 else ''}: {v:,}" for k, v in sorted(t.scans.items()))),
        (f"range ({u}), median (5 to 95 %)", spread(t.range_m, per)),
        ("incidence (degrees)", spread(t.incidence_deg, fmt=".1f")),
        ("point density / expected", spread(t.density_ratio)
         + f"; N0 {esc(t.n0_source)} (angular step {steps})"),
        ("occlusion (share of points missing)", spread(t.occlusion)),
        ("predicted noise inflation, % of ODR", spread(t.noise_pct, fmt="+.1f")
         + f" (the paper's target A at this noise: {t.target_noise_pct:+.1f} %)"),
        ("predicted beam smoothing, % of ODR", spread(t.smoothing_pct, fmt="+.1f")
         + f" (asperity radius {t.asperity_scale_m / rper:.3g} {ru})"),
        ("net predicted bias, % of ODR", spread(t.bias_pct, fmt="+.1f")),
        ("flagged", f"incidence above 22.5°: {t.flagged['incidence']:,}; range outside the "
                    f"calibrated span: {t.flagged['range']:,}; predicted noise above 30 % of "
                    f"the roughness: {t.flagged['noise']:,}"),
        ("trusted", f"{t.trusted:,} of {t.cells:,} ({100.0 * t.trusted / t.cells:.0f} %)"),
    ]
    body = "".join(f"<tr><td>{esc(a)}</td><td>{esc(b)}</td></tr>" for a, b in rows)
    return ["<h3>Scanner</h3>", f'<table class="meta">{body}</table>',
            '<p class="note">Per cell: range and incidence from the scanner to the cell '
            "centroid against its ODR normal; density = points over those the scanner's "
            "angular grid puts there; occlusion against the densest neighbour along the beam; "
            "predicted bias from the bias paper's simulated target at the calibration "
            "(docs/scanner.md).</p>"]


def rock_mass_html(sets, unit: str = "m") -> list[str]:
    """The rock-mass figures of a section's sets (``Jv``, block size index, RQD
    estimate with its formula and limits) and the table of every set's joints,
    spacing and roughness (docs/sets.md), lengths in ``unit``, roughness in
    :func:`~rough_viewer.vocabulary.roughness_scale`'s unit."""
    if not sets.n_sets:
        return []
    from rough_viewer.structure.joints import RQD_INTERCEPT, RQD_JV_RANGE, RQD_SLOPE

    esc = html.escape
    per, u = UNIT_METRES[unit], UNIT_LABELS[unit]
    rper, ru = roughness_scale(unit)
    f = sets.figures
    lo, hi = RQD_JV_RANGE
    if f.sets_counted:
        in_m = "" if unit == "m" else f"{f.jv:.3g} per m³; "
        figures = (f"Rock mass: volumetric joint count Jv = {f.jv * per:.3g} joints per "
                   f"{u}³ ({in_m}the sum over the {f.sets_counted} "
                   f"set{'s' if f.sets_counted != 1 else ''} with a spacing of 1 / mean "
                   f"spacing; ISRM 1978, Palmström 2005); block size index Ib = "
                   f"{f.block_size_index / per:.3g} {u} (the mean of the sets' mean "
                   f"spacings); RQD estimate {f.rqd_estimate:.0f} % from "
                   f"RQD = {RQD_INTERCEPT:g} − {RQD_SLOPE:g} Jv (Jv per m³, Palmström "
                   "2005), clipped to 0–100: a correlation with a wide scatter, for Jv "
                   f"from {lo:g} to {hi:g} (100 below, 0 above), not a measured RQD.")
    else:
        figures = ("Rock mass: no set has two joints apart, so no Jv, block size index or "
                   "RQD estimate.")
    r = sets.roughness

    def num(v: float, fmt: str = ".3g", scale: float = 1.0) -> str:
        return format(v / scale, fmt) if np.isfinite(v) else "–"

    head = ["set", "dip / direction (°)", "joints", f"spacing mean ({u})",
            f"scanline spacing ({u})", f"ODR mean ({ru})", f"ODR median ({ru})",
            f"ODR std ({ru})", "JRC estimate dip", "JRC estimate strike",
            "θ*max/(C+1) dip (°)", "θ*max/(C+1) strike (°)", "ΔT dip (°)", "ΔT strike (°)",
            "joints measured", "profiles dip / strike"]
    rows = []
    for k in range(sets.n_sets):
        cells = [f"{k + 1}", f"{sets.dip_deg[k]:02.0f} / {sets.dip_direction_deg[k]:03.0f}",
                 f"{sets.n_joints_per_set[k]:,}", num(sets.spacing_mean[k], scale=per),
                 num(sets.spacing_scanline_mean[k], scale=per),
                 num(r.odr_mean[k], scale=rper), num(r.odr_median[k], scale=rper),
                 num(r.odr_std[k], scale=rper),
                 num(r.jrc_estimate_dip[k], ".1f"), num(r.jrc_estimate_strike[k], ".1f"),
                 num(r.theta_max_c1_dip[k], ".1f"), num(r.theta_max_c1_strike[k], ".1f"),
                 num(r.delta_t_dip[k], ".1f"), num(r.delta_t_strike[k], ".1f"),
                 f"{r.joints_measured[k]:,}",
                 f"{r.profiles_dip[k]:,} / {r.profiles_strike[k]:,}"]
        rows.append("<tr>" + "".join(f"<td>{esc(c)}</td>" for c in cells) + "</tr>")
    out = [f'<p class="note" data-table="rock_mass">{esc(figures)}</p>',
           '<table class="meta" data-table="set_roughness"><tr>'
           + "".join(f"<th>{esc(h)}</th>" for h in head) + "</tr>" + "".join(rows)
           + "</table>",
           '<p class="note">Roughness of each set: ODR = the roughness of the cells whose '
           "poles made the set (planar cells, so at most the planar threshold); along dip "
           "and strike: each of the set's largest joints turned into its own plane's frame, "
           "profiles laid down its dip and along its strike (JRC estimate = 32.2 + 32.47 "
           "log10 Z2, Tse and Cruden 1979, the mean over the profiles: an estimate, "
           "calibrated for profiles sampled at 0.5–1 mm) and its points triangulated in "
           "that plane (θ*max/(C+1), Grasselli; ΔT, the mean apparent dip of the facets "
           "facing the shear; the facets of all the set's joints pooled), shear down the "
           "dip and along the strike (docs/sets.md).</p>"]
    out += [f'<p class="note">warning: {esc(w)}</p>' for w in r.warnings]
    return out


def _sets_line(sets) -> str:
    """One sentence on a section's joint sets."""
    if not sets.n_sets:
        return sets.note
    p, j = sets.planes.n_planes, sets.joints.n_joints
    line = (f"{sets.n_sets} set{'s' if sets.n_sets != 1 else ''} of "
            f"{int(sets.cells.sum()):,} planar cells, {p:,} plane{'s' if p != 1 else ''}, "
            f"{j:,} joint{'s' if j != 1 else ''}.")
    return f"{line} ⚠ {sets.face_note}" if sets.face_note else line


def check_png_export() -> None:
    """Raise InputError (one line) unless the optional kaleido package is installed."""
    from rough_viewer.visual.export import check_figure_export

    check_figure_export("png")


def png_figures(report: Report) -> list[tuple[str, Any]]:
    """``(file name, figure)`` for every figure of every grid section, for PNG export
    (``fig.to_image(format="png")`` needs kaleido: see :func:`check_png_export`)."""
    return [
        (png_name(s.grid_size, key, report.unit), fig)
        for s in report.sections
        for key, fig in report_figures(report, s).items()
    ]
