"""Issue 13 in headless Chromium at 1600 x 1000 on the demo outcrop: panels a person
can read, colours that inform, roughness across scales on a click, and the scan's
own colours.

One server and one page for the module; the RGB test runs last (it loads another
file). The demo's 1.96 M points all count for roughness; 150,000 are drawn (software
WebGL is slow).
"""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.app.features.file import FileFeature
from rough_viewer.visual import colormaps
from tests.app import browser as b
from tests.app.protocol import shown_colours
from tests.helpers import face_cloud, write_las_with_colours
from tests.visual import figure_browser as fb

pytestmark = pytest.mark.browser

#: Narrowest plot accepted, px (issue 13: "at least ~500 px" at 1600 x 1000).
MIN_PLOT_WIDTH = 480


@pytest.fixture(scope="module")
def demo(chromium, tmp_path_factory):
    import viser

    from rough_viewer.app.server import build_app
    from rough_viewer.synthetic import demos

    data = tmp_path_factory.mktemp("data")
    write_las_with_colours(data / "colours.las", face_cloud(60_000, seed=11))
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = build_app(server, demos.load_demo("outcrop"), max_display=150_000, data_dir=data)
    assert app.wait_idle(300)
    with b.app_page(chromium, app, viewport=b.WIDE, coloured=0.03,
                    timeout=180, step_timeout_ms=60_000) as page:
        yield app, page


def _legible(page, where: str) -> None:
    """Every visible plot is wide enough and none has cut or overlapping text."""
    widths = b.plot_widths(page)
    assert widths and min(widths) >= MIN_PLOT_WIDTH, (where, widths)
    plots = page.locator(".js-plotly-plot")
    for i in range(plots.count()):
        if plots.nth(i).is_visible():
            m = fb.measure(page, index=i)
            assert fb.problems(m) == [], (where, i, fb.problems(m))


def test_every_panel_is_wide_and_its_text_whole(demo):
    app, page = demo
    _legible(page, "Map")  # the colour bar
    page.get_by_role("tab", name="Panels").click()
    page.locator(".js-plotly-plot .gtitle", has_text="Table 1 trend").first.wait_for()
    page.locator(".js-plotly-plot .gtitle", has_text="Roughness summary (Table 1)").first \
        .wait_for(timeout=180_000)  # after the semivariograms of 1.96 M points
    assert len(b.plot_widths(page)) == 5  # colour bar, histogram, semivariogram, Table 1, trend
    _legible(page, "Panels")
    # Table 1: every value whole (plotly cuts cell text that does not fit: "1.782e")
    table = page.locator(".js-plotly-plot", has=page.locator(".gtitle", has_text="Table 1)"))
    m = table.first.evaluate(fb.MEASURE_JS)
    cells = [t for t in m["texts"] if t["kind"] == "cell"]
    assert len(cells) >= 4 * 8 and fb.problems(m) == []
    page.get_by_role("tab", name="Profile").click()
    _legible(page, "Profile")
    page.get_by_role("tab", name="Bias").click()
    page.get_by_role("button", name="Predict bias", exact=True).click()
    page.get_by_text("ER / r =").first.wait_for(timeout=60_000)
    _legible(page, "Bias")
    page.get_by_role("tab", name="Map").click()


def test_no_colour_covers_half_of_the_drawn_demo_at_the_default_stretch(demo):
    app, page = demo
    assert app.session.shown.settings.stretch == colormaps.ROUGHNESS_STRETCH
    page.get_by_text("percentiles 2–98, log").first.wait_for()  # the colour bar says which
    rgba = b.canvas_rgba(page)
    share, n = b.drawn_colour_share(rgba, colormaps.lut("viridis"))
    sent = shown_colours(app)
    _, counts = np.unique(sent, axis=0, return_counts=True)
    print(f"\nlargest colour: {share:.3f} of {n:,} drawn cloud pixels, "
          f"{counts.max() / len(sent):.3f} of the {len(sent):,} colours sent")
    assert n > 20_000
    assert share < 0.5 and counts.max() / len(sent) < 0.5


def test_a_click_shows_the_point_across_the_preset_grids(demo):
    app, page = demo
    rgba = b.canvas_rgba(page)
    h, w = rgba.shape[:2]
    mask = rgba[..., 3] > 250
    mask[: int(0.15 * h)] = False
    ys, xs = np.nonzero(mask)
    y, x = int(np.median(ys)), int(np.median(xs))
    assert mask[y, x]
    before = len(app.map.pick_timings)
    page.mouse.click(x, y)
    b.wait_until(lambda: len(app.map.pick_timings) > before, 60, "a click report")
    # the point's own figure ("this point's cells"), not the placeholder before it
    # ("a clicked point's cells"), which is on the page all along
    plot = page.locator(".js-plotly-plot",
                        has=page.locator(".gtitle", has_text="this point's cells")).first
    plot.wait_for()
    presets = app.session.shown.loaded.presets
    traces = plot.locator(".scatterlayer .trace")
    b.wait_until(lambda: traces.count() == 3, 30, "the three traces")  # ODR, OLS, hybrid
    for k in range(3):
        assert traces.nth(k).locator(".points path").count() == len(presets)
    assert plot.bounding_box()["width"] >= MIN_PLOT_WIDTH
    assert fb.problems(plot.evaluate(fb.MEASURE_JS)) == []
    ticks = plot.locator(".xtick text").evaluate_all("els => els.map(e => e.textContent)")
    assert ticks == [f"{g:g}" for g in sorted(presets)]
    page.get_by_text(f"Cell {app.session.last_pick.ijk}").first.wait_for()

    def marker_drawn(img):  # the marker's black cross on its light label, over the points
        win = img[max(0, y - 20):y + 20, max(0, x - 20):x + 20]
        dark = (win[..., 3] > 250) & (win[..., :3].astype(int).sum(axis=2) < 80)
        light = (win[..., 3] > 250) & (win[..., :3].astype(int).min(axis=2) > 200)
        return dark.sum() > 10 and light.sum() > 50

    b.wait_until(lambda: marker_drawn(b.canvas_rgba(page)), 60, "the marker over the points")


def test_the_rgb_layer_of_a_file_with_colours(demo):
    """Runs last: it loads another file."""
    app, page = demo
    page.get_by_role("tab", name="File", exact=True).click()
    box = b.text_input(page, "File path")
    box.fill("colours.las")
    box.press("Enter")
    b.wait_until(lambda: app.feature(FileFeature).path.value == "colours.las", 20, "the typed path")
    page.get_by_role("button", name="Load file", exact=True).click()
    b.wait_until(lambda: app.session.shown.loaded.n_total == 60_000 and not app.worker.busy, 120,
                 "the LAS file")
    page.get_by_role("tab", name="Map").click()
    b.choose(page, "Colour by", "scan colours (RGB)")
    b.wait_until(lambda: app.session.shown.settings.layer == "rgb" and not app.worker.busy, 30, "RGB")

    def red_follows_x(rgba):
        on = rgba[..., 3] > 250
        if on.mean() < 0.05:
            return False
        ys, xs = np.nonzero(on)
        red = rgba[ys, xs, 0].astype(float)
        return np.corrcoef(xs, red)[0, 1] > 0.8

    end = __import__("time").time() + 60
    while not red_follows_x(b.canvas_rgba(page)):
        assert __import__("time").time() < end, "the scan's colours on the canvas"
    page.get_by_text("no colour scale").first.wait_for()
