"""The Zones tab in headless Chromium: the zones render in their colours, a click on
a zone selects it (highlighted on the rock, its numbers and table shown)."""

from __future__ import annotations

import os

import numpy as np
import pytest

from rough_viewer.app.features.zones import HIGHLIGHT_RGB, ZonesFeature
from rough_viewer.app.settings import MapSettings
from rough_viewer.io import PointCloud
from rough_viewer.visual import colormaps
from rough_viewer.vocabulary import hex_to_rgb
from tests.app import browser as b
from tests.app.test_zones_mode import BANDS
from tests.helpers import PAPER_PRESETS, banded_face

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def live(chromium):
    import viser

    from rough_viewer.app.server import build_app

    pts, _ = banded_face(90.0, 180.0, BANDS, rough=0.01, n=100_000, seed=3)
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = build_app(server, PointCloud.from_xyz(pts, source="banded face"), prefetch=False,
                    presets=PAPER_PRESETS, settings=MapSettings(cell_size=0.25))
    app.map.threshold.value = 0.2
    assert app.wait_idle(60)
    with b.app_page(chromium, app) as page:
        yield app, page


def near(img: np.ndarray, rgb, tol: int = 40) -> np.ndarray:
    return np.abs(img.astype(int) - np.asarray(rgb, int)).sum(axis=2) < tol


def test_zones_render_and_a_click_selects_one(live):
    app, page = live
    m = app.feature(ZonesFeature)
    page.get_by_role("tab", name="Zones").click()
    b.control(page, "Show zones").click()
    b.wait_until(lambda: m.zones is not None and not app.worker.busy, 30, "zones on the server")
    assert m.labelling.n_zones == 3
    zone_rgb = [hex_to_rgb(colormaps.zone_colour(k)) for k in (1, 2, 3)]
    # every zone shows on the rock in its colour, the rest light grey (no viridis left)
    viridis = colormaps.lut("viridis").astype(int)[::16]
    # the zone cloud is added, then the map's cloud hidden: wait for both
    img = b.wait_pixels(page, lambda im: all(near(im, c).mean() > 0.003 for c in zone_rgb)
                        and near(im, viridis[-1]).mean() < 0.001, 60, "the three zone colours")
    coloured = b.coloured_mask(img) & ~np.any([near(img, c) for c in zone_rgb], axis=0)
    assert near(img, viridis[-1]).mean() < 0.001 and coloured.mean() < 0.01
    page.get_by_text("3 zones").first.wait_for()
    page.locator(".js-plotly-plot .gtitle", has_text="3 zones").first.wait_for()
    # click the middle of zone 2 on the canvas
    full = b.to_array(b.png(page))
    h, w = full.shape[:2]
    mask = near(full, zone_rgb[1], 12)
    mask[:, int(0.62 * w):] = False
    mask[: int(0.12 * h), :] = False
    ys, xs = np.nonzero(mask)
    k = int(np.argmin((ys - np.median(ys)) ** 2 + (xs - np.median(xs)) ** 2))
    page.mouse.click(int(xs[k]), int(ys[k]))
    b.wait_until(lambda: m.labelling.zone_at(m.anchor) == 2 and not app.worker.busy, 30,
                 "zone 2 selected")
    page.get_by_text("of 3").first.wait_for()  # "Zone 2 of 3" with its numbers
    page.get_by_text(f"{int(m.zones.cells[1]):,} / {int(m.zones.points[1]):,}").wait_for()
    # highlighted on the rock: magenta where zone 2 was
    shot = b.wait_pixels(page, lambda im: near(im, HIGHLIGHT_RGB).mean() > 0.002, 60,
                         "the highlight")
    before = near(img, zone_rgb[1])
    after = near(shot, HIGHLIGHT_RGB)
    assert (after & before).sum() > 0.5 * after.sum()
    os.makedirs("/tmp/rough-viewer-shots", exist_ok=True)
    page.screenshot(path="/tmp/rough-viewer-shots/zones-selected.png", timeout=60_000)
