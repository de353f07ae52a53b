"""The Lesson tab in headless Chromium: a person chooses a lesson, reads the step,
types the tool's number, presses Check and sees the verdict and the explanation;
Next step sets the next scene up; Download handout saves the page."""

from __future__ import annotations

import re

import numpy as np
import pytest

from rough_viewer.app.features import lesson as lm
from rough_viewer.app.features.lesson import LessonFeature
from tests.app import browser as b

pytestmark = pytest.mark.browser


def test_a_person_takes_the_turned_wall_lesson(chromium, cloud, tmp_path):
    import viser

    from rough_viewer.app.server import build_app

    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = build_app(server, cloud, prefetch=False)
    assert app.wait_idle(60)
    f = app.feature(LessonFeature)
    with b.app_page(chromium, app, viewport=b.WIDE, accept_downloads=True) as page:
        page.get_by_role("tab", name="Lesson").click()
        b.choose(page, lm.L_LESSON, "turned-wall")
        page.get_by_text("step 1 of 4", exact=False).wait_for()
        b.wait_until(lambda: f.waiting is None and app.session.shown.result is not None
                     and app.session.shown.loaded.label.startswith("outcrop-small")
                     and not app.worker.busy, 120, "the main face")
        assert app.wait_idle(120)
        res = app.session.shown.result
        ok = np.isfinite(res.theta_ols) & np.isfinite(res.theta_odr)
        ratio = float(np.median(res.theta_ols[ok] / res.theta_odr[ok]))
        box = b.control(page, lm.L_ANSWER)
        box.fill(f"{ratio:.3f}")
        box.press("Enter")
        page.get_by_role("button", name=lm.L_CHECK).click()
        page.get_by_text(re.compile(r"^Correct\.")).wait_for()
        assert page.get_by_text("the main face is square to y", exact=False).is_visible()
        page.screenshot(path=str(tmp_path / "lesson-checked.png"))
        page.get_by_role("button", name=lm.L_NEXT).click()
        page.get_by_text("step 2 of 4", exact=False).wait_for()
        b.wait_until(lambda: f.step == 1 and f.waiting is None and not app.worker.busy, 120,
                     "the turned wall")
        assert app.session.shown.loaded.n_total < 50_000  # the wall alone
        assert b.control(page, lm.L_ANSWER).input_value() in ("0", "0.0", "")
        with page.expect_download() as got:
            page.get_by_role("button", name=lm.L_HANDOUT).click()
        saved = tmp_path / "handout.html"
        got.value.save_as(saved)
        assert got.value.suggested_filename == "turned-wall_handout.html"
        text = saved.read_text()
        assert f"{ratio:.3f}"[:4] in text and "The turned wall" in text
