"""The Export folder: every download arrives in a (protocol-level) browser through
viser's file transfer, and its content is the app's result; a failed or refused
export sends nothing and leaves no temporary file (issue 15, items 4 and 5)."""

from __future__ import annotations

import csv
import errno
import io
import json
import tempfile
import zipfile
from pathlib import Path

import laspy
import numpy as np
import pytest

from rough_viewer.app.features import export as em
from rough_viewer.app.features.export import ExportFeature, panel_figures, safe_name
from rough_viewer.app.features.panels import PanelsFeature
from rough_viewer.app.settings import MapSettings
from rough_viewer.grid.table import cell_columns, point_fields
from rough_viewer.io import load_points
from rough_viewer.report.view import file_sha256, load_view
from tests.app.protocol import ProtocolClient
from tests.helpers import PAPER_PRESETS, face_cloud
from tests.io.test_las_out import GEOKEYS, _check_fields_equal_table, make_pf3

N_POINTS = 6000


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """An app on a LAS 1.2 PF 3 file with RGB, GPS time and a CRS, and a browser."""
    import viser

    from rough_viewer.app.server import build_app

    folder = tmp_path_factory.mktemp("export")
    path = folder / "scan site.las"  # a space: the download's name is made safe
    make_pf3(path, n=N_POINTS)
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = build_app(server, load_points(path), prefetch=False, data_dir=folder,
                    presets=PAPER_PRESETS, settings=MapSettings(cell_size=0.25))
    assert app.wait_idle(60)
    client = ProtocolClient(server.get_port())
    client.wait_for(lambda m: m.get("type") == "GuiButtonMessage"
                    and m["props"].get("label") == em.L_VIEW, what="the Export folder")
    yield app, client, path
    client.close()
    app.stop()
    server.stop()


def _download(client: ProtocolClient, app, label: str, name_part: str) -> tuple[str, bytes]:
    mark = len(client.messages)  # a file downloaded before does not count
    client.press(label)
    name, data = client.wait_download(name_part, since=mark)
    app.wait_idle(60)
    return name, data


def _said(client: ProtocolClient, text: str, what: str = "a message", *, after: int = 0) -> None:
    """Wait for a control created or updated with ``text`` in it (Markdown escaped),
    among the messages after the first ``after``."""
    def said(m) -> bool:
        return text in str(m.get("updates", m.get("props", ""))).replace("\\", "")

    client.wait_for(said, 30, what, since=after)


def _csv_rows(data: bytes) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(data.decode())))


def test_cell_table_csv_is_the_shown_grid(exported):
    app, client, _ = exported
    name, data = _download(client, app, em.L_TABLE, "_cells.csv")
    assert name == "scan_site_g0.25_cells.csv"
    rows = _csv_rows(data)
    want = cell_columns(app.session.shown.result)
    assert len(rows) == len(want["ix"]) > 100
    for col, values in want.items():
        got = np.array([float(r[col]) if r[col] else np.nan for r in rows])
        np.testing.assert_array_equal(got, values.astype(np.float64), err_msg=col)


def test_cell_table_parquet(exported):
    pq = pytest.importorskip("pyarrow.parquet")
    app, client, _ = exported
    client.set_value(em.L_TABLE_FORMAT, "Parquet")
    try:
        _, data = _download(client, app, em.L_TABLE, "_cells.parquet")
    finally:
        client.set_value(em.L_TABLE_FORMAT, "CSV")
    table = pq.read_table(io.BytesIO(data))
    want = cell_columns(app.session.shown.result)
    assert table.column_names == [*want, "unit_m"]  # the table says its unit: metres
    assert set(table.column("unit_m").to_pylist()) == {1.0}
    assert table.schema.metadata[b"rough_viewer.unit"] == b"m"
    for col, values in want.items():
        got = table.column(col).to_numpy(zero_copy_only=False).astype(np.float64)
        np.testing.assert_array_equal(np.nan_to_num(got, nan=-1.0),
                                      np.nan_to_num(values.astype(np.float64), nan=-1.0))
    assert table.schema.metadata[b"rough_viewer.grid_size_m"] == b"0.25"


def test_laz_download_is_the_input_with_its_roughness(exported):
    app, client, path = exported
    name, data = _download(client, app, em.L_POINTS, "_points.laz")
    assert name == "scan_site_g0.25_points.laz"
    out = laspy.read(io.BytesIO(data))
    src = laspy.read(path)
    # every point in order with every original dimension, same format, CRS kept
    assert out.header.point_format.id == 3 and len(out.points) == N_POINTS
    for dim in src.point_format.dimension_names:
        np.testing.assert_array_equal(out[dim], src[dim], err_msg=dim)
    np.testing.assert_array_equal(out.header.scales, src.header.scales)
    geo = [v for v in out.header.vlrs if v.record_id == 34735]
    assert len(geo) == 1 and geo[0].record_data_bytes() == GEOKEYS
    # the added dimensions equal the app's cell table (downloaded as CSV)
    _, table_bytes = _download(client, app, em.L_TABLE, "_cells.csv")
    table = {(int(r["ix"]), int(r["iy"]), int(r["iz"])): r for r in _csv_rows(table_bytes)}
    result = app.session.shown.result
    _check_fields_equal_table(out, table, grid=0.25, origin=result.grid.origin,
                              min_points=result.min_points,
                              xyz=app.session.shown.loaded.cloud.xyz())


def test_ply_download(exported):
    from plyfile import PlyData

    app, client, _ = exported
    client.set_value(em.L_POINTS_FORMAT, "PLY")
    try:
        _, data = _download(client, app, em.L_POINTS, "_points.ply")
    finally:
        client.set_value(em.L_POINTS_FORMAT, "LAZ")
    vertex = PlyData.read(io.BytesIO(data))["vertex"]
    cloud = app.session.shown.loaded.cloud
    np.testing.assert_array_equal(vertex["x"], cloud.x)
    np.testing.assert_array_equal(vertex["z"], cloud.z)
    fields = point_fields(app.session.shown.result)
    theta = fields.gather(0, cloud.n)[0]
    np.testing.assert_array_equal(vertex["theta_odr"], theta)


def test_figure_html_and_all_panels(exported):
    app, client, _ = exported
    client.set_value(em.L_FIGURE, "Histogram of normalised roughness")
    _, data = _download(client, app, em.L_FIGURE_BUTTON, "_histogram.html")
    html = data.decode()
    hist = app.feature(PanelsFeature).histogram.figure
    assert "plotly" in html.lower() and len(html) > 1_000_000  # plotly.js inlined: offline
    # the page draws the panel's own data (plotly's JSON of its traces, as embedded)
    from plotly.io.json import to_json_plotly

    assert to_json_plotly(hist.to_plotly_json()["data"]) in html
    assert "Normalised roughness histogram" in hist.layout.title.text and \
        "Normalised roughness histogram" in html
    client.set_value(em.L_FIGURE, em.ALL_FIGURES)
    _, data = _download(client, app, em.L_FIGURE_BUTTON, "_figures_html.zip")
    names = zipfile.ZipFile(io.BytesIO(data)).namelist()
    assert {n.rsplit("_", 1)[-1] for n in names} >= {"histogram.html", "variogram.html",
                                                      "summary.html", "bar.html"}
    # the profile panel is empty (no profile picked): left out
    assert not any("profile" in n for n in names)


def _server_paths(path: Path) -> list[bytes]:
    """The server's absolute paths a download could give away: the input's, its
    folder's (as given and resolved, also JSON-escaped) and the temporary folder's."""
    out = set()
    for p in (path, path.resolve(), path.parent, path.parent.resolve(),
              Path(tempfile.gettempdir()).resolve()):
        out.add(str(p).encode())
        out.add(json.dumps(str(p))[1:-1].encode())
    return sorted(out)


def test_report_download(exported):
    """The report names its input by its name in the data folder, not the server's
    absolute path (issue 36 item 18: downloads revealed it while errors hid it)."""
    app, client, path = exported
    _, data = _download(client, app, em.L_REPORT, "_report.html")
    html = data.decode()
    assert "<html" in html.lower() and "0.25" in html
    assert html.count("Plotly.newPlot") >= 3  # the report's figures, drawn offline
    assert "<td>input</td><td>scan site.las</td>" in html
    for secret in _server_paths(path):
        assert secret not in data, secret


def test_view_download_reopens(exported, tmp_path):
    app, client, path = exported
    name, data = _download(client, app, em.L_VIEW, ".view.json")
    assert name == "scan_site.view.json"
    saved = tmp_path / name
    saved.write_bytes(data)
    for secret in _server_paths(path):  # issue 36 item 18
        assert secret not in data, secret
    # the input is named in the data folder; a view opened without it does not find it
    assert load_view(saved).input_check.status == "missing"
    loaded = load_view(saved, data_folder=path.parent)
    view = loaded.view
    assert view.input.sha256 == file_sha256(path) and view.input.path == "scan site.las"
    assert loaded.input_check.status == "unchanged"
    assert loaded.input_check.path == path.parent / "scan site.las"
    s = app.session.shown.settings
    assert (view.cell_size_m, view.model, view.axis, view.min_points, view.threshold) == \
        (s.cell_size, s.model, s.axis, s.min_points, s.threshold)
    assert view.colour.colormap == s.colormap and view.colour.stretch == s.stretch
    # the camera of the browser that asked (the protocol client's), in the file frame
    assert view.camera is not None
    np.testing.assert_allclose(view.camera.position,
                               np.array([0.0, -3.0, 1.0]) + app.session.shown.loaded.origin)
    assert json.loads(data)["input"]["relative_path"] is None  # unknown on the browser's side


def _export_dirs() -> set[str]:
    return {p.name for p in Path(tempfile.gettempdir()).glob("rough-viewer-export-*")}


def test_a_failure_mid_write_sends_nothing_and_leaves_nothing(exported, monkeypatch):
    from rough_viewer.io import las_out
    from rough_viewer.io.output import write_path_atomic

    app, client, _ = exported
    written: list[Path] = []

    def half_then_full_disk(source, path, cloud, fields, **kw):
        def write_to(tmp: Path) -> None:
            tmp.write_bytes(b"LASF" + b"\0" * 100_000)  # half a file is on disk...
            written.append(tmp)
            raise OSError(errno.ENOSPC, "No space left on device")  # ...then the disk is full

        write_path_atomic(path, write_to)

    monkeypatch.setattr(las_out, "copy_las_with_fields", half_then_full_disk)
    before_dirs, starts = _export_dirs(), len(client.of_type("FileTransferStartDownload"))
    seen = len(client.messages)
    client.press(em.L_POINTS)
    mode = app.feature(ExportFeature)
    _said(client, "Export failed", "the failure", after=seen)
    app.wait_idle(30)
    assert written and not written[0].exists()
    assert app.host.errors[-1] == ("export: cannot write scan_site_g0.25_points.laz: no space "
                              "left on device")
    assert "/tmp" not in app.host.errors[-1] and "rough-viewer-export" not in app.host.errors[-1]
    assert "Export failed" in mode.status.content
    assert len(client.of_type("FileTransferStartDownload")) == starts  # nothing offered
    assert _export_dirs() <= before_dirs  # the private folder is gone


def test_a_download_that_cannot_fit_in_memory_is_refused(exported, monkeypatch):
    from rough_viewer import memory

    app, client, _ = exported
    starts = len(client.of_type("FileTransferStartDownload"))
    monkeypatch.setattr(memory, "available_bytes", lambda: 200_000.0)  # 200 kB free
    seen = len(client.messages)
    client.press(em.L_POINTS)
    _said(client, "Export failed", "the refusal", after=seen)
    app.wait_idle(30)
    assert "sending scan_site_g0.25_points.laz" in app.host.errors[-1]
    assert "of memory available" in app.host.errors[-1]
    assert len(client.of_type("FileTransferStartDownload")) == starts


def test_panels_are_named_by_their_features(exported):
    """Each feature names its own panels (no names from field names): the zones'
    are prefixed by the tab, and a name is safe as a file-name part."""
    app, _, _ = exported
    from rough_viewer.app.features.zones import ZonesFeature

    assert safe_name("../../etc/<x> y.laz") == "etc_x_y.laz"
    zones = app.feature(ZonesFeature).figures()
    assert set(zones) == {"zones_table", "zones_stereonet"}
    assert all(safe_name(n) == n for n in panel_figures(app.host))


def test_figure_dropdown_lists_every_panel(exported):
    app, _, _ = exported
    names = set(panel_figures(app.host))
    assert {"colour_bar", "histogram", "variogram", "summary", "profile", "bias"} <= names
    # the list shows each panel's title (no raw names); every title names one panel
    titles = em.panel_titles(app.host)
    assert set(titles.values()) == names and "colour_bar" not in titles
    assert {"Colour bar", "Semivariograms", "Table 1: summary statistics"} <= set(titles)
    assert set(app.feature(ExportFeature).figure.options) == set(titles) | {em.ALL_FIGURES}


def test_in_memory_cloud_points_and_no_view(server, tmp_path):
    """A cloud with no file on the server: LAS 1.4 from its coordinates; a view is
    refused with one line (it must name an input file)."""
    from rough_viewer.app.server import build_app

    cloud = face_cloud(5000, seed=4)
    app = build_app(server, cloud, prefetch=False, data_dir=tmp_path,
                    presets=PAPER_PRESETS, settings=MapSettings(cell_size=0.25))
    try:
        assert app.wait_idle(60)
        client = ProtocolClient(server.get_port())
        try:
            _, data = _download(client, app, em.L_POINTS, "_points.laz")
            las = laspy.read(io.BytesIO(data))
            assert las.header.version.minor == 4 and las.header.point_format.id == 6
            np.testing.assert_allclose(las.x, cloud.x, atol=1e-6)
            client.press(em.L_VIEW)
            _said(client, "a view records the input file", "the refusal")
            assert not any(n.endswith(".view.json") for n in client.downloads())
        finally:
            client.close()
    finally:
        app.stop()


@pytest.mark.skipif(not em._has("kaleido"), reason="kaleido not installed (rough_viewer[images])")
def test_png_and_svg_downloads(exported):
    """With kaleido (rough_viewer[images]) and a Chromium it can start: the panels as
    PNG (at twice the pixels of the figure's size) and as SVG."""
    from PIL import Image

    app, client, _ = exported
    mode = app.feature(ExportFeature)
    assert tuple(mode.figure_format.options) == ("HTML", "PNG", "SVG")
    client.set_value(em.L_FIGURE_FORMAT, "PNG")
    client.set_value(em.L_FIGURE, "Histogram of normalised roughness")
    name, data = _download(client, app, em.L_FIGURE_BUTTON, "_histogram.png")
    image = Image.open(io.BytesIO(data))
    assert image.format == "PNG" and image.size[0] >= 800
    pixels = np.asarray(image.convert("RGB"))
    assert len(np.unique(pixels.reshape(-1, 3), axis=0)) > 20  # bars, axes and text drawn
    client.set_value(em.L_FIGURE_FORMAT, "SVG")
    client.set_value(em.L_FIGURE, "Table 1: summary statistics")
    _, data = _download(client, app, em.L_FIGURE_BUTTON, "_summary.svg")
    svg = data.decode()
    assert svg.startswith("<svg") and "Table 1" in svg
    client.set_value(em.L_FIGURE_FORMAT, "PNG")  # every panel, one browser for all
    client.set_value(em.L_FIGURE, em.ALL_FIGURES)
    _, data = _download(client, app, em.L_FIGURE_BUTTON, "_figures_png.zip")
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        names = zf.namelist()
        assert {n.rsplit("_", 1)[-1] for n in names} >= {"histogram.png", "summary.png"}
        assert all(zf.read(n).startswith(b"\x89PNG\r\n\x1a\n") for n in names)
    client.set_value(em.L_FIGURE_FORMAT, "HTML")
    assert not any("export failed" in str(e) for e in app.host.errors)


def test_without_kaleido_the_folder_says_so(server, monkeypatch):
    from rough_viewer.app.server import build_app

    monkeypatch.setattr(em, "_has", lambda module: module != "kaleido" and em.importlib.util
                        .find_spec(module) is not None)
    app = build_app(server, face_cloud(3_000), prefetch=False, presets=PAPER_PRESETS)
    try:
        assert app.wait_idle(60)
        mode = app.feature(ExportFeature)
        assert tuple(mode.figure_format.options) == ("HTML",)
        client = ProtocolClient(server.get_port())
        try:
            _said(client, "need the optional package kaleido", "the kaleido note")
        finally:
            client.close()
    finally:
        app.stop()


def test_download_names_carry_the_grid_as_shown():
    """A millimetre scan's 2.5 mm grid is 'g2.5mm' in its downloads, not 'g0.0025'."""
    from dataclasses import replace

    from rough_viewer.app.cloud import LoadedCloud

    mm = LoadedCloud(replace(face_cloud(3_000), source_unit="mm"))
    assert em.grid_tag(mm, 0.0025) == "g2.5mm"
    ft = LoadedCloud(replace(face_cloud(3_000), source_unit="ft"))
    assert em.grid_tag(ft, 0.3048) == "g1ft"
    metres = LoadedCloud(face_cloud(3_000))
    assert em.grid_tag(metres, 0.25) == "g0.25"


def test_the_sent_note_goes_with_its_cloud(server):
    from rough_viewer.app.server import build_app

    app = build_app(server, face_cloud(3_000), prefetch=False, presets=PAPER_PRESETS)
    try:
        assert app.wait_idle(60)
        mode = app.feature(ExportFeature)
        mode.say("Sent **outcrop_g0.64_points.laz** (1 MB, 0.3 s).")
        app.load(cloud=face_cloud(4_000))
        assert app.wait_idle(60)
        assert mode.status.content == ""
    finally:
        app.stop()


def test_a_millimetre_cloud_exports_ply_and_table_in_millimetres(tmp_path):
    """Issue 31 item 9: the app's PLY of a mm scan was in metres while its cell table
    was in mm; both are in mm now, and each says so (the PLY's comment, the table's
    unit_m column)."""
    import viser
    from plyfile import PlyData

    from rough_viewer.app.server import build_app

    mm = face_cloud(4000, seed=3).xyz() - [500_000.0, 4_000_000.0, 0.0]
    path = tmp_path / "joint.npy"
    np.save(path, mm * 1000.0)  # a lab scan in millimetres
    cloud = load_points(path, units="mm")
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = build_app(server, cloud, prefetch=False, data_dir=tmp_path,
                    settings=MapSettings(cell_size=0.25))
    client = ProtocolClient(server.get_port())
    try:
        assert app.wait_idle(60)
        client.wait_for(lambda m: m.get("type") == "GuiButtonMessage"
                        and m["props"].get("label") == em.L_VIEW, what="the Export folder")
        client.set_value(em.L_POINTS_FORMAT, "PLY")
        name, data = _download(client, app, em.L_POINTS, "_points.ply")
        assert name == "joint_g250mm_points.ply"
        ply = PlyData.read(io.BytesIO(data))
        vertex = ply["vertex"]
        shown = app.session.shown.loaded.cloud
        np.testing.assert_allclose(vertex["x"], shown.x * 1000.0, rtol=1e-12)
        np.testing.assert_allclose(vertex["z"], shown.z * 1000.0, rtol=1e-12)
        theta = point_fields(app.session.shown.result).gather(0, shown.n)[0]
        np.testing.assert_allclose(vertex["theta_odr"], theta * 1000.0, rtol=1e-6)
        assert any(c.startswith("rough_viewer.unit mm (x, y, z, theta_odr") for c in ply.comments)
        _, table = _download(client, app, em.L_TABLE, "_cells.csv")
        rows = _csv_rows(table)
        want = cell_columns(app.session.shown.result)
        np.testing.assert_allclose([float(r["cx"]) for r in rows], want["cx"] * 1000.0,
                                   rtol=1e-12)
        assert {r["unit_m"] for r in rows} == {"0.001"}
    finally:
        client.close()
        app.stop()
        server.stop()
