"""Roughness by direction of one surface: profile sets and the TIN parameters at a
step of azimuths, as ``rough-viewer directions``, the report and the app show them.

:func:`analyse_directions` measures a cloud (and its mesh, when the file has one,
else the cloud triangulated in its best-fit plane) with one face frame for both
the profiles (:mod:`rough_viewer.profiles.profile_sets`) and the triangles
(:mod:`rough_viewer.tin`); :func:`directions_table` is the one table every output
shows (the ``DIRECTIONS.csv`` contract, :data:`TABLE_COLUMNS`); the window map's
table is :meth:`rough_viewer.tin.directional.WindowRoughness.table` (``WINDOWS.csv``).
"""

from __future__ import annotations

import html
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rough_viewer.grid.maps import FaceFrame, face_frame
from rough_viewer.grid.planes import whole_cloud_plane
from rough_viewer.io.cloud import PointCloud
from rough_viewer.io.jsonable import to_jsonable
from rough_viewer.io.mesh import TriangleMesh
from rough_viewer.profiles.profile_sets import (
    DEFAULT_MIN_SAMPLES,
    ProfileSet,
    profile_sets,
    set_warnings,
)
from rough_viewer.tin.directional import (
    DEFAULT_DIP_STEP_DEG,
    DEFAULT_MIN_COVERAGE,
    DirectionalRoughness,
    WindowRoughness,
    azimuths,
    directional_roughness,
    window_roughness,
)
from rough_viewer.tin.surface import triangulate_cloud
from rough_viewer.vocabulary import UNIT_LABELS, UNIT_METRES, InputError, ProgressFn

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
#: Window radius by default: this share of the face's shorter extent.
DEFAULT_WINDOW_RADIUS_SHARE = 0.1
#: Progress steps per stage of :func:`analyse_directions` (profiles, triangles,
#: windows): ``progress(done, total)`` counts in these.
STAGE_STEPS = 1000


@dataclass(frozen=True)
class DirectionSettings:
    """How a surface is measured by direction (lengths in metres)."""

    step_deg: float = 15.0
    """Azimuth step, degrees: azimuths 0, step, ... below 360."""
    spacing: float | None = None
    """Distance between profile lines (default: see :mod:`.profile_sets`)."""
    half_width: float | None = None
    """Band half-width of each profile (default: the point spacing)."""
    sample_spacing: float | None = None
    """Sample spacing along the profiles (default: the point spacing)."""
    windows: tuple[float, ...] | str | None = None
    """Roughness-length window lengths, or a rule (default: the default rule of
    :mod:`rough_viewer.profiles.fractal`)."""
    window_radius: float | None = None
    """Radius of the circular windows of the map; None: no map unless
    ``window_map`` (then :data:`DEFAULT_WINDOW_RADIUS_SHARE` of the shorter extent)."""
    window_step: float | None = None
    """Spacing of the window centres (default: the radius)."""
    window_map: bool = False
    """Make the window map."""
    dip_step_deg: float = DEFAULT_DIP_STEP_DEG
    min_coverage: float = DEFAULT_MIN_COVERAGE
    min_samples: int = DEFAULT_MIN_SAMPLES
    max_edge: float | None = None
    """Longest triangle edge kept when a cloud is triangulated (default 5 point
    spacings)."""
    tin: bool = True
    """Measure the TIN parameters (θ*max/(C+1), ΔT); False leaves them out (a cloud's
    triangulation takes most of the time)."""


@dataclass(frozen=True)
class DirectionsResult:
    """Everything measured by direction on one surface."""

    source: str
    """The input, as named to the user."""
    n_points: int
    frame: FaceFrame
    """The face frame of the azimuths (profiles and triangles alike)."""
    azimuth_deg: np.ndarray
    sets: tuple[ProfileSet, ...]
    tin: DirectionalRoughness | None
    """None where the surface has no triangles (``tin_error`` says why)."""
    surface: str
    """``"mesh"`` (the file's triangles), ``"triangulated"`` or ``"none"``."""
    n_triangles: int
    windows: WindowRoughness | None = None
    tin_error: str | None = None
    window_error: str | None = None
    warnings: tuple[str, ...] = ()
    settings: DirectionSettings = field(default_factory=DirectionSettings)


def analyse_directions(
    cloud: PointCloud,
    settings: DirectionSettings,
    *,
    mesh: TriangleMesh | None = None,
    source: str = "",
    progress: ProgressFn | None = None,
) -> DirectionsResult:
    """Profile sets and TIN parameters of one surface at every azimuth.

    Parameters
    ----------
    cloud : PointCloud
        The points (metres); for a mesh, its vertices.
    settings : DirectionSettings
    mesh : TriangleMesh, optional
        The surface's own triangles (an STL or PLY mesh); without them the cloud is
        triangulated in its best-fit plane, and where that fails the TIN parameters
        are left out with the reason (``tin_error``).
    source : str
        Name of the input, for messages.
    progress : callable, optional
        ``progress(done, total)`` in stages (profile directions, then the TIN, then
        the windows).
    """
    az = azimuths(settings.step_deg)
    plane = whole_cloud_plane(cloud)
    frame = face_frame(plane)
    stages = 2 + (1 if settings.window_map else 0)

    def stage(k: int) -> None:
        if progress is not None:
            progress(k * STAGE_STEPS, stages * STAGE_STEPS)

    def within(k: int) -> ProgressFn | None:
        """Progress inside stage ``k`` (0-based), called between azimuths."""
        if progress is None:
            return None
        report = progress

        def step(done: int, total: int) -> None:
            share = done / total if total > 0 else 0.0
            report(k * STAGE_STEPS + int(share * (STAGE_STEPS - 1)), stages * STAGE_STEPS)

        return step

    sets = profile_sets(cloud, az, spacing=settings.spacing, band_half_width=settings.half_width,
                        sample_spacing=settings.sample_spacing, windows=settings.windows,
                        plane=plane, min_samples=settings.min_samples, progress=within(0))
    stage(1)
    warnings = list(set_warnings(sets))
    surface, tin, tin_error, n_tri = "none", None, None, 0
    surf = mesh
    try:
        if not settings.tin:
            raise InputError("not asked for")
        if surf is None:
            surf = triangulate_cloud(cloud, plane=plane, max_edge=settings.max_edge)
            surface = "triangulated"
        else:
            surface = "mesh"
        tin = directional_roughness(surf, az, dip_step_deg=settings.dip_step_deg, plane=plane,
                                    progress=within(1))
        n_tri = tin.n_triangles
    except InputError as exc:
        tin_error, surface, surf = str(exc), "none", None
        if settings.tin:
            warnings.append(f"no TIN parameters (theta*max/(C+1), Delta-T): {exc}")
    stage(2)
    windows, window_error = None, None
    if settings.window_map and surf is not None:
        radius, step = window_size(cloud, frame, settings)
        try:
            windows = window_roughness(surf, az, radius=radius, step=step,
                                       dip_step_deg=settings.dip_step_deg,
                                       min_coverage=settings.min_coverage, plane=plane,
                                       progress=within(2))
        except InputError as exc:
            window_error = str(exc)
            warnings.append(f"no window map: {exc}")
        stage(3)
    elif settings.window_map:
        window_error = "the surface has no triangles"
    return DirectionsResult(
        source=source or cloud.source, n_points=cloud.n, frame=frame, azimuth_deg=az,
        sets=sets, tin=tin, surface=surface, n_triangles=n_tri, windows=windows,
        tin_error=tin_error, window_error=window_error,
        warnings=tuple(dict.fromkeys(warnings)), settings=settings,
    )


def window_size(cloud: PointCloud, frame: FaceFrame, settings: DirectionSettings
                ) -> tuple[float, float]:
    """(radius, step) of the window map in metres: as given, else
    :data:`DEFAULT_WINDOW_RADIUS_SHARE` of the face's shorter extent in its plane and
    a step of one radius."""
    radius = settings.window_radius
    if radius is None:
        rel = cloud.xyz() - frame.origin
        extent = np.ptp(np.column_stack([rel @ frame.u_axis, rel @ frame.v_axis]), axis=0)
        radius = DEFAULT_WINDOW_RADIUS_SHARE * float(extent.min())
    step = settings.window_step if settings.window_step is not None else radius
    return float(radius), float(step)


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


def analyse_paths(
    paths: Sequence[Any],
    settings: DirectionSettings,
    *,
    units: str | None = None,
    progress: ProgressFn | None = None,
) -> list[DirectionsResult]:
    """:func:`analyse_directions` of each file on its own (its mesh where it has
    one): the report's section per input."""
    from rough_viewer.io.load import load_points
    from rough_viewer.io.mesh import load_mesh

    out = []
    for i, p in enumerate(paths):
        cloud = load_points(p, units=units)  # type: ignore[arg-type]
        mesh = load_mesh(p, units=cloud.source_unit)  # type: ignore[arg-type]
        out.append(analyse_directions(cloud, settings, mesh=mesh, source=str(p)))
        if progress is not None:
            progress(i + 1, len(paths))
    return out
