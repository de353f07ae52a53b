"""Issue 31 item 4 in headless Chromium: every figure and table of the Zones, Panels,
Profile and Sets tabs legible at 1600 x 1000 and 1280 x 800 (Directions has its own
test, test_directions_e2e.py). Each visible plot is measured: wide enough, not
squashed (its height against its width), and every title, label, header and cell
whole (nothing cut at the figure's edge or its cell's, nothing overlapping)."""

from __future__ import annotations

import re

import pytest

from rough_viewer.app.features.sets import L_ON as L_SETS_ON
from rough_viewer.app.features.sets import SetsFeature
from rough_viewer.app.features.zones import L_ON as L_ZONES_ON
from rough_viewer.app.features.zones import ZonesFeature
from rough_viewer.app.settings import MapSettings
from rough_viewer.io import PointCloud
from rough_viewer.synthetic.joints import generate_rock_mass
from tests.app import browser as b
from tests.app.test_joints_app import SMALL_ROCK_MASS
from tests.app.test_zones_mode import BANDS
from tests.helpers import PAPER_PRESETS, banded_face
from tests.visual import figure_browser as fb

pytestmark = pytest.mark.browser

VIEWPORTS = pytest.mark.parametrize("viewport", [b.WIDE, b.VIEWPORT],
                                    ids=["1600x1000", "1280x800"])
#: Narrowest plot accepted, px: issue 13's 480 at 1600 x 1000; the panel is narrower
#: in a 1280 px window.
MIN_WIDTH = {1600: 480, 1280: 380}


def _title(m: dict) -> str:
    return " ".join(t["text"] for t in m["texts"] if t["kind"] == "title")


def _in_view(m: dict) -> dict:
    """``m`` without the rows a scrolling table shows only in part or not at all (the
    Sets tab's plane table holds 50 rows and scrolls); every row above them must be
    whole."""
    def below(t: dict) -> bool:
        return (t["kind"] == "cell" and not t["header"] and t["view"] is not None
                and t["cell"]["y1"] > t["view"]["y1"] + 1)

    return dict(m, texts=[t for t in m["texts"] if not below(t)])


def measured(page, viewport: dict[str, int], where: str,
             scrolls: str | None = None) -> dict[str, dict]:
    """Every visible plot, by its title: wide enough and its text whole (asserted);
    the measures, for the caller's checks of height against width. A table whose title
    matches ``scrolls`` may hold rows below its visible area."""
    out = {}
    plots = page.locator(".js-plotly-plot")
    for i in range(plots.count()):
        if not plots.nth(i).is_visible():
            continue
        m = fb.measure(page, index=i)
        title = _title(m) or f"(untitled {i})"
        if scrolls and re.search(scrolls, title):
            n = len(m["texts"])
            m = _in_view(m)
            print(f"  {n - len(m['texts'])} cell texts of rows scrolled out of view")
        print(f"{where} {viewport['width']}x{viewport['height']}: {title[:50]!r} "
              f"{m['width']:.0f} x {m['height']:.0f} px")
        assert m["width"] >= MIN_WIDTH[viewport["width"]], (where, title, m["width"])
        assert fb.problems(m) == [], (where, title, fb.problems(m))
        out[title] = m
    return out


def _one(plots: dict[str, dict], pattern: str) -> dict:
    hits = [m for t, m in plots.items() if re.search(pattern, t)]
    assert len(hits) == 1, (pattern, list(plots))
    return hits[0]


def _headers(m: dict) -> list[str]:
    return [t["text"] for t in m["texts"] if t["kind"] == "cell" and t["header"]]


@VIEWPORTS
def test_zones_panels_and_profile_are_legible(chromium, viewport):
    import viser

    from rough_viewer.app.server import build_app

    pts, _ = banded_face(90.0, 180.0, BANDS, rough=0.01, n=40_000, seed=3)
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = build_app(server, PointCloud.from_xyz(pts, source="banded face"), prefetch=False,
                    presets=PAPER_PRESETS, settings=MapSettings(cell_size=0.25))
    app.map.threshold.value = 0.2
    assert app.wait_idle(60)
    with b.app_page(chromium, app, viewport=viewport, step_timeout_ms=60_000) as page:
        # Zones: the table of the three zones and their stereonet
        z = app.feature(ZonesFeature)
        page.get_by_role("tab", name="Zones").click()
        b.control(page, L_ZONES_ON).click()
        b.wait_until(lambda: z.zones is not None and not app.worker.busy, 60, "the zones")
        assert z.labelling.n_zones == 3
        page.locator(".js-plotly-plot .gtitle", has_text="3 zones").first.wait_for()
        page.locator(".js-plotly-plot .gtitle", has_text="Stereonet of").first.wait_for()
        plots = measured(page, viewport, "Zones")
        table = _one(plots, "3 zones")
        heads = _headers(table)
        assert len(heads) >= 5, heads
        rows = [t for t in table["texts"] if t["kind"] == "cell" and not t["header"]]
        assert len(rows) >= 3 * len(heads) - 3, [t["text"] for t in rows]
        net = _one(plots, "^Stereonet of")
        assert net["height"] >= 0.85 * net["width"], (net["width"], net["height"])
        # Panels: histogram, semivariograms, Table 1 and its trend
        page.get_by_role("tab", name="Panels").click()
        page.locator(".js-plotly-plot .gtitle", has_text="Roughness summary (Table 1)").first \
            .wait_for(timeout=120_000)
        plots = measured(page, viewport, "Panels")
        assert len(plots) == 4, list(plots)
        for pattern in ("^Normalised roughness histogram", "^Normalised semivariograms",
                        r"\(Table 1 trend\)"):  # plots, not strips
            m = _one(plots, pattern)
            assert m["height"] >= 0.6 * m["width"], (pattern, m["width"], m["height"])
        t1 = _one(plots, r"Table 1\)")
        assert len([t for t in t1["texts"] if t["kind"] == "cell"]) >= 4 * 8
        # Profile (its Directions folder has its own test)
        page.get_by_role("tab", name="Profile").click()
        measured(page, viewport, "Profile")


def test_the_sets_tables_are_legible_at_1280x800(chromium):
    import viser

    from rough_viewer.app.server import build_app

    g = 0.25
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = build_app(server, generate_rock_mass(SMALL_ROCK_MASS).cloud, prefetch=False,
                    variogram=False, presets=(g,), settings=MapSettings(cell_size=g))
    assert app.wait_idle(120)
    with b.app_page(chromium, app, viewport=b.VIEWPORT) as page:
        f = app.feature(SetsFeature)
        page.get_by_role("tab", name="Sets").click()
        b.control(page, L_SETS_ON).click()
        b.wait_until(lambda: f.sets is not None and not app.worker.busy, 60, "the sets")
        assert f.sets.n_sets == 3
        page.locator(".js-plotly-plot .gtitle", has_text="joints").first.wait_for()
        plots = measured(page, b.VIEWPORT, "Sets", scrolls=r"planes \(the first \d+ shown\)")
        net = _one(plots, "^3 joint sets: planar-cell poles")
        assert net["height"] >= 0.85 * net["width"], (net["width"], net["height"])
        sets = _one(plots, "^3 joint sets\u200b")
        joints = _one(plots, "^12 joints")
        for m in (sets, joints):
            assert len(_headers(m)) >= 5, _headers(m)
        n_rows = len([t for t in joints["texts"] if t["kind"] == "cell" and not t["header"]])
        assert n_rows >= 12, n_rows
