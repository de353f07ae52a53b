"""The map: the cloud coloured by cell roughness, and the Map tab's controls.

The Map tab chooses what colours the points (the roughness map of a grid, model,
dependent axis and minimum points, continuous or binary, its colour map and
stretch; or a colour layer), the point size and the camera preset; a click on a
point reports its cell. Everything the tab does is a job on the worker:

=============  =======================================================  =================
job            stages                                                    lane (cancels)
=============  =======================================================  =================
ShowJob        show (a cloud into the scene), then RenderJob's           load (render,
                                                                         panels, pick)
LoadJob        read, prepare, show, then RenderJob's                     load (render,
                                                                         panels, pick)
RenderJob      check, grid, colours                                      render (panels)
PickJob        pick, cell and across scales, or a feature's handler      pick, keep all
AxisJob        axis                                                      axis
CameraJob      camera (a preset view)                                    camera
PointSizeJob   points                                                    points
=============  =======================================================  =================

The package holds, by idea: :mod:`.binding` (the tab's handles, labels and
:class:`~.binding.MapBinding`), :mod:`.controls` (adding and wiring them),
:mod:`.render` (colouring the map, the colour bar and status), :mod:`.load`
(showing another cloud) and :mod:`.pick` (a click's cell). Other features reach
the map only through their :class:`~rough_viewer.app.host.Host` (``request``,
``settings``, ``take_overlay``, ``show_cloud``, ...), which the shell hands to
the :class:`MapFeature` mounted here. The level-of-detail jobs and the camera
watch are the scene's (:mod:`rough_viewer.app.detail`).

A control change submits a :class:`RenderJob` naming the control and its new value
(its callbacks do nothing else); on the worker, :meth:`MapBinding.settle` puts the
value back if the app showed another meanwhile, moves the controls that follow it (a typed free size
picks the "free" grid, a preset shows its size, dragged or typed limits pick that stretch) and reads the controls. A pending
RenderJob or LoadJob merges a newer RenderJob (the changes it carries), so a load
followed at once by a control change shows the new file with the new settings.
"""
from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

from rough_viewer.app.cloud import LoadedCloud
from rough_viewer.app.colouring import Colouring
from rough_viewer.app.features.map.binding import MapTab
from rough_viewer.app.features.map.controls import add_controls, wire
from rough_viewer.app.features.map.load import InMemory, LoadJob, ShowJob, show_cloud
from rough_viewer.app.features.map.render import (
    RenderJob,
    RestoreMapJob,
    check_view_for_app,
    prefetch_presets,
    render_stages,
)
from rough_viewer.app.host import CloudSource, Host
from rough_viewer.app.settings import MapSettings
from rough_viewer.app.worker import Job, Run
from rough_viewer.report.view import ColourSettings, View
from rough_viewer.vocabulary import UNITS, Unit

__all__ = ["InMemory", "LoadJob", "MapFeature", "ShowJob", "check_view_for_app", "mount"]


@dataclass(eq=False)
class MapFeature(MapTab):
    """The mounted Map tab: what other features ask of the map (through their host,
    :class:`~rough_viewer.app.host.MapService`) and its part of saved views."""

    # ------------------------------------------------------------------ for other features
    def request(self, **changes: object) -> int:
        """Queue the map the controls show once the named controls hold these values
        (as a person sets them: a control's own change, or another tab's twin of a
        control); ``toggle=True`` flips ODR and OLS."""
        return self.host.submit(RenderJob(self, changes=tuple(changes.items())))

    def show_cloud(self, loaded: LoadedCloud, settings: MapSettings, *,
                   frame: bool = True) -> None:
        """Put ``loaded`` in the scene with ``settings`` in the controls (worker;
        :func:`~.load.show_cloud`)."""
        show_cloud(self, loaded, settings, frame=frame)

    def render(self, run: Run, settings: MapSettings) -> Iterator[str]:
        """The stages that colour the map with ``settings`` (a job's; worker)."""
        return render_stages(self, run, settings)

    def load(self, source: CloudSource, *, stash: bool = False, label: str = "",
             adjust: Callable[[MapSettings], MapSettings] | None = None) -> int:
        """Queue showing the cloud ``source`` reads (a :class:`~.load.LoadJob`)."""
        return self.host.submit(LoadJob(self, source, stash=stash, label=label, adjust=adjust))

    def last_render(self) -> dict[str, object]:
        """The timing record of the last map coloured (``{}`` before the first)."""
        return self.timings[-1] if self.timings else {}

    def show_view(self, loaded: LoadedCloud, settings: MapSettings) -> int:
        """Queue ``loaded`` with ``settings`` (only a recolouring when it is the cloud
        on screen)."""
        if loaded is self.host.session.shown.loaded:
            return self.host.submit(RenderJob(self, settings=settings))
        return self.host.submit(ShowJob(self, loaded, settings))

    def holds_overlay(self, owner: object) -> bool:
        """True while ``owner``'s colours are on the points."""
        return self.overlay is owner

    def map_colouring(self) -> Colouring | None:
        """The map's own colours of the points (None before the first map)."""
        return self.colouring

    # ------------------------------------------------------------------ saved views
    def snapshot(self) -> dict[str, Any]:
        s = self.host.session.shown.settings
        unit = self.host.session.shown.loaded.cloud.source_unit
        units: Unit = unit if unit in UNITS else "m"
        return {"cell_size_m": float(s.cell_size), "min_points": int(s.min_points),
                "axis": s.axis, "model": s.model, "units": units,
                "threshold": float(s.threshold),
                "colour": ColourSettings(colormap=s.colormap, mode=s.display,
                                         stretch=s.stretch, layer=s.layer)}

    def restore(self, view: View) -> Job[Host]:
        return RestoreMapJob(self, check_view_for_app(view, "saved view"), view.camera)


def mount(host: Host) -> MapFeature:
    """The colour bar above the tabs and the Map tab; every control queues a job."""
    m = add_controls(host, MapFeature)
    wire(host, m)
    host.on_idle(lambda run: prefetch_presets(host, run))
    return m
