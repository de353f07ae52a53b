"""Issue 31 item 16 in headless Chromium: on the airborne LAZ eight notices (reader
warnings, outliers, the threshold, empty cells) took eight lines over the tabs and
pushed them down; they are one line now, the notes in a closed folder."""

from __future__ import annotations

from dataclasses import replace

import pytest

from rough_viewer.app.shell import NOTICE_FOLDER
from tests.app import browser as b
from tests.helpers import face_cloud

pytestmark = pytest.mark.browser

#: Eight long reader warnings, as an airborne LAZ gives them.
WARNINGS = tuple(f"warning {k}: " + "the file says something long about its points " * 4
                 for k in range(8))


def tab_top(chromium, warnings: tuple[str, ...]) -> tuple[float, float, int]:
    """The tabs' top edge (px) and the notice line's height (px) in a 1600 x 1000
    page, and how many notices the line names."""
    import viser

    from rough_viewer.app.server import build_app

    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    cloud = replace(face_cloud(20_000, seed=4), warnings=warnings)
    app = build_app(server, cloud, max_display=20_000, variogram=False)
    assert app.wait_idle(120)
    with b.app_page(chromium, app, viewport=b.WIDE, coloured=0.02, timeout=120) as page:
        tab = page.get_by_role("tab", name="Map", exact=True)
        tab.wait_for()
        top = tab.bounding_box()["y"]
        line = app.host.notice_line.content
        if not warnings:
            return top, 0.0, 0
        shown = page.get_by_text("notices", exact=False).first
        box = shown.bounding_box()
        # the notes are in the closed folder: not on screen until it is opened
        first = page.get_by_text("warning 0:", exact=False).first
        assert not first.is_visible()
        page.get_by_text(NOTICE_FOLDER, exact=True).last.click()  # the folder, not the line
        first.wait_for(state="visible")
        return top, box["height"], int(line.split("**")[1].split()[0])


def test_eight_notices_take_one_line_over_the_tabs(chromium):
    plain, _, _ = tab_top(chromium, ())
    top, line_height, n = tab_top(chromium, WARNINGS)
    assert n == 8
    assert line_height < 30  # one line of text
    # the line and the folder's closed header: the tabs move by at most ~3 lines
    assert top - plain < 90, (plain, top)
