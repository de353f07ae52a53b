"""Roughness by direction as text, plain numbers and the report's HTML section, from a
:class:`~rough_viewer.directions.analysis.DirectionsResult` and its table
(:func:`rough_viewer.directions.table.directions_table`)."""

from __future__ import annotations

import html
import math
from typing import Any

from rough_viewer.directions.analysis import DirectionsResult
from rough_viewer.directions.table import directions_table
from rough_viewer.io.jsonable import to_jsonable
from rough_viewer.vocabulary import UNIT_LABELS, UNIT_METRES


def _num(v: float, fmt: str) -> str:
    """``v`` formatted, or ``-`` as wide as ``fmt``'s width where it is not finite."""
    if v is None or not math.isfinite(v):
        width = int("".join(c for c in fmt.split(".")[0] if c.isdigit()) or 0)
        return "-".rjust(width)
    return format(v, fmt)


def describe(result: DirectionsResult, *, unit: str = "m") -> list[str]:
    """What was measured, one line each, lengths in ``unit`` (text and report alike)."""
    per, u = UNIT_METRES[unit], UNIT_LABELS[unit]
    f = result.frame
    s0 = result.sets[0]
    used = [x.summary().profiles for x in result.sets[: max(1, result.azimuth_deg.size // 2)]]
    vec = ", ".join
    lines = [
        f"{result.source}: {result.n_points:,} points; face normal "
        f"({vec(f'{c:.3f}' for c in f.normal)}), azimuth 0 along u "
        f"({vec(f'{c:.3f}' for c in f.u_axis)}), 90 along v ({vec(f'{c:.3f}' for c in f.v_axis)})",
        f"profiles every {s0.spacing / per:.4g} {u}, band +-{s0.band_half_width / per:.4g} {u}, "
        f"samples every {s0.sample_spacing / per:.4g} {u}; "
        f"{min(used)}-{max(used)} profiles measured per direction",
    ]
    skipped: dict[str, int] = {}
    for x in result.sets[: max(1, result.azimuth_deg.size // 2)]:
        for reason, n in x.skipped:
            skipped[reason] = skipped.get(reason, 0) + n
    if skipped:
        lines.append("profiles not measured: " + "; ".join(
            f"{n} {reason}" for reason, n in sorted(skipped.items(), key=lambda r: -r[1]))
            + (" (--min-samples, or a finer --sample-spacing)"
               if any("samples" in r for r in skipped) else ""))
    if result.tin is not None:
        what = ("the file's mesh" if result.surface == "mesh"
                else "the cloud triangulated in its plane")
        lines.append(f"TIN: {result.n_triangles:,} triangles of {what}, area "
                     f"{result.tin.area / per**2:.4g} {u}2, dip thresholds every "
                     f"{result.tin.dip_step_deg:g} degrees")
    w = result.windows
    if w is not None:
        lines.append(f"window map: {w.n_windows:,} windows of radius {w.radius / per:.4g} {u} "
                     f"every {w.step / per:.4g} {u} (of {w.candidates:,} centres; kept where "
                     f"triangles cover {w.min_coverage:.0%} of the disc)")
    return lines


def format_directions(result: DirectionsResult, *, unit: str = "m") -> str:
    """The command's text: what was measured and the table, one row per azimuth."""
    from rough_viewer.vocabulary import roughness_scale

    rf, ru = roughness_scale(unit)
    t = directions_table(result, unit="m")
    lines = describe(result, unit=unit)
    lines.append("")
    head = (f"{'azimuth':>7} {'profiles':>8} {'H':>6} {'+-':>5} {'D':>6} {'H dn':>6} "
            f"{'RMS ' + ru:>9} {'Z2':>7} {'JRC est.':>8} {'tmax/(C+1)':>10} {'Delta-T':>8}")
    lines.append(head)
    for i in range(result.azimuth_deg.size):
        lines.append(
            f"{t['azimuth_deg'][i]:7.1f} {int(t['profiles'][i]):8d} {_num(t['h_mean'][i], '6.3f')} "
            f"{_num(t['h_std'][i], '5.3f')} {_num(t['d_mean'][i], '6.3f')} "
            f"{_num(t['h_denoised_mean'][i], '6.3f')} {_num(t['rms_mean'][i] / rf, '9.4g')} "
            f"{_num(t['z2_mean'][i], '7.4f')} {_num(t['jrc_mean'][i], '8.1f')} "
            f"{_num(t['theta_max_c1'][i], '10.2f')} "
            f"{_num(t['delta_t'][i] if 'delta_t' in t else math.nan, '8.2f')}")
    lines.append("")
    lines.append("H, D = 2 - H: roughness length of the profiles (mean +- std over them); H dn: "
                 "after wavelet de-noising; JRC est.: Tse and Cruden (1979) from each profile's "
                 "Z2; tmax/(C+1) and Delta-T in degrees, facing the direction")
    return "\n".join(lines)


def directions_dict(result: DirectionsResult, *, unit: str = "m") -> dict[str, Any]:
    """Plain numbers (JSON): the settings, the frame, the table (``columns`` and
    ``rows``), the windows' count; lengths in ``unit``."""
    per = UNIT_METRES[unit]
    t = directions_table(result, unit=unit)
    s0 = result.sets[0]
    return {
        "source": result.source,
        "points": result.n_points,
        "unit": unit,
        "face": {"centroid": to_jsonable(result.frame.origin / per),
                 "normal": to_jsonable(result.frame.normal),
                 "u_axis": to_jsonable(result.frame.u_axis),
                 "v_axis": to_jsonable(result.frame.v_axis)},
        "profile_spacing": s0.spacing / per,
        "band_half_width": s0.band_half_width / per,
        "sample_spacing": s0.sample_spacing / per,
        "surface": result.surface,
        "triangles": result.n_triangles,
        "tin_error": result.tin_error,
        "windows": None if result.windows is None else result.windows.n_windows,
        "warnings": list(result.warnings),
        "columns": list(t),
        "rows": [[to_jsonable(t[c][i]) for c in t] for i in range(result.azimuth_deg.size)],
    }


def directions_html(result: DirectionsResult, *, unit: str = "m", sid: str = "directions"
                    ) -> list[str]:
    """The report's section for one surface: what was measured, the rose, the table
    and, where made, the window map (figures from :mod:`rough_viewer.visual.directions`)."""
    from rough_viewer.visual.directions import (
        directions_table_figure,
        rose_figure,
        window_map_figure,
    )

    esc = html.escape
    parts = [f'<section id="{esc(sid)}" class="directions-section">',
             f"<h2>Roughness by direction: {esc(result.source)}</h2>"]
    parts += [f'<p class="note">{esc(line)}</p>' for line in describe(result, unit=unit)]
    parts += [f'<p class="error">warning: {esc(w)}</p>' for w in result.warnings]
    figures = {"rose": rose_figure(directions_table(result, unit=unit), unit=unit),
               "table": directions_table_figure(directions_table(result, unit=unit), unit=unit)}
    if result.windows is not None:
        figures["windows"] = window_map_figure(result.windows, unit=unit)
    for key, fig in figures.items():
        div = fig.to_html(full_html=False, include_plotlyjs=False, div_id=f"{sid}-{key}",
                          config={"displaylogo": False})
        parts.append(f'<div class="figure" data-figure="directions-{key}">{div}</div>')
    parts.append("</section>")
    return parts
