"""``rough-viewer serve``: the browser app.

Contract::

    rough-viewer serve [INPUT ...] [--demo NAME] [--port 8080] [--host 127.0.0.1]
        [--grid G] [--model odr|ols|hybrid|e_ols] [--axis auto|x|y|z]
        [--min-points K] [--point-budget N] [--max-points N] [--memory SIZE]
        [--overview-points N]
        [--units m|mm|ft|us-ft]
        [--data-dir DIR] [--max-upload-mb MB] [--max-connections N]
        [--allow-origin ORIGIN ...] [--no-token] [--view VIEW.json] [--save-views]
        [--classroom]
        [--scanner X,Y,Z | --scanners FILE] [--noise M] [--beam-radius M]
        [--calibration FILE ...] [--asperity-radius M] [--angular-step DEG]
        [--lesson NAME|FILE.toml]

Several inputs (files or quoted globs) open as one merged cloud. With no INPUT the
bundled demo outcrop opens (``--demo NAME`` picks another demo). ``--units`` (default:
the unit of a LAS file's CRS, else m) is the unit of the input's coordinates and of
every length given or shown (``--grid``, grid presets, coordinates; roughness in mm
for metric input, in the input's unit otherwise). Without ``--grid`` the first map
uses the cloud's default grid (from its point spacing; the app's presets are it
times 1, 2, 4 and 8).
The server listens on 127.0.0.1 only unless ``--host`` says otherwise; it says its
address on stderr at once (``listening at URL``), before it reads the input, and
prints ``N points, open URL`` on stdout once the first map is ready. It carries a random access token (``/t/<token>/``);
WebSocket connections without it, or from pages of another origin, are refused
(see :mod:`rough_viewer.app.gate`); at most ``--max-connections`` (default 32) are
open at once, and one whose browser stops reading is closed. Ctrl-C stops it.

Files opened from the browser ("Load file", uploads) are decoded in a child process
(:mod:`rough_viewer.io.sandbox.isolate`): a file that crashes its reader is a notice, and the
server keeps serving. ``--point-budget`` is the most points a browser tab draws at
once (level of detail: every point where its camera looks, up to that many);
``--max-points``, as in every command that reads a cloud, is the decompression-bomb
guard only: the most points a compressed file (INPUT, or one the browser loads or
uploads) may declare when its size cannot hold them.

``--memory SIZE`` (``2GB``, ``512MB``; default 80 % of the memory available when
serve starts) is what the server may use: before any point is read, the inputs'
headers give their points and the server's peak is estimated (the read's peak,
:mod:`rough_viewer.io.estimates`, plus what the app holds once prepared,
:data:`rough_viewer.app.limits.APP_BYTES_PER_POINT`: :func:`rough_viewer.app.files.serve_need`);
inputs that need more are refused in one line that suggests ``rough-viewer index``
and ``rough-viewer compute --memory`` (a COPC input: ``compute --memory`` only), and
a file the File tab loads or uploads is refused with a notice.

A single COPC file (``rough-viewer index``) too big for ``--memory`` (or of more points
than ``--overview-points N``) is served as a *campaign*
(:mod:`rough_viewer.app.campaign`, docs/campaign.md "Serving a campaign"): its
hierarchy is read and checked before the server opens (a damaged one is one line),
the top levels of its hierarchy (whole levels, at most ``--overview-points``, default
4,000,000, or what ``--memory`` leaves room for) are the cloud the tabs draw and
clicks read, said on stderr (``overview of 3.9 M of its 100 M points``), and every
map is computed from every point of the file by tiles (each node decoded once, in
the reader sandbox), its cells cached on disk for the next open. Crops and scanner
options are refused for a campaign.

The scanner options (docs/scanner.md) put the scanner positions into the cloud the app
opens (``PointCloud.scanner_positions``, ``scan_index``; E57 poses and the demos carry
theirs) and are checked here; the app's scanner colour layers and cell report read
them from the cloud.

``--view VIEW.json`` reopens a saved view (the Export folder's "Download view"): its
input, grid, model, axis, units, threshold, colours, profiles, zone settings and
camera; the view's settings replace ``--grid``, ``--model``, ``--axis`` and
``--min-points``. The view's input must lie in the data folder (``--data-dir``,
default the view file's folder; bundled demos always open), or be given as INPUT. A
view whose input moved or changed says so (stderr and the app). ``--save-views`` lets
the Export folder also write views next to the input in the data folder.

``--classroom`` gives every browser tab its own analysis of the one cloud (its own
controls, map, panels, crop, profiles, zones, ...; the grids are computed once for
all: :mod:`rough_viewer.app.classroom`) and prints two addresses, each on its own
line with its own token: ``open URL`` for the students and ``teacher URL`` for the
teacher, whose tab also has the Class tab (the students listed, their views, "Send
my view to everyone", "Follow me").

``--lesson NAME`` (a bundled lesson or a lesson file, docs/lessons.md, checked before
the server opens) opens the Lesson tab on it: once the first map is shown, its first
step sets its scene up (with ``--classroom``, in every tab, each then on its own).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import io
import math
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from rough_viewer.app.gate import DEFAULT_MAX_CONNECTIONS
from rough_viewer.app.limits import DEFAULT_MAX_UPLOAD_MB
from rough_viewer.cli._inputs import add_inputs
from rough_viewer.cli._options import add_axis, add_units
from rough_viewer.cli._scanner import add_scanner_options
from rough_viewer.io import PointCloud
from rough_viewer.vocabulary import DEFAULT_MIN_POINTS, InputError

Progress = Callable[[int, int, int], None]
"""``progress(file index, done, total)`` of the input's reading."""

if TYPE_CHECKING:
    import viser

    from rough_viewer.app.campaign import Campaign
    from rough_viewer.app.classroom import Classroom
    from rough_viewer.app.cloud import LoadedCloud
    from rough_viewer.app.gate import Gate
    from rough_viewer.app.host import AppOptions
    from rough_viewer.app.server import App
    from rough_viewer.app.settings import MapSettings
    from rough_viewer.app.views import OpenedView
    from rough_viewer.lessons import Lesson


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "serve",
        help="open the roughness viewer in the browser",
        description="Start the interactive roughness viewer (viser) on a cloud or a demo.",
    )
    add_inputs(p, optional=True, what="point cloud (default: the demo outcrop)")
    p.add_argument("--demo", metavar="NAME", help="open a bundled demo instead of INPUT")
    p.add_argument("--port", type=int, default=8080, help="port (default 8080; 0 = any free)")
    p.add_argument("--host", default="127.0.0.1",
                   help="address to listen on (default 127.0.0.1; 0.0.0.0 exposes it)")
    p.add_argument("--grid", type=float, default=None, metavar="G",
                   help="initial grid cell size in --units (default: from the point spacing, "
                   "so that a typical cell holds about 16 points)")
    p.add_argument("--model", choices=("odr", "ols", "hybrid", "e_ols"), default="odr",
                   help="initial map (default odr)")
    add_axis(p, help="initial dependent axis of OLS and hybrid (default auto)")
    p.add_argument("--min-points", type=int, default=DEFAULT_MIN_POINTS, metavar="K",
                   help="initial minimum points per cell (default 4)")
    p.add_argument("--point-budget", dest="point_budget", type=int, default=None,
                   metavar="N", help="most points a browser tab draws at once, where its "
                   "camera looks (default 3000000; roughness always uses every point)")
    p.add_argument("--memory", metavar="SIZE", default=None,
                   help="most memory the server may use, e.g. 2GB or 512MB (default: 80%% "
                   "of the memory available at start); inputs whose points need more are "
                   "refused before they are read")
    p.add_argument("--overview-points", dest="overview_points", type=int, default=None,
                   metavar="N", help="serve a COPC file of more than N points as a campaign: "
                   "the top levels of its hierarchy (at most N points) drawn, the map from "
                   "every point (default: a COPC file too big for --memory, with an overview "
                   "of at most 4000000 points)")
    p.add_argument("--data-dir", metavar="DIR",
                   help="folder the File tab's 'Load file' may read from (default: the "
                   "folder of the first INPUT, or the current folder); paths outside are "
                   "refused")
    p.add_argument("--max-upload-mb", type=float, default=DEFAULT_MAX_UPLOAD_MB, metavar="MB",
                   help=f"largest file a browser may upload (default {DEFAULT_MAX_UPLOAD_MB})")
    p.add_argument("--max-connections", type=int, default=DEFAULT_MAX_CONNECTIONS, metavar="N",
                   help=f"most browser connections open at once (default "
                   f"{DEFAULT_MAX_CONNECTIONS}); more are refused")
    p.add_argument("--allow-origin", action="append", default=[], metavar="ORIGIN",
                   help="also accept connections from pages of this origin, e.g. "
                   "http://myhost:8080 (repeatable); pages of other origins are refused")
    p.add_argument("--no-token", action="store_true",
                   help="do not require the access token in the URL (trusted networks only)")
    add_units(p)
    p.add_argument("--view", metavar="VIEW.json",
                   help="reopen a saved view (input, grid, model, colours, profiles, camera); "
                   "its input must lie in the data folder (default: the view file's folder) "
                   "or be given as INPUT")
    p.add_argument("--save-views", action="store_true",
                   help="let the Export folder also save views next to the input in the data "
                   "folder (without it views are only downloaded)")
    p.add_argument("--classroom", action="store_true",
                   help="every browser tab its own analysis of the one cloud (grids computed "
                   "once for all); prints the students' address (open ...) and the "
                   "teacher's (teacher ...), whose tab has the Class tab")
    p.add_argument("--lesson", metavar="NAME",
                   help="open the Lesson tab on a lesson: a bundled one (tilted-board, "
                   "turned-wall, scale; `rough-viewer lesson --list`) or a lesson file "
                   "(.toml, docs/lessons.md)")
    p.add_argument("--no-block", action="store_true", help=argparse.SUPPRESS)
    add_scanner_options(p)
    p.set_defaults(func=run)


def _load_cloud(args: argparse.Namespace, also: Progress | None = None) -> PointCloud:
    if args.inputs and args.demo:
        raise InputError("give either INPUT or --demo, not both")
    if args.inputs:
        from rough_viewer.cli._inputs import input_paths, load_inputs

        paths = input_paths(args)
        return _with_scanners(load_inputs(paths, units=getattr(args, "units", None), quiet=False,
                                          max_points=args.file_max_points, also=also),
                              paths, args)
    try:
        from rough_viewer.synthetic import demos
    except ImportError:
        raise InputError("no demo data in this installation; give a point-cloud file") from None
    name = args.demo or "outcrop"
    try:
        return _with_scanners(demos.load_demo(name), [], args)  # the demos know theirs
    except KeyError:
        raise InputError(f"unknown demo {name!r}") from None


def _with_scanners(cloud: PointCloud, paths: list[Path], args: argparse.Namespace) -> PointCloud:
    """The cloud with the positions of ``--scanner`` / ``--scanners`` (the app reads them
    from the cloud: ``scanner_positions``, ``scan_index``), after checking every scanner
    option (:func:`rough_viewer.cli._scanner.trust_settings`: the calibration the app's
    scanner layers will use)."""
    from rough_viewer.cli._scanner import apply_scanner_options, trust_settings

    trust_settings(args, cloud.source_unit)
    if args.scanners and not paths:
        raise InputError("--scanners needs INPUT files (their point source ids); the demos "
                         "carry their scanner's position")
    return apply_scanner_options(cloud, paths, args, cloud.source_unit)


def _memory_budget(args: argparse.Namespace) -> float | None:
    """The server's memory budget, bytes: ``--memory``, else 80 % of the memory
    available now (:func:`rough_viewer.app.files.default_memory`; None when unknown).
    Sets ``args.memory_bytes``."""
    from rough_viewer.app.files import default_memory
    from rough_viewer.scale.chunked import parse_bytes

    budget = (float(parse_bytes(args.memory)) if getattr(args, "memory", None)
              else default_memory())
    args.memory_bytes = budget
    return budget


def _check_memory(args: argparse.Namespace, paths: list[Path], typed: Sequence[str]) -> None:
    """Refuse, from the headers only (no point read), inputs whose server peak
    (:func:`rough_viewer.app.files.serve_need`) is above the memory budget, in one
    line that names them, the need and the budget and says what to run instead."""
    import shlex

    from rough_viewer.app.files import serve_need
    from rough_viewer.cli._inputs import describe
    from rough_viewer.io.copc.reader import is_copc
    from rough_viewer.memory import format_bytes

    budget = _memory_budget(args)
    args.campaign = None
    if not paths:
        return
    if budget is None and getattr(args, "overview_points", None) is None:
        return
    need = serve_need(paths, args.file_max_points)
    asked = getattr(args, "overview_points", None)
    if asked is not None and asked < 1:
        raise InputError(f"--overview-points must be positive, got {asked}")
    big = (budget is not None and need.total > budget) or (asked is not None
                                                           and need.points > asked)
    if big and len(paths) == 1 and is_copc(paths[0]):
        args.campaign = _open_campaign(args, paths[0], budget)
        return
    if budget is None or need.total <= budget:
        return
    given = getattr(args, "memory", None)
    allowed = (f"more than --memory {given} allows" if given else
               f"more than the {format_bytes(budget)} this machine can give (80 % of the "
               "memory available; --memory sets it)")
    size = given or f"{max(1, int(budget / 1e9))}GB"
    head = (f"{describe(paths)}: {need.points:,} points need about "
            f"{format_bytes(need.total)} in the server, {allowed}")
    copc = [is_copc(p) for p in paths]
    if all(copc):
        raise InputError(
            f"{head}; serve one COPC campaign at a time (one larger than memory is served "
            "as an overview, its map from every point), or compute their map out of core "
            f"with 'rough-viewer compute {' '.join(shlex.quote(str(p)) for p in paths)} "
            f"--memory {size} --grid G --out cells.csv'")
    inputs = " ".join(shlex.quote(t) for t in typed)
    las = all(p.suffix.lower() in (".las", ".laz") for p in paths)
    first = "" if las else " (index reads LAS/LAZ: write the others as LAS/LAZ first)"
    raise InputError(
        f"{head}; index the survey once with 'rough-viewer index {inputs} --out "
        f"campaign.copc.laz'{first} and compute its map out of core with 'rough-viewer "
        f"compute campaign.copc.laz --memory {size} --grid G --out cells.csv'")


def _check_options(args: argparse.Namespace) -> Path:
    """Validate the options that need no file; returns the data folder."""
    from rough_viewer.app.features.map.binding import MAX_BUDGET, MIN_BUDGET
    from rough_viewer.app.gate import normalise_origin

    if args.point_budget is not None and not MIN_BUDGET <= args.point_budget <= MAX_BUDGET:
        # the Map tab's budget control spans this range: a budget outside it cannot be shown
        raise InputError(f"--point-budget must be {MIN_BUDGET:,}-{MAX_BUDGET:,} points a tab, "
                         f"got {args.point_budget:,}")
    if not 0 <= args.port < 65536:
        raise InputError(f"--port must be 0-65535, got {args.port}")
    if args.max_connections < 1:
        raise InputError(f"--max-connections must be positive, got {args.max_connections}")
    if not args.max_upload_mb > 0:
        raise InputError(f"--max-upload-mb must be positive, got {args.max_upload_mb:g}")
    for origin in args.allow_origin:
        normalise_origin(origin)
    if args.data_dir is not None:
        folder = Path(args.data_dir).expanduser()
        if not folder.is_dir():
            raise InputError(f"--data-dir is not a folder: {args.data_dir}")
        return folder
    if args.inputs:
        from rough_viewer.cli._inputs import expand_inputs

        return expand_inputs(list(args.inputs))[0].expanduser().resolve().parent
    return Path.cwd()


def run(args: argparse.Namespace) -> int:
    from rough_viewer.lod.select import DEFAULT_BUDGET

    if args.point_budget is None:
        args.point_budget = DEFAULT_BUDGET
    return _run(args)


def _start_background() -> None:
    """What the app needs soon but not for listening: a reader process ready for every
    file a browser loads, and the grid kernels loaded (the app computes grids for as
    long as it runs); both start once the address is printed."""
    from rough_viewer.grid import fast
    from rough_viewer.io.sandbox import isolate

    isolate.warm(keep=True)
    fast.preload()


def _run(args: argparse.Namespace) -> int:
    _check_grid_and_units(args)
    opened = _open_view(args)
    data_dir = _data_dir(args, opened)
    _check_source(args, opened)  # what can be refused at once is, before the server opens
    args.lesson_data = _lesson(args)  # a bad lesson file is refused before the server opens
    server, gate = _open_server(args)
    url = gate.url(args.host, server.get_port())
    waiting = _say_listening(server, url, _what_loads(args, opened))
    app: App | Classroom | None = None
    previous = _stop_on_terminate()
    try:
        _start_background()
        cloud, settings = _cloud_and_settings(
            args, opened, _page_progress(waiting, _what_loads(args, opened)))
        campaign = getattr(args, "campaign", None)
        n_points = cloud.n if campaign is None else campaign.n_points
        waiting.content = (f"**{cloud.n:,} points read: computing the first map…**"
                           if campaign is None else
                           f"**An overview of {cloud.n:,} points read: computing the map "
                           f"from all {n_points:,} points…**")
        if args.classroom:
            app = _start_classroom(args, server, gate, cloud, settings, data_dir, opened)
            del cloud
            waiting.remove()
            print(f"rough-viewer: {n_points:,} points, a classroom: every tab its own "
                  "analysis", flush=True)
            print(f"open {url}", flush=True)
            print(f"teacher {gate.url(args.host, server.get_port(), teacher=True)}",
                  flush=True)
        else:
            app = _start_app(args, server, cloud, settings, data_dir)
            del cloud  # the app holds it while a tab shows it: this frame must not (issue 36)
            waiting.remove()
            if opened is not None:
                app.wait_idle(timeout=None if not args.no_block else 120.0)
                _apply_opened_view(app, opened, args)
            else:  # the first map is ready: the panels and the rest come after
                _wait_first_map(app, timeout=None if not args.no_block else 120.0)
            print(f"rough-viewer: {n_points:,} points, open {url}", flush=True)
            _say_warnings(list(app.host.errors)[-1:])
        while not args.no_block:
            time.sleep(3600)
    except KeyboardInterrupt:
        pass
    finally:
        if app is not None:
            app.stop()  # removes the upload folder(s)
        server.stop()
        _restore_signals(previous)
    return 0


def _lesson(args: argparse.Namespace) -> Lesson | None:
    """The lesson of ``--lesson`` read and checked (None without it)."""
    if not getattr(args, "lesson", None):
        return None
    from rough_viewer.lessons import find_lesson

    return find_lesson(args.lesson)


def _page_progress(waiting: viser.GuiMarkdownHandle, what: str) -> Progress:
    """The waiting page's line told how far the reading is (at most twice a second)."""
    last = [0.0]

    def tell(i: int, done: int, total: int) -> None:
        now = time.monotonic()
        if total <= 0 or (now - last[0] < 0.5 and done < total):
            return
        last[0] = now
        file = f" (file {i + 1})" if i else ""
        waiting.content = (f"**Reading {_markdown_text(what)}{file}: "
                           f"{min(100.0, 100.0 * done / total):.0f} %…** the map appears when "
                           "the cloud is read and its first grid computed.")

    return tell


def _wait_first_map(app: App, timeout: float | None) -> None:
    """Until the app has coloured its first map (or has nothing left to do: a map it
    could not make is an error line), not for the panels that follow it."""
    end = None if timeout is None else time.monotonic() + timeout
    while not app.map.timings and app.worker.busy:
        if end is not None and time.monotonic() > end:
            return
        time.sleep(0.05)


def _cloud_and_settings(args: argparse.Namespace, opened: OpenedView | None,
                        also: Progress | None = None) -> tuple[PointCloud, MapSettings]:
    """The cloud to show and its first map's settings (the saved view's, ``--grid``
    in the input's unit, else the cloud's default grid: its finest preset)."""
    from rough_viewer.app.settings import MapSettings, check_settings
    from rough_viewer.vocabulary import UNIT_METRES

    settings: MapSettings | None = opened.settings if opened is not None else None
    cloud = _read_cloud(args, opened, also)
    if opened is None and args.grid is not None:
        # --grid is in the input's unit (--units, else its CRS's, else m)
        settings = MapSettings(cell_size=args.grid * UNIT_METRES[cloud.source_unit],
                               model=args.model, axis=args.axis, min_points=args.min_points)
        check_settings(settings)
    if not args.inputs and opened is None:  # files: load_inputs said them already, once
        _say_warnings(cloud.warnings)
    if settings is None:  # the default grid: the finest preset (a campaign: that fits)
        settings = MapSettings(cell_size=_first_grid(args, cloud), model=args.model,
                               axis=args.axis, min_points=args.min_points)
        check_settings(settings)
    return cloud, settings


def _app_options(args: argparse.Namespace, cloud: PointCloud, data_dir: Path) -> dict[str, object]:
    from rough_viewer.app.limits import DEFAULT_MAX_DISPLAY
    from rough_viewer.cli._scanner import trust_settings

    return {"max_display": min(int(args.point_budget), DEFAULT_MAX_DISPLAY),
            "point_budget": args.point_budget, "max_points": args.file_max_points,
            "data_dir": data_dir, "max_upload_mb": args.max_upload_mb, "units": args.units,
            "save_views": args.save_views, "trust": trust_settings(args, cloud.source_unit),
            "memory": getattr(args, "memory_bytes", None),
            "lesson": getattr(args, "lesson_data", None)}


def _start_app(args: argparse.Namespace, server: viser.ViserServer, cloud: PointCloud,
               settings: MapSettings, data_dir: Path) -> App:
    """One analysis shared by every tab (``serve`` without ``--classroom``)."""
    from rough_viewer.app.server import app_options, build_app, mount_app

    kwargs = _app_options(args, cloud, data_dir)
    if getattr(args, "campaign", None) is None:
        return build_app(server, cloud, settings=settings, presets=_presets(args, cloud),
                         **kwargs)  # type: ignore[arg-type]
    options = app_options(cloud, **kwargs)  # type: ignore[arg-type]
    return mount_app(server, _campaign_loaded(args, cloud, options), settings, options)


def _start_classroom(args: argparse.Namespace, server: viser.ViserServer, gate: Gate,
                     cloud: PointCloud, settings: MapSettings, data_dir: Path,
                     opened: OpenedView | None) -> Classroom:
    """Every tab its own analysis of the one cloud (``serve --classroom``); a saved
    view (``--view``) is restored in every tab as it opens."""
    from rough_viewer.app.cache import default_slots
    from rough_viewer.app.classroom import Classroom
    from rough_viewer.app.server import app_options, shared_cloud

    kwargs = _app_options(args, cloud, data_dir)
    options = app_options(cloud, **kwargs)  # type: ignore[arg-type]
    options = dataclasses.replace(options, compute_slots=default_slots())
    loaded = (shared_cloud(cloud, options) if getattr(args, "campaign", None) is None
              else _campaign_loaded(args, cloud, options))
    prepare = None
    if opened is not None:
        def prepare(app: App, role: str) -> None:
            from rough_viewer.app.views import apply_view

            apply_view(app.host, opened.view, source=Path(args.view).name, notice="")

    return Classroom(server, gate, loaded, settings, options, prepare=prepare).start()


def _check_grid_and_units(args: argparse.Namespace) -> None:
    """Refuse a --grid that is no positive length, and --units with a demo."""
    if args.grid is not None and not (math.isfinite(args.grid) and args.grid > 0):
        raise InputError(f"--grid must be a positive length, got {args.grid:g}")
    if args.demo and args.units:
        raise InputError("--units applies to INPUT files; the demos are in metres")


def _data_dir(args: argparse.Namespace, opened: OpenedView | None) -> Path:
    """The folder the File tab may read from: --data-dir, else the saved view's, else
    the first input's (:func:`_check_options`, which checks the options first)."""
    data_dir = _check_options(args)
    if opened is not None and opened.data_dir is not None and args.data_dir is None:
        return opened.data_dir
    return data_dir


def _say_listening(server: viser.ViserServer, url: str, what: str) -> viser.GuiMarkdownHandle:
    """Say the address first (stderr) and what the page waits for until the cloud is
    read; returns the waiting page's text."""
    print(f"rough-viewer: listening at {url} ; reading {what}, the page fills in once it "
          "is ready", file=sys.stderr, flush=True)
    return server.gui.add_markdown(f"**Reading {_markdown_text(what)}…** the map appears "
                                   "when the cloud is read and its first grid computed.")


def _say_warnings(warnings: Sequence[str]) -> None:
    """Each warning on stderr, one a line."""
    for warning in warnings:
        print(f"rough-viewer: warning: {warning}", file=sys.stderr)


def _open_view(args: argparse.Namespace) -> OpenedView | None:
    """The saved view of ``--view`` opened (its input found, its settings checked), or
    None without one."""
    if not args.view:
        return None
    from rough_viewer.app.views import open_view
    from rough_viewer.cli._inputs import input_paths

    if args.demo:
        raise InputError("give either --view or --demo, not both")
    return open_view(args.view, inputs=input_paths(args) if args.inputs else (),
                     data_dir=args.data_dir)


def _open_server(args: argparse.Namespace) -> tuple[viser.ViserServer, Gate]:
    """The viser server behind its gate (token, origins, connections; with
    ``--classroom`` a teacher's token beside the students')."""
    from rough_viewer.app.gate import new_token, open_server

    if args.classroom and args.no_token:
        raise InputError("--classroom needs the tokens (the students' and the teacher's "
                         "addresses differ by them): drop --no-token")
    with contextlib.redirect_stdout(io.StringIO()):  # viser's banner shows a URL without the token
        server, gate = open_server(args.host, args.port,
                                   token=None if args.no_token else new_token(),
                                   allow_origins=args.allow_origin,
                                   max_connections=args.max_connections,
                                   teacher_token=new_token() if args.classroom else None)
    return server, gate


def _read_cloud(args: argparse.Namespace, opened: OpenedView | None,
                also: Progress | None = None) -> PointCloud:
    """The cloud to show: the saved view's input, else INPUT or the demo, with the
    scanner options applied (``also(i, done, total)``: the reading's progress); a
    campaign (:func:`_open_campaign`): its overview."""
    if getattr(args, "campaign", None) is not None:
        return _read_overview(args, also)
    if opened is None:
        return _load_cloud(args, also)
    from rough_viewer.cli._inputs import load_inputs

    return _with_scanners(
        load_inputs([opened.input_path], units=opened.view.units, quiet=False,
                    max_points=args.file_max_points, also=also),
        [opened.input_path], args)


def _open_campaign(args: argparse.Namespace, path: Path, budget: float | None) -> Campaign:
    """The COPC file ``path`` opened as a campaign (:mod:`rough_viewer.app.campaign`):
    its hierarchy read and checked (a damaged one is one line, before the server
    opens), the overview's cap checked against the budget."""
    from rough_viewer.app.campaign import open_campaign, overview_cap

    if getattr(args, "scanner", None) or getattr(args, "scanners", None):
        raise InputError(f"{path}: a campaign larger than the server holds is served as an "
                         "overview, and its scanner figures are not built yet: drop "
                         "--scanner/--scanners, or compute 'rough-viewer bias' on the file")
    try:
        overview_cap(budget, getattr(args, "overview_points", None))
    except InputError as exc:
        raise InputError(f"{path}: {exc}") from None
    return open_campaign(path, units=getattr(args, "units", None),
                         max_points=args.file_max_points)


def _read_overview(args: argparse.Namespace, also: Progress | None = None) -> PointCloud:
    """The overview of ``args.campaign`` (the top levels of its hierarchy), said on
    stderr; ``args.campaign`` gets the memory its map's pass may take and
    ``args.campaign_presets`` the grid presets of its density."""
    from rough_viewer.app.campaign import (
        campaign_presets,
        compute_memory,
        describe_overview,
        overview_cap,
        read_overview,
    )

    campaign = args.campaign
    budget = getattr(args, "memory_bytes", None)
    cap = overview_cap(budget, getattr(args, "overview_points", None))
    overview = read_overview(campaign, cap, progress=None if also is None else
                             (lambda done, total: also(0, done, total)))
    args.campaign = dataclasses.replace(campaign,
                                        memory_bytes=compute_memory(budget, overview.n))
    args.campaign_presets = campaign_presets(overview, campaign.n_points)
    print(f"rough-viewer: {describe_overview(campaign, overview)}", file=sys.stderr,
          flush=True)
    _say_warnings(overview.warnings)
    return overview


def _presets(args: argparse.Namespace, cloud: PointCloud) -> tuple[float, ...]:
    """The app's grid presets: a campaign's (of its density), else the cloud's."""
    from rough_viewer.app.cloud import grid_presets

    if getattr(args, "campaign", None) is not None:
        return tuple(args.campaign_presets)
    return grid_presets(cloud)


def _first_grid(args: argparse.Namespace, cloud: PointCloud) -> float:
    """The first map's grid without ``--grid``: the finest preset; a campaign's
    finest whose cells fit its pass's memory (said on stderr when that is not the
    finest)."""
    presets = _presets(args, cloud)
    if getattr(args, "campaign", None) is None:
        return presets[-1]
    from rough_viewer.app.campaign import first_grid
    from rough_viewer.app.units import Units

    g = first_grid(args.campaign, cloud, presets)
    if g != presets[-1]:
        u = Units(cloud.source_unit)
        print(f"rough-viewer: note: the cells of the finest grid, {u.size_text(presets[-1])}, "
              f"would not fit --memory beside the pass: the first map is grid "
              f"{u.size_text(g)} (finer ones are tried when asked for)", file=sys.stderr,
              flush=True)
    return g


def _campaign_loaded(args: argparse.Namespace, cloud: PointCloud,
                     options: AppOptions) -> LoadedCloud:
    """The campaign's overview prepared for the app, its map from every point."""
    from rough_viewer.app.campaign import campaign_cloud

    return campaign_cloud(args.campaign, cloud, presets=_presets(args, cloud),
                          max_display=options.max_display, cache_bytes=options.cache_bytes,
                          cache_pool=options.cache_pool, trust_settings=options.trust)


def _apply_opened_view(app: App, opened: OpenedView, args: argparse.Namespace) -> None:
    """Restore the saved view on the running app and wait until it shows."""
    from rough_viewer.app.views import apply_view

    # browsers see file names, never the server's folders (the terminal does)
    public = opened.notice
    for full in {str(opened.view.input.path), str(opened.input_path)}:
        if full:
            public = public.replace(full, Path(full).name)
    apply_view(app.host, opened.view, source=Path(args.view).name, notice=public)
    app.wait_idle(timeout=None if not args.no_block else 120.0)
    if opened.notice:
        print(f"rough-viewer: note: {opened.notice}", file=sys.stderr)


def _check_source(args: argparse.Namespace, opened: object) -> None:
    """Refuse at once what :func:`_load_cloud` would refuse without reading: INPUT with
    --demo, a missing input file, an unknown demo, inputs too big for ``--memory``
    (:func:`_check_memory`, from their headers)."""
    if opened is not None:
        path = Path(str(getattr(opened, "input_path", "")))
        _check_memory(args, [path], [str(path)])
        return
    if args.inputs and args.demo:
        raise InputError("give either INPUT or --demo, not both")
    if args.inputs:
        from rough_viewer.cli._inputs import input_paths

        _check_memory(args, input_paths(args), list(args.inputs))
        return
    _memory_budget(args)  # a bad --memory is refused with the demos too
    try:
        from rough_viewer.synthetic import demos
    except ImportError:
        raise InputError("no demo data in this installation; give a point-cloud file") from None
    name = args.demo or "outcrop"
    if name not in {d.name for d in demos.list_demos()}:
        raise InputError(f"unknown demo {name!r}")


def _what_loads(args: argparse.Namespace, opened: object) -> str:
    """What serve reads before its first map, as the terminal and the waiting page say
    it (file names only: the page never shows the server's folders)."""
    if opened is not None:
        return Path(str(getattr(opened, "input_path", "the view's input"))).name
    if args.inputs:
        names = [Path(str(p)).name for p in args.inputs]
        return names[0] if len(names) == 1 else f"{len(names)} files"
    return f"the {args.demo or 'outcrop'} demo"


def _markdown_text(text: str) -> str:
    """``text`` with Markdown's and HTML's special characters escaped (a file name is
    the user's, shown in every browser)."""
    return "".join("\\" + c if c in "\\`*_{}[]()#+-.!|<>&" else c for c in text)


def _stop_on_terminate() -> dict[int, object]:
    """SIGTERM and SIGHUP (a service manager, a closed terminal) end the server as
    Ctrl-C does, so its cleanup runs (the upload folder in the temp folder was left
    behind). Returns the handlers replaced (none off the main thread)."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return {}

    def interrupt(_signum: int, _frame: object) -> None:
        raise KeyboardInterrupt

    previous: dict[int, object] = {}
    for name in ("SIGTERM", "SIGHUP"):
        sig = getattr(signal, name, None)
        if sig is not None:
            previous[sig] = signal.signal(sig, interrupt)
    return previous


def _restore_signals(previous: dict[int, object]) -> None:
    import signal

    for sig, handler in previous.items():
        signal.signal(sig, handler)  # type: ignore[arg-type]
