"""The Sets tab in headless Chromium flags a set parallel to the exposure face
(issue 31 item 2): the warning line shows under the status and the set table's row
carries its marker."""

from __future__ import annotations

import pytest

from rough_viewer.app.features.sets import SetsFeature
from rough_viewer.app.settings import MapSettings
from rough_viewer.io import PointCloud
from tests.app import browser as b
from tests.structure.test_face import hillside

pytestmark = pytest.mark.browser


def test_the_hillside_set_is_flagged_in_the_tab(chromium, tmp_path):
    import viser

    from rough_viewer.app.server import build_app

    pts = hillside(size=40.0, step=0.5)
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = build_app(server, PointCloud.from_xyz(pts, source="hillside"), prefetch=False,
                    presets=(2.0,), settings=MapSettings(cell_size=2.0))
    assert app.wait_idle(60)
    f = app.feature(SetsFeature)
    with b.app_page(chromium, app) as page:
        page.get_by_role("tab", name="Sets").click()
        b.control(page, "Show sets").click()
        b.wait_until(lambda: f.sets is not None and not app.worker.busy, 60, "the sets")
        assert f.sets is not None and f.sets.face_parallel.tolist() == [True]
        warning = page.get_by_text("lies parallel to the exposure face").first
        warning.wait_for()
        assert "its spacing is not a joint spacing" in warning.inner_text()
        title = page.locator(".js-plotly-plot .gtitle", has_text="exposure face").first
        title.wait_for()
        assert "1 joint set (⚠ 1: exposure face)" in title.text_content()
        table = page.locator(".js-plotly-plot", has_text="1 joint set (⚠ 1").first
        table.wait_for()
        table.scroll_into_view_if_needed()
        page.screenshot(path=str(tmp_path / "sets_face.png"))  # to look at
        texts = table.locator(".cell-text").all_text_contents()
        texts = [t.replace(" ", "") for t in texts]  # a cell's lines join without a space
        assert "1⚠" in texts and "1.75⚠" in texts  # the set's id and its spacing, marked
        assert f"{f.sets.face_angle_deg[0]:.1f}⚠face" in texts
