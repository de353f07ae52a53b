"""Roughness by direction of one surface: profile sets and the TIN parameters at a
step of azimuths, as ``rough-viewer directions``, the report and the app show them.

:func:`analyse_directions` measures a cloud (and its mesh, when the file has one,
else the cloud triangulated in its best-fit plane) with one face frame for both
the profiles (:mod:`rough_viewer.profiles.profile_sets`) and the triangles
(:mod:`rough_viewer.tin`); :func:`rough_viewer.directions.table.directions_table` is the
one table every output shows (the ``DIRECTIONS.csv`` contract); the window map's
table is :meth:`rough_viewer.tin.directional.WindowRoughness.table` (``WINDOWS.csv``).
The text and the report's section are :mod:`rough_viewer.report.directions`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rough_viewer.grid.maps import FaceFrame, face_frame
from rough_viewer.grid.planes import whole_cloud_plane
from rough_viewer.io.cloud import PointCloud
from rough_viewer.io.formats.mesh import TriangleMesh
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
from rough_viewer.vocabulary import InputError, ProgressFn

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
    if not settings.tin:
        tin_error, surf = "not asked for", None
    else:
        try:
            if surf is None:
                surf = triangulate_cloud(cloud, plane=plane, max_edge=settings.max_edge)
                surface = "triangulated"
            else:
                surface = "mesh"
            tin = directional_roughness(surf, az, dip_step_deg=settings.dip_step_deg,
                                        plane=plane, progress=within(1))
            n_tri = tin.n_triangles
        except InputError as exc:
            tin_error, surface, surf = str(exc), "none", None
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


def analyse_paths(
    paths: Sequence[Any],
    settings: DirectionSettings,
    *,
    units: str | None = None,
    progress: ProgressFn | None = None,
) -> list[DirectionsResult]:
    """:func:`analyse_directions` of each file on its own (its mesh where it has
    one): the report's section per input."""
    from rough_viewer.io.formats.mesh import load_mesh
    from rough_viewer.io.load import load_points

    out = []
    for i, p in enumerate(paths):
        cloud = load_points(p, units=units)  # type: ignore[arg-type]
        mesh = load_mesh(p, units=cloud.source_unit)  # type: ignore[arg-type]
        out.append(analyse_directions(cloud, settings, mesh=mesh, source=str(p)))
        if progress is not None:
            progress(i + 1, len(paths))
    return out
