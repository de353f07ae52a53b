"""Issue 31 in headless Chromium: the Directions tab's rose and table readable at
1600 x 1000 and 1280 x 800 (the rose was a 519 x 104 px strip with its angle labels on
top of each other; the table's headers were clipped: "zimuth", "rofiles")."""

from __future__ import annotations

import pytest

from rough_viewer.app.features.profile.directions import L_MEASURE, L_STEP
from tests.app import browser as b
from tests.helpers import face_cloud
from tests.visual import figure_browser as fb

pytestmark = pytest.mark.browser


@pytest.mark.parametrize("viewport", [b.WIDE, b.VIEWPORT], ids=["1600x1000", "1280x800"])
def test_the_rose_and_its_table_are_readable(chromium, viewport):
    import viser

    from rough_viewer.app.server import build_app

    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = build_app(server, face_cloud(40_000, seed=4), max_display=40_000, variogram=False)
    assert app.wait_idle(120)
    with b.app_page(chromium, app, viewport=viewport, coloured=0.02, timeout=120,
                    step_timeout_ms=60_000) as page:
        page.get_by_role("tab", name="Profile").click()  # its Directions folder
        b.type_number(page, L_STEP, "30")
        page.get_by_role("button", name=L_MEASURE, exact=True).click()
        assert app.wait_idle(300)
        rose = page.locator(".js-plotly-plot", has=page.locator(".gtitle",
                                                                has_text="Roughness by direction"))
        rose.first.locator(".polarlayer").wait_for(timeout=120_000)
        page.locator(".js-plotly-plot .gtitle", has_text="table").first.wait_for()
        plots = page.locator(".js-plotly-plot")
        seen = 0
        for i in range(plots.count()):
            if not plots.nth(i).is_visible():
                continue
            m = fb.measure(page, index=i)
            titles = " ".join(t["text"] for t in m["texts"] if t["kind"] == "title")
            if "Roughness by direction" not in titles:
                continue
            seen += 1
            assert fb.problems(m) == [], (titles[:60], fb.problems(m))
            if ": table" not in titles:  # the rose: about as high as it is wide
                assert m["height"] >= 0.9 * m["width"], (m["width"], m["height"])
            else:  # every header whole, on its lines
                heads = [t for t in m["texts"] if t["kind"] == "cell" and t["header"]]
                assert len(heads) >= 8, [t["text"] for t in heads]
                texts = " | ".join(t["text"] for t in heads)
                assert "azi-muth °" in texts and "pro-files" in texts, texts
        assert seen == 2
