"""Assemble the app on a viser server: scene, GUI, worker, callbacks.

``build_app(server, cloud)`` returns an :class:`App` holding every handle, so the
command line (``rough-viewer serve``), the tests and the benchmarks drive the same
object. All scene nodes and GUI controls are server-level: every browser tab
sees the same state.
"""

from __future__ import annotations

import os
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
import viser

from rough_viewer.app import panels
from rough_viewer.app.controller import LatestWorker
from rough_viewer.app.layout import (
    GRID_PRESET_OPTIONS,
    MODEL_BY_LABEL,
    Gui,
    build_gui,
    resolve_colormap,
)
from rough_viewer.app.picking import pick_point
from rough_viewer.app.state import (
    DEFAULT_MAX_DISPLAY,
    MODEL_LABELS,
    PRESET_CELL_SIZES,
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
from rough_viewer.grid.roughness import GridRoughness
from rough_viewer.io import PointCloud, load_points
from rough_viewer.visual.app import colour_bar_figure
from rough_viewer.vocabulary import InputError

AXIS_VECTORS = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}
AXIS_COLOUR = (230, 60, 40)
PICK_COLOUR = (255, 30, 200)


@dataclass(frozen=True)
class Request:
    """One job for the worker: show ``settings``, after loading a file if given."""

    settings: ViewSettings
    load_path: str | None = None
    upload: tuple[str, bytes] | None = None
    cloud: PointCloud | None = None
    kind: Literal["view", "load"] = "view"


@dataclass
class Shown:
    """What the scene shows now (replaced as a whole by the worker)."""

    loaded: LoadedCloud
    settings: ViewSettings
    result: GridRoughness | None = None
    stats: MapStats | None = None


@dataclass
class App:
    """Handles of a running app (see :func:`build_app`)."""

    server: viser.ViserServer
    gui: Gui
    worker: LatestWorker
    shown: Shown
    cloud_handle: viser.PointCloudHandle
    timings: list[dict] = field(default_factory=list)
    """One record per handled request: seconds to colours, to panels, cached or not."""
    errors: list[str] = field(default_factory=list)
    """Error messages shown to the user, oldest first."""
    last_pick: CellInfo | None = None
    pick_nodes: list = field(default_factory=list)
    profile: dict | None = None
    """Profile mode state (``items``: kept :class:`ProfileAnalysis`, ``start``)."""
    profile_pick: object = None
    profile_settings: object = None
    board: dict | None = None
    """Board teaching view state (``lesson``: the last :class:`BoardLesson`)."""
    _syncing: bool = False
    _panel_key: tuple | None = None
    _lock: threading.RLock = field(default_factory=threading.RLock)

    # ------------------------------------------------------------------ settings
    def settings_from_gui(self) -> ViewSettings:
        """The settings the controls currently ask for."""
        g = self.gui
        cell = float(g.grid_free.value) if g.grid.value == "free" else float(g.grid.value)
        model = MODEL_BY_LABEL[g.model.value]
        lo, hi = (float(v) for v in g.clip.value)
        return ViewSettings(
            cell_size=cell,
            model=model,  # type: ignore[arg-type]
            axis=g.axis.value,  # type: ignore[arg-type]
            min_points=int(g.min_points.value),
            mode=g.display.value,  # type: ignore[arg-type]
            threshold=float(g.threshold.value),
            colormap=resolve_colormap(g.colormap.value, model),
            clip=(lo, hi),
        )

    def request_update(self) -> int:
        """Queue the settings the controls show (ignored while the app sets controls)."""
        if self._syncing:
            return 0
        return self.worker.submit(Request(self.settings_from_gui()))

    def load(
        self,
        path: str | None = None,
        upload: tuple[str, bytes] | None = None,
        cloud: PointCloud | None = None,
    ) -> int:
        """Queue showing another cloud: a path on the server, uploaded bytes, or
        an in-memory cloud."""
        return self.worker.submit(Request(self.settings_from_gui(), load_path=path,
                                          upload=upload, cloud=cloud, kind="load"))

    def wait_idle(self, timeout: float = 120.0) -> bool:
        """Block until the worker has nothing left to do (tests, scripts)."""
        return self.worker.wait_idle(timeout)

    def stop(self) -> None:
        self.worker.stop()

    # ------------------------------------------------------------------ messages
    def notify(self, title: str, body: str, *, color: str | None = None, seconds: float = 6.0) -> None:
        for client in self.server.get_clients().values():
            client.add_notification(title, body, auto_close_seconds=seconds, color=color)

    def show_error(self, message: str) -> None:
        self.errors.append(message)
        self.gui.error.content = f"**Error:** {message}  \nThe previous view is kept."
        self.gui.error.visible = True
        self.notify("Error", message, color="red", seconds=10.0)

    def clear_error(self) -> None:
        if self.gui.error.visible:
            self.gui.error.visible = False

    def sync_controls(self, settings: ViewSettings) -> None:
        """Set the controls to ``settings`` without queuing work (after an error)."""
        g = self.gui
        self._syncing = True
        try:
            text = f"{settings.cell_size:g}"
            g.grid.value = text if text in GRID_PRESET_OPTIONS else "free"
            g.grid_free.value = settings.cell_size
            g.model.value = MODEL_LABELS[settings.model]
            g.axis.value = settings.axis
            g.min_points.value = settings.min_points
        finally:
            self._syncing = False


def _initial_camera(server: viser.ViserServer, loaded: LoadedCloud) -> None:
    pts = loaded.display_points.astype(np.float64)
    centre = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    extent = float(np.max(pts.max(axis=0) - pts.min(axis=0))) or 1.0
    normal = loaded.plane.normal
    if abs(normal[2]) > 0.8:  # near-horizontal surface: look down at an angle
        direction = np.array([0.0, -0.6, 0.8])
        right = np.array([1.0, 0.0, 0.0])
    else:  # steep face: look at it straight on, slightly from above
        horiz = np.array([normal[0], normal[1], 0.0])
        horiz /= np.linalg.norm(horiz)
        if horiz[0] - horiz[1] < 0:  # keep +x (or +y) to the right on screen
            horiz = -horiz
        direction = horiz + np.array([0.0, 0.0, 0.35])
        right = np.array([-horiz[1], horiz[0], 0.0])
    direction /= np.linalg.norm(direction)
    # aim right of the centre so the cloud sits left of the control panel
    target = centre + 0.22 * extent * right
    server.initial_camera.look_at = tuple(target)
    server.initial_camera.position = tuple(target + 0.8 * extent * direction)
    server.initial_camera.up = (0.0, 0.0, 1.0)


def default_point_size(loaded: LoadedCloud) -> float:
    """A point size (metres) that closes the gaps between displayed points."""
    w = loaded.plane.eigenvalues  # descending: the two largest are the face's spreads
    area = 12.0 * np.sqrt(max(w[0], 1e-12) * max(w[1], 1e-12))
    spacing = np.sqrt(area / max(loaded.n_display, 1))
    size = float(np.clip(1.5 * spacing, 1e-4, 1.0))
    return float(f"{size:.2g}")


def _add_cloud(server: viser.ViserServer, loaded: LoadedCloud, point_size: float):
    grey = np.full((loaded.n_display, 3), 190, dtype=np.uint8)
    return server.scene.add_point_cloud(
        "/cloud",
        points=loaded.display_points,
        colors=grey,
        point_size=point_size,
        point_shape="square",
        point_shading="flat",
        precision="float32",
    )


def build_app(
    server: viser.ViserServer,
    cloud: PointCloud,
    *,
    settings: ViewSettings | None = None,
    max_display: int = DEFAULT_MAX_DISPLAY,
    variogram: bool = True,
    prefetch: bool = True,
) -> App:
    """Put the app for ``cloud`` on ``server`` and start computing the first map.

    Parameters
    ----------
    server
        A running viser server.
    cloud
        Points in the file frame (metres).
    settings
        Initial view (default :class:`ViewSettings`).
    max_display
        Most points drawn in the browser (roughness uses every point).
    variogram
        Compute the semivariogram panel (can be slow on very fine grids).
    prefetch
        While idle, compute the preset grid sizes for the current axis and
        minimum points, so switching presets only recolours.

    Returns
    -------
    App
        Handles; ``app.wait_idle()`` blocks until the first map is shown.
    """
    settings = settings or ViewSettings()
    loaded = LoadedCloud(cloud, max_display=max_display)
    server.scene.set_up_direction("+z")
    _initial_camera(server, loaded)
    size = default_point_size(loaded)
    gui = build_gui(server, settings, point_size=size, source=cloud.source)
    cloud_handle = _add_cloud(server, loaded, size)

    holder: dict[str, App] = {}

    def handle(request: Request, is_stale) -> None:
        _handle_request(holder["app"], request, is_stale, variogram=variogram)

    def on_error(exc: BaseException) -> None:
        app = holder["app"]
        app.gui.progress.visible = False
        app.show_error(f"{type(exc).__name__}: {exc}")

    def idle(is_stale) -> bool:
        return _prefetch_presets(holder["app"], is_stale)

    worker = LatestWorker(handle, on_error=on_error, idle=idle if prefetch else None)
    app = App(server, gui, worker, Shown(loaded, settings), cloud_handle)
    holder["app"] = app
    _wire(app)
    from rough_viewer.app.profile_mode import add_profile_tab

    add_profile_tab(app, gui.tabs)
    from rough_viewer.app.board_mode import add_board_tab

    add_board_tab(app, gui.tabs)
    app.request_update()
    return app


def _prefetch_presets(app: App, is_stale) -> bool:
    """Compute one preset grid not yet cached; True if it did (call again)."""
    shown = app.shown
    if shown.result is None:
        return False
    for size in PRESET_CELL_SIZES:
        candidate = shown.settings.with_(cell_size=size)
        if not shown.loaded.is_cached(candidate):
            if is_stale():
                return False
            shown.loaded.result(candidate)
            return True
    return False


def _wire(app: App) -> None:
    g = app.gui
    for control in (g.grid, g.model, g.axis, g.display, g.threshold, g.min_points,
                    g.colormap, g.clip):
        control.on_update(lambda _event: app.request_update())

    @g.grid_free.on_update
    def _(_event) -> None:
        if app._syncing:
            return
        if g.grid.value != "free":
            app._syncing = True
            try:
                g.grid.value = "free"
            finally:
                app._syncing = False
        app.request_update()

    @g.grid.on_update
    def _(_event) -> None:
        if g.grid.value != "free" and not app._syncing:
            app._syncing = True
            try:
                g.grid_free.value = float(g.grid.value)
            finally:
                app._syncing = False

    @g.point_size.on_update
    def _(_event) -> None:
        app.cloud_handle.point_size = float(g.point_size.value)

    @g.toggle.on_click
    def _(_event) -> None:
        g.model.value = "OLS" if g.model.value == "ODR" else "ODR"

    @g.show_axis.on_update
    def _(_event) -> None:
        _draw_axis(app)

    @g.load.on_click
    def _(_event) -> None:
        app.load(path=g.path.value.strip())

    @g.upload.on_upload
    def _(_event) -> None:
        f = g.upload.value
        app.load(upload=(f.name, f.content))

    @app.server.scene.on_click()
    def _(event: viser.SceneClickEvent) -> None:
        on_scene_click(app, event.ray_origin, event.ray_direction)


def on_scene_click(app: App, origin, direction) -> CellInfo | None:
    """Pick the displayed point under a click ray and report its cell."""
    shown = app.shown
    if shown.result is None:
        return None
    i = pick_point(shown.loaded.display_points, origin, direction)
    if i is None:
        app.gui.pick.content = "No point under the click."
        return None
    point = int(shown.loaded.display_index[i])
    xyz = shown.loaded.to_file_frame(shown.loaded.display_points[i])
    local = np.asarray(shown.loaded.display_points[i], dtype=np.float64)
    if app.profile_pick is not None and app.profile_pick(xyz, local):
        return None
    info = cell_info(shown.result, point, xyz)
    app.last_pick = info
    app.gui.pick.content = format_cell_info(info, shown.result.grid.cell_size)
    g = shown.result.grid.cell_size
    centre_local = tuple(np.asarray(info.centre) - shown.loaded.origin)
    app.pick_nodes = [
        app.server.scene.add_icosphere("/pick/point", radius=0.15 * g, color=PICK_COLOUR,
                                       position=tuple(local)),
        app.server.scene.add_box("/pick/cell", color=PICK_COLOUR, dimensions=(g, g, g),
                                 wireframe=True, position=centre_local),
    ]
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


def _draw_axis(app: App) -> None:
    shown = app.shown
    if shown.result is None:
        return
    visible = bool(app.gui.show_axis.value)
    pts = shown.loaded.display_points
    lo, hi = pts.min(axis=0).astype(np.float64), pts.max(axis=0).astype(np.float64)
    centre = 0.5 * (lo + hi)
    length = 0.3 * float(np.max(hi - lo))
    vec = np.asarray(AXIS_VECTORS[shown.result.axis])
    seg = np.array([[centre, centre + length * vec]], dtype=np.float32)
    app.server.scene.add_line_segments("/axis/line", seg, AXIS_COLOUR, thickness=4.0,
                                       thickness_units="screen", visible=visible)
    how = "auto" if shown.settings.axis == "auto" else "chosen"
    app.server.scene.add_label("/axis/label", f"OLS dependent axis {shown.result.axis} ({how})",
                               position=tuple(centre + 1.05 * length * vec), visible=visible)


def _status_text(app: App, result: GridRoughness, stats: MapStats, settings: ViewSettings,
                 seconds: float, cached: bool) -> str:
    loaded = app.shown.loaded
    where = "cached" if cached else f"computed in {seconds:.2f} s"
    name = Path(loaded.cloud.source).name if loaded.cloud.source else "in-memory cloud"
    return "\n".join([
        f"**{name}**: {loaded.n_display:,} points shown of {loaded.n_total:,} used  ",
        f"{MODEL_LABELS[settings.model]}, grid {settings.cell_size:g} m, axis {result.axis}, "
        f"{stats.valid_cells:,} of {stats.cells:,} cells with a value ({where})",
    ])


def _handle_request(app: App, request: Request, is_stale, *, variogram: bool) -> None:
    gui = app.gui
    settings = request.settings
    if request.kind == "load":
        try:
            loaded = _load(app, request)
        except (InputError, OSError, ValueError, MemoryError) as exc:
            gui.progress.visible = False
            app.show_error(str(exc))
            return
        with app._lock:
            app.shown = Shown(loaded, app.shown.settings)
            size = default_point_size(loaded)
            gui.point_size.min, gui.point_size.max = size / 10, size * 10
            gui.point_size.step = size / 10
            gui.point_size.value = size
            app.cloud_handle = _add_cloud(app.server, loaded, size)
            for node in app.pick_nodes:
                node.remove()
            app.pick_nodes = []
            app.last_pick = None
            gui.pick.content = "Click a point to see its cell."
            _initial_camera(app.server, loaded)
            for client in app.server.get_clients().values():
                client.camera.position = app.server.initial_camera.position
                client.camera.look_at = app.server.initial_camera.look_at
        app._panel_key = None

    loaded = app.shown.loaded
    t0 = time.perf_counter()
    try:
        check_settings(settings)
    except InputError as exc:
        app.show_error(str(exc))
        app.sync_controls(app.shown.settings)
        return
    cached = loaded.is_cached(settings)
    note = None
    if not cached:
        gui.progress.value = 0.0
        gui.progress.visible = True

        def progress(done: int, total: int) -> None:
            if total > 0:
                gui.progress.value = float(min(100.0, 100.0 * done / total))

    try:
        if not cached and loaded.n_total > 1_000_000:
            note = [c.add_notification("Computing", f"grid {settings.cell_size:g} m on "
                                       f"{loaded.n_total:,} points", loading=True,
                                       with_close_button=False)
                    for c in app.server.get_clients().values()]
        result = loaded.result(settings, progress=None if cached else progress)
    except (InputError, ValueError, MemoryError) as exc:
        app.show_error(f"grid {settings.cell_size:g} m: {exc}")
        app.sync_controls(app.shown.settings)
        return
    finally:
        gui.progress.visible = False
        for n in note or ():
            n.remove()
    if is_stale():
        return  # a newer request is waiting; the result stays cached for it
    norm = normalised_map(result, settings.model)
    colours = point_colours(result, settings, loaded.display_index, normalised=norm)
    stats = map_stats(result, settings)
    with app._lock:
        app.cloud_handle.colors = colours
        app.shown = Shown(loaded, settings, result, stats)
    t_colours = time.perf_counter() - t0
    app.clear_error()
    gui.colour_bar.figure = colour_bar_figure(
        colormap=settings.colormap, theta_min_m=stats.theta_min, theta_max_m=stats.theta_max,
        clip=settings.clip, mode=settings.mode, threshold=settings.threshold,
        title=f"{MODEL_LABELS[settings.model]} roughness, grid {settings.cell_size:g} m, "
              f"axis {result.axis}, {loaded.n_total:,} points",
        no_value_cells=stats.cells - stats.valid_cells,
    )
    gui.status.content = _status_text(app, result, stats, settings, t_colours, cached)
    auto = loaded.auto_axis
    gui.axis_note.content = (f"auto chose **{auto}** (closest to the whole-cloud normal); "
                             f"using **{result.axis}**")
    _draw_axis(app)
    record = {"cell_size": settings.cell_size, "model": settings.model, "cached": cached,
              "colours_s": t_colours}
    if not is_stale():
        key = (settings.grid_key, settings.model, variogram)
        if key != app._panel_key:
            t1 = time.perf_counter()
            figs = panels.build_panels(result, settings, variogram=variogram, is_stale=is_stale)
            if figs is not None:
                gui.histogram.figure = figs.histogram
                if figs.variogram is not None:
                    gui.variogram.figure = figs.variogram
                gui.summary.figure = figs.summary
                app._panel_key = key
            record["panels_s"] = time.perf_counter() - t1
    app.timings.append(record)


def _load(app: App, request: Request) -> LoadedCloud:
    if request.cloud is not None:
        return LoadedCloud(request.cloud, max_display=app.shown.loaded.max_display)
    if request.upload is not None:
        name, content = request.upload
        suffix = "".join(Path(name).suffixes[-1:]) or ".xyz"
        fd, tmp = tempfile.mkstemp(prefix="rough-viewer-upload-", suffix=suffix)
        try:
            with os.fdopen(fd, "wb") as fh:
                fh.write(content)
            cloud = load_points(tmp, cache=False)
            cloud = PointCloud.from_xyz(cloud.xyz(), intensity=cloud.intensity, source=name)
        finally:
            os.unlink(tmp)
    else:
        path = request.load_path or ""
        if not path:
            raise InputError("no file path given")
        if not Path(path).is_file():
            raise InputError(f"file not found: {path}")
        cloud = load_points(path)
    return LoadedCloud(cloud, max_display=app.shown.loaded.max_display)
