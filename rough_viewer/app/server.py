"""Wiring: put the app on a viser server and connect its controls to jobs.

``build_app(server, cloud)`` returns an :class:`App` holding every handle, so the
command line (``rough-viewer serve``), the tests and the benchmarks drive the same
object. All scene nodes and GUI controls are server-level: every browser tab sees
the same state. GUI callbacks (viser's thread pool) only read their control and
submit a job (:mod:`rough_viewer.app.jobs`); the worker (:mod:`rough_viewer.app.
worker`) runs the jobs one at a time and is the only thread that changes the
scene and the app's state.

The modes listed in :data:`MODES` are mounted after the map's controls, in tab
order; each is one module with a ``mount(app)`` function.
"""

from __future__ import annotations

import os
import sys
import threading
import traceback
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import viser

from rough_viewer.app import bias_panel, board_mode, export_mode, profile_mode, scene, zones_mode
from rough_viewer.app.controls import ClientValues
from rough_viewer.app.files import DataFolder
from rough_viewer.app.jobs import (
    AxisJob,
    CameraJob,
    ClickHandler,
    LoadJob,
    PickJob,
    Shown,
    ViewJob,
    grid_choice,
    on_scene_click,
    valid_ray,
)
from rough_viewer.app.layout import (
    AXIS_BY_NAME,
    DISPLAY_BY_NAME,
    LAYER_BY_LABEL,
    MODEL_BY_LABEL,
    VIEW_OPTIONS,
    Gui,
    assign,
    build_gui,
    limit_step,
    quietly,
    resolve_colormap,
    round_limit,
)
from rough_viewer.app.limits import (
    CACHE_BYTES,
    DEFAULT_MAX_UPLOAD_MB,
    MAX_ERRORS,
    MAX_JOB_RECORDS,
    MAX_MESSAGE,
    MAX_PENDING_JOBS,
    MAX_TIMINGS,
)
from rough_viewer.app.markup import md
from rough_viewer.app.state import (
    DEFAULT_MAX_DISPLAY,
    MODEL_LABELS,
    CellInfo,
    LoadedCloud,
    ViewSettings,
)
from rough_viewer.app.uploads import UploadedFile, Uploads
from rough_viewer.app.worker import Job, QueueFull, Run, Worker
from rough_viewer.grid.scales import PointScales
from rough_viewer.io import PointCloud
from rough_viewer.io.load import SUPPORTED_SUFFIXES
from rough_viewer.memory import format_bytes
from rough_viewer.visual import colormaps
from rough_viewer.vocabulary import COLOUR_LAYER_LABELS, UNITS, InputError, Unit

__all__ = ["App", "AppOptions", "MODES", "build_app", "on_scene_click"]

Mount = Callable[["App"], object]
"""A mode: adds its controls (a tab or a folder) and wiring to the app, returns its state."""

#: The modes every app gets, in tab order after Map, Panels and File. A new mode is
#: one module with a ``mount(app)`` function and one line here.
MODES: tuple[Mount, ...] = (
    profile_mode.mount,
    board_mode.mount,
    bias_panel.mount,
    zones_mode.mount,
    export_mode.mount,  # the Export folder (below the tabs): keep it last
)

T = TypeVar("T")


@dataclass(frozen=True)
class AppOptions:
    """Limits and switches of one app (``serve``'s options)."""

    max_display: int = DEFAULT_MAX_DISPLAY
    """Most points drawn in the browser (roughness uses every point)."""
    variogram: bool = True
    """Compute the semivariogram panel."""
    prefetch: bool = True
    """While idle, compute the preset grids for the current axis and minimum points."""
    data_dir: Path | None = None
    """Folder "Load file" may read from (None: the cloud's folder, or the current one)."""
    max_upload_bytes: int = DEFAULT_MAX_UPLOAD_MB << 20
    """Largest upload accepted, bytes."""
    cache_bytes: int = CACHE_BYTES
    """Memory budget of the cached grids of the loaded cloud, bytes."""
    units: Unit | None = None
    """Unit of the coordinates of files loaded from the File tab (``serve --units``;
    None: each file's CRS unit, else metres)."""


@dataclass(eq=False, repr=False)
class App:
    """Handles of a running app (see :func:`build_app`)."""

    server: viser.ViserServer
    gui: Gui
    options: AppOptions
    shown: Shown
    """What the scene shows (replaced as a whole by the worker)."""
    cloud_handle: viser.PointCloudHandle
    data: DataFolder
    """The folder "Load file" reads from."""
    controls: ClientValues = field(init=False)
    uploads: Uploads = field(init=False)
    worker: Worker[App] = field(init=False)
    timings: deque[dict[str, object]] = field(default_factory=lambda: deque(maxlen=MAX_TIMINGS))
    """One record per shown view: seconds to colours (``colours_s``) and to panels
    (``panels_s``), cached or not; the last :data:`MAX_TIMINGS`."""
    errors: deque[str] = field(default_factory=lambda: deque(maxlen=MAX_ERRORS))
    """Error messages shown to the user, oldest first (the last :data:`MAX_ERRORS`)."""
    pick_timings: deque[dict[str, object]] = field(
        default_factory=lambda: deque(maxlen=MAX_TIMINGS))
    """One record per reported click: seconds to the cell report and the
    across-scales plot (``pick_s``); the last :data:`MAX_TIMINGS`."""
    last_pick: CellInfo | None = None
    stashed: Shown | None = None
    """The scan put aside while the board lesson is shown (restored by the Board
    tab's button); None when nothing is put aside."""
    pick_nodes: list[viser.SceneNodeHandle] = field(default_factory=list)
    modes: list[object] = field(default_factory=list)
    """The state each mode's ``mount`` returned, in :data:`MODES` order."""
    click_handlers: list[ClickHandler] = field(default_factory=list)
    """Modes that take scene clicks, asked in order before the cell report."""
    cloud_handlers: list[Callable[[App], None]] = field(default_factory=list)
    """Called (on the worker) each time another cloud is put in the scene."""
    view_listeners: list[Callable[[App], None]] = field(default_factory=list)
    """Modes that follow the view: each is called (on the worker, inside the view job,
    so keep it quick: submit a job) after a view's colours are shown."""
    panel_key: tuple[object, ...] | None = None
    face_key: tuple[object, ...] | None = None
    """(axis, min points, threshold) of the whole-face trend shown in the Panels."""
    pick_scales: PointScales | None = None
    """The last clicked point's roughness across the preset grids."""
    lock: threading.RLock = field(default_factory=threading.RLock)
    controls_lock: threading.RLock = field(default_factory=threading.RLock)
    """Held while reading the Map tab's controls into a job, and while a callback or
    :meth:`sync_controls` sets controls that others depend on: viser runs callbacks
    in parallel, and a reading taken before another callback moved the grid to
    "free" but submitted after it would leave the map on the old grid for good."""
    _local: threading.local = field(default_factory=threading.local)

    # ------------------------------------------------------------------ state
    def mode(self, kind: type[T]) -> T:
        """The mounted mode state of type ``kind``."""
        for m in self.modes:
            if isinstance(m, kind):
                return m
        raise KeyError(kind.__name__)

    def settings_from_gui(self) -> ViewSettings:
        """The settings the controls currently ask for (InputError if a control holds
        a value the app cannot use). Lengths typed in the cloud's unit become metres."""
        g = self.gui
        u = g.length_units
        if g.grid.value == "free":
            cell = float(g.grid_free.value) * u.per
        else:
            preset = g.grid_values.get(g.grid.value)
            if preset is None:
                raise InputError("the grid size is not one of this cloud's presets")
            cell = preset
        model = MODEL_BY_LABEL.get(g.model.value)
        axis = AXIS_BY_NAME.get(g.axis.value)
        mode = DISPLAY_BY_NAME.get(g.display.value)
        layer = LAYER_BY_LABEL.get(g.layer.value)
        if model is None or axis is None or mode is None or layer is None:
            raise InputError("a control holds a value that is not one of its options")
        return ViewSettings(
            cell_size=cell,
            model=model,
            axis=axis,
            min_points=int(g.min_points.value),
            mode=mode,
            threshold=float(g.threshold.value),
            colormap=resolve_colormap(g.colormap.value, model),
            stretch=self.stretch_from_gui(),
            layer=layer,
        )

    def stretch_from_gui(self) -> colormaps.Stretch:
        """The colour stretch the controls ask for: percentiles of the cells, or the
        absolute limits typed in the roughness unit (InputError if unusable)."""
        g = self.gui
        log = bool(g.log.value)
        if g.stretch.value == "absolute":
            per = g.length_units.rough_per
            lo, hi = float(g.range_lo.value), float(g.range_hi.value)
            if log and lo <= 0:
                raise InputError("a log colour scale needs a lowest θ above 0")
            return colormaps.Stretch("absolute", lo * per, hi * per, log=log)
        p_lo, p_hi = (float(v) for v in g.percentiles.value)
        return colormaps.Stretch("percentile", p_lo, p_hi, log=log)

    def gui_settings(self) -> ViewSettings:
        """:meth:`settings_from_gui`, or the shown settings if a control is unusable."""
        try:
            return self.settings_from_gui()
        except InputError:
            return self.shown.settings

    # ------------------------------------------------------------------ jobs
    def submit(self, job: Job[App]) -> int:
        """Queue a job on the worker; 0 (with a notice) when too many wait."""
        try:
            return self.worker.submit(job)
        except QueueFull:
            self.notify("Busy", "Too many requests are waiting; try again in a moment.",
                        color="yellow")
            return 0

    def request_update(self) -> int:
        """Queue the view the controls show (ignored while the app sets controls)."""
        if self.syncing:
            return 0
        with self.controls_lock:  # the newest job reads the newest controls
            try:
                settings = self.settings_from_gui()
            except InputError as exc:
                self.reject_settings(str(exc))
                return 0
            return self.submit(ViewJob(settings))

    def load(self, path: str | None = None, *, upload: UploadedFile | None = None,
             cloud: PointCloud | None = None) -> int:
        """Queue showing another cloud: a path in the data folder (as typed), a
        finished upload, or an in-memory cloud. Files are read in the File tab's
        unit (``auto``: the CRS's unit, else metres)."""
        settings = self.gui_settings()
        choice: str = self.gui.units.value
        units: Unit | None = next((u for u in UNITS if u == choice), None)
        if cloud is not None:
            job = LoadJob(settings, cloud=cloud, shown_as=cloud.source)
        elif upload is not None:
            job = LoadJob(settings, upload=upload, shown_as=upload.name, units=units)
        else:
            job = LoadJob(settings, typed=path or "", shown_as=path or "", units=units)
        return self.submit(job)

    def wait_idle(self, timeout: float | None = 120.0) -> bool:
        """Block until the worker has nothing left to do (tests, scripts)."""
        return self.worker.wait_idle(timeout)

    def stop(self) -> None:
        """Stop the worker and drop unfinished uploads."""
        self.worker.stop()
        self.uploads.close()

    # ------------------------------------------------------------------ messages
    def notify(self, title: str, body: str, *, color: Any = None, seconds: float = 6.0) -> None:
        """A notification in every browser (plain text, never Markdown)."""
        for client in self.server.get_clients().values():
            client.add_notification(title, body, auto_close_seconds=seconds, color=color)

    def notify_client(self, client_id: int, title: str, body: str) -> None:
        """A red notification in one browser."""
        client = self.server.get_clients().get(client_id)
        if client is not None:
            client.add_notification(title, body, auto_close_seconds=10.0, color="red")

    def show_error(self, message: str, *, kept: str = "The previous view is kept.") -> None:
        """Show an error under the status line and as a notice (escaped, shortened)."""
        self.errors.append(message)
        self.gui.error.content = f"**Error:** {md(message, max_chars=MAX_MESSAGE)}  \n{kept}"
        self.gui.error.visible = True
        self.notify("Error", message[:MAX_MESSAGE], color="red", seconds=10.0)

    def clear_error(self) -> None:
        if self.gui.error.visible:
            self.gui.error.visible = False

    def reject_settings(self, message: str) -> None:
        """Show an error and put the controls back to the shown view."""
        self.show_error(message)
        self.sync_controls(self.shown.settings)

    @property
    def syncing(self) -> bool:
        """True while this thread sets controls (their callbacks queue nothing)."""
        return bool(getattr(self._local, "syncing", False))

    def sync_controls(self, settings: ViewSettings) -> None:
        """Set the controls to ``settings`` without queuing work (after an error, a
        restored view, or a cloud with other presets)."""
        g = self.gui
        u = g.length_units
        with self.controls_lock, quietly(self._local):
            assign(g.grid, grid_choice(settings.cell_size, g.grid_values))
            assign(g.grid_free, u.length(settings.cell_size))
            assign(g.model, MODEL_LABELS[settings.model])
            assign(g.axis, settings.axis)
            assign(g.min_points, int(settings.min_points))
            assign(g.display, settings.mode)
            assign(g.threshold, float(settings.threshold))
            auto = resolve_colormap("auto", settings.model)
            assign(g.colormap, "auto" if settings.colormap == auto else settings.colormap)
            label = COLOUR_LAYER_LABELS[settings.layer]
            if label in g.layer.options:
                assign(g.layer, label)
            st = settings.stretch
            assign(g.stretch, st.mode)
            assign(g.log, bool(st.log))
            if st.mode == "absolute":
                for handle, metres in ((g.range_lo, st.lo), (g.range_hi, st.hi)):
                    value = round_limit(u.rough(metres))
                    handle.step = limit_step(value)
                    assign(handle, value)
            else:
                assign(g.percentiles, (float(st.lo), float(st.hi)))

    def show_range(self, colour_range: colormaps.ColourRange) -> None:
        """Put the roughness range the colours span into the lowest/highest fields
        (roughness unit, 3 digits), so switching to an absolute stretch pins it."""
        g = self.gui
        u = g.length_units
        lo, hi = round_limit(u.rough(colour_range.lo)), round_limit(u.rough(colour_range.hi))
        if hi <= lo:
            return
        with self.controls_lock, quietly(self._local):
            # the fields show as many decimals as their step has: 3 digits of each
            for handle, value in ((g.range_lo, lo), (g.range_hi, hi)):
                handle.step = limit_step(value)
                assign(handle, value)


def _default_data_dir(cloud: PointCloud) -> Path:
    src = Path(cloud.source) if cloud.source else None
    if src is not None and src.is_file():
        return src.resolve().parent
    return Path(os.getcwd())


def build_app(
    server: viser.ViserServer,
    cloud: PointCloud,
    *,
    settings: ViewSettings | None = None,
    max_display: int = DEFAULT_MAX_DISPLAY,
    variogram: bool = True,
    prefetch: bool = True,
    data_dir: str | os.PathLike[str] | None = None,
    max_upload_mb: float = DEFAULT_MAX_UPLOAD_MB,
    cache_bytes: int = CACHE_BYTES,
    units: Unit | None = None,
    presets: Sequence[float] | None = None,
) -> App:
    """Put the app for ``cloud`` on ``server`` and start computing the first map.

    Parameters
    ----------
    server
        A running viser server (see :func:`rough_viewer.app.gate.open_server` for
        one that checks Origins and a token).
    cloud
        Points in the file frame (metres).
    settings
        Initial view. Default: :class:`ViewSettings` at the cloud's default grid
        (the finest of its presets, from the point spacing:
        :func:`rough_viewer.app.state.grid_presets`).
    max_display
        Most points drawn in the browser (roughness uses every point).
    variogram
        Compute the semivariogram panel (can be slow on very fine grids).
    prefetch
        While idle, compute the preset grid sizes for the current axis and
        minimum points, so switching presets only recolours.
    data_dir
        Folder "Load file" may read from (default: the cloud's folder, or the
        current folder).
    max_upload_mb
        Largest upload accepted, megabytes.
    cache_bytes
        Memory budget of the cached grids, bytes (default 1 GiB).
    units
        Unit of the coordinates of files loaded later from the File tab
        (``serve --units``; default: each file's CRS unit, else metres). The
        shown cloud's own unit is ``cloud.source_unit``.
    presets
        Grid presets of ``cloud``, metres (default
        :func:`rough_viewer.app.state.grid_presets`: from its point spacing). Files
        loaded later get their own.

    Returns
    -------
    App
        Handles; ``app.wait_idle()`` blocks until the first map is shown.
    """
    if units is not None and units not in UNITS:
        raise InputError(f"unknown unit {units!r}; choose one of {', '.join(UNITS)}")
    options = AppOptions(max_display=max_display, variogram=variogram, prefetch=prefetch,
                         data_dir=Path(data_dir) if data_dir is not None else None,
                         max_upload_bytes=int(max_upload_mb * (1 << 20)),
                         cache_bytes=int(cache_bytes), units=units)
    data = DataFolder.of(options.data_dir or _default_data_dir(cloud))
    loaded = LoadedCloud(cloud, max_display=max_display, cache_bytes=options.cache_bytes,
                         presets=tuple(presets) if presets is not None else None)
    settings = settings or ViewSettings(cell_size=loaded.default_cell_size)
    server.scene.set_up_direction("+z")
    scene.initial_camera(server, loaded)
    size = scene.default_point_size(loaded)
    assert loaded.presets is not None
    gui = build_gui(server, settings, point_size=size, source=cloud.source,
                    presets=loaded.presets, units=loaded.units, layers=loaded.layers,
                    file_units=units or "auto",
                    upload_limit=f", at most {format_bytes(options.max_upload_bytes)}")
    app = App(server, gui, options, Shown(loaded, settings),
              scene.add_cloud(server, loaded, size), data)
    app.controls = ClientValues(server, app.notify_client)
    app.uploads = Uploads(server, max_bytes=options.max_upload_bytes,
                          suffixes=SUPPORTED_SUFFIXES,
                          refuse=lambda cid, msg: app.notify_client(cid, "Upload refused", msg))
    app.worker = Worker(app, on_error=lambda job, exc: _on_error(app, job, exc),
                        max_pending=MAX_PENDING_JOBS, max_records=MAX_JOB_RECORDS,
                        idle=(lambda run: _prefetch_presets(app, run)) if prefetch else None)
    _wire(app)
    for mount in MODES:
        app.modes.append(mount(app))
    app.request_update()
    return app


def _on_error(app: App, job: Job[App], exc: BaseException) -> None:
    """A job failed: tell the user (never a traceback or a server path), log the rest."""
    app.gui.progress.visible = False
    if isinstance(exc, InputError):
        app.show_error(str(exc))
    elif isinstance(exc, MemoryError):
        app.show_error(f"{job.title}: not enough memory")
    else:
        traceback.print_exception(type(exc), exc, exc.__traceback__, file=sys.stderr)
        app.show_error(f"{job.title} failed ({type(exc).__name__}); the server's log has "
                       "the details")


def _prefetch_presets(app: App, run: Run) -> bool:
    """Compute one preset grid not yet cached; True if it did (call again)."""
    shown = app.shown
    if shown.result is None or shown.loaded.presets is None:
        return False
    for size in shown.loaded.presets:
        candidate = shown.settings.with_(cell_size=size)
        if not shown.loaded.is_cached(candidate):
            if run.cancelled:
                return False
            shown.loaded.result(candidate, progress=run.progress())
            # a grid that does not fit the cache budget is not prefetched again
            return shown.loaded.is_cached(candidate)
    return False


def _wire(app: App) -> None:
    """Connect the map's controls, the File tab and scene clicks to jobs."""
    app.controls.allow(*app.gui.inputs())
    _wire_map(app)
    _wire_file(app)

    @app.server.scene.on_click()
    def _(event: viser.SceneClickEvent) -> None:
        if valid_ray(event.ray_origin, event.ray_direction):
            o, d = event.ray_origin, event.ray_direction
            app.submit(PickJob((float(o[0]), float(o[1]), float(o[2])),
                               (float(d[0]), float(d[1]), float(d[2]))))


def _wire_map(app: App) -> None:
    """The Map tab: every change queues a view; grid and free grid follow each other,
    and so do the colour stretch and its limits."""
    g = app.gui

    def update(_event: object) -> None:
        app.request_update()

    for control in (g.layer, g.grid, g.model, g.axis, g.display, g.threshold, g.min_points,
                    g.colormap, g.stretch, g.log):
        control.on_update(update)

    def set_quietly(handle: Any, value: object) -> None:
        with quietly(app._local):
            assign(handle, value)

    def switching(handle: Any, value: str) -> Callable[[object], None]:
        """A callback that moves ``handle`` to ``value`` (quietly) and queues the view,
        both under :attr:`App.controls_lock`."""

        def callback(_event: object) -> None:
            if app.syncing:
                return
            with app.controls_lock:
                if handle.value != value:
                    set_quietly(handle, value)
                app.request_update()

        return callback

    # a typed free size picks "free"; dragged percentiles or a typed limit pick
    # that colour stretch
    g.grid_free.on_update(switching(g.grid, "free"))
    g.percentiles.on_update(switching(g.stretch, "percentile"))
    g.range_lo.on_update(switching(g.stretch, "absolute"))
    g.range_hi.on_update(switching(g.stretch, "absolute"))

    @g.grid.on_update
    def _(_event: object) -> None:
        size = g.grid_values.get(g.grid.value)
        if size is not None and not app.syncing:
            with app.controls_lock:
                set_quietly(g.grid_free, g.length_units.length(size))

    @g.point_size.on_update
    def _(_event: object) -> None:
        with app.lock:
            app.cloud_handle.point_size = float(g.point_size.value)

    @g.toggle.on_click
    def _(_event: object) -> None:
        assign(g.model, "OLS" if g.model.value == "ODR" else "ODR")

    @g.show_axis.on_update
    def _(_event: object) -> None:
        app.submit(AxisJob(bool(g.show_axis.value)))

    @g.camera.on_click
    def _(_event: object) -> None:
        if g.camera.value in VIEW_OPTIONS:
            app.submit(CameraJob(g.camera.value))


def _wire_file(app: App) -> None:
    """The File tab: "Load file" and uploads queue a load."""
    g = app.gui

    @g.load.on_click
    def _(_event: object) -> None:
        app.load(path=g.path.value)

    def uploaded(file: UploadedFile) -> None:
        app.load(upload=file)

    app.uploads.register(g.upload, uploaded)
