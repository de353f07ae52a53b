"""The map's jobs: load a cloud, show a view, build the panels, pick a point.

Each is a :class:`rough_viewer.app.worker.Job` run on the app's worker thread,
in named stages (the worker may stop a cancelled job between them):

=============  =======================================================  =================
job            stages                                                    lane (cancels)
=============  =======================================================  =================
LoadJob        read, prepare, show, then ViewJob's                       load (view,
                                                                         panels, pick)
ViewJob        check, grid, colours (then queues PanelsJob)              view (panels)
PanelsJob      distribution, grid sizes (the face trend), variogram      panels
PickJob        pick, cell and across scales, or the mode's handler       pick, keep all
AxisJob        axis                                                      axis
CameraJob      camera (a preset view)                                    camera
=============  =======================================================  =================

A pending LoadJob absorbs a newer ViewJob (it shows the new file with the newest
settings, at the new file's own default grid); a newer LoadJob replaces it. Modes
add their own jobs in their module.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, ClassVar

import numpy as np
import plotly.graph_objects as go
import viser

from rough_viewer.app import scene
from rough_viewer.app.files import read_cloud
from rough_viewer.app.layout import (
    PICK_PROMPT,
    assign,
    grid_options,
    l_grid,
    l_grid_free,
    l_range_hi,
    l_range_lo,
    quietly,
    scales_placeholder,
)
from rough_viewer.app.markup import md
from rough_viewer.app.panels import distribution_figures, face_scales_figure_of, variogram_figure_of
from rough_viewer.app.picking import pick_point
from rough_viewer.app.state import (
    MAX_CELL_SIZE,
    MIN_CELL_SIZE,
    MODEL_LABELS,
    CellInfo,
    LoadedCloud,
    MapStats,
    Units,
    ViewSettings,
    cell_info,
    check_settings,
    map_stats,
    point_colours,
)
from rough_viewer.app.uploads import UploadedFile
from rough_viewer.app.worker import Job, Run
from rough_viewer.grid.roughness import GridRoughness, exact_fit_text
from rough_viewer.grid.scales import PointScales, point_scales_from_prepared
from rough_viewer.io import PointCloud
from rough_viewer.visual.app import colour_bar_figure, colour_scale_figure, panel_aspect
from rough_viewer.visual.scales import point_scales_figure
from rough_viewer.vocabulary import COLOUR_LAYER_LABELS, InputError, Unit

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
    """Check the settings, compute (or fetch) the grid, colour the points (by the
    roughness map or a colour layer), update the colour bar, status and notices,
    then queue the panels. ``keep_error``: leave an error shown by an earlier stage
    on screen."""
    loaded = app.shown.loaded
    try:
        check_settings(settings)
        if settings.layer != "roughness":
            loaded.layer(settings.layer)  # InputError when the cloud lacks it
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
    stats = map_stats(result, settings)
    if settings.layer == "roughness":
        colours = point_colours(result, settings, loaded.display_index,
                                colours_range=stats.colour_range)
    else:
        colours = loaded.layer(settings.layer).colours
    with app.lock:
        app.cloud_handle.colors = colours
        app.shown = Shown(loaded, settings, result, stats)
        loaded.mark_shown(settings)
    t_colours = time.perf_counter() - t0
    # the colour bar and status always go with the colours (no stage in between)
    if not keep_error:
        app.clear_error()
    _show_map_text(app, loaded, result, stats, settings, t_colours, cached)
    record: dict[str, object] = {"cell_size": settings.cell_size, "model": settings.model,
                                 "layer": settings.layer, "cached": cached,
                                 "colours_s": t_colours}
    app.timings.append(record)
    if stats.sparse and not cached:
        app.notify("Most cells have no value", sparse_message(loaded, stats, settings),
                   color="yellow", seconds=10.0)
    for listener in app.view_listeners:  # modes that follow the view (e.g. zones)
        listener(app)
    yield "colours"
    if panel_key(app, settings) != app.panel_key or face_key(settings) != app.face_key:
        app.submit(PanelsJob(settings, result, record))


def panel_key(app: App, settings: ViewSettings) -> tuple[object, ...]:
    """What the grid's panels (histogram, semivariogram, Table 1) depend on."""
    return (settings.grid_key, settings.model, app.options.variogram)


def face_key(settings: ViewSettings) -> tuple[object, ...]:
    """What the whole-face trend against the preset grids depends on."""
    return (settings.axis, settings.min_points, settings.threshold)


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
    fig = colour_bar_of(loaded, result, stats, settings)
    gui.colour_bar.figure = fig
    gui.colour_bar.aspect = panel_aspect(fig)
    if (settings.layer == "roughness" and settings.mode == "continuous"
            and settings.stretch.mode == "percentile"):
        app.show_range(stats.colour_range)  # the typed limits start from what is shown
    gui.status.content = status_text(loaded, result, stats, settings, seconds, cached)
    notes = notice_text(loaded, stats, settings)
    gui.notice.content = notes
    gui.notice.visible = bool(notes)
    gui.axis_note.content = (f"auto chose **{loaded.auto_axis}** (closest to the whole-cloud "
                             f"normal); using **{result.axis}**")
    scene.draw_axis(app.server, loaded, result.axis, chosen=settings.axis != "auto",
                    visible=bool(gui.show_axis.value))


def colour_bar_of(loaded: LoadedCloud, result: GridRoughness, stats: MapStats,
                  settings: ViewSettings) -> go.Figure:
    """The colour bar of what colours the points: the roughness map (its stretch in
    the roughness unit; the binary transform's two colours), or a colour layer."""
    u = loaded.units
    scale = 1.0 / u.rough_per
    title = (f"{MODEL_LABELS[settings.model]} roughness · grid {u.size_text(settings.cell_size)}"
             f" · axis {result.axis} · {loaded.n_total:,} points")
    if settings.layer == "roughness":
        if settings.mode == "binary":
            return colour_bar_figure(
                colormap=settings.colormap, theta_min_m=stats.theta_min,
                theta_max_m=stats.theta_max, mode="binary", threshold=settings.threshold,
                title=title, no_value_cells=stats.cells - stats.valid_cells,
                unit=u.rough_label, scale=scale)
        return colour_scale_figure(stats.colour_range, colormap=settings.colormap, title=title,
                                   unit=u.rough_label, scale=scale,
                                   no_value=stats.cells - stats.valid_cells)
    layer = loaded.layer(settings.layer)
    shown = f"{loaded.n_display:,} points shown"
    if layer.colour_range is None or layer.colormap is None:
        fig = go.Figure()
        fig.update_layout(
            title={"text": f"{layer.label[:1].upper()}{layer.label[1:]} · {shown}<br><sup>the scan's own "
                   "colours; no colour scale</sup>", "font": {"size": 12}, "x": 0.01,
                   "xanchor": "left"},
            height=70, margin={"l": 12, "r": 12, "t": 50, "b": 4},
            xaxis={"visible": False}, yaxis={"visible": False}, plot_bgcolor="white")
        return fig
    if settings.layer == "intensity":
        return colour_scale_figure(layer.colour_range, colormap=layer.colormap,
                                   title=f"Intensity as stored in the file · {shown}",
                                   quantity="intensity", unit="", scale=1.0)
    # distances in the roughness unit (mm) unless the face bends by metres
    big = abs(layer.colour_range.hi) / u.rough_per >= 1000.0
    return colour_scale_figure(
        layer.colour_range, colormap=layer.colormap,
        title=f"Distance to the whole-cloud face plane · {shown}",
        quantity="distance", unit=u.label if big else u.rough_label,
        scale=1.0 / u.per if big else scale)


def status_text(loaded: LoadedCloud, result: GridRoughness, stats: MapStats,
                settings: ViewSettings, seconds: float, cached: bool) -> str:
    """Markdown of the status line (the file name escaped)."""
    where = "cached" if cached else f"computed in {seconds:.2f} s"
    name = md(loaded.label or Path(loaded.cloud.source).name or "in-memory cloud",
              max_chars=120)
    colours = "" if settings.layer == "roughness" else \
        f"; colours: {COLOUR_LAYER_LABELS[settings.layer]}"
    return "\n".join([
        f"**{name}**: {loaded.n_display:,} points shown of {loaded.n_total:,} used  ",
        f"{MODEL_LABELS[settings.model]}, grid {loaded.units.size_text(settings.cell_size)}, "
        f"axis {result.axis}, {stats.valid_cells:,} of {stats.cells:,} cells with a value "
        f"({where}){colours}",
    ])


def sparse_message(loaded: LoadedCloud, stats: MapStats, settings: ViewSettings) -> str:
    """Plain text: most occupied cells have no value, and which grid to try."""
    u = loaded.units
    share = 100.0 * stats.valid_cells / max(stats.cells, 1)
    presets = loaded.presets or ()
    larger = [g for g in sorted(presets) if g > settings.cell_size * (1 + 1e-9)
              and g >= loaded.default_cell_size]
    hint = (f"try grid {u.size_text(larger[0])}" if larger else
            "try a larger grid")
    return (f"only {stats.valid_cells:,} of {stats.cells:,} occupied cells ({share:.0f} %) "
            f"have a value at grid {u.size_text(settings.cell_size)}: too few points per cell "
            f"(at least {settings.min_points} needed); {hint} (the default, "
            f"{u.size_text(loaded.default_cell_size)}, holds about 16 points in a typical cell)")


def notice_text(loaded: LoadedCloud, stats: MapStats | None, settings: ViewSettings) -> str:
    """Markdown of the notices that stay on screen: the reader's warnings (escaped),
    a grid where most occupied cells have no value, and cells that fit their plane
    exactly. Empty when there is none."""
    lines = [f"**Warning:** {md(w, max_chars=400)}" for w in loaded.cloud.warnings[:10]]
    if stats is not None and stats.sparse:
        lines.append(f"**Most cells have no value:** {md(sparse_message(loaded, stats, settings))}")
    if stats is not None and stats.exact_fit:
        lines.append(f"**Cells of roughness 0:** "
                     f"{md(exact_fit_text(stats.exact_fit, stats.valid_cells))} and take the "
                     "smoothest colour. A larger *Min points per cell* leaves them out.")
    return "  \n".join(lines)


# ----------------------------------------------------------------------------- panels


@dataclass(frozen=True)
class PanelsJob(Job["App"]):
    """Histogram, summary table and semivariogram of the shown grid and model, and
    the whole face's roughness against the preset grid sizes."""

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
        loaded = app.shown.loaded
        unit = loaded.units.unit
        s = self.settings
        if face_key(s) != app.face_key and loaded.presets:
            results = []
            for g in loaded.presets:  # cached after prefetching; each stops if cancelled
                results.append(loaded.result(s.with_(cell_size=g), progress=run.progress()))
                yield f"grid {g:g}"
            trend = face_scales_figure_of(results, threshold=s.threshold, unit=unit)
            _set_figure(gui.face_scales, trend)
            app.face_key = face_key(s)
            yield "grid sizes"
        if panel_key(app, s) == app.panel_key:
            return  # only the trend changed (the binary threshold)
        dist = distribution_figures(self.result, s, unit=unit)
        yield "distribution"
        fig = None
        if app.options.variogram:
            try:
                fig = variogram_figure_of(self.result, s, is_stale=lambda: run.cancelled,
                                          progress=run.progress(), unit=unit)
            except (InputError, MemoryError) as exc:
                what = "not enough memory" if isinstance(exc, MemoryError) else str(exc)
                app.show_error(f"semivariogram of grid {loaded.units.size_text(s.cell_size)}: "
                               f"{what}", kept="The map and the other panels are shown.")
            else:
                if fig is None:  # cancelled between maps
                    run.check()
                    return
            yield "variogram"
        # the grid's panels change together, as the grid they describe
        _set_figure(gui.histogram, dist.histogram)
        _set_figure(gui.summary, dist.summary)
        if fig is not None:
            _set_figure(gui.variogram, fig)
        app.panel_key = panel_key(app, s)
        self.record["panels_s"] = time.perf_counter() - t0


def _set_figure(handle: viser.GuiPlotlyHandle, fig: go.Figure) -> None:
    """Show ``fig`` at the height its builder laid it out for (at the panel width)."""
    if fig.layout.height is not None:
        handle.aspect = panel_aspect(fig)
    handle.figure = fig


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
    units: Unit | None = None
    """Unit of the file's coordinates (None: its CRS's, else metres)."""
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
                               units=self.units, progress=run.progress())
            self.upload.delete()
            return replace(cloud, source=self.upload.name)
        path = app.data.resolve(self.typed)
        return read_cloud(path, self.typed.strip(), units=self.units, progress=run.progress())

    def stages(self, ctx: App, run: Run) -> Iterator[str]:
        return load_stages(ctx, run, lambda r: self.read(ctx, r), self.settings)


def load_stages(app: App, run: Run, read: Callable[[Run], PointCloud],
                settings: ViewSettings, *, stash: bool = False,
                label: str = "") -> Iterator[str]:
    """Read a cloud, prepare it for display, put it in the scene, then show it with
    ``settings`` at its own default grid (its presets come from its point spacing).

    ``stash``: put the scan shown now aside (:attr:`App.stashed`) instead of
    dropping it, so it can be shown again as it was (the board lesson); a load
    without it drops anything put aside. A cloud that cannot be read or prepared
    leaves the old one shown (with the error) and shows ``settings`` on it, so
    control changes merged into the load are not lost. ``label``: the status line's
    name of a cloud that is no file (:attr:`LoadedCloud.label`).
    """
    try:
        cloud = read(run)
        yield "read"
        loaded = LoadedCloud(cloud, max_display=app.options.max_display,
                             cache_bytes=app.options.cache_bytes, label=label)
    except (InputError, MemoryError) as exc:
        app.show_error(str(exc) if isinstance(exc, InputError) else "not enough memory "
                       "to load this cloud")
        yield "read failed"
        yield from view_stages(app, run, settings, keep_error=True)
        return
    yield "prepare"
    if stash:
        if app.stashed is None:
            app.stashed = app.shown
    else:
        app.stashed = None
    layer = settings.layer if settings.layer in loaded.layers else "roughness"
    settings = settings.with_(cell_size=loaded.default_cell_size, layer=layer)
    show_cloud(app, loaded, settings)
    for warning in cloud.warnings[:10]:
        app.notify("Warning", warning, color="yellow", seconds=12.0)
    yield "show"
    yield from view_stages(app, run, settings)


def show_cloud(app: App, loaded: LoadedCloud, settings: ViewSettings | None = None) -> None:
    """Replace the cloud in the scene (and forget the old cloud's pick and panels);
    the grid presets, unit labels and colour layers follow the new cloud, and the
    controls show ``settings`` (default: the shown settings)."""
    gui = app.gui
    with app.lock:
        app.shown = Shown(loaded, settings or app.shown.settings)
        size = scene.default_point_size(loaded)
        _controls_for(app, loaded)
        with quietly(app._local):
            gui.point_size.min, gui.point_size.max = size / 10, size * 10
            gui.point_size.step = size / 10
            assign(gui.point_size, size)
        app.sync_controls(app.shown.settings)
        app.cloud_handle = scene.add_cloud(app.server, loaded, size)
        forget_pick(app, PICK_PROMPT)
        scene.initial_camera(app.server, loaded)
        scene.reset_cameras(app.server)
        app.panel_key = None
        app.face_key = None
    for handler in app.cloud_handlers:
        handler(app)


def _controls_for(app: App, loaded: LoadedCloud) -> None:
    """Grid presets, unit labels and colour layers of ``loaded`` in the controls
    (without queuing work)."""
    gui = app.gui
    u = loaded.units
    assert loaded.presets is not None
    values = grid_options(loaded.presets, u)
    with quietly(app._local):
        gui.grid_values = values
        gui.length_units = u
        gui.grid.options = (*values, "free")
        gui.grid.label = l_grid(u)
        gui.grid_free.label = l_grid_free(u)
        gui.grid_free.min, gui.grid_free.max = u.length(MIN_CELL_SIZE), u.length(MAX_CELL_SIZE)
        gui.range_lo.label = l_range_lo(u)
        gui.range_hi.label = l_range_hi(u)
        gui.layer.options = tuple(COLOUR_LAYER_LABELS[n] for n in loaded.layers)


@dataclass(frozen=True)
class CameraJob(Job["App"]):
    """Move every browser's camera to a preset view of the cloud."""

    preset: str
    """``"face-on"``, ``"top"`` or ``"side"`` (:func:`rough_viewer.app.scene.camera_pose`)."""
    lane: ClassVar[str] = "camera"

    def stages(self, ctx: App, run: Run) -> Iterator[str]:
        scene.move_cameras(ctx.server, ctx.shown.loaded, self.preset)
        yield "camera"


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


def forget_pick(app: App, text: str) -> None:
    """Drop the clicked point's marker, report and across-scales plot; the Map tab's
    click report then reads ``text``."""
    scene.clear_pick(app.pick_nodes)
    app.pick_nodes = []
    app.last_pick = None
    app.gui.pick.content = text
    _set_figure(app.gui.scales, scales_placeholder())


def on_scene_click(app: App, origin: object, direction: object) -> CellInfo | None:
    """Pick the displayed point under a click ray; let a mode take it, or report
    its cell and the roughness of its cells on every preset grid (returned: the
    cell report)."""
    shown = app.shown
    if shown.result is None or not valid_ray(origin, direction):
        return None
    t0 = time.perf_counter()
    o = np.asarray(origin, dtype=np.float64)
    d = np.asarray(direction, dtype=np.float64)
    i = pick_point(shown.loaded.display_points, o, d)
    if i is None:  # the earlier point's report and plot go with it
        forget_pick(app, "No point under the click.")
        return None
    local = np.asarray(shown.loaded.display_points[i], dtype=np.float64)
    pick = Pick(int(shown.loaded.display_index[i]), shown.loaded.to_file_frame(local), local)
    for handler in app.click_handlers:
        if handler(app, pick):
            return None
    info = cell_info(shown.result, pick.point, pick.xyz)
    g = shown.result.grid.cell_size
    u = shown.loaded.units
    with app.lock:
        app.last_pick = info
        app.gui.pick.content = format_cell_info(info, g, u)
        scene.clear_pick(app.pick_nodes)
        app.pick_nodes = scene.mark_pick(app.server, shown.loaded, info, local, g)
    t_cell = time.perf_counter() - t0
    scales = across_scales(shown.loaded, shown.settings, shown.result, pick.point)
    fig = point_scales_figure(scales, point_xyz=pick.xyz.tolist(), n_points=shown.loaded.n_total,
                              unit=u.unit)
    _set_figure(app.gui.scales, fig)
    app.pick_scales = scales
    app.pick_timings.append({"cell_s": t_cell, "pick_s": time.perf_counter() - t0,
                             "grids": len(scales.cell_sizes)})
    return info


def across_scales(loaded: LoadedCloud, settings: ViewSettings, result: GridRoughness,
                  point: int) -> PointScales:
    """ODR, OLS, hybrid roughness and e_ols of the cells holding cloud point ``point``
    on every preset grid (with the shown axis and minimum points): only those cells
    are evaluated, on the nested grids' cell membership (the finest preset's,
    coarsened), so a click costs milliseconds."""
    assert loaded.presets is not None
    grids = [loaded.prepared(g) for g in loaded.presets]
    return point_scales_from_prepared(loaded.cloud, grids, point, axis=result.axis,
                                      min_points=settings.min_points)


def format_cell_info(info: CellInfo, cell_size: float, units: Units | None = None) -> str:
    """Markdown of a picked cell (roughness in the roughness unit, mm for metric
    input; coordinates and the grid in the cloud's unit)."""
    u = units or Units("m")

    def rough(v: float) -> str:
        return "—" if not np.isfinite(v) else f"{u.rough(v):.4g} {u.rough_label}"

    n = info.normal
    normal = "—" if not np.all(np.isfinite(n)) else f"({n[0]:.3f}, {n[1]:.3f}, {n[2]:.3f})"
    p = [c / u.per for c in info.point]
    return "\n".join([
        f"**Cell {info.ijk}** ({u.size_text(cell_size)}), {info.n_points} points  ",
        f"point ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) {u.label}  ",
        f"θ ODR {rough(info.theta['odr'])}, OLS ({info.axis}) {rough(info.theta['ols'])}  ",
        f"θ hybrid {rough(info.theta['hybrid'])}, e_ols {rough(info.theta['e_ols'])}  ",
        f"normal {normal}",
    ])


def grid_choice(cell_size: float, options: dict[str, float]) -> str:
    """The grid dropdown entry for a cell size (metres): a preset, or ``free``."""
    for text, size in options.items():
        if abs(size - cell_size) <= 1e-9 * max(size, 1e-12):
            return text
    return "free"
