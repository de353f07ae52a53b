"""Issue 22 in headless Chromium at 1600 x 1000: a km-scale tile and a mm-scale joint
both open framed in the part of the window the control panel leaves free (a tile
3.4 x 4.6 km across opened blank: the camera stood beyond viser's far plane)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from tests.app import browser as b
from tests.helpers import face_cloud

pytestmark = pytest.mark.browser

#: The canvas left of the panel, and under it (fractions of the window's width).
PANEL_EDGE = 1.0 - (560 + 24) / 1600


def _tile(scale: float, *, flat: bool):
    """The test face scaled by ``scale`` (4 m -> 4 km at 1000), lying flat as an airborne
    tile or standing as a joint face."""
    base = face_cloud(30_000, seed=5)
    x, y, z = base.x * scale, base.y * scale, base.z * scale
    if flat:  # the face (x, z) becomes the ground (x, y), relief up
        x, y, z = x, z, y
    return replace(base, x=x + 500_000.0 * (scale > 10), y=y, z=z)


@pytest.mark.parametrize("scale, flat", [(1000.0, True), (0.005, False)],
                         ids=["4 km tile", "20 mm joint"])
def test_a_cloud_opens_framed_left_of_the_panel(chromium, scale, flat):
    import viser

    from rough_viewer.app.server import build_app

    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = build_app(server, _tile(scale, flat=flat), prefetch=False, variogram=False)
    assert app.wait_idle(120)
    with b.app_page(chromium, app, viewport=b.WIDE, coloured=0.02, timeout=120) as page:
        free = b.scene_pixels(page, 320, 200, region=(0.0, 0.0, PANEL_EDGE, 1.0))
        under = b.scene_pixels(page, 120, 200, region=(PANEL_EDGE + 0.02, 0.0, 1.0, 1.0))
        drawn = b.coloured_mask(free)
        ys, xs = np.nonzero(drawn)
        assert drawn.mean() > 0.02, drawn.mean()  # points are drawn (not blank)
        # the cloud spans most of the free part, and (almost) nothing hides under the panel
        span = max(np.ptp(xs) / drawn.shape[1], np.ptp(ys) / drawn.shape[0])
        assert span > 0.6, span
        assert b.coloured_mask(under).mean() < 0.01
