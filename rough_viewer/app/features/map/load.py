"""Show another cloud: :class:`LoadJob` (from a file, an upload, points in
memory), :class:`ShowJob` (a prepared cloud), and :func:`show_cloud`."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from typing import ClassVar

from rough_viewer.app import scene as scene_mod
from rough_viewer.app.cloud import LoadedCloud
from rough_viewer.app.features.map.binding import (
    PICK_PROMPT,
    Changes,
    MapTab,
)
from rough_viewer.app.features.map.render import RenderJob, render_stages, resolve
from rough_viewer.app.host import CloudSource, Host
from rough_viewer.app.settings import MapSettings
from rough_viewer.app.worker import Job, Run
from rough_viewer.io import PointCloud
from rough_viewer.vocabulary import (
    InputError,
)


@dataclass(frozen=True)
class InMemory:
    """A cloud already in memory (the command line's, a script's)."""

    cloud: PointCloud

    @property
    def title(self) -> str:
        return self.cloud.source or "a cloud"

    def read(self, host: Host, run: Run) -> PointCloud:
        return self.cloud

    def release(self) -> None:
        pass


# ----------------------------------------------------------------------------- clouds


@dataclass(frozen=True)
class LoadJob(Job[Host]):
    """Show another cloud from ``source`` (a file, an upload, points in memory)."""

    m: MapTab = field(compare=False)
    source: CloudSource = field(compare=False)
    settings: MapSettings | None = None
    """Settings to show it with (None: the controls', read when the job runs)."""
    changes: Changes = ()
    stash: bool = False
    """Put the scan shown now aside (:func:`load_stages`)."""
    label: str = ""
    """The status line's name of a cloud that is no file."""
    adjust: Callable[[MapSettings], MapSettings] | None = field(default=None, compare=False)
    """Changes the settings before the cloud is shown with them (the board's own
    colour range)."""
    lane: ClassVar[str] = "load"
    cancels: ClassVar[frozenset[str]] = frozenset({"render", "panels", "pick"})

    @property
    def title(self) -> str:
        return f"loading {self.source.title}"

    def absorb(self, newer: Job[Host]) -> Job[Host] | None:
        if isinstance(newer, RenderJob):
            return replace(self, settings=newer.settings, changes=self.changes + newer.changes)
        return None

    def release(self) -> None:
        self.source.release()

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        settings = resolve(self.m, self.settings, self.changes) \
            or ctx.session.shown.settings
        if self.adjust is not None:
            settings = self.adjust(settings)
        return load_stages(self.m, run, lambda r: self.source.read(ctx, r), settings,
                           stash=self.stash, label=self.label)


def load_stages(m: MapTab, run: Run, read: Callable[[Run], PointCloud],
                settings: MapSettings, *, stash: bool = False,
                label: str = "") -> Iterator[str]:
    """Read a cloud, prepare it for display, put it in the scene, then show it with
    ``settings`` at its own default grid (its presets come from its point spacing).

    ``stash``: put the scan shown now aside (:attr:`Session.stashed`) instead of
    dropping it, so it can be shown again as it was (the board lesson); a load
    without it drops anything put aside. A cloud that cannot be read or prepared
    leaves the old one shown (with the error) and shows ``settings`` on it, so
    control changes merged into the load are not lost. ``label``: the status line's
    name of a cloud that is no file (:attr:`LoadedCloud.label`).
    """
    host = m.host
    try:
        cloud = read(run)
        yield "read"
        loaded = LoadedCloud(cloud, max_display=host.options.max_display,
                             cache_bytes=host.options.cache_bytes, label=label,
                             cache_pool=host.options.cache_pool,
                             trust_settings=host.options.trust)
    except (InputError, MemoryError) as exc:
        host.show_error(str(exc) if isinstance(exc, InputError) else "not enough memory "
                        "to load this cloud")
        yield "read failed"
        m.binding.show(settings)
        yield from render_stages(m, run, settings, keep_error=True)
        return
    yield "prepare"
    if stash:
        host.session.put_aside()
    else:
        host.session.stashed = None
    layer = settings.layer if settings.layer in loaded.layers else "roughness"
    settings = settings.with_(cell_size=loaded.default_cell_size, layer=layer)
    show_cloud(m, loaded, settings)
    for warning in cloud.warnings[:10]:
        host.notify("Warning", warning, color="yellow", seconds=12.0)
    yield "show"
    yield from render_stages(m, run, settings)


def show_cloud(m: MapTab, loaded: LoadedCloud, settings: MapSettings, *,
               frame: bool = True) -> None:
    """Replace the cloud in the scene (and forget the old cloud's pick and panels);
    the grid presets, unit labels and colour layers follow the new cloud, and the
    controls show ``settings`` (worker). ``frame``: every browser's camera frames
    it (False: the cameras and point size stay, as for a crop of the cloud shown)."""
    host = m.host
    host.session.new_cloud(loaded, settings)
    size = scene_mod.default_point_size(loaded) if frame else float(host.scene.point_size)
    m.binding.follow(loaded, size)
    m.binding.show(settings)
    host.scene.show_cloud(loaded, size)
    m.forget_pick(PICK_PROMPT)
    if frame:
        host.scene.frame(loaded)
    host.cloud_shown()


@dataclass(frozen=True)
class ShowJob(Job[Host]):
    """Show a prepared cloud with ``settings`` (the app's first cloud; a scan put
    aside, shown again with its cached grids)."""

    m: MapTab = field(compare=False)
    loaded: LoadedCloud = field(compare=False)
    settings: MapSettings
    lane: ClassVar[str] = "load"
    cancels: ClassVar[frozenset[str]] = frozenset({"render", "panels", "pick"})

    @property
    def title(self) -> str:
        return "showing the cloud"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        show_cloud(self.m, self.loaded, self.settings)
        yield "show"
        yield from render_stages(self.m, run, self.settings)


