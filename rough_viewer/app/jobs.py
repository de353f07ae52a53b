"""The map's jobs: load a cloud, show a view, build the panels, pick a point.

Each is a :class:`rough_viewer.app.worker.Job` run on the app's worker thread,
in named stages (the worker may stop a cancelled job between them):

=============  =======================================================  =================
job            stages                                                    lane (cancels)
=============  =======================================================  =================
LoadJob        read, prepare, show, then ViewJob's                       load (view,
                                                                         panels, pick)
ViewJob        check, grid, colours (then queues PanelsJob)              view (panels)
PanelsJob      distribution, variogram                                   panels
PickJob        pick, cell or the mode's click handler                    pick, keep all
AxisJob        axis                                                      axis
=============  =======================================================  =================

A pending LoadJob absorbs a newer ViewJob (it shows the new file with the newest
settings); a newer LoadJob replaces it. Modes add their own jobs in their module.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from rough_viewer.app import scene
from rough_viewer.app.files import read_cloud
from rough_viewer.app.layout import GRID_PRESET_OPTIONS, assign
from rough_viewer.app.markup import md
from rough_viewer.app.panels import distribution_figures, variogram_figure_of
from rough_viewer.app.picking import pick_point
from rough_viewer.app.state import (
    MODEL_LABELS,
    CellInfo,
    LoadedCloud,
    MapStats,
    ViewSettings,
    cell_info,
    check_settings,
    map_stats,
    normalised_map,
    point_colours,
)
from rough_viewer.app.uploads import UploadedFile
from rough_viewer.app.worker import Job, Run
from rough_viewer.grid.roughness import GridRoughness
from rough_viewer.io import PointCloud
from rough_viewer.visual.app import colour_bar_figure
from rough_viewer.vocabulary import InputError

if TYPE_CHECKING:
    from rough_viewer.app.server import App

#: Notify every browser while computing a grid on more points than this.
BIG_CLOUD = 1_000_000


@dataclass(frozen=True)
class Shown:
    """What the scene shows now (replaced as a whole by the worker)."""

    loaded: LoadedCloud
    settings: ViewSettings
    result: GridRoughness | None = None
    stats: MapStats | None = None


# ----------------------------------------------------------------------------- view


@dataclass(frozen=True)
class ViewJob(Job["App"]):
    """Show the map for ``settings`` on the loaded cloud."""

    settings: ViewSettings
    lane: ClassVar[str] = "view"
    cancels: ClassVar[frozenset[str]] = frozenset({"panels"})

    @property
    def title(self) -> str:
        return f"grid {self.settings.cell_size:g} m"

    def stages(self, ctx: App, run: Run) -> Iterator[str]:
        return view_stages(ctx, run, self.settings)


def view_stages(app: App, run: Run, settings: ViewSettings, *,
                keep_error: bool = False) -> Iterator[str]:
    """Check the settings, compute (or fetch) the grid, colour the points, update
    the colour bar and status, then queue the panels. ``keep_error``: leave an
    error shown by an earlier stage on screen."""
    loaded = app.shown.loaded
    try:
        check_settings(settings)
    except InputError as exc:
        app.reject_settings(str(exc))
        return
    yield "check"
    t0 = time.perf_counter()
    cached = loaded.is_cached(settings)
    result = _grid(app, run, loaded, settings, cached)
    if result is None:
        return
    yield "grid"
    norm = normalised_map(result, settings.model)
    colours = point_colours(result, settings, loaded.display_index, normalised=norm)
    stats = map_stats(result, settings)
    with app.lock:
        app.cloud_handle.colors = colours
        app.shown = Shown(loaded, settings, result, stats)
    t_colours = time.perf_counter() - t0
    # the colour bar and status always go with the colours (no stage in between)
    if not keep_error:
        app.clear_error()
    _show_map_text(app, loaded, result, stats, settings, t_colours, cached)
    record: dict[str, object] = {"cell_size": settings.cell_size, "model": settings.model,
                                 "cached": cached, "colours_s": t_colours}
    app.timings.append(record)
    for listener in app.view_listeners:  # modes that follow the view (e.g. zones)
        listener(app)
    yield "colours"
    key = (settings.grid_key, settings.model, app.options.variogram)
    if key != app.panel_key:
        app.submit(PanelsJob(settings, result, record))


def _grid(app: App, run: Run, loaded: LoadedCloud, settings: ViewSettings,
          cached: bool) -> GridRoughness | None:
    gui = app.gui
    notes = []
    if not cached:
        assign(gui.progress, 0.0)
        gui.progress.visible = True
        if loaded.n_total > BIG_CLOUD:
            notes = [c.add_notification("Computing", f"grid {settings.cell_size:g} m on "
                                        f"{loaded.n_total:,} points", loading=True,
                                        with_close_button=False)
                     for c in app.server.get_clients().values()]

    def report(done: int, total: int) -> None:
        if total > 0:
            assign(gui.progress, float(min(100.0, 100.0 * done / total)))

    try:
        return loaded.result(settings, progress=None if cached else run.progress(report))
    except (InputError, ValueError, MemoryError) as exc:
        what = "not enough memory" if isinstance(exc, MemoryError) else str(exc)
        app.reject_settings(f"grid {settings.cell_size:g} m: {what}")
        return None
    finally:
        gui.progress.visible = False
        for n in notes:
            n.remove()


def _show_map_text(app: App, loaded: LoadedCloud, result: GridRoughness, stats: MapStats,
                   settings: ViewSettings, seconds: float, cached: bool) -> None:
    gui = app.gui
    gui.colour_bar.figure = colour_bar_figure(
        colormap=settings.colormap, theta_min_m=stats.theta_min, theta_max_m=stats.theta_max,
        clip=settings.clip, mode=settings.mode, threshold=settings.threshold,
        title=f"{MODEL_LABELS[settings.model]} roughness, grid {settings.cell_size:g} m, "
              f"axis {result.axis}, {loaded.n_total:,} points",
        no_value_cells=stats.cells - stats.valid_cells,
    )
    gui.status.content = status_text(loaded, result, stats, settings, seconds, cached)
    gui.axis_note.content = (f"auto chose **{loaded.auto_axis}** (closest to the whole-cloud "
                             f"normal); using **{result.axis}**")
    scene.draw_axis(app.server, loaded, result.axis, chosen=settings.axis != "auto",
                    visible=bool(gui.show_axis.value))


def status_text(loaded: LoadedCloud, result: GridRoughness, stats: MapStats,
                settings: ViewSettings, seconds: float, cached: bool) -> str:
    """Markdown of the status line (the file name escaped)."""
    where = "cached" if cached else f"computed in {seconds:.2f} s"
    name = md(Path(loaded.cloud.source).name, max_chars=120) if loaded.cloud.source \
        else "in-memory cloud"
    return "\n".join([
        f"**{name}**: {loaded.n_display:,} points shown of {loaded.n_total:,} used  ",
        f"{MODEL_LABELS[settings.model]}, grid {settings.cell_size:g} m, axis {result.axis}, "
        f"{stats.valid_cells:,} of {stats.cells:,} cells with a value ({where})",
    ])


# ----------------------------------------------------------------------------- panels


@dataclass(frozen=True)
class PanelsJob(Job["App"]):
    """Histogram, summary table and semivariogram of the shown grid and model."""

    settings: ViewSettings
    result: GridRoughness
    record: dict[str, object] = dataclasses.field(compare=False)
    """The view's timing record (gets ``panels_s``)."""
    lane: ClassVar[str] = "panels"

    @property
    def title(self) -> str:
        return f"panels of grid {self.settings.cell_size:g} m"

    def stages(self, ctx: App, run: Run) -> Iterator[str]:
        app, gui, t0 = ctx, ctx.gui, time.perf_counter()
        if app.shown.result is not self.result:
            return
        dist = distribution_figures(self.result, self.settings)
        yield "distribution"
        fig = None
        if app.options.variogram:
            try:
                fig = variogram_figure_of(self.result, self.settings,
                                          is_stale=lambda: run.cancelled)
            except (InputError, MemoryError) as exc:
                what = "not enough memory" if isinstance(exc, MemoryError) else str(exc)
                app.show_error(f"semivariogram of grid {self.settings.cell_size:g} m: {what}",
                               kept="The map and the other panels are shown.")
            else:
                if fig is None:  # cancelled between maps
                    run.check()
                    return
            yield "variogram"
        # all panels change together, as the grid they describe
        gui.histogram.figure = dist.histogram
        gui.summary.figure = dist.summary
        if fig is not None:
            gui.variogram.figure = fig
        app.panel_key = (self.settings.grid_key, self.settings.model, app.options.variogram)
        self.record["panels_s"] = time.perf_counter() - t0


# ----------------------------------------------------------------------------- load


@dataclass(frozen=True)
class LoadJob(Job["App"]):
    """Show another cloud: a file in the data folder, an upload, or points in memory."""

    settings: ViewSettings
    typed: str = ""
    """A path as typed in the File tab (resolved in the data folder when read)."""
    shown_as: str = ""
    """How the file is named to the user (the path as typed, the upload's name)."""
    upload: UploadedFile | None = None
    cloud: PointCloud | None = None
    lane: ClassVar[str] = "load"
    cancels: ClassVar[frozenset[str]] = frozenset({"view", "panels", "pick"})

    @property
    def title(self) -> str:
        return f"loading {self.shown_as or 'a cloud'}"

    def absorb(self, newer: Job[App]) -> Job[App] | None:
        if isinstance(newer, ViewJob):
            return replace(self, settings=newer.settings)
        return None

    def release(self) -> None:
        if self.upload is not None:
            self.upload.delete()

    def read(self, app: App, run: Run) -> PointCloud:
        """The points to show (raises InputError naming the file as the user knows it)."""
        if self.cloud is not None:
            return self.cloud
        if self.upload is not None:
            cloud = read_cloud(self.upload.path, self.upload.name, cache=False,
                               progress=run.progress())
            self.upload.delete()
            return replace(cloud, source=self.upload.name)
        path = app.data.resolve(self.typed)
        return read_cloud(path, self.typed.strip(), progress=run.progress())

    def stages(self, ctx: App, run: Run) -> Iterator[str]:
        return load_stages(ctx, run, lambda r: self.read(ctx, r), self.settings)


def load_stages(app: App, run: Run, read: Callable[[Run], PointCloud],
                settings: ViewSettings) -> Iterator[str]:
    """Read a cloud, prepare it for display, put it in the scene, then show ``settings``.

    A cloud that cannot be read or prepared leaves the old one shown (with the
    error) and shows ``settings`` on it, so control changes merged into the load
    are not lost.
    """
    try:
        cloud = read(run)
        yield "read"
        loaded = LoadedCloud(cloud, max_display=app.options.max_display,
                             cache_bytes=app.options.cache_bytes)
    except (InputError, MemoryError) as exc:
        app.show_error(str(exc) if isinstance(exc, InputError) else "not enough memory "
                       "to load this cloud")
        yield "read failed"
        yield from view_stages(app, run, settings, keep_error=True)
        return
    yield "prepare"
    show_cloud(app, loaded)
    yield "show"
    yield from view_stages(app, run, settings)


def show_cloud(app: App, loaded: LoadedCloud) -> None:
    """Replace the cloud in the scene (and forget the old cloud's pick and panels)."""
    gui = app.gui
    with app.lock:
        app.shown = Shown(loaded, app.shown.settings)
        size = scene.default_point_size(loaded)
        gui.point_size.min, gui.point_size.max = size / 10, size * 10
        gui.point_size.step = size / 10
        assign(gui.point_size, size)
        app.cloud_handle = scene.add_cloud(app.server, loaded, size)
        for node in app.pick_nodes:
            node.remove()
        app.pick_nodes = []
        app.last_pick = None
        gui.pick.content = "Click a point to see its cell."
        scene.initial_camera(app.server, loaded)
        scene.reset_cameras(app.server)
        app.panel_key = None


@dataclass(frozen=True)
class AxisJob(Job["App"]):
    """Show or hide the dependent-axis marker."""

    visible: bool
    lane: ClassVar[str] = "axis"

    def stages(self, ctx: App, run: Run) -> Iterator[str]:
        shown = ctx.shown
        if shown.result is not None:
            scene.draw_axis(ctx.server, shown.loaded, shown.result.axis,
                            chosen=shown.settings.axis != "auto", visible=self.visible)
        yield "axis"


# ----------------------------------------------------------------------------- pick


@dataclass(frozen=True)
class Pick:
    """A displayed point under a click: its index in the cloud and its position."""

    point: int
    """Index into the loaded cloud."""
    xyz: np.ndarray
    """(3,) file frame, metres."""
    local: np.ndarray
    """(3,) display frame (relative to the local origin), metres."""


ClickHandler = Callable[["App", Pick], bool]
"""A mode's click handler: True when it took the click (then cells are not reported)."""


@dataclass(frozen=True)
class PickJob(Job["App"]):
    """A click in the scene: pick the point under the ray, then report its cell (or
    hand it to a mode that takes clicks, e.g. profile mode)."""

    origin: tuple[float, float, float]
    direction: tuple[float, float, float]
    lane: ClassVar[str] = "pick"
    keep_all: ClassVar[bool] = True

    def stages(self, ctx: App, run: Run) -> Iterator[str]:
        on_scene_click(ctx, self.origin, self.direction)
        yield "pick"


def valid_ray(origin: object, direction: object) -> bool:
    """Both are 3 finite numbers and the direction is not zero (a client's ray)."""
    try:
        o = np.asarray(origin, dtype=np.float64)
        d = np.asarray(direction, dtype=np.float64)
    except (TypeError, ValueError):
        return False
    return (o.shape == (3,) and d.shape == (3,) and bool(np.all(np.isfinite(o)))
            and bool(np.all(np.isfinite(d))) and float(np.linalg.norm(d)) > 0)


def on_scene_click(app: App, origin: object, direction: object) -> CellInfo | None:
    """Pick the displayed point under a click ray; let a mode take it, or report
    its cell (returned)."""
    shown = app.shown
    if shown.result is None or not valid_ray(origin, direction):
        return None
    o = np.asarray(origin, dtype=np.float64)
    d = np.asarray(direction, dtype=np.float64)
    i = pick_point(shown.loaded.display_points, o, d)
    if i is None:
        app.gui.pick.content = "No point under the click."
        return None
    local = np.asarray(shown.loaded.display_points[i], dtype=np.float64)
    pick = Pick(int(shown.loaded.display_index[i]), shown.loaded.to_file_frame(local), local)
    for handler in app.click_handlers:
        if handler(app, pick):
            return None
    info = cell_info(shown.result, pick.point, pick.xyz)
    g = shown.result.grid.cell_size
    with app.lock:
        app.last_pick = info
        app.gui.pick.content = format_cell_info(info, g)
        app.pick_nodes = scene.mark_pick(app.server, shown.loaded, info, local, g)
    return info


def format_cell_info(info: CellInfo, cell_size: float) -> str:
    """Markdown of a picked cell (roughness in millimetres, coordinates in metres)."""

    def mm(v: float) -> str:
        return "—" if not np.isfinite(v) else f"{1e3 * v:.3f} mm"

    n = info.normal
    normal = "—" if not np.all(np.isfinite(n)) else f"({n[0]:.3f}, {n[1]:.3f}, {n[2]:.3f})"
    p = info.point
    return "\n".join([
        f"**Cell {info.ijk}** ({cell_size:g} m), {info.n_points} points  ",
        f"point ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) m  ",
        f"θ ODR {mm(info.theta['odr'])}, OLS ({info.axis}) {mm(info.theta['ols'])}  ",
        f"θ hybrid {mm(info.theta['hybrid'])}, e_ols {mm(info.theta['e_ols'])}  ",
        f"normal {normal}",
    ])


def grid_choice(cell_size: float) -> str:
    """The grid dropdown entry for a cell size: a preset, or ``free``."""
    text = f"{cell_size:g}"
    return text if text in GRID_PRESET_OPTIONS else "free"
