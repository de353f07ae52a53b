"""Saved views in the app: a view saved from one app and opened by a second gives the
same settings, point colours, panels, profiles and camera; a moved or changed input
says so; a hostile view file is one line (issue 15, item 6)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from plotly.io.json import to_json_plotly

from rough_viewer.app.binding import assign
from rough_viewer.app.colouring import point_colours
from rough_viewer.app.features import export as em
from rough_viewer.app.features.export import ExportFeature, panel_figures
from rough_viewer.app.features.map import PickJob
from rough_viewer.app.features.profile import ProfileFeature
from rough_viewer.app.settings import MapSettings
from rough_viewer.app.views import apply_view, open_view
from rough_viewer.cli import main
from rough_viewer.io import load_points
from rough_viewer.report.view import (
    Camera,
    ColourSettings,
    ProfilePick,
    View,
    ZoneSettings,
    input_ref,
    load_view,
    save_view,
)
from rough_viewer.visual.colormaps import Stretch
from rough_viewer.vocabulary import InputError
from tests.app.browser import wait_until
from tests.app.protocol import ProtocolClient, shown_colours
from tests.helpers import PAPER_PRESETS
from tests.io.test_las_out import make_pf3

PANELS = ("colour_bar", "histogram", "variogram", "summary")


def _app(server, path: Path, settings: MapSettings | None = None):
    from rough_viewer.app.server import build_app

    app = build_app(server, load_points(path), settings=settings, prefetch=False,
                    presets=PAPER_PRESETS,
                    data_dir=path.parent)
    assert app.wait_idle(60)
    return app


def _reopen(server, view_file: Path, **kw):
    """What ``serve --view`` does, in process."""
    opened = open_view(view_file, **kw)
    app = _app(server, opened.input_path, opened.settings)
    apply_view(app.host, opened.view, source=str(view_file), notice=opened.notice)
    assert app.wait_idle(60)
    return app, opened


def _click_point(app, local: np.ndarray) -> None:
    """A click straight down onto a displayed point (the scan is a near-flat surface)."""
    o = local + np.array([0.0, 0.0, 20.0])
    app.submit(PickJob(app.map, (float(o[0]), float(o[1]), float(o[2])), (0.0, 0.0, -1.0)))


def _figure_json(handle) -> str:
    return to_json_plotly(handle.figure.to_plotly_json()["data"])


@pytest.fixture
def scan(tmp_path) -> Path:
    path = tmp_path / "site" / "scan.las"
    path.parent.mkdir()
    make_pf3(path, n=8000)
    return path


def test_view_saved_and_reopened_gives_the_same_picture(scan):
    import viser

    server1 = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    server2 = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app1 = _app(server1, scan)
    client = ProtocolClient(server1.get_port())
    try:
        g = app1.map  # a user's choices, through the controls
        assign(g.grid, "0.5")
        assign(g.model, "OLS")
        assign(g.display, "binary")
        assign(g.threshold, 0.3)
        assign(g.colormap, "cividis")
        pm = app1.feature(ProfileFeature)
        assign(pm.on, True)
        assign(pm.wavelet, "sym4")
        pts = app1.session.shown.loaded.display_points.astype(np.float64)
        a = pts[np.argmin(pts[:, 0] + pts[:, 1])]
        b = pts[np.argmax(pts[:, 0] + pts[:, 1])]
        _click_point(app1, 0.8 * a + 0.2 * b)
        _click_point(app1, 0.2 * a + 0.8 * b)
        assert app1.wait_idle(60) and len(pm.items) == 1
        client.wait_for(lambda m: m.get("type") == "GuiButtonMessage"
                        and m["props"].get("label") == em.L_VIEW, what="the Export folder")
        client.press(em.L_VIEW)
        name, data = client.wait_download(".view.json")
        view_file = scan.parent / name  # kept beside the scan
        view_file.write_bytes(data)

        app2, opened = _reopen(server2, view_file)
        assert opened.notice == "" and opened.loaded.input_check.status == "unchanged"
        s1, s2 = app1.session.shown.settings, app2.session.shown.settings
        assert s2 == s1
        assert (s1.cell_size, s1.model, s1.display, s1.threshold, s1.colormap) == \
            (0.5, "ols", "binary", 0.3, "cividis")
        # the same colours went to the scene, and they are the settings' colours
        c1, c2 = np.asarray(shown_colours(app1)), np.asarray(shown_colours(app2))
        np.testing.assert_array_equal(c2, c1)
        loaded = app2.session.shown.loaded
        np.testing.assert_array_equal(
            c2, point_colours(app2.session.shown.result, s1, loaded.display_index))
        assert len(np.unique(c2, axis=0)) <= 3  # binary: two colours and "no value"
        # the same panels
        for panel in PANELS:
            assert _figure_json(panel_figures(app2.host)[panel]) == \
                _figure_json(panel_figures(app1.host)[panel])
        # the profile was extracted and de-noised again with its settings
        pm2 = app2.feature(ProfileFeature)
        assert len(pm2.items) == 1 and pm2.wavelet.value == "sym4"
        p1, p2 = pm.items[0], pm2.items[0]
        np.testing.assert_array_equal(p2.profile.heights, p1.profile.heights)
        assert p2.denoised_fit.dimension == p1.denoised_fit.dimension
        assert _figure_json(pm2.plot) == _figure_json(pm.plot)
        # the camera of the browser that saved it is every browser's initial camera
        np.testing.assert_allclose(server2.initial_camera.position, [0.0, -3.0, 1.0], atol=1e-6)
        np.testing.assert_allclose(server2.initial_camera.look_at, [0.0, 0.0, 0.0], atol=1e-6)
        # and the reopened app saves the same view again
        assert app2.session.view.zones is None and app2.map.colormap.value == "cividis"
        app2.stop()
    finally:
        client.close()
        app1.stop()
        server1.stop()
        server2.stop()


def _view(scan: Path, **changes) -> View:
    base = View(input=input_ref(scan), cell_size_m=0.5, min_points=5, axis="z", model="hybrid",
                threshold=0.2, colour=ColourSettings("magma", "continuous",
                                                     Stretch("percentile", 5.0, 95.0, log=False)),
                zones=ZoneSettings(map="hybrid", connectivity="face", min_cells=4, selected=2))
    return base.with_(**changes) if changes else base


def _saved_again(app, server) -> dict:
    client = ProtocolClient(server.get_port())
    try:
        client.wait_for(lambda m: m.get("props", {}).get("label") == em.L_VIEW, what="Export")
        client.press(em.L_VIEW)
        _, data = client.wait_download(".view.json")
        return json.loads(data)
    finally:
        client.close()


def test_zones_restored_through_the_zones_mode(scan, server):
    from rough_viewer.app.features.zones import ZonesFeature

    view_file = save_view(scan.parent / "v.json", _view(scan))
    app, _ = _reopen(server, view_file)
    try:
        zm = app.feature(ZonesFeature)
        # the zones tab took the view's zones: a saved view gets them from the tab
        assert zm.active and zm.snapshot()["zones"] == zm.settings()
        z = zm.settings()
        assert (z.map, z.connectivity, z.min_cells) == ("hybrid", "face", 4)
        assert app.session.shown.settings.stretch == Stretch("percentile", 5.0, 95.0, log=False)
        again = _saved_again(app, server)
        assert {k: again["zones"][k] for k in ("map", "connectivity", "min_cells")} == \
            {"map": "hybrid", "connectivity": "face", "min_cells": 4}
        assert again["zones"]["selected"] in (2, None)  # 2 once labelled, if it exists
    finally:
        app.stop()


def test_zones_kept_as_data_without_a_zones_mode(scan, server, monkeypatch):
    from rough_viewer.app import server as server_module
    from rough_viewer.app.features import zones as zones_mode

    monkeypatch.setattr(server_module, "FEATURES", tuple(
        m for m in server_module.FEATURES if m is not zones_mode.mount))
    view_file = save_view(scan.parent / "v.json", _view(scan))
    app, _ = _reopen(server, view_file)
    try:
        assert app.session.view.zones == _view(scan).zones
        assert app.session.shown.settings.colormap == "magma"
        assert app.session.shown.settings.stretch == Stretch("percentile", 5.0, 95.0, log=False)
        again = _saved_again(app, server)
        assert again["zones"] == {"map": "hybrid", "connectivity": "face", "min_cells": 4,
                                  "selected": 2, "threshold_rule": "auto"}
        assert again["colour"]["stretch"] == "percentile" and again["colour"]["range"] == [5, 95]
        assert again["grid"] == {"cell_size_m": 0.5, "min_points": 5, "axis": "z"}
    finally:
        app.stop()


def test_moved_input_is_found_and_said(scan, server, tmp_path):
    save_view(scan.parent / "v.json", _view(scan))
    moved = tmp_path / "moved"
    shutil.move(scan.parent, moved)  # the whole folder went elsewhere
    app, opened = _reopen(server, moved / "v.json")
    try:
        assert opened.loaded.input_check.status == "moved"
        assert opened.input_path == (moved / "scan.las").resolve()
        assert app.host.note.visible and "input moved" in app.host.pinned
        assert app.session.shown.settings.model == "hybrid"
    finally:
        app.stop()


def test_changed_input_is_said(scan, server):
    save_view(scan.parent / "v.json", _view(scan))
    make_pf3(scan, n=8000, seed=9)  # same name and size, other content
    app, opened = _reopen(server, scan.parent / "v.json")
    try:
        assert opened.loaded.input_check.status == "changed"
        assert "has changed" in app.host.pinned
    finally:
        app.stop()


def test_input_outside_the_data_folder_opens_only_with_the_views_content(scan, tmp_path):
    """Issue 31: a browser download never sits beside the data, so --view refused every
    downloaded view. The input it names opens when its content is the view's (a note
    says so, and the data folder, what browsers may read, stays the view's folder); an
    input with another content outside the data folder is still refused."""
    elsewhere = tmp_path / "downloads"
    elsewhere.mkdir()
    view_file = save_view(elsewhere / "v.json", _view(scan))
    opened = open_view(view_file)
    assert opened.input_path == scan.resolve() and opened.data_dir == elsewhere.resolve()
    assert "lies outside the data folder" in opened.notice and "its content is the view's" \
        in opened.notice
    assert open_view(view_file, data_dir=scan.parent).input_path == scan.resolve()
    assert open_view(view_file, data_dir=scan.parent).notice == ""
    # an input given on the command line is the operator's choice; the hash compares it
    other = tmp_path / "other.las"
    make_pf3(other, n=500, seed=3)
    assert "not the file the view was saved from" in open_view(view_file, inputs=[other]).notice
    assert open_view(view_file, inputs=[scan]).notice == ""
    make_pf3(scan, n=8000, seed=9)  # same name, other content: not the view's input
    with pytest.raises(InputError, match="lies outside the data folder .* and is not the file"):
        open_view(view_file)


def test_a_downloaded_view_names_its_input_in_the_data_folder(scan, tmp_path):
    """Issue 36 item 18: a view downloaded from the app names its input relative to
    the server's data folder (no absolute path of the server); serve --view with
    --data-dir finds it there by name and SHA-256, as the same file, and without it
    says to pass --data-dir (no guess in the working folder)."""
    from dataclasses import replace

    downloads = tmp_path / "downloads"
    downloads.mkdir()
    view = _view(scan)
    view = replace(view, input=replace(view.input, path="site/scan.las"))
    view_file = save_view(downloads / "scan.view.json", view)
    assert str(tmp_path) not in view_file.read_text().replace(  # only the relative_path
        json.loads(view_file.read_text())["input"]["relative_path"], "")
    opened = open_view(view_file, data_dir=tmp_path)
    assert opened.input_path == scan.resolve() and opened.notice == ""
    assert opened.loaded.input_check.status == "unchanged"
    with pytest.raises(InputError, match="names site/scan.las in the data folder: pass --data-dir"):
        open_view(view_file)
    make_pf3(scan, n=8000, seed=9)  # same name, another content: said, inside the data folder
    opened = open_view(view_file, data_dir=tmp_path)
    assert opened.loaded.input_check.status == "changed" and "has changed" in opened.notice


def _hostile(scan: Path, tmp_path: Path, change) -> Path:
    doc = json.loads(save_view(scan.parent / "base.json", _view(scan,
                     profiles=(ProfilePick((1.0, 2.0, 3.0), (4.0, 5.0, 6.0)),),
                     camera=Camera((1.0, 2.0, 3.0), (0.0, 0.0, 0.0)))).read_text())
    (scan.parent / "base.json").unlink()
    change(doc)
    path = scan.parent / "hostile.json"
    path.write_text(doc if isinstance(doc, str) else json.dumps(doc))
    return path


HOSTILE = {
    "cell size a string": lambda d: d["grid"].update(cell_size_m="0.5; rm -rf /"),
    "huge cell size": lambda d: d["grid"].update(cell_size_m=1e300),
    "cell size beyond the app": lambda d: d["grid"].update(cell_size_m=50_000.0),
    "huge min points": lambda d: d["grid"].update(min_points=10**30),
    "huge camera": lambda d: d["camera"].update(position=[1e308, 0, 0]),
    "threshold a list": lambda d: d.update(threshold=[0.1]),
    "path traversal": lambda d: d["input"].update(path="../../../../../../etc/passwd"),
    "relative traversal": lambda d: d["input"].update(path="site/../../../../etc/hostname"),
    "absolute elsewhere": lambda d: d["input"].update(path="/etc/hostname"),
    "traversal beside": lambda d: d["input"].update(path="/nowhere/x.las",
                                                    relative_path="../../../../etc/hostname"),
    "NUL in path": lambda d: d["input"].update(path="scan\x00.las"),
    "many profiles": lambda d: d.update(profiles=[d["profiles"][0]] * 10_000),
    "script colormap": lambda d: d["colour"].update(colormap="<script>alert(1)</script>"),
    "unknown key": lambda d: d.update(__proto__={"x": 1}),
}


@pytest.mark.parametrize("case", list(HOSTILE), ids=list(HOSTILE))
def test_hostile_view_is_one_line(scan, tmp_path, capsys, case):
    path = _hostile(scan, tmp_path, HOSTILE[case])
    assert main(["serve", "--view", str(path), "--port", "0", "--no-block"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("rough-viewer: error: ") and "\n" not in err, err
    assert "Traceback" not in err and "<script>" not in err.split("got", 1)[0]


@pytest.mark.parametrize("text", ["[" * 100_000, '{"format": NaN}', "not json", "x" * (2 << 20)],
                         ids=["deep", "nan", "garbage", "huge"])
def test_malformed_view_file_is_one_line(tmp_path, capsys, text):
    path = tmp_path / "bad.json"
    path.write_text(text)
    assert main(["serve", "--view", str(path), "--port", "0", "--no-block"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"rough-viewer: error: view file {path}") and "\n" not in err


def test_view_file_round_trip_keeps_the_layer(scan, tmp_path):
    view = _view(scan, colour=ColourSettings("viridis", layer="intensity"))
    assert load_view(save_view(tmp_path / "l.json", view)).view.colour.layer == "intensity"


def test_save_view_beside_the_input_only_when_allowed(scan, server):
    import viser

    from rough_viewer.app.server import build_app

    app = _app(server, scan)
    client = ProtocolClient(server.get_port())
    try:
        mode = app.feature(ExportFeature)
        assert not mode.save_view.visible
        client.wait_for(lambda m: m.get("props", {}).get("label") == em.L_SAVE_VIEW, what="it")
        client.press(em.L_SAVE_VIEW)  # a page that presses the hidden button anyway
        wait_until(lambda: "does not save views" in mode.status.content, 20, "the refusal")
        assert not list(scan.parent.glob("*.json"))
    finally:
        client.close()
        app.stop()
    allowed = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)  # serve --save-views
    app = build_app(allowed, load_points(scan), prefetch=False, presets=PAPER_PRESETS,
                    data_dir=scan.parent, save_views=True)
    client = ProtocolClient(allowed.get_port())
    try:
        assert app.wait_idle(60)
        mode = app.feature(ExportFeature)
        assert mode.save_view.visible
        client.wait_for(lambda m: m.get("props", {}).get("label") == em.L_SAVE_VIEW, what="it")
        for expected in ("scan.view.json", "scan.view-2.json"):  # never replaces one
            client.press(em.L_SAVE_VIEW)
            wait_until(lambda e=expected: (scan.parent / e).is_file(), 20, expected)
        assert load_view(scan.parent / "scan.view.json").input_check.status == "unchanged"
        assert "Saved" in mode.status.content and str(scan.parent) not in mode.status.content
    finally:
        client.close()
        app.stop()
        allowed.stop()
