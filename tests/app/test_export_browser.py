"""The Export folder in headless Chromium: a click downloads the file into the browser
(no link to click), and the downloaded files are the app's results."""

from __future__ import annotations

import io
import json
import os
from pathlib import Path

import laspy
import numpy as np
import pytest

from rough_viewer.app.features import export as em
from rough_viewer.app.settings import MapSettings
from rough_viewer.io import load_points
from rough_viewer.report.view import file_sha256
from tests.app import browser as b
from tests.helpers import PAPER_PRESETS
from tests.io.test_las_out import make_pf3

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def page_and_app(chromium, tmp_path_factory):
    import viser

    from rough_viewer.app.server import build_app

    folder = tmp_path_factory.mktemp("browser-export")
    scan = folder / "scan.las"
    make_pf3(scan, n=30_000)
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = build_app(server, load_points(scan), prefetch=False, data_dir=folder,
                    presets=PAPER_PRESETS, settings=MapSettings(cell_size=0.25))
    assert app.wait_idle(60)
    with b.app_page(chromium, app, accept_downloads=True) as page:
        yield page, app, scan


def _download(page, label: str, out: Path) -> tuple[str, bytes]:
    with page.expect_download(timeout=60_000) as info:
        page.get_by_role("button", name=label, exact=True).click()
    dl = info.value
    target = out / dl.suggested_filename
    dl.save_as(target)
    return dl.suggested_filename, target.read_bytes()


def test_points_download_in_the_browser(page_and_app, tmp_path):
    page, app, scan = page_and_app
    name, data = _download(page, em.L_POINTS, tmp_path)
    assert name == "scan_g0.25_points.laz"
    las = laspy.read(io.BytesIO(data))
    src = laspy.read(scan)
    np.testing.assert_array_equal(las.X, src.X)
    np.testing.assert_array_equal(las.gps_time, src.gps_time)
    cells = app.session.shown.result
    np.testing.assert_array_equal(
        las.theta_odr, cells.theta_odr.astype(np.float32)[cells.point_cell])
    shots = Path(os.environ.get("ROUGH_VIEWER_SHOTS", "/tmp/rough-viewer-shots"))
    shots.mkdir(parents=True, exist_ok=True)
    page.get_by_role("button", name=em.L_VIEW, exact=True).scroll_into_view_if_needed()
    page.screenshot(path=str(shots / "export-folder.png"), timeout=60_000)


def test_view_and_table_downloads_in_the_browser(page_and_app, tmp_path):
    page, app, scan = page_and_app
    b.choose(page, "Model", "OLS")
    b.wait_until(lambda: app.session.shown.settings.model == "ols", 60, "the OLS map")
    name, data = _download(page, em.L_VIEW, tmp_path)
    view = json.loads(data)
    assert name == "scan.view.json" and view["model"] == "ols"
    assert view["input"]["sha256"] == file_sha256(scan)
    # the camera is the browser's own (file frame: near the scan, not the local origin)
    pos = np.asarray(view["camera"]["position"])
    assert np.linalg.norm(pos - app.session.shown.loaded.origin) < 1e3
    name, data = _download(page, em.L_TABLE, tmp_path)
    assert name.endswith("_cells.csv")
    assert data.decode().splitlines()[0].startswith("ix,iy,iz,cx,cy,cz,n_points,theta_odr")
