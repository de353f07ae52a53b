"""Build the app: put it on a viser server and mount its features.

``build_app(server, cloud)`` returns an :class:`App`, so the command line
(``rough-viewer serve``), the tests and the benchmarks drive the same object. An app
is a composition: the viser server, the session (what is shown), the worker (the
only thread that changes the session and the scene), the shell (the features' host:
:mod:`rough_viewer.app.shell`), the features (:data:`FEATURES`, mounted in tab
order) and the options. The GUI controls and the scene's overlays (axis, labels,
outlines) are server-level, so every browser tab sees the same analysis; the cloud's
points are per tab (each tab draws the octree nodes its camera needs, within its point
budget: :mod:`rough_viewer.app.scene`).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import viser

from rough_viewer.app.cloud import LoadedCloud
from rough_viewer.app.features import (
    bias,
    board,
    crop,
    export,
    file,
    lesson,
    measure,
    panels,
    profile,
    sets,
    zones,
)
from rough_viewer.app.features import map as roughness_map
from rough_viewer.app.features.file import FileFeature
from rough_viewer.app.features.map import InMemory, LoadJob, MapFeature, ShowJob
from rough_viewer.app.features.profile import directions
from rough_viewer.app.files import DataFolder, UploadedFile
from rough_viewer.app.host import AppOptions, Host
from rough_viewer.app.layout import CONTROL_WIDTH
from rough_viewer.app.limits import CACHE_BYTES, DEFAULT_MAX_DISPLAY, DEFAULT_MAX_UPLOAD_MB
from rough_viewer.app.session import Session, Shown
from rough_viewer.app.settings import MapSettings
from rough_viewer.app.shell import Shell
from rough_viewer.app.stage import Stage, stage_of
from rough_viewer.app.worker import Job, Worker
from rough_viewer.io import PointCloud
from rough_viewer.io.estimates import max_points_limit
from rough_viewer.lessons import Lesson
from rough_viewer.lod.select import DEFAULT_BUDGET
from rough_viewer.scanner.trust import TrustSettings
from rough_viewer.vocabulary import UNITS, InputError, Unit

__all__ = ["App", "AppOptions", "FEATURES", "app_options", "build_app", "mount_app",
           "shared_cloud"]

T = TypeVar("T")

Mount = Callable[[Host], object]
"""A feature: adds its controls (a tab or a folder) and wiring, returns its state."""

#: The features every app gets, in tab order (the map first: the others use it). A new
#: feature is one module of :mod:`rough_viewer.app.features` and one line here.
FEATURES: tuple[Mount, ...] = (
    roughness_map.mount,
    panels.mount,
    file.mount,
    profile.mount,
    directions.mount,  # a folder in the Profile tab
    board.mount,
    lesson.mount,  # the Lesson tab: guided steps (serve --lesson)
    bias.mount,
    zones.mount,
    sets.mount,
    crop.mount,  # the Select tab (its saved-view part is restored first)
    measure.mount,
    export.mount,  # the Export folder (below the tabs, lists every panel): keep it last
)


@dataclass(eq=False, repr=False)
class App:
    """A running app (see :func:`build_app`)."""

    server: viser.ViserServer
    host: Shell
    """The features' host: the GUI, checks, messages, events."""
    map: MapFeature
    """The map (the first feature; every other uses it)."""
    options: AppOptions

    @property
    def session(self) -> Session:
        """What the app shows (written by the worker only)."""
        return self.host.session

    @property
    def worker(self) -> Worker[Shell]:
        """The one thread that runs jobs."""
        return self.host.worker

    @property
    def features(self) -> Sequence[object]:
        return self.host.features()

    def feature(self, kind: type[T]) -> T:
        """The mounted feature of type ``kind`` (KeyError if none)."""
        return self.host.feature(kind)

    def submit(self, job: Job[Any]) -> int:
        """Queue a job on the worker; 0 (with a notice) when too many wait."""
        return self.host.submit(job)

    def load(self, path: str | None = None, *, upload: UploadedFile | None = None,
             cloud: PointCloud | None = None) -> int:
        """Queue showing another cloud: a path in the data folder (as typed), a
        finished upload (both in the File tab's unit), or an in-memory cloud."""
        if cloud is not None:
            return self.submit(LoadJob(self.map, InMemory(cloud)))
        f = self.feature(FileFeature)
        return f.load_upload(upload) if upload is not None else f.load_path(path or "")

    def wait_idle(self, timeout: float | None = 120.0) -> bool:
        """Block until the worker has nothing left to do (tests, scripts)."""
        return self.worker.wait_idle(timeout)

    def stop(self) -> None:
        """Stop the worker and drop unfinished uploads."""
        self.worker.stop()
        self.host.uploads.close()


def _default_data_dir(cloud: PointCloud) -> Path:
    src = Path(cloud.source) if cloud.source else None
    if src is not None and src.is_file():
        return src.resolve().parent
    return Path(os.getcwd())


def build_app(
    server: viser.ViserServer,
    cloud: PointCloud,
    *,
    settings: MapSettings | None = None,
    max_display: int = DEFAULT_MAX_DISPLAY,
    variogram: bool = True,
    prefetch: bool = True,
    data_dir: str | os.PathLike[str] | None = None,
    max_upload_mb: float = DEFAULT_MAX_UPLOAD_MB,
    cache_bytes: int = CACHE_BYTES,
    units: Unit | None = None,
    presets: Sequence[float] | None = None,
    save_views: bool = False,
    trust: TrustSettings | None = None,
    point_budget: int = DEFAULT_BUDGET,
    max_points: int | None = None,
    lesson: Lesson | None = None,
    memory: float | None = None,
) -> App:
    """Put the app for ``cloud`` on ``server`` and start showing its first map.

    Parameters
    ----------
    server
        A running viser server (see :func:`rough_viewer.app.gate.open_server` for
        one that checks Origins and a token).
    cloud
        Points in the file frame (metres).
    settings
        Initial map. Default: :class:`MapSettings` at the cloud's default grid
        (the finest of its presets, from the point spacing:
        :func:`rough_viewer.app.cloud.grid_presets`).
    max_display
        Points of the even overview sample (camera framing, point size, highlights;
        roughness uses every point).
    point_budget
        Most points a browser tab shows at once: each tab gets the nodes of the
        cloud's octree its camera sees (level of detail, :mod:`rough_viewer.lod`).
    max_points
        The decompression-bomb guard's limit for the files the File tab loads or
        uploads (``serve --max-points``; default
        :data:`rough_viewer.io.estimates.DEFAULT_MAX_POINTS`).
    lesson
        The lesson the Lesson tab opens on (``serve --lesson``): its first step's
        scene is set up once the first map is shown.
    memory
        The server's memory budget, bytes (``serve --memory``; None: none): files
        the File tab loads or uploads that need more are refused before reading.
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
        :func:`rough_viewer.app.cloud.grid_presets`: from its point spacing). Files
        loaded later get their own.
    save_views
        "Save view beside the input" may write into the data folder
        (``serve --save-views``).
    trust
        Calibration of the scanner colour layers and cell report of clouds with
        scanner positions (default: the bias paper's; docs/scanner.md).

    Returns
    -------
    App
        ``app.wait_idle()`` blocks until the first map is shown.
    """
    options = app_options(cloud, max_display=max_display, variogram=variogram,
                          prefetch=prefetch, data_dir=data_dir, max_upload_mb=max_upload_mb,
                          cache_bytes=cache_bytes, units=units, save_views=save_views,
                          trust=trust, point_budget=point_budget, max_points=max_points,
                          lesson=lesson, memory=memory)
    loaded = shared_cloud(cloud, options, presets=presets)
    return mount_app(server, loaded, settings or MapSettings(cell_size=loaded.default_cell_size),
                     options)


def app_options(
    cloud: PointCloud,
    *,
    max_display: int = DEFAULT_MAX_DISPLAY,
    variogram: bool = True,
    prefetch: bool = True,
    data_dir: str | os.PathLike[str] | None = None,
    max_upload_mb: float = DEFAULT_MAX_UPLOAD_MB,
    cache_bytes: int = CACHE_BYTES,
    units: Unit | None = None,
    save_views: bool = False,
    trust: TrustSettings | None = None,
    point_budget: int = DEFAULT_BUDGET,
    max_points: int | None = None,
    lesson: Lesson | None = None,
    memory: float | None = None,
) -> AppOptions:
    """The options of an app for ``cloud`` (:func:`build_app`'s parameters, checked)."""
    if units is not None and units not in UNITS:
        raise InputError(f"unknown unit {units!r}; choose one of {', '.join(UNITS)}")
    data = DataFolder.of(data_dir if data_dir is not None else _default_data_dir(cloud))
    return AppOptions(data=data, max_display=max_display, variogram=variogram,
                      prefetch=prefetch, max_upload_bytes=int(max_upload_mb * (1 << 20)),
                      cache_bytes=int(cache_bytes), units=units, save_views=save_views,
                      trust=trust, point_budget=int(point_budget),
                      max_points=max_points_limit(max_points), lesson=lesson,
                      memory=memory)


def shared_cloud(cloud: PointCloud, options: AppOptions, *,
                 presets: Sequence[float] | None = None) -> LoadedCloud:
    """``cloud`` prepared for the app (overview sample, presets, store under the
    options' one cache budget): what every analysis showing it shares."""
    return LoadedCloud(cloud, max_display=options.max_display, cache_bytes=options.cache_bytes,
                       cache_pool=options.cache_pool,
                       presets=tuple(presets) if presets is not None else None,
                       trust_settings=options.trust)


def mount_app(stage: viser.ViserServer | Stage, loaded: LoadedCloud, settings: MapSettings,
              options: AppOptions, *, extra: Sequence[Mount] = ()) -> App:
    """Mount every feature (and ``extra`` ones after them) on ``stage`` (a server:
    its shared GUI; a tab's stage: that tab's own) and start showing ``loaded``."""
    stage = stage_of(stage)
    stage.scene.set_up_direction("+z")
    stage.gui.configure_theme(control_width="large", show_share_button=False)
    stage.gui.main_panel.set_width(CONTROL_WIDTH)
    shell = Shell(stage, options, Shown(loaded, settings))
    for mount in (*FEATURES, *extra):
        feature = mount(shell)
        shell.add_feature(feature)
        if isinstance(feature, MapFeature):  # the other features' map calls go to it
            shell.use_map(feature)
    app = App(stage.server, shell, shell.feature(MapFeature), options)
    app.submit(ShowJob(app.map, loaded, settings))
    return app
