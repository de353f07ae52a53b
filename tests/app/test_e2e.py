"""The app in headless Chromium: rendering, controls, panels and picking.

One server and one page for the module (page setup costs seconds under software
WebGL); each test sets the controls it relies on. ~120k points.
"""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.app.features.bias import BiasPanel
from rough_viewer.app.features.file import FileFeature
from rough_viewer.app.features.panels import PanelsFeature
from rough_viewer.app.features.profile import ProfileFeature
from rough_viewer.visual import colormaps
from tests.app import browser as b
from tests.helpers import face_cloud

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def live(chromium):
    import viser

    from rough_viewer.app.server import build_app

    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = build_app(server, face_cloud(120_000, seed=5))
    assert app.wait_idle(60)
    with b.app_page(chromium, app) as page:
        yield app, page


def _share_near(img, rgb, tol=40):
    d = np.abs(img.astype(int) - np.asarray(rgb, int)).sum(axis=2)
    return float(np.mean(d < tol))


def test_renders_coloured_points(live):
    app, page = live
    img = b.scene_pixels(page)
    coloured = b.coloured_mask(img)
    assert coloured.mean() > 0.1
    # the rendered colours are viridis colours of the map
    lut = colormaps.lut("viridis").astype(int)
    px = img[coloured].astype(int)
    dist = np.abs(px[:, None, :] - lut[None, ::8, :]).sum(axis=2).min(axis=1)
    assert np.median(dist) < 40
    assert len(app.server.get_clients()) == 1


def test_grid_and_model_change_colours_and_histogram(live):
    app, page = live
    before = b.scene_pixels(page)
    fine, coarse = app.map.grid.options[-2], app.map.grid.options[0]  # presets from the data
    page.get_by_role("tab", name="Panels").click()
    page.locator(".js-plotly-plot .gtitle", has_text=f"grid {fine} m").first.wait_for()
    page.get_by_role("tab", name="Map").click()
    b.choose(page, "Grid size (m)", coarse)
    b.wait_until(lambda: app.session.shown.settings.cell_size == float(coarse) and not app.worker.busy,
                 30, "the coarsest preset on the server")
    b.wait_pixels(page, lambda im: np.abs(im.astype(int) - before).sum(axis=2).mean() > 5,
                  60, "colours to change with the grid")
    page.get_by_role("tab", name="Panels").click()
    page.locator(".js-plotly-plot .gtitle", has_text=f"grid {coarse} m").first.wait_for()
    page.get_by_role("tab", name="Map").click()
    mid = b.scene_pixels(page)
    # OLS along y on a face looking along y barely differs from ODR; the OLS error
    # map (magma, its own sequential map) must look different
    b.choose(page, "Model", "OLS error e_ols")
    b.wait_until(lambda: app.session.shown.settings.model == "e_ols" and not app.worker.busy, 30, "e_ols")
    b.wait_pixels(page, lambda im: np.abs(im.astype(int) - mid).sum(axis=2).mean() > 10,
                  60, "colours to change with the model")
    names = [t.name for t in app.feature(PanelsFeature).variogram.figure.data]
    assert names[0] == "e_OLS"
    page.get_by_role("tab", name="Panels").click()
    page.locator(".js-plotly-plot .legendtext", has_text="e_OLS").first.wait_for()
    page.get_by_role("tab", name="Map").click()
    b.choose(page, "Model", "ODR")
    b.choose(page, "Grid size (m)", fine)
    b.wait_until(lambda: app.session.shown.settings.cell_size == float(fine)
                 and app.session.shown.settings.model == "odr" and not app.worker.busy, 30,
                 "back to ODR at the finest preset")


def test_threshold_switches_to_binary_view(live):
    app, page = live
    b.choose(page, "Display", "binary")
    b.type_number(page, "Threshold", "0.3")
    b.wait_until(lambda: app.session.shown.settings.display == "binary"
                 and app.session.shown.settings.threshold == 0.3 and not app.worker.busy, 30, "binary")
    lut = colormaps.lut("viridis")
    lo, hi = lut[0], lut[-1]

    def two_colours(img):
        # both colours present: a frame drawn at a threshold typed halfway ("0") is
        # nearly all one colour and must not end the wait
        c = b.coloured_mask(img)
        return (c.mean() > 0.05
                and (_share_near(img, lo) + _share_near(img, hi)) / c.mean() > 0.8
                and _share_near(img, lo) > 0.01 and _share_near(img, hi) > 0.01)

    img = b.wait_pixels(page, two_colours, 60, "two-colour binary view")
    assert _share_near(img, lo) > 0.01 and _share_near(img, hi) > 0.01
    b.choose(page, "Display", "continuous")
    b.wait_until(lambda: app.session.shown.settings.display == "continuous" and not app.worker.busy, 30)


def test_click_reports_cell(live):
    app, page = live
    img = b.to_array(b.png(page))
    h, w = img.shape[:2]
    mask = b.coloured_mask(img)
    mask[:, int(0.62 * w):] = False
    mask[: int(0.12 * h), :] = False
    ys, xs = np.nonzero(mask)
    y, x = int(np.median(ys)), int(np.median(xs))
    assert mask[y, x]
    page.mouse.click(x, y)
    info = b.wait_until(lambda: app.session.last_pick, 30, "a picked cell")
    page.get_by_text(f"Cell {info.ijk}").wait_for()
    res = app.session.shown.result
    assert info.theta["odr"] == pytest.approx(res.theta_odr[info.cell])
    assert info.n_points == res.n_points[info.cell]


def test_two_clicks_make_a_profile_with_fractal_dimension(live):
    app, page = live
    page.get_by_role("tab", name="Profile").click()
    m = app.feature(ProfileFeature)
    control = b.control(page, "Profile mode")
    control.click()
    b.wait_until(lambda: m.on.value, 20, "profile mode on")
    img = b.to_array(b.png(page))
    h, w = img.shape[:2]
    mask = b.coloured_mask(img)
    mask[:, int(0.62 * w):] = False
    mask[: int(0.12 * h), :] = False
    ys, xs = np.nonzero(mask)
    y = int(np.median(ys))
    row = np.flatnonzero(mask[y])
    # two points on one image row of the face, well apart
    # (coloured columns themselves: a percentile between two of them can fall in a gap)
    x0, x1 = int(row[int(0.3 * (len(row) - 1))]), int(row[int(0.7 * (len(row) - 1))])
    assert mask[y, x0] and mask[y, x1]
    try:
        page.mouse.click(x0, y)
        b.wait_until(lambda: m.start is not None, 30, "the profile start")
        page.mouse.click(x1, y)
        b.wait_until(lambda: len(m.items) == 1, 60, "a profile")
        a = m.items[0]
        d_raw, d_den = a.raw_fit.dimension, a.denoised_fit.dimension
        assert a.profile.length > 0.5 and a.profile.n_points > 50
        assert 1.0 < d_raw < 2.5 and np.isfinite(d_den)
        # the panel in the browser shows the values
        page.get_by_text(f"{d_raw:.3f}").first.wait_for()
        page.get_by_text(f"{d_den:.3f}").first.wait_for()
        # the note's text is set before the figure is built: wait for the figure too
        fig = b.wait_until(lambda: m.plot.figure if len(m.plot.figure.data) >= 2 else None, 30,
                           "the profile figure")
        assert len(fig.data) >= 2 and any(len(t.x) == len(a.profile.distance) for t in fig.data)
        page.locator(".js-plotly-plot:visible").first.wait_for()
    finally:
        m.on.value = False
        page.get_by_role("tab", name="Map").click()


def test_bias_predictions_are_reached_from_the_app(live):
    app, page = live
    page.get_by_role("tab", name="Bias").click()
    page.get_by_role("button", name="Predict bias", exact=True).click()
    page.get_by_text("ER / r =").first.wait_for(timeout=60_000)
    page.locator(".js-plotly-plot:visible").first.wait_for()
    # the result text is set before the curve figure and the panel's record
    b.wait_until(lambda: app.feature(BiasPanel).last is not None, 30, "the bias record")
    page.get_by_role("tab", name="Map").click()


HOSTILE_NAME = '<img src=x onerror="window.__xss=1"> **b** [a](javascript:window.__xss=3).xyz'
HOSTILE_PATH = "<iframe srcdoc='<script>parent.__xss=2</script>'></iframe>.las"


def test_hostile_file_name_and_path_render_as_text(live):
    """Runs last: it replaces the cloud."""
    app, page = live
    page.get_by_role("tab", name="File", exact=True).click()
    box = b.text_input(page, "File path")
    box.fill(HOSTILE_PATH)
    box.press("Enter")
    b.wait_until(lambda: app.feature(FileFeature).path.value == HOSTILE_PATH, 20, "the typed path")
    page.get_by_role("button", name="Load file", exact=True).click()
    page.get_by_text(f"file not found: {HOSTILE_PATH}").first.wait_for()
    xyz = face_cloud(3000, seed=8).xyz()
    data = "\n".join(f"{x:.4f} {y:.4f} {z:.4f}" for x, y, z in xyz).encode()
    page.locator("input[type=file]").set_input_files(
        files=[{"name": HOSTILE_NAME, "mimeType": "text/plain", "buffer": data}])
    b.wait_until(lambda: app.session.shown.loaded.n_total == 3000 and not app.worker.busy, 60,
                 "the uploaded cloud")
    page.get_by_text(HOSTILE_NAME).first.wait_for()  # the name, character for character
    assert page.evaluate("() => window.__xss") is None
    assert page.locator("img[src=x], iframe[srcdoc]").count() == 0
    assert page.locator("a[href^='javascript']").count() == 0
    page.screenshot(path="/tmp/rough-viewer-shots/hostile-names.png", timeout=60_000)
