"""Saved views in the app: what the app shows as a :class:`~rough_viewer.report.view.View`,
and a view put back on an app.

A view file (:mod:`rough_viewer.report.view`) records the input (path, size, content
hash), the grid, the map, units, threshold, colour settings, open panels, picked
profiles, zone settings and the camera. Three steps use it here:

- :func:`view_of_app`: the view of what an app shows (the Export folder's "Download
  view" and "Save view beside the input");
- :func:`open_view`: ``rough-viewer serve --view VIEW.json`` before any server starts:
  read and validate the (untrusted) view file, find its input, apply the data-folder
  rule, and say whether the input changed or moved (:class:`OpenedView`);
- :func:`apply_view`: on a built app, set the controls, show the view's settings
  (colours included), re-run its profiles, restore its zone settings and camera, and
  show the notice.

The data-folder rule (as for ``serve INPUT``): the browser may only ever read files
in the data folder, and a view names its input itself, so a view's input must lie in
the data folder: ``--data-dir``, or by default the folder of the view file. The
bundled demo scans are always allowed. An input given on the command line
(``serve INPUT --view VIEW.json``) is the operator's choice and opens as usual; the
view's hash then says whether it is the same file.
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from rough_viewer.app.layout import assign, resolve_colormap
from rough_viewer.app.limits import MAX_PROFILES
from rough_viewer.app.state import MAX_CELL_SIZE, MIN_CELL_SIZE, ViewSettings, check_settings
from rough_viewer.app.worker import Job, Run
from rough_viewer.report.view import (
    Camera,
    ColourSettings,
    InputRef,
    LoadedView,
    ProfilePick,
    View,
    ZoneSettings,
    file_sha256,
    load_view,
)
from rough_viewer.vocabulary import UNITS, InputError, Unit

if TYPE_CHECKING:
    import viser

    from rough_viewer.app.profile_mode import ProfileMode
    from rough_viewer.app.server import App
    from rough_viewer.app.zones_mode import ZonesMode

#: Largest cell size the app's "Free grid size" control takes, metres (layout.build_gui).
APP_MAX_CELL_SIZE = MAX_CELL_SIZE
#: Largest "Min points per cell" the app's control takes (layout.build_gui).
APP_MAX_MIN_POINTS = 100_000
#: Names of the analysis panels a view lists (the app draws all of them).
PANEL_NAMES: tuple[str, ...] = ("histogram", "variogram", "summary")


# ----------------------------------------------------------------------------- app -> view


def settings_of_view(view: View) -> ViewSettings:
    """The app settings a view asks for (grid, model, threshold, colours)."""
    c = view.colour
    return ViewSettings(cell_size=float(view.cell_size_m), model=view.model, axis=view.axis,
                        min_points=int(view.min_points), mode=c.mode,
                        threshold=float(view.threshold), colormap=c.colormap,
                        stretch=c.stretch, layer=c.layer)


def profile_picks(app: App) -> tuple[ProfilePick, ...]:
    """The profiles kept in the Profile tab as view entries (file frame, metres)."""
    mode = _profile_mode(app)
    if mode is None:
        return ()
    picks = []
    for a in mode.items:
        s = a.settings
        p0, p1 = a.source.start, a.source.end
        picks.append(ProfilePick(
            start=(float(p0[0]), float(p0[1]), float(p0[2])),
            end=(float(p1[0]), float(p1[1]), float(p1[2])),
            band_half_width_m=None if s.band_half_width is None else float(s.band_half_width),
            wavelet=s.wavelet, level=int(s.level), decomposition=s.decomposition,
            threshold_rule=s.threshold, mode=s.mode, detrend=s.detrend))
    return tuple(picks)


def camera_of(app: App, client: viser.ClientHandle | None) -> Camera | None:
    """The camera of one browser (or the server's initial camera when None), in the
    file frame (metres)."""
    origin = app.shown.loaded.origin
    try:  # a browser's camera is known once it has sent one
        cam = client.camera if client is not None else None
        if cam is not None:
            position, look_at, up = cam.position, cam.look_at, cam.up_direction
            fov = float(cam.fov)
    except (AssertionError, AttributeError):
        cam = None
    if cam is None:
        init = app.server.initial_camera
        position, look_at = init.position, init.look_at
        up = init.up if init.up is not None else np.array([0.0, 0.0, 1.0])
        fov = float(init.fov)

    def vec(v: Any, shift: np.ndarray | None) -> tuple[float, float, float]:
        a = np.asarray(v, dtype=np.float64).reshape(3)
        if shift is not None:
            a = a + shift
        return float(a[0]), float(a[1]), float(a[2])

    p, t, u = vec(position, origin), vec(look_at, origin), vec(up, None)
    if p == t or not np.all(np.isfinite([*p, *t, *u])) or u == (0.0, 0.0, 0.0):
        return None
    fov_deg = float(np.degrees(fov))
    return Camera(position=p, look_at=t, up=u,
                  fov_deg=fov_deg if 0.0 < fov_deg <= 180.0 else 50.0)


def view_of_app(app: App, ref: InputRef, *, camera: Camera | None,
                zones: ZoneSettings | None = None) -> View:
    """The view of what ``app`` shows now, for the input ``ref``.

    Settings are the shown map's (``app.shown.settings``); profiles come from the
    Profile tab; zone settings from the zones mode when it is mounted, else
    ``zones`` (as a view brought them).
    """
    s = app.shown.settings
    unit = app.shown.loaded.cloud.source_unit
    units: Unit = unit if unit in UNITS else "m"
    mounted = zone_settings(app)
    return View(
        input=ref, cell_size_m=float(s.cell_size), min_points=int(s.min_points), axis=s.axis,
        model=s.model, units=units, threshold=float(s.threshold),
        colour=ColourSettings(colormap=s.colormap, mode=s.mode, stretch=s.stretch,
                              layer=s.layer),
        panels=PANEL_NAMES if app.options.variogram else PANEL_NAMES[::2],
        profiles=profile_picks(app)[-MAX_PROFILES:],
        zones=mounted if mounted is not None else zones,
        camera=camera,
    )


# ----------------------------------------------------------------------------- zones


def _zones_mode(app: App) -> ZonesMode | None:
    """The zones mode's state when it is mounted, else None."""
    from rough_viewer.app.zones_mode import ZonesMode

    try:
        return app.mode(ZonesMode)
    except KeyError:
        return None


def zone_settings(app: App) -> ZoneSettings | None:
    """The zones mode's settings (its ``settings()``), or None without a zones mode or
    while it shows no zones (its ``active`` is False)."""
    mode = _zones_mode(app)
    if mode is None or not mode.active:
        return None
    return mode.settings()


def restore_zones(app: App, zones: ZoneSettings) -> bool:
    """Give ``zones`` to the zones mode (its ``apply(settings)``); False without one."""
    mode = _zones_mode(app)
    if mode is None:
        return False
    mode.apply(zones)
    return True


# ----------------------------------------------------------------------------- view -> app


def _profile_mode(app: App) -> ProfileMode | None:
    from rough_viewer.app.profile_mode import ProfileMode

    try:
        return app.mode(ProfileMode)
    except KeyError:
        return None


def check_view_for_app(view: View, source: str) -> ViewSettings:
    """The view's settings, refused (one line naming ``source``) where the app's
    controls cannot take them."""
    where = f"view file {source}:"
    if not MIN_CELL_SIZE <= view.cell_size_m <= APP_MAX_CELL_SIZE:
        raise InputError(f"{where} grid.cell_size_m {view.cell_size_m:g} is outside the "
                         f"app's range [{MIN_CELL_SIZE:g}, {APP_MAX_CELL_SIZE:g}] m")
    if view.min_points > APP_MAX_MIN_POINTS:
        raise InputError(f"{where} grid.min_points {view.min_points} is more than the app's "
                         f"{APP_MAX_MIN_POINTS:,}")
    settings = settings_of_view(view)
    try:
        check_settings(settings)
    except InputError as exc:
        raise InputError(f"{where} {exc}") from None
    return settings


def apply_camera(app: App, camera: Camera) -> None:
    """Make ``camera`` (file frame) the initial camera of every browser, and move the
    connected ones there."""
    origin = app.shown.loaded.origin

    def local(v: Sequence[float]) -> tuple[float, float, float]:
        a = np.asarray(v, dtype=np.float64) - origin
        return float(a[0]), float(a[1]), float(a[2])

    position, look_at = local(camera.position), local(camera.look_at)
    fov = float(np.radians(camera.fov_deg))
    init = app.server.initial_camera
    init.position, init.look_at, init.up, init.fov = position, look_at, camera.up, fov
    for client in app.server.get_clients().values():
        client.camera.position = position
        client.camera.look_at = look_at
        client.camera.up_direction = camera.up
        client.camera.fov = fov


def apply_view(app: App, view: View, *, source: str = "(in memory)", notice: str = "") -> None:
    """Put ``view`` on a built app: controls, the shown map (colours included), the
    profiles (re-run as a job), zone settings (given to the zones mode, or kept as
    data by the Export folder, which saves them again) and camera; ``notice`` (the
    input moved or changed) is shown above the tabs and to each browser.

    Call it once the app shows its cloud (``app.wait_idle()``), from any thread but
    the worker's. Raises InputError (naming ``source``) when the app's controls cannot
    take the view's settings; the app is then unchanged.
    """
    from rough_viewer.app.jobs import ViewJob

    settings = check_view_for_app(view, source)
    # zones first: the zones mode sets its controls and may set the Map tab's model;
    # the view's own settings below are then shown last, and the zones follow them
    zones_kept = False
    if view.zones is not None:
        try:
            zones_kept = restore_zones(app, view.zones)
        except InputError as exc:
            app.show_error(f"saved view: zones: {exc}", kept="The map is shown without zones.")
    g = app.gui
    app.sync_controls(settings)  # grid, model, axis, min points, display (quietly)
    # controls sync_controls leaves alone; each queues a view, which the next replaces
    assign(g.threshold, float(settings.threshold))
    auto = resolve_colormap("auto", settings.model) == settings.colormap
    assign(g.colormap, "auto" if auto else settings.colormap)
    app.submit(ViewJob(settings))
    if view.camera is not None:
        apply_camera(app, view.camera)
    mode = _profile_mode(app)
    if mode is not None and view.profiles:
        _set_profile_controls(mode, view.profiles[0])
        app.submit(RestoreProfilesJob(mode, view.profiles))
    from rough_viewer.app.export_mode import ExportMode

    try:
        export = app.mode(ExportMode)
    except KeyError:
        return
    export.zones = None if zones_kept else view.zones
    if notice:
        export.show_notice(notice)


def _set_profile_controls(mode: ProfileMode, pick: ProfilePick) -> None:
    """The Profile tab's de-noising controls as the first profile had them."""
    for handle, value in ((mode.wavelet, pick.wavelet), (mode.decomposition, pick.decomposition),
                          (mode.threshold, pick.threshold_rule), (mode.mode, pick.mode)):
        if value in handle.options:
            assign(handle, value)
    if mode.level.min <= pick.level <= mode.level.max:
        assign(mode.level, int(pick.level))
    from rough_viewer.app.profile_mode import DETRENDS, detrend_choice

    if pick.detrend is None or detrend_choice(pick.detrend) in DETRENDS:
        assign(mode.detrend, detrend_choice(pick.detrend))
    band = (pick.band_half_width_m or 0.0) / mode.units.per  # the control is in the cloud's unit
    if mode.band.max is None or band <= mode.band.max:
        assign(mode.band, float(band))


@dataclass(frozen=True)
class RestoreProfilesJob(Job["App"]):
    """Extract and de-noise a view's profiles again, each with its own settings."""

    mode: ProfileMode = field(compare=False)
    picks: tuple[ProfilePick, ...] = ()
    lane: ClassVar[str] = "profile-restore"

    @property
    def title(self) -> str:
        return "restoring the view's profiles"

    def stages(self, ctx: App, run: Run) -> Iterator[str]:
        from rough_viewer.app.profile_mode import ProfileSettings

        failed: list[str] = []
        for k, pick in enumerate(self.picks, start=1):
            run.check()
            settings = ProfileSettings(wavelet=pick.wavelet, level=pick.level,
                                       decomposition=pick.decomposition,
                                       threshold=pick.threshold_rule, mode=pick.mode,
                                       band_half_width=pick.band_half_width_m,
                                       detrend=pick.detrend)
            try:
                self.mode.add_profile(ctx, np.asarray(pick.start), np.asarray(pick.end),
                                      settings)
            except (InputError, ValueError) as exc:
                failed.append(f"profile {k}: {exc}")
            yield f"profile {k}"
        if failed:
            more = f" (and {len(failed) - 1} more)" if len(failed) > 1 else ""
            ctx.show_error(f"saved view: {failed[0]}{more}",
                           kept="The other profiles are shown.")


# ----------------------------------------------------------------------------- serve --view


@dataclass(frozen=True)
class OpenedView:
    """A view file read for ``serve --view``, its input found and allowed."""

    loaded: LoadedView
    input_path: Path
    """The file to open."""
    data_dir: Path | None
    """The data folder the view implies (None: the one ``serve`` chooses, for an input
    given on the command line)."""
    settings: ViewSettings
    notice: str
    """One line when the input moved or changed ("" when it is the same file)."""

    @property
    def view(self) -> View:
        return self.loaded.view


def _is_bundled_demo(path: Path) -> bool:
    try:
        from rough_viewer.synthetic.demos import DEMO_DIR
    except ImportError:
        return False
    try:
        return path.resolve().is_relative_to(Path(DEMO_DIR).resolve())
    except (OSError, RuntimeError):
        return False


def open_view(view_file: str | os.PathLike[str], *, inputs: Sequence[Path] = (),
              data_dir: str | os.PathLike[str] | None = None) -> OpenedView:
    """Read a view file for ``serve --view`` and decide what to open.

    Parameters
    ----------
    view_file
        The view (untrusted: validated by :func:`rough_viewer.report.view.load_view`).
    inputs
        Input files given on the command line (at most one); they replace the view's
        recorded input, whose hash then tells whether they are the same file.
    data_dir
        ``--data-dir``; default the view file's folder. The view's own input must lie
        in it (or be a bundled demo).

    Raises
    ------
    InputError
        One line: the file is not a valid view, its input is missing or outside the
        data folder, or its settings do not fit the app's controls.
    """
    vf = Path(view_file)
    if len(inputs) > 1:
        raise InputError("--view opens one input file; give at most one INPUT with it")
    loaded = load_view(vf, check=not inputs)
    view = loaded.view
    settings = check_view_for_app(view, str(vf))
    if inputs:
        path = Path(inputs[0])
        if not path.is_file():
            raise InputError(f"input file not found: {path}")
        same = path.stat().st_size == view.input.size_bytes and \
            file_sha256(path) == view.input.sha256
        notice = "" if same else (f"{path} is not the file the view was saved from "
                                  f"({view.input.path}: another content); the view's "
                                  "numbers may not match")
        return OpenedView(loaded, path, None, settings, notice)
    check = loaded.input_check
    if check.path is None or check.status == "missing":
        raise InputError(f"view file {vf}: {check.message}")
    folder = Path(data_dir) if data_dir is not None else vf.resolve().parent
    if not folder.is_dir():
        raise InputError(f"--data-dir is not a folder: {folder}")
    path = check.path.resolve()
    if not path.is_relative_to(folder.resolve()) and not _is_bundled_demo(path):
        raise InputError(f"view file {vf}: its input {path} lies outside the data folder "
                         f"{folder}; pass --data-dir with a folder that holds it, or give "
                         "the input file as INPUT")
    notice = "" if check.status == "unchanged" else check.message
    return OpenedView(loaded, path, folder, settings, notice)
