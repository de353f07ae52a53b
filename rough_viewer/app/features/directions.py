"""Roughness by direction, in the Profile tab's "Directions" folder (docs/directions.md).

"Measure directions" runs a :class:`DirectionsJob` on the whole shown cloud: parallel
profiles across the face at every azimuth step (each extracted, de-noised and fitted
as the Profile tab does, with its fit windows), and, when asked, the TIN parameters
θ*max/(C+1) and ΔT of the surface (its own triangles for an STL or PLY mesh in the
data folder or uploaded, those of a crop's kept vertices for a crop, else the cloud
triangulated in its best-fit plane: the slow part). The
folder then shows the rose, the per-direction table, and the profile lines on the
rock, coloured by direction (:mod:`rough_viewer.visual.directions`).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import viser

from rough_viewer.app.binding import Binding
from rough_viewer.app.cloud import LoadedCloud
from rough_viewer.app.features.profile import ProfileFeature
from rough_viewer.app.host import Host
from rough_viewer.app.layout import PLOTLY_CONFIG, placeholder, set_figure
from rough_viewer.app.markup import md
from rough_viewer.app.worker import Job, Run
from rough_viewer.io import PointCloud
from rough_viewer.io.mesh import MESH_SUFFIXES, TriangleMesh, load_mesh
from rough_viewer.report.directions import (
    DirectionSettings,
    DirectionsResult,
    analyse_directions,
    directions_table,
)
from rough_viewer.report.view import DirectionsView, View
from rough_viewer.visual.directions import (
    directions_table_figure,
    profile_segments,
    rose_figure,
    segment_colours,
)
from rough_viewer.vocabulary import UNITS, Unit

L_STEP = "Azimuth step (°)"
#: Warnings shown under the directions' status, and the most characters of each (a
#: bound on what a hostile cloud's text can make the page hold).
MAX_WARNINGS = 4
WARNING_CHARS = 2000
L_SPACING = "Line spacing"
L_TIN = "Triangle parameters (slow)"
L_MEASURE = "Measure directions"
L_LINES = "Show direction lines"
#: Scene node of the profile lines.
NODE_LINES = "/directions/lines"


def spacing_label(unit_label: str) -> str:
    return f"{L_SPACING} ({unit_label})"


@dataclass(eq=False)
class DirectionsFeature:
    """Handles and state of the Directions folder."""

    host: Host
    profile: ProfileFeature
    step: viser.GuiNumberHandle[float]
    spacing: viser.GuiNumberHandle[float]
    tin: viser.GuiCheckboxHandle
    measure: viser.GuiButtonHandle
    lines: viser.GuiCheckboxHandle
    status: viser.GuiMarkdownHandle
    rose: viser.GuiPlotlyHandle
    table: viser.GuiPlotlyHandle
    binding: Binding = field(default_factory=Binding)
    result: DirectionsResult | None = None
    """The last measurement, of :attr:`cloud`."""
    cloud: LoadedCloud | None = None
    nodes: list[viser.SceneNodeHandle] = field(default_factory=list)
    uploaded: tuple[PointCloud, TriangleMesh] | None = None
    """An uploaded mesh file's cloud and its triangles, read before the upload was
    deleted (:meth:`keep_upload_mesh`)."""

    def keep_upload_mesh(self, cloud: PointCloud, mesh: TriangleMesh | None) -> None:
        """Remember the triangles of an uploaded file read as ``cloud`` (None: it has
        none; a mesh kept before is dropped)."""
        self.uploaded = None if mesh is None else (cloud, mesh)

    def settings(self) -> DirectionSettings:
        """The settings the controls ask for (the fit windows are the Profile tab's)."""
        per = self.host.session.shown.loaded.units.per
        spacing = float(self.spacing.value) * per
        windows = self.profile.binding.read().windows
        return DirectionSettings(step_deg=float(self.step.value),
                                 spacing=spacing if spacing > 0 else None,
                                 windows=windows if windows is None or isinstance(windows, str)
                                 else tuple(float(w) for w in windows),
                                 tin=bool(self.tin.value))

    def mesh(self, loaded: LoadedCloud) -> TriangleMesh | None:
        """The triangles of the shown cloud's file (an STL or a PLY with faces in the
        data folder, or uploaded), for a crop those of its kept vertices, or None."""
        whole = loaded.uncropped or loaded
        if self.uploaded is not None and self.uploaded[0] is whole.cloud:
            mesh: TriangleMesh | None = self.uploaded[1]
        else:
            mesh = self._file_mesh(whole.cloud)
        if mesh is None or loaded.crop_mask is None:
            return mesh
        if mesh.n_vertices != whole.cloud.n:  # its vertices are not the points
            return None
        return mesh.kept(loaded.crop_mask)

    def _file_mesh(self, cloud: PointCloud) -> TriangleMesh | None:
        source = Path(cloud.source) if cloud.source else None
        if source is None or source.suffix.lower() not in MESH_SUFFIXES or not source.is_file():
            return None
        try:
            inside = source.resolve().is_relative_to(self.host.options.data.root)
        except OSError:
            return None
        if not inside:
            return None
        unit: Unit | None = next((u for u in UNITS if u == cloud.source_unit), None)
        return load_mesh(source, units=unit)

    def figures(self) -> dict[str, viser.GuiPlotlyHandle]:
        return {"directions_rose": self.rose, "directions_table": self.table}

    # ------------------------------------------------------------------ saved views
    def snapshot(self) -> dict[str, Any]:
        """The folder's settings (the spacing in metres) and whether the shown cloud's
        directions were measured."""
        per = self.host.session.shown.loaded.units.per
        spacing = float(self.spacing.value) * per
        measured = self.result is not None and self.cloud is self.host.session.shown.loaded
        return {"directions": DirectionsView(
            step_deg=float(self.step.value), spacing_m=spacing if spacing > 0 else None,
            tin=bool(self.tin.value), lines=bool(self.lines.value), measured=measured)}

    def restore(self, view: View) -> Job[Host] | None:
        return None if view.directions is None else RestoreDirectionsJob(self, view.directions)

    def on_cloud(self) -> None:
        """Another cloud: the measurement and its lines belong to the one before."""
        self.host.scene.remove(self.nodes)
        self.nodes = []
        self.result, self.cloud = None, self.host.session.shown.loaded
        session = self.host.session
        if self.uploaded is not None and not any(
                s is not None and (s.loaded.uncropped or s.loaded).cloud is self.uploaded[0]
                for s in (session.shown, session.stashed)):
            self.uploaded = None  # its cloud is gone
        self.spacing.label = spacing_label(self.host.session.shown.loaded.units.label)
        self.status.content = "Press **Measure directions** for this cloud."


@dataclass(frozen=True)
class DirectionsJob(Job[Host]):
    """Measure the shown cloud by direction and show the rose, the table and lines."""

    f: DirectionsFeature = field(compare=False)
    lane: ClassVar[str] = "directions"
    #: a load or a crop (lane "load") replaces the cloud being measured: this job
    #: gives way (it held another tab's load 43 s at a 1-degree step; issue 36 item 17)
    yields_to: ClassVar[frozenset[str]] = frozenset({"load"})

    @property
    def title(self) -> str:
        return "roughness by direction"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        f = self.f
        loaded = ctx.session.shown.loaded
        settings = f.settings()  # InputError: named
        f.status.content = "_measuring by direction…_"
        mesh = f.mesh(loaded) if settings.tin else None
        yield "settings"
        ctx.progress(0.0)

        def report(done: int, total: int) -> None:
            ctx.progress(100.0 * done / max(total, 1))

        try:
            result = analyse_directions(loaded.cloud, settings, mesh=mesh,
                                        source=Path(loaded.cloud.source).name,
                                        progress=run.progress(report))
        finally:
            ctx.progress(None)
        yield "measure"
        f.result, f.cloud = result, loaded
        unit = loaded.units.unit
        table = directions_table(result, unit=unit)
        values = ("h_mean", "h_denoised_mean") if result.tin is None \
            else ("h_mean", "theta_max_c1", "delta_t")
        set_figure(f.rose, rose_figure(table, values=values, unit=unit))
        set_figure(f.table, directions_table_figure(table, unit=unit))
        profiles = int(sum(int(np.count_nonzero(s.used)) for s in result.sets))
        tin = (f", TIN of {result.n_triangles:,} triangles ({result.surface})"
               if result.tin is not None else "")
        # every warning whole, one a line (one cut at 400 characters ended in "…")
        notes = "".join(f"  \n⚠ {md(w, max_chars=WARNING_CHARS)}"
                        for w in result.warnings[:MAX_WARNINGS])
        f.status.content = (f"**{len(result.azimuth_deg)} directions**, {profiles:,} profiles"
                            f"{md(tin)}" + notes)
        yield "figures"
        ctx.scene.remove(f.nodes)
        segs, az = profile_segments(result.sets)
        f.nodes = []
        if len(segs):
            # lifted off the rock to both sides (as the Profile tab's lines), so the
            # points in front cannot hide them
            lift = (2.0 * float(ctx.scene.point_size)) * np.asarray(result.frame.normal)
            local = segs.astype(np.float64) - loaded.origin
            colours = segment_colours(az)
            visible = bool(f.lines.value)
            f.nodes = [ctx.scene.segments(f"{NODE_LINES}/{side}", local + sign * lift, colours,
                                          visible=visible)
                       for side, sign in (("front", 1.0), ("back", -1.0))]
        yield "lines"


@dataclass(frozen=True)
class RestoreDirectionsJob(Job[Host]):
    """A saved view's Directions settings in the controls, and the directions measured
    again when they were measured when it was saved."""

    f: DirectionsFeature = field(compare=False)
    directions: DirectionsView
    lane: ClassVar[str] = "directions-restore"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        f, d = self.f, self.directions
        per = ctx.session.shown.loaded.units.per
        f.binding.set(f.step, float(d.step_deg))
        f.binding.set(f.spacing, 0.0 if d.spacing_m is None else float(d.spacing_m) / per)
        f.binding.set(f.tin, bool(d.tin))
        f.binding.set(f.lines, bool(d.lines))
        yield "settings"
        if d.measured:
            ctx.submit(DirectionsJob(f))


@dataclass(frozen=True)
class LinesJob(Job[Host]):
    """Show or hide the profile lines."""

    f: DirectionsFeature = field(compare=False)
    lane: ClassVar[str] = "directions-lines"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        for node in self.f.nodes:
            ctx.scene.update(node, visible=bool(self.f.lines.value))
        yield "lines"


def mount(host: Host) -> DirectionsFeature:
    """The Directions folder at the end of the Profile tab."""
    gui = host.gui
    units = host.session.shown.loaded.units
    with host.tab("Profile"), host.folder("Directions"):
        f = DirectionsFeature(
            host=host, profile=host.feature(ProfileFeature),
            step=gui.add_number(L_STEP, 15.0, min=1.0, max=90.0, step=1.0,
                                hint="Profiles every this many degrees of azimuth in the "
                                "face's plane."),
            spacing=gui.add_number(spacing_label(units.label), 0.0, min=0.0, max=1e6,
                                   step=0.001, hint="Distance between parallel profile "
                                   "lines; 0 = the default (at most 100 lines a direction, "
                                   "bands that do not overlap)."),
            tin=gui.add_checkbox(L_TIN, False, hint="θ*max/(C+1) and ΔT of the surface: "
                                 "a mesh's own triangles, else the cloud triangulated "
                                 "(seconds to a minute at millions of points)."),
            measure=gui.add_button(L_MEASURE),
            lines=gui.add_checkbox(L_LINES, True),
            status=gui.add_markdown("Press **Measure directions** to profile the face "
                                    "in every direction."),
            rose=gui.add_plotly(placeholder("Rose of roughness by direction",
                                            "press Measure directions"),
                                config=PLOTLY_CONFIG, aspect=0.2),
            table=gui.add_plotly(placeholder("Roughness by direction: table"),
                                 config=PLOTLY_CONFIG, aspect=0.15),
        )
    f.cloud = host.session.shown.loaded
    host.allow(f.step, f.spacing, f.tin, f.measure, f.lines)
    f.binding.on_change([f.measure], lambda _h: host.submit(DirectionsJob(f)))
    f.binding.on_change([f.lines], lambda _h: host.submit(LinesJob(f)))
    host.on_cloud(f.on_cloud)
    return f


__all__ = ["DirectionsFeature", "DirectionsJob", "mount"]
