"""Issue 23's crop and measure in the app, on a real viser server with websocket tabs:
a Shift-drag selects every point under the rectangle (against a brute-force pinhole
projection); keep/remove crops give the same cells as ``compute --crop``; exports,
saved views and undo follow the crop; the plane of a selected planted plane and a
cell's dip and dip direction are within 0.5 degrees; two clicks measure a distance."""

from __future__ import annotations

import csv
import json
import math

import laspy
import numpy as np
import pytest

from rough_viewer.app.features import export as em
from rough_viewer.app.features.crop import (
    HIGHLIGHT,
    L_APPLY,
    L_BOX,
    L_MODE,
    CropFeature,
    CropJob,
)
from rough_viewer.app.features.measure import LINE_DOTS, MeasureFeature
from rough_viewer.app.gate import open_server
from rough_viewer.app.server import build_app
from rough_viewer.app.settings import MapSettings
from rough_viewer.app.views import apply_view
from rough_viewer.cli import main
from rough_viewer.grid.table import cell_columns, table_metadata
from rough_viewer.io import load_points
from rough_viewer.io.crop import CropBox
from rough_viewer.io.table import write_table
from rough_viewer.report.view import load_view
from tests.app.browser import wait_until
from tests.app.protocol import join, pick, settle
from tests.helpers import UTM, face_cloud

GRID = 0.25


def brute_force_rect(xyz, eye, target, fov, width, height, a, b):
    """Which points a pinhole camera at ``eye`` looking at ``target`` (z up) sees
    inside the window rectangle from ``a`` to ``b`` (normalised, top left (0, 0))."""
    forward = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    rel = xyz - eye
    depth = rel @ forward
    f = (height / 2) / math.tan(fov / 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = f * (rel @ right) / depth + width / 2
        v = f * (rel @ down) / depth + height / 2
    u0, u1 = sorted((a[0] * width, b[0] * width))
    v0, v1 = sorted((a[1] * height, b[1] * height))
    return (depth > 0) & (u >= u0) & (u <= u1) & (v >= v0) & (v <= v1)


def rows_of(path):
    with open(path, newline="") as fh:
        return [r for r in csv.reader(fh) if r and not r[0].startswith("#")]


@pytest.fixture
def face_file(tmp_path):
    """The synthetic 4 m x 2 m face at UTM coordinates as a LAS file with intensity."""
    xyz = face_cloud(60_000, seed=4).xyz()
    header = laspy.LasHeader(point_format=1, version="1.2")
    header.scales = [1e-4, 1e-4, 1e-4]
    header.offsets = UTM
    las = laspy.LasData(header)
    las.x, las.y, las.z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    las.intensity = np.random.default_rng(4).integers(0, 65535, len(xyz), dtype=np.uint16)
    path = tmp_path / "face.las"
    las.write(path)
    return path


@pytest.fixture
def app_of(face_file):
    made = []

    def make(path=face_file, **kw):
        server, _ = open_server("127.0.0.1", 0, token=None, log=False)
        app = build_app(server, load_points(path), prefetch=False, variogram=False,
                        settings=MapSettings(cell_size=GRID), presets=(0.5, GRID),
                        data_dir=path.parent, **kw)
        assert app.wait_idle(120)
        made.append((app, server))
        return app, server

    yield make
    for app, server in made:
        app.stop()
        server.stop()


def test_a_shift_drag_selects_every_point_under_the_rectangle(app_of):
    app, server = app_of()
    f = app.host.feature(CropFeature)
    loaded = app.session.shown.loaded
    client = join(server)
    try:
        eye = UTM + [1.5, -2.5, 1.2] - loaded.origin
        target = UTM + [1.8, 0.0, 0.9] - loaded.origin
        client.look_from(eye, target, fov=0.9, width=1200, height=800)
        settle(app, lambda: np.allclose(
            server.get_clients()[client.client_id].camera.position, eye), "the camera")
        client.rect_select((0.35, 0.3), (0.6, 0.75))
        settle(app, lambda: f.selection is not None, "the selection")
        ref = brute_force_rect(loaded.cloud.xyz() - loaded.origin, eye, target, 0.9, 1200, 800,
                               (0.35, 0.3), (0.6, 0.75))
        assert 2_000 < ref.sum() < 30_000
        np.testing.assert_array_equal(f.selection.mask, ref)
        # drawn in magenta over the map, and its box is offered for a crop
        sel = np.flatnonzero(ref)[:500]
        assert (app.host.scene.colours(sel) == HIGHLIGHT).all()
        assert not (app.host.scene.colours(np.flatnonzero(~ref)[:500]) == HIGHLIGHT).all(axis=1).any()
        lo = loaded.cloud.xyz()[ref].min(axis=0)
        assert np.allclose([float(v) for v in f.box.value.split(",")][:3], lo, atol=1e-6)
        # a rectangle without Shift is no selection (viser's modifier filter)
        f_before = f.selection
        client.rect_select((0.0, 0.0), (1.0, 1.0), modifier=None)
        above = ((0.45, 0.0), (0.55, 0.01))  # above the face's top edge: no point there
        assert not brute_force_rect(loaded.cloud.xyz() - loaded.origin, eye, target, 0.9,
                                    1200, 800, *above).any()
        client.rect_select(*above)
        settle(app, lambda: f.selection is None, "the empty selection")
        assert f_before is not None and "No point in the rectangle" in f.note.content
    finally:
        client.close()


@pytest.mark.parametrize("mode", ["keep", "remove"])
def test_crop_in_the_app_and_compute_crop_give_the_same_cells(app_of, face_file, tmp_path, mode):
    app, server = app_of()
    f = app.host.feature(CropFeature)
    box = "512000.6,4169999,100.4,512002.9,4170001,101.6"
    client = join(server)
    try:  # typed and applied in a browser
        client.set_value(L_BOX, box)
        client.set_value(L_MODE, mode)
        settle(app, lambda: f.box.value == box and f.mode.value == mode, "the typed box")
        client.press(L_APPLY)
        settle(app, lambda: app.session.shown.loaded.crop is not None
               and app.session.shown.result is not None
               and app.session.shown.result.n_points_total == app.session.shown.loaded.cloud.n,
               "the crop")
    finally:
        client.close()
    shown = app.session.shown
    assert shown.loaded.crop.mode == mode
    mine = tmp_path / "app.csv"
    write_table(mine, cell_columns(shown.result, unit="m"),
                metadata=table_metadata(shown.result, face_file.name, unit="m"), unit="m")
    cli = tmp_path / "cli.csv"
    assert main(["compute", str(face_file), "--grid", str(GRID), "--crop", box,
                 "--crop-mode", mode, "--out", str(cli), "--quiet"]) == 0
    assert rows_of(mine) == rows_of(cli) and len(rows_of(cli)) > 20
    whole = load_points(face_file).xyz()
    lo, hi = _corners(box)
    inside = np.all((whole >= lo) & (whole <= hi), axis=1)
    assert shown.loaded.cloud.n == int(inside.sum() if mode == "keep" else (~inside).sum())
    assert "of 60,000 points are used" in f.status.content


def test_crop_to_the_exact_selection_and_undo(app_of):
    """Issue 31 item 16: a selection of 226,861 points cropped to the 239,125 of its
    bounding box; 'Crop to selection (exact points)' keeps exactly the selected points
    (against a brute-force pinhole projection), a second exact crop of the cropped
    cloud keeps its selection's points of the whole cloud, and Undo gives every point
    back."""
    from rough_viewer.app.features.crop import L_EXACT, L_UNDO

    app, server = app_of()
    f = app.host.feature(CropFeature)
    loaded = app.session.shown.loaded
    whole = loaded.cloud.xyz()
    client = join(server)
    try:
        eye = UTM + [1.5, -3.5, 1.8] - loaded.origin  # looking down on the face at a slant:
        target = UTM + [1.8, 0.0, 0.9] - loaded.origin  # the selection is no box
        client.look_from(eye, target, fov=0.9, width=1200, height=800)
        settle(app, lambda: np.allclose(
            server.get_clients()[client.client_id].camera.position, eye), "the camera")
        rect = ((0.3, 0.25), (0.55, 0.7))
        client.rect_select(*rect)
        settle(app, lambda: f.selection is not None, "the selection")
        ref = brute_force_rect(whole - loaded.origin, eye, target, 0.9, 1200, 800, *rect)
        np.testing.assert_array_equal(f.selection.mask, ref)
        lo, hi = whole[ref].min(axis=0), whole[ref].max(axis=0)
        in_box = np.all((whole >= lo) & (whole <= hi), axis=1)
        assert in_box.sum() > ref.sum() > 2_000  # the box holds more than the selection
        client.press(L_EXACT)
        settle(app, lambda: app.session.shown.loaded.crop_exact
               and app.session.shown.result is not None
               and app.session.shown.result.n_points_total == int(ref.sum()), "the exact crop")
        kept = app.session.shown.loaded
        assert kept.cloud.n == int(ref.sum())
        np.testing.assert_array_equal(kept.cloud.xyz(), whole[ref])
        np.testing.assert_array_equal(kept.crop_mask, ref)
        assert kept.crop == CropBox(tuple(lo), tuple(hi), "keep")  # what a view holds
        said = f.status.content.replace("\\", "")
        assert f"Cropped to the selection's {int(ref.sum()):,} points" in said
        assert "bounding box" in said
        # a second exact crop, of a selection on the cropped cloud: its points of the whole
        rect2 = ((0.35, 0.3), (0.45, 0.6))
        client.rect_select(*rect2)
        settle(app, lambda: f.selection is not None and f.selection.loaded is kept,
               "the second selection")
        ref2 = ref & brute_force_rect(whole - loaded.origin, eye, target, 0.9, 1200, 800, *rect2)
        assert 100 < ref2.sum() < ref.sum()
        client.press(L_EXACT)
        settle(app, lambda: app.session.shown.loaded is not kept
               and app.session.shown.loaded.cloud.n == int(ref2.sum())
               and app.session.shown.result is not None
               and app.session.shown.result.n_points_total == int(ref2.sum()), "the re-crop")
        np.testing.assert_array_equal(app.session.shown.loaded.crop_mask, ref2)
        client.press(L_UNDO)
        settle(app, lambda: app.session.shown.loaded.crop is None
               and app.session.shown.result is not None
               and app.session.shown.result.n_points_total == 60_000, "the undo")
        assert app.session.shown.loaded is loaded and list(app.host.errors) == []
    finally:
        client.close()


def _corners(text):
    v = [float(x) for x in text.split(",")]
    return tuple(v[:3]), tuple(v[3:])


def test_a_crop_is_exported_saved_and_undone(app_of, face_file, tmp_path):
    app, server = app_of()
    f = app.host.feature(CropFeature)
    box = CropBox((512000.5, 4169999.0, 100.5), (512002.0, 4170001.0, 101.5), "keep")
    app.host.submit(CropJob(f, box))
    assert app.wait_idle(120)
    kept = app.session.shown.loaded.cloud.n
    assert 0 < kept < 60_000
    client = join(server)
    try:
        # the LAS copy holds the kept points only, every dimension of them
        client.set_value(em.L_POINTS_FORMAT, "LAS")
        settle(app, lambda: app.host.feature(em.ExportFeature).points_format.value == "LAS",
               "the format")
        mark = len(client.messages)
        client.press(em.L_POINTS)
        _name, data = client.wait_download("_points.las", since=mark)
        out = tmp_path / "out.las"
        out.write_bytes(data)
        mark = len(client.messages)
        client.press(em.L_VIEW)
        _name, view_bytes = client.wait_download(".json", since=mark)
    finally:
        client.close()
    las = laspy.read(out)
    assert len(las.points) == kept
    src = laspy.read(face_file)
    lo, hi = np.array(box.lo), np.array(box.hi)
    xyz = np.column_stack([src.x, src.y, src.z])
    inside = np.all((xyz >= lo) & (xyz <= hi), axis=1)
    np.testing.assert_array_equal(np.asarray(las.intensity), np.asarray(src.intensity)[inside])
    np.testing.assert_allclose(las.x, src.x[inside])
    res = app.session.shown.result  # each kept point carries its cell's roughness
    np.testing.assert_allclose(np.asarray(las["theta_odr"], dtype=np.float64),
                               res.values("odr")[res.point_cell], rtol=1e-6, equal_nan=True)
    # a saved view holds the crop; compute --crop-file reads it
    view = tmp_path / "face.view.json"
    view.write_bytes(view_bytes)
    assert json.loads(view_bytes)["crop"] == {"min": list(box.lo), "max": list(box.hi),
                                              "mode": "keep"}
    assert main(["compute", str(face_file), "--grid", str(GRID), "--crop-file", str(view),
                 "--out", str(tmp_path / "c.csv"), "--quiet"]) == 0
    assert len(rows_of(tmp_path / "c.csv")) == app.session.shown.result.n_cells + 1
    # undo: every point again; restoring the view crops again
    app.host.submit(CropJob(f, None))
    assert app.wait_idle(120)
    assert app.session.shown.loaded.cloud.n == 60_000 and app.session.shown.loaded.crop is None
    apply_view(app.host, load_view(view, check=False).view)
    assert app.wait_idle(120)
    assert app.session.shown.loaded.crop == box and app.session.shown.loaded.cloud.n == kept
    assert app.session.shown.result is not None
    assert app.session.shown.result.n_points_total == kept


def test_the_plane_of_a_selected_planted_plane_and_a_cells_dip(app_of, tmp_path):
    """A plane dipping 35 degrees toward azimuth 120: the selection's ODR plane and a
    clicked cell's plane report it within 0.5 degrees."""
    rng = np.random.default_rng(7)
    n = 40_000
    dip, dd = math.radians(35.0), math.radians(120.0)
    down = np.array([math.sin(dd) * math.cos(dip), math.cos(dd) * math.cos(dip), -math.sin(dip)])
    strike = np.array([math.sin(dd - math.pi / 2), math.cos(dd - math.pi / 2), 0.0])
    s, t = rng.uniform(-1.5, 1.5, n), rng.uniform(-1.5, 1.5, n)
    normal = np.cross(strike, down)
    xyz = UTM + s[:, None] * strike + t[:, None] * down \
        + rng.normal(0, 0.001, n)[:, None] * normal
    path = tmp_path / "plane.npy"
    np.save(path, xyz)
    app, server = app_of(path)
    f = app.host.feature(CropFeature)
    loaded = app.session.shown.loaded
    client = join(server)
    try:
        eye = loaded.plane.centroid - loaded.origin + 6.0 * np.asarray(loaded.plane.normal)
        client.look_from(eye, loaded.plane.centroid - loaded.origin, fov=0.8)
        settle(app, lambda: np.allclose(
            server.get_clients()[client.client_id].camera.position, eye), "the camera")
        client.rect_select((0.3, 0.3), (0.7, 0.7))
        settle(app, lambda: f.selection is not None, "the selection")
    finally:
        client.close()
    plane = f.selection.plane
    assert plane is not None and plane.n_points > 1_000
    assert abs(plane.dip_deg - 35.0) < 0.5 and abs(plane.dip_direction_deg - 120.0) < 0.5
    assert plane.rms_m == pytest.approx(0.001, rel=0.1)
    assert "dip 35.0°, dip direction 120.0°" in f.note.content
    centre = xyz[0] - loaded.origin
    info = pick(app, centre + 0.2 * normal, -normal)
    assert info is not None
    assert abs(info.dip_deg - 35.0) < 0.5 and abs(info.dip_direction_deg - 120.0) < 0.5
    assert (f"plane dip {info.dip_deg:.1f}°, dip direction {info.dip_direction_deg:05.1f}°"
            in app.map.pick.content)


def test_two_clicks_in_measure_mode_give_the_distance(app_of):
    app, _server = app_of()
    m = app.host.feature(MeasureFeature)
    loaded = app.session.shown.loaded
    m.on.value = True
    xyz = loaded.cloud.xyz()
    a, b = xyz[100], xyz[30_000]
    for p in (a, b):
        assert pick(app, p - loaded.origin + [0.0, -0.5, 0.0], (0.0, 1.0, 0.0)) is None
    assert len(m.items) == 1
    _k, d, nodes = m.items[0]
    np.testing.assert_allclose(d.a, a, atol=0.01)
    np.testing.assert_allclose(d.b, b, atol=0.01)
    assert d.distance_m == pytest.approx(float(np.linalg.norm(d.b - d.a)))
    assert d.distance_m == pytest.approx(float(np.linalg.norm(b - a)), abs=0.02)
    assert f"D1**: {d.distance_m:.4g} m" in m.note.content and len(nodes) == 2 + LINE_DOTS
    assert app.session.last_pick is None  # the cell report waited
    m.clear.value = True
    wait_until(lambda: not m.items and not app.worker.busy, 30, "the measures cleared")


def test_a_crop_of_a_cloud_served_by_a_relative_path_saves_its_view(face_file, tmp_path,
                                                                     monkeypatch):
    """Issue 31 item 1: ``cd data && serve face.las``, crop, download the view: the view
    names the file (in the data folder), through the crop, its undo and a second crop."""
    monkeypatch.chdir(face_file.parent)
    cloud = load_points(face_file.name)
    assert cloud.source == "face.las"  # as typed
    server, _ = open_server("127.0.0.1", 0, token=None, log=False)
    app = build_app(server, cloud, prefetch=False, variogram=False,
                    settings=MapSettings(cell_size=GRID), presets=(0.5, GRID),
                    data_dir=face_file.parent)
    try:
        assert app.wait_idle(120)
        f = app.host.feature(CropFeature)
        boxes = [CropBox((512000.5, 4169999.0, 100.5), (512002.0, 4170001.0, 101.5), "keep"),
                 None, CropBox((512001.0, 4169999.0, 100.0), (512003.0, 4170001.0, 102.0),
                               "remove")]
        client = join(server)
        try:
            for box in boxes:
                app.host.submit(CropJob(f, box))
                assert app.wait_idle(120)
                assert app.session.shown.loaded.crop == box
                mark = len(client.messages)
                client.press(em.L_VIEW)
                _name, view_bytes = client.wait_download(".json", since=mark)
                data = json.loads(view_bytes)
                # named in the data folder, not by the server's absolute path (issue 36)
                assert data["input"]["path"] == "face.las"
                want = None if box is None else {"min": list(box.lo), "max": list(box.hi),
                                                 "mode": box.mode}
                assert data.get("crop") == want
                # the LAS copy of a crop is the file's kept rows (it needs the file too)
                assert app.host.feature(em.ExportFeature).input_file(
                    app.session.shown.loaded) == face_file.resolve()
        finally:
            client.close()
    finally:
        app.stop()
        server.stop()


def test_a_saved_view_keeps_the_selection(app_of, tmp_path):
    """Issue 31 item 11: views kept no selection; a saved view holds the camera and
    the rectangle that made it, and a fresh app given the view selects exactly the
    same points (against the brute-force pinhole projection)."""
    from rough_viewer.app.views import view_of
    from rough_viewer.report.view import InputRef, save_view

    app, server = app_of()
    f = app.host.feature(CropFeature)
    loaded = app.session.shown.loaded
    client = join(server)
    try:
        eye = UTM + [1.5, -2.5, 1.2] - loaded.origin
        target = UTM + [1.8, 0.0, 0.9] - loaded.origin
        client.look_from(eye, target, fov=0.9, width=1200, height=800)
        settle(app, lambda: np.allclose(
            server.get_clients()[client.client_id].camera.position, eye), "the camera")
        rect = ((0.35, 0.3), (0.6, 0.75))
        client.rect_select(*rect)
        settle(app, lambda: f.selection is not None, "the selection")
    finally:
        client.close()
    ref = brute_force_rect(loaded.cloud.xyz() - loaded.origin, eye, target, 0.9, 1200, 800,
                           *rect)
    assert ref.sum() > 2_000 and np.array_equal(f.selection.mask, ref)
    inp = InputRef(path=str(tmp_path / "face.las"), sha256="0" * 64, size_bytes=1)
    saved = load_view(save_view(tmp_path / "v.json", view_of(app.host, inp, camera=None)),
                      check=False).view
    assert saved.selection is not None and saved.selection.corner_a == rect[0]
    other, _ = app_of()
    apply_view(other.host, saved)
    assert other.wait_idle(120) and list(other.host.errors) == []
    g = other.host.feature(CropFeature)
    assert g.selection is not None
    np.testing.assert_array_equal(g.selection.mask, ref)
    assert f"**{int(ref.sum()):,} points selected**" in g.note.content
