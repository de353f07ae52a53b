"""The Export folder: the shown result as files the browser downloads, and saved views.

Downloads (the file comes to the browser that pressed the button, through viser's
file transfer on the app's WebSocket, so it works when the server runs on another
machine; the browser saves it at once, no link to click):

- **points**: every point with its cell's roughness as LAS/LAZ extra dimensions or
  PLY properties (:mod:`rough_viewer.io.formats.las_out`, :mod:`rough_viewer.io.formats.ply`); a
  cloud read from a LAS/LAZ file on the server is copied from that file with all its
  dimensions, VLRs (the CRS) and EVLRs, as ``compute --las-out`` does;
- **cell table**: CSV, or Parquet when pyarrow is installed (the ``compute --out``
  table, lengths in the input's unit);
- **tables of a tab** (:class:`TablePart`): a feature's own tables as CSV, e.g. the
  Sets tab's Dips CSV, SETS.csv, PLANES.csv and JOINTS.csv, as the command line
  writes them;
- **figures**: any panel of the app (every feature lists its own,
  :class:`rough_viewer.app.host.FigureSource`), or all of them in one ZIP, as HTML, or
  PNG/SVG when kaleido is installed;
- **report**: the HTML report of ``rough-viewer report`` for the shown grid, axis,
  minimum points and threshold;
- **view**: the saved view (JSON) of what is shown (:func:`rough_viewer.app.views.
  view_of`), and, when ``serve --save-views`` allows it, "Save view beside the input"
  writes it next to the input in the data folder.

Each download is an :class:`ExportJob` on the worker (lane ``export``: every request
runs, in order; a repeated identical one still waiting is merged). Stages: check
(something is shown; the estimated file fits the disk and the memory needed to send
it, :func:`rough_viewer.memory.require`), write (into a private temporary folder,
``0700``, atomically, with progress), read (the size checked again), send. The
temporary folder is removed whatever happens, and only a complete file is sent: a
failed export offers nothing. Names are made of the input's name and the settings,
reduced to ``[A-Za-z0-9._-]`` (:func:`safe_name`) and put in the folder with
:func:`rough_viewer.io.output.path_in_folder`.

Memory: viser keeps a download in memory until the browser has it: the file's bytes,
a copy cut in 1 MiB parts per browser, and the message windows it encodes (msgpack,
zstd) while sending; :data:`SEND_FACTOR` covers that.
"""

from __future__ import annotations

import importlib.util
import re
import shutil
import tempfile
import time
import weakref
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Literal, Protocol, runtime_checkable

import numpy as np
import viser

from rough_viewer.app.binding import Binding
from rough_viewer.app.cloud import LoadedCloud
from rough_viewer.app.host import FigureSource, Host
from rough_viewer.app.markup import md, public_message
from rough_viewer.app.session import Shown
from rough_viewer.app.views import camera_of, view_of
from rough_viewer.app.worker import Job, Run
from rough_viewer.grid.roughness import GridRoughness
from rough_viewer.io import PointCloud
from rough_viewer.io.formats.point_fields import CellField, PointFields
from rough_viewer.io.output import check_output_path, path_in_folder, write_atomic
from rough_viewer.memory import format_bytes, require
from rough_viewer.report.view import Camera, InputRef, file_sha256, view_text
from rough_viewer.visual.export import FORMATS_NOTE, figure_formats, figure_title
from rough_viewer.vocabulary import UNIT_LABELS, InputError
from rough_viewer.vocabulary import grid_tag as vocabulary_grid_tag

if TYPE_CHECKING:
    from viser._gui_handles import GuiProgressBarHandle

    from rough_viewer.app.files import DataFolder

ExportKind = Literal["points", "table", "tab-table", "figure", "report", "view"]

#: Labels (tests and users find the controls by them).
L_POINTS_FORMAT = "Points file"
L_POINTS = "Download points"
L_TABLE_FORMAT = "Cell table"
L_TABLE = "Download cell table"
L_TAB_TABLE_CHOICE = "Table of a tab"
L_TAB_TABLE = "Download table (CSV)"
L_FIGURE = "Figure"
L_FIGURE_FORMAT = "Figure format"
L_FIGURE_BUTTON = "Download figure"
L_REPORT = "Download report (HTML)"
L_VIEW = "Download view (JSON)"
L_SAVE_VIEW = "Save view beside the input"

POINTS_OPTIONS: tuple[str, ...] = ("LAZ", "LAS", "PLY")
ALL_FIGURES = "all panels (ZIP)"

#: Bytes of server memory per byte of a download, per browser it goes to, while viser
#: sends it (its 1 MiB parts, then each window of up to 128 parts as msgpack and as
#: zstd); the file's own bytes come on top.
SEND_FACTOR = 3.0
#: Largest download offered, bytes (a browser holds it in memory as well).
MAX_DOWNLOAD_BYTES = 4 << 30
#: Free disk space kept beside a temporary export file, bytes.
DISK_MARGIN = 256 << 20
#: Estimated file bytes per point (LAS/PLY: a PF 3 record and the eight fields; LAZ:
#: compressed, the check after writing is the exact one) and per cell (CSV, Parquet).
BYTES_PER_POINT = {"las": 64.0, "laz": 16.0, "ply": 60.0}
BYTES_PER_CELL = {"csv": 260.0, "parquet": 120.0}
#: Estimated CSV bytes per field of a tab's table.
BYTES_PER_FIELD = 26.0
#: More of them when the cloud has scanner positions (the nine scanner fields).
TRUST_BYTES_PER_POINT = {"las": 32.0, "laz": 8.0, "ply": 32.0}
TRUST_BYTES_PER_CELL = {"csv": 110.0, "parquet": 50.0}
#: Estimated size of one figure as HTML (plotly.js inlined) and of the report, bytes;
#: in a ZIP of figures each page loads the one plotly.js beside it.
FIGURE_BYTES = 5 << 20
ZIP_FIGURE_BYTES = 1 << 20
REPORT_BYTES = 12 << 20
#: Finished downloads kept in :attr:`ExportFeature.sent`.
MAX_SENT_RECORDS = 100


def _has(module: str) -> bool:
    return importlib.util.find_spec(module) is not None


def grid_tag(loaded: LoadedCloud, cell_size: float) -> str:
    """``g<G>`` of a download's name: the grid size as the app shows it, in the
    cloud's unit, the unit named unless metres (``g0.25``, ``g2.5mm``, ``g1ft``)."""
    u = loaded.units
    return vocabulary_grid_tag(u.length(cell_size), u.unit)


def safe_name(text: str, default: str = "cloud") -> str:
    """``text`` as a file-name part of at most 60 characters from ``[A-Za-z0-9._-]``.

    >>> safe_name("../../etc/pass wd<script>.laz")
    'etc_pass_wd_script_.laz'
    >>> safe_name("...")
    'cloud'
    """
    s = re.sub(r"[^A-Za-z0-9._-]+", "_", text)
    s = re.sub(r"\.{2,}", ".", s).strip("._-")
    return s[:60].rstrip("._-") or default


def panel_figures(host: Host) -> dict[str, viser.GuiPlotlyHandle]:
    """Every plotly panel of the app by name (a file-name part), from each feature's
    own list (:meth:`~rough_viewer.app.host.FigureSource.figures`), in mount order."""
    out: dict[str, viser.GuiPlotlyHandle] = {}
    for f in host.features():
        if isinstance(f, FigureSource):
            out.update(f.figures())
    return out


def panel_titles(host: Host) -> dict[str, str]:
    """Title shown in the figure list (:func:`rough_viewer.visual.export.figure_title`)
    -> the panel's name, in mount order."""
    return {figure_title(name): name for name in panel_figures(host)}


def _has_data(fig: Any) -> bool:
    """Whether a plotly figure shows anything (a trace with values)."""
    for trace in fig.data:
        if getattr(trace, "type", "") == "table":
            values = trace.cells.values
        else:
            values = next((v for v in (getattr(trace, a, None) for a in ("x", "y", "z", "values"))
                           if v is not None), None)
        if values is not None and len(values) > 0:
            return True
    return False


@dataclass(frozen=True)
class Sent:
    """A finished download."""

    name: str
    size_bytes: int
    clients: int
    seconds: float
    """From the job's start to the file handed to viser."""


@dataclass(eq=False)
class ExportFeature:
    """Handles and state of the Export folder."""

    host: Host
    points_format: viser.GuiDropdownHandle[str]
    points: viser.GuiButtonHandle
    table_format: viser.GuiDropdownHandle[str]
    table: viser.GuiButtonHandle
    tab_table: viser.GuiDropdownHandle[str]
    tab_table_button: viser.GuiButtonHandle
    figure: viser.GuiDropdownHandle[str]
    figure_format: viser.GuiDropdownHandle[str]
    figure_button: viser.GuiButtonHandle
    report: viser.GuiButtonHandle
    view: viser.GuiButtonHandle
    save_view: viser.GuiButtonHandle
    status: viser.GuiMarkdownHandle
    progress: GuiProgressBarHandle
    initial: weakref.ref[PointCloud]
    """The cloud the app was started on (its file may be named relative to the
    server's folder), weakly: it is freed once no tab shows it (a strong reference
    kept it for the server's life; issue 36 item 2)."""
    initial_path: Path | None = None
    """:attr:`initial`'s file, resolved in the folder the server started in (None:
    no file)."""
    binding: Binding = field(default_factory=Binding)
    """Writes the folder's status line and progress bar (on the worker)."""
    sent: deque[Sent] = field(default_factory=lambda: deque(maxlen=MAX_SENT_RECORDS))
    _hashes: dict[tuple[str, int, int], InputRef] = field(default_factory=dict, repr=False)

    # ------------------------------------------------------------------ input
    def input_file(self, loaded: LoadedCloud) -> Path | None:
        """The file ``loaded``'s cloud was read from on the server (a crop's: its whole
        cloud's), or None (an upload, which is deleted once read; several merged files;
        a cloud made in memory)."""
        cloud = (loaded.uncropped or loaded).cloud
        if not cloud.source:
            return None
        p = Path(cloud.source)
        if not p.is_absolute():
            # only the cloud given to serve may name a file relative to the server's
            # folder (resolved when the app started); an upload's name is a bare name
            # and no file here
            if cloud is not self.initial() or self.initial_path is None:
                return None
            p = self.initial_path
        return p if p.is_file() else None

    def shown_name(self, loaded: LoadedCloud, data: DataFolder) -> str:
        """How ``loaded``'s input is named in what leaves the server (a download): its
        path relative to the data folder ``data``, else its file name; never the
        server's absolute path (issue 36 item 18)."""
        source = self.input_file(loaded)
        if source is not None:
            return data.shown(source.resolve())
        cloud = (loaded.uncropped or loaded).cloud
        return Path(cloud.source).name if cloud.source else "cloud"

    def input_ref(self, path: Path, progress: Callable[[int, int], None] | None = None
                  ) -> InputRef:
        """Path, size and content hash of the input (hashed once per file version)."""
        st = path.stat()
        key = (str(path), st.st_size, st.st_mtime_ns)
        ref = self._hashes.get(key)
        if ref is None:
            ref = InputRef(path=str(path.resolve()), sha256=file_sha256(path, progress=progress),
                           size_bytes=st.st_size)
            self._hashes = {key: ref}
        return ref

    def say(self, text: str) -> None:
        """The Export folder's status line (Markdown; escape user text first)."""
        self.binding.write(self.status, content=text)


# ----------------------------------------------------------------------------- plans


@dataclass(frozen=True)
class Plan:
    """What one export writes."""

    name: str
    """File name offered to the browser (safe)."""
    estimate_bytes: float
    """Expected file size, bytes (checked against memory and disk before writing)."""
    write: Callable[[Path, Callable[[int, int], None]], None]
    """Write the whole file at the path (atomically), reporting progress(done, total)."""


def _stem(cloud: PointCloud) -> str:
    return safe_name(Path(cloud.source).stem if cloud.source else "cloud")


def _points_plan(e: ExportFeature, shown: Shown, fmt: str) -> Plan:
    from rough_viewer.grid.table import POINT_LENGTH_FIELDS, point_fields
    from rough_viewer.io.formats.las_out import LAS_SUFFIXES, copy_las_with_fields, write_las_points
    from rough_viewer.io.formats.ply import write_ply_fields

    assert shown.result is not None
    cloud, result = shown.loaded.cloud, shown.result
    source = e.input_file(shown.loaded)
    name = f"{_stem(cloud)}_{grid_tag(shown.loaded, result.grid.cell_size)}_points.{fmt}"
    n_rows = cloud.n + cloud.dropped_nonfinite

    extra = _extra_fields(e.host, result)

    def write(path: Path, progress: Callable[[int, int], None]) -> None:
        pf = point_fields(result, _trust_columns(shown, progress))
        pf = PointFields(fields=pf.fields + extra, point_cell=pf.point_cell)
        if fmt == "ply":
            # in the cloud's unit, as its cell table (a mm STL: mm)
            unit = cloud.source_unit
            write_ply_fields(path, cloud, pf, comments=[
                f"rough_viewer: {Path(cloud.source).name or 'cloud'}, "
                f"grid {shown.loaded.units.size_text(result.grid.cell_size)}, "
                f"axis {result.axis}, coordinates and roughness in {UNIT_LABELS[unit]}"],
                unit=unit, lengths=POINT_LENGTH_FIELDS)
        elif source is not None and source.suffix.lower() in LAS_SUFFIXES \
                and shown.loaded.file_rows:  # a campaign's overview or crop: its points
            # a crop: the file's rows it kept, every dimension of them
            copy_las_with_fields(source, path, cloud, pf, progress=progress,
                                 keep=shown.loaded.crop_mask)
        else:
            write_las_points(path, cloud, pf, progress=progress)

    per_point = BYTES_PER_POINT[fmt] + (TRUST_BYTES_PER_POINT[fmt]
                                        if _has_scanners(cloud) else 0.0)
    return Plan(name, n_rows * per_point, write)


def _has_scanners(cloud: PointCloud) -> bool:
    return cloud.scanner_positions is not None and cloud.scan_index is not None


def _trust_columns(shown: Shown, progress: Callable[[int, int], None]
                   ) -> dict[str, np.ndarray] | None:
    """The scanner columns of the shown grid, as the app shows them and ``compute``
    writes them (:meth:`rough_viewer.app.cloud.LoadedCloud.trust`, cached per grid;
    None without scanner positions)."""
    assert shown.result is not None
    trust = shown.loaded.trust(shown.result, progress=progress)
    return None if trust is None else trust.columns()


@runtime_checkable
class ExportPart(Protocol):
    """A feature whose results the cell table and the points downloads carry (the
    Zones tab's ``zone``, the Sets tab's ``set_id`` and ``plane_id``, as ``zones`` and
    ``sets`` write them)."""

    def table_columns(self, result: GridRoughness) -> dict[str, np.ndarray]:
        """Column name -> an (M,) array over every cell of ``result`` (the table keeps
        the rows of :func:`rough_viewer.grid.table.cell_columns`); empty when the
        feature shows nothing of ``result``."""
        ...

    def point_fields_of(self, result: GridRoughness) -> tuple[CellField, ...]:
        """The per-point fields of the points downloads (each point its cell's);
        empty when the feature shows nothing of ``result``."""
        ...


@runtime_checkable
class TablePart(Protocol):
    """A feature whose own tables the Export folder downloads as CSV (the Sets tab's
    Dips CSV, SETS.csv, PLANES.csv, JOINTS.csv)."""

    def download_tables(self) -> dict[str, str]:
        """Title in the Export folder's list -> the table's name (a file-name part)."""
        ...

    def download_table(self, name: str, result: GridRoughness, unit: str
                       ) -> dict[str, np.ndarray]:
        """Column -> values of table ``name`` of ``result``, lengths in ``unit``;
        InputError when the feature shows nothing of ``result``."""
        ...


def tab_tables(host: Host) -> dict[str, tuple[TablePart, str]]:
    """Every feature's downloadable table: title -> (feature, name), in mount order."""
    return {title: (f, name) for f in host.features() if isinstance(f, TablePart)
            for title, name in f.download_tables().items()}


def _tab_table_plan(e: ExportFeature, shown: Shown, title: str) -> Plan:
    from rough_viewer.io.table import write_table

    assert shown.result is not None
    chosen = tab_tables(e.host).get(title)
    if chosen is None:
        raise InputError("no such table to download")  # a hostile title: not echoed
    part, name = chosen
    unit = shown.loaded.units.unit
    columns = part.download_table(name, shown.result, unit)
    rows = len(next(iter(columns.values()))) if columns else 0
    file = (f"{_stem(shown.loaded.cloud)}_{grid_tag(shown.loaded, shown.result.grid.cell_size)}"
            f"_{safe_name(name, 'table')}.csv")

    def write(path: Path, progress: Callable[[int, int], None]) -> None:
        write_table(path, columns)

    return Plan(file, (rows + 1) * max(len(columns), 1) * BYTES_PER_FIELD, write)


def _extra_columns(host: Host, result: GridRoughness) -> dict[str, np.ndarray]:
    keep = result.n_points >= result.min_points  # the rows of cell_columns
    out: dict[str, np.ndarray] = {}
    for f in host.features():
        if isinstance(f, ExportPart):
            out.update({k: np.asarray(v)[keep] for k, v in f.table_columns(result).items()})
    return out


def _extra_fields(host: Host, result: GridRoughness) -> tuple[CellField, ...]:
    return tuple(c for f in host.features() if isinstance(f, ExportPart)
                 for c in f.point_fields_of(result))


def _table_plan(e: ExportFeature, shown: Shown, fmt: str) -> Plan:
    from rough_viewer.grid.table import cell_columns, table_metadata
    from rough_viewer.io.table import check_table_output, write_table

    assert shown.result is not None
    cloud, result = shown.loaded.cloud, shown.result
    name = f"{_stem(cloud)}_{grid_tag(shown.loaded, result.grid.cell_size)}_cells.{fmt}"
    check_table_output(name)
    unit = cloud.source_unit

    extra = _extra_columns(e.host, result)

    def write(path: Path, progress: Callable[[int, int], None]) -> None:
        write_table(path, {**cell_columns(result, unit=unit,
                                          trust=_trust_columns(shown, progress)), **extra},
                    metadata=table_metadata(result, Path(cloud.source).name, unit=unit),
                    unit=unit)

    per_cell = BYTES_PER_CELL[fmt] + (TRUST_BYTES_PER_CELL[fmt] if _has_scanners(cloud)
                                      else 0.0)
    return Plan(name, len(result.n_points) * per_cell, write)


def _figure_plan(shown: Shown, fmt: str, panel: str,
                 figures: tuple[tuple[str, Any], ...]) -> Plan:
    from rough_viewer.visual.export import check_figure_export, figure_bytes, write_figures_zip

    check_figure_export(fmt)  # type: ignore[arg-type]
    assert shown.result is not None
    base = f"{_stem(shown.loaded.cloud)}_{grid_tag(shown.loaded, shown.result.grid.cell_size)}"
    chosen = [(n, f) for n, f in figures if _has_data(f)]
    if panel != ALL_FIGURES:
        chosen = [(n, f) for n, f in chosen if n == panel]
        if not chosen:
            raise InputError(f"the {panel} panel has nothing to export yet")
        n, fig = chosen[0]

        def write_one(path: Path, progress: Callable[[int, int], None]) -> None:
            data = figure_bytes(fig, fmt)  # type: ignore[arg-type]
            write_atomic(path, lambda fh: fh.write(data), mode="wb")

        return Plan(f"{base}_{safe_name(n)}.{fmt}", FIGURE_BYTES, write_one)
    if not chosen:
        raise InputError("no panel has anything to export yet")

    def write_all(path: Path, progress: Callable[[int, int], None]) -> None:
        # one plotly.js in the ZIP for every HTML page (9 copies made a 40 MB ZIP)
        named = [(f"{base}_{safe_name(n)}", fig) for n, fig in chosen]
        write_atomic(path, lambda fh: write_figures_zip(fh, named, fmt,  # type: ignore[arg-type]
                                                        progress=progress), mode="wb")

    return Plan(f"{base}_figures_{fmt}.zip", FIGURE_BYTES + ZIP_FIGURE_BYTES * len(chosen),
                write_all)


def _report_plan(host: Host, e: ExportFeature, shown: Shown) -> Plan:
    from rough_viewer.report.export import ReportSettings, compute_report
    from rough_viewer.report.html import report_html

    s = shown.settings
    cloud = shown.loaded.cloud
    settings = ReportSettings(min_points=int(s.min_points), grid_sizes=(float(s.cell_size),),
                              axis=s.axis, threshold=float(s.threshold))
    settings.check()

    name = e.shown_name(shown.loaded, host.options.data)

    def write(path: Path, progress: Callable[[int, int], None]) -> None:
        report = replace(compute_report(cloud, settings, progress=progress), source=name)
        text = report_html(report)
        write_atomic(path, lambda fh: fh.write(text))

    return Plan(f"{_stem(cloud)}_{grid_tag(shown.loaded, s.cell_size)}_report.html",
                REPORT_BYTES, write)


def _view_plan(host: Host, e: ExportFeature, shown: Shown, camera: Camera | None, *,
               download: bool = True) -> Plan:
    """The view file; a ``download``'s input is named relative to the data folder
    (``serve --view VIEW --data-dir FOLDER`` finds it there by name and SHA-256), a
    view saved beside its input on the server keeps the absolute path."""
    source = e.input_file(shown.loaded)
    if source is None:
        raise InputError("a view records the input file on the server; this cloud was "
                         "uploaded, merged from several files or made in memory: put its "
                         "file in the data folder and load it from there")

    def write(path: Path, progress: Callable[[int, int], None]) -> None:
        ref = e.input_ref(source, progress)
        if download:
            ref = replace(ref, path=host.options.data.shown(Path(ref.path)))
        text = view_text(view_of(host, ref, camera=camera))
        write_atomic(path, lambda fh: fh.write(text))

    return Plan(f"{_stem(shown.loaded.cloud)}.view.json", 64 << 10, write)


# ----------------------------------------------------------------------------- jobs


def _targets(host: Host, client_id: int | None) -> list[viser.ClientHandle]:
    clients = host.clients()
    if client_id is None:
        return list(clients.values())
    client = clients.get(client_id)
    return [client] if client is not None else []


def _room(size: float, clients: int, what: str, folder: Path | None = None) -> None:
    """Refuse (InputError) a download the server cannot hold while sending, or whose
    temporary file the disk cannot take."""
    if size > MAX_DOWNLOAD_BYTES:
        raise InputError(f"{what} would be about {format_bytes(size)}, more than the "
                         f"{format_bytes(MAX_DOWNLOAD_BYTES)} a download may be; use "
                         "rough-viewer compute on the server")
    require(size * (1.0 + SEND_FACTOR * max(1, clients)), f"sending {what} "
            f"({format_bytes(size)}) to the browser",
            hint="use rough-viewer compute on the server, or a larger grid")
    if folder is not None and shutil.disk_usage(folder).free < size + DISK_MARGIN:
        raise InputError(f"not enough free disk space on the server for {what} "
                         f"({format_bytes(size)})")


@dataclass(frozen=True)
class ExportJob(Job[Host]):
    """Write one export into a private temporary folder and send it to a browser."""

    e: ExportFeature = field(compare=False)
    kind: ExportKind
    fmt: str
    client_id: int | None
    """The browser that asked (None: every connected browser)."""
    shown: Shown = field(compare=False)
    """What was shown when the button was pressed."""
    panel: str = ""
    figures: tuple[tuple[str, Any], ...] = field(default=(), compare=False)
    """(name, figure) of every panel when the button was pressed (figure exports)."""
    camera: Camera | None = None
    """The asking browser's camera (view exports)."""
    lane: ClassVar[str] = "export"
    keep_all: ClassVar[bool] = True

    @property
    def title(self) -> str:
        return f"export ({self.kind})"

    def absorb(self, newer: Job[Host]) -> Job[Host] | None:
        if isinstance(newer, ExportJob) and newer == self and newer.shown is self.shown:
            return self  # the same request twice while it waits: once is enough
        return None

    def plan(self, host: Host) -> Plan:
        if self.shown.result is None:
            raise InputError("nothing to export yet: the map is still being computed")
        if self.kind == "points":
            return _points_plan(self.e, self.shown, self.fmt)
        if self.kind == "table":
            return _table_plan(self.e, self.shown, self.fmt)
        if self.kind == "tab-table":
            return _tab_table_plan(self.e, self.shown, self.panel)
        if self.kind == "figure":
            return _figure_plan(self.shown, self.fmt, self.panel, self.figures)
        if self.kind == "report":
            return _report_plan(host, self.e, self.shown)
        return _view_plan(host, self.e, self.shown, self.camera)

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        m, t0 = self.e, time.perf_counter()
        paths: dict[str, str] = {}
        source = self.e.input_file(self.shown.loaded)
        if source is not None:
            paths[str(source)] = source.name
        try:
            plan = self.plan(ctx)
            targets = _targets(ctx, self.client_id)
            if not targets:
                m.say("The browser that asked has left; nothing sent.")
                return
            m.say(f"Preparing **{md(plan.name)}**…")
            m.binding.set(m.progress, 0.0)
            m.binding.write(m.progress, visible=True)
            _room(plan.estimate_bytes, len(targets), plan.name, Path(tempfile.gettempdir()))
            yield "check"
            with tempfile.TemporaryDirectory(prefix="rough-viewer-export-") as tmp:
                path = path_in_folder(tmp, plan.name)
                paths.update({str(path): plan.name, tmp: "the export folder"})

                def report(done: int, total: int) -> None:
                    if total > 0:
                        m.binding.set(m.progress, float(min(99.0, 100.0 * done / total)))

                plan.write(path, run.progress(report))
                yield "write"
                size = path.stat().st_size
                _room(size, len(targets), plan.name)
                data = path.read_bytes()
            yield "read"
            for client in _targets(ctx, self.client_id):
                client.send_file_download(plan.name, data, save_immediately=True)
            del data
            seconds = time.perf_counter() - t0
            m.sent.append(Sent(plan.name, size, len(targets), seconds))
            m.say(f"Sent **{md(plan.name)}** ({format_bytes(size)}, {seconds:.1f} s).")
            yield "send"
        except (InputError, MemoryError, OSError) as exc:
            what = "not enough memory" if isinstance(exc, MemoryError) else \
                public_message(str(exc), paths=paths)
            m.say(f"Export failed: {md(what)}")
            ctx.show_error(f"export: {what}", kept="Nothing was sent.")
        finally:
            m.binding.write(m.progress, visible=False)


@dataclass(frozen=True)
class SaveViewJob(Job[Host]):
    """Write the view beside the input, in the data folder (``serve --save-views``)."""

    e: ExportFeature = field(compare=False)
    camera: Camera | None = None
    lane: ClassVar[str] = "export"
    keep_all: ClassVar[bool] = True

    @property
    def title(self) -> str:
        return "saving the view"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        m = self.e
        shown = ctx.session.shown
        data = ctx.options.data
        source = m.input_file(shown.loaded)
        try:
            if not ctx.options.save_views:
                raise InputError("this server does not save views (start it with "
                                 "--save-views); download the view instead")
            if shown.result is None:
                raise InputError("nothing to save yet: the map is still being computed")
            plan = _view_plan(ctx, m, shown, self.camera, download=False)
            assert source is not None
            relative = source.resolve().parent.relative_to(data.root) \
                if source.resolve().is_relative_to(data.root) else None
            if relative is None:
                raise InputError(f"{source.name} is not in the data folder; the server "
                                 "only writes there")
            stem = plan.name.removesuffix(".view.json")
            path = None
            for k in range(1, 100):
                name = f"{stem}.view.json" if k == 1 else f"{stem}.view-{k}.json"
                candidate = path_in_folder(data.root, relative / name)
                if not candidate.exists() and not candidate.is_symlink():
                    path = check_output_path(candidate, force=False, inputs=[source])
                    break
            if path is None:
                raise InputError(f"{stem}.view-99.json exists: too many saved views")
            yield "check"
            plan.write(path, run.progress())
            m.say(f"Saved **{md(data.shown(path))}** in the data folder.")
            yield "write"
        except (InputError, OSError) as exc:
            what = public_message(str(exc), paths={str(data.root): "the data folder"})
            m.say(f"Saving the view failed: {md(what)}")
            ctx.show_error(f"save view: {what}", kept="Nothing was written.")


# ----------------------------------------------------------------------------- mount


def mount(host: Host) -> ExportFeature:
    """Add the Export folder (downloads, saved views); mount it last, so its figure
    list holds every other feature's panels."""
    gui = host.gui
    formats = figure_formats() if _has("kaleido") else ("html",)
    with host.folder("Export"):
        points_format = gui.add_dropdown(L_POINTS_FORMAT, POINTS_OPTIONS, initial_value="LAZ",
                                         hint="Every point with its cell's roughness: LAS/LAZ "
                                         "extra dimensions or PLY properties (CloudCompare "
                                         "scalar fields).")
        points = gui.add_button(L_POINTS)
        table_format = gui.add_dropdown(L_TABLE_FORMAT, ("CSV", "Parquet") if _has("pyarrow")
                                        else ("CSV",), initial_value="CSV",
                                        hint="One row per cell (rough-viewer compute --out).")
        table = gui.add_button(L_TABLE)
        tab_titles = tuple(tab_tables(host)) or ("none",)
        tab_table = gui.add_dropdown(L_TAB_TABLE_CHOICE, tab_titles, initial_value=tab_titles[0],
                                     hint="A tab's own table, as the command line writes "
                                     "it (the joint sets: tick Show sets first).")
        tab_table_button = gui.add_button(L_TAB_TABLE)
        figures = (*panel_titles(host), ALL_FIGURES)
        figure = gui.add_dropdown(L_FIGURE, figures, initial_value=ALL_FIGURES,
                                  hint="One panel of the app, or all of them in one ZIP.")
        figure_format = gui.add_dropdown(L_FIGURE_FORMAT, tuple(f.upper() for f in formats),
                                         initial_value="HTML")
        if "png" not in formats:
            gui.add_markdown(f"{md(FORMATS_NOTE)} (on the server).")
        figure_button = gui.add_button(L_FIGURE_BUTTON)
        report = gui.add_button(L_REPORT, hint="The page of rough-viewer report for the "
                                "shown grid, axis, minimum points and threshold.")
        view = gui.add_button(L_VIEW, hint="Reopen it with rough-viewer serve --view FILE.")
        save_view = gui.add_button(L_SAVE_VIEW, visible=host.options.save_views,
                                   hint="Write the view next to the input on the server.")
        status = gui.add_markdown("")
        progress = gui.add_progress_bar(0.0, visible=False, animated=True)
    whole = host.session.shown.loaded.uncropped or host.session.shown.loaded
    first = whole.cloud.source
    m = ExportFeature(host, points_format, points, table_format, table, tab_table,
                      tab_table_button, figure, figure_format,
                      figure_button, report, view, save_view, status, progress,
                      initial=weakref.ref(whole.cloud), initial_path=Path(first).resolve() if first else None)
    host.allow(points_format, points, table_format, table, tab_table, tab_table_button, figure,
               figure_format, figure_button, report, view, save_view)
    _wire(host, m)
    return m


def _wire(host: Host, m: ExportFeature) -> None:
    """Each button submits an export of what is shown when it is pressed."""
    m.points.on_click(lambda e: _export(host, m, e, "points", m.points_format.value))
    m.table.on_click(lambda e: _export(host, m, e, "table", m.table_format.value))
    m.tab_table_button.on_click(lambda e: _export(host, m, e, "tab-table", "csv",
                                                  panel=m.tab_table.value))
    m.figure_button.on_click(lambda e: _export(host, m, e, "figure", m.figure_format.value,
                                               panel=m.figure.value, figures=True))
    m.report.on_click(lambda e: _export(host, m, e, "report", "html"))
    m.view.on_click(lambda e: _export(host, m, e, "view", "json", camera=True))

    @m.save_view.on_click
    def _(event: viser.GuiEvent[viser.GuiButtonHandle]) -> None:
        host.submit(SaveViewJob(m, camera_of(host, event.client)))

    host.on_cloud(lambda: m.say(""))  # what was sent was of the cloud before


def _export(host: Host, m: ExportFeature, event: viser.GuiEvent[viser.GuiButtonHandle],
            kind: ExportKind, fmt: str, *, panel: str = "", figures: bool = False,
            camera: bool = False) -> None:
    """Submit the export a button press asks for, of what is shown now (the figure
    list's ``panel`` title becomes the panel's name; ``figures``: every panel's
    figure; ``camera``: the asking browser's)."""
    if kind == "figure":
        panel = panel_titles(host).get(panel, panel)
    host.submit(ExportJob(
        m, kind, fmt.lower(), event.client_id, host.session.shown, panel=panel,
        figures=tuple((n, h.figure) for n, h in panel_figures(host).items()) if figures else (),
        camera=camera_of(host, event.client) if camera else None))
