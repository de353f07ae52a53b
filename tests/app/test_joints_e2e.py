"""The Sets tab in headless Chromium on a small planted rock mass (issue 30 items 3 and
5): Show sets, Colour sets by joint (the rock takes the joints' colours, not only the
sets'), the tab's set table counts the planted joints, the Jv it shows is the one
``rough-viewer sets --summary-json`` writes for the same file, and the set and joint
tables are whole at 1600 x 1000 (issue 31 item 4)."""

from __future__ import annotations

import json
import os
import re

import numpy as np
import pytest

from rough_viewer.app.features.sets import L_COLOUR, L_ON, SetsFeature
from rough_viewer.app.settings import MapSettings
from rough_viewer.cli import main
from rough_viewer.io import load_points, write_las
from rough_viewer.synthetic.joints import generate_rock_mass
from rough_viewer.visual import colormaps
from rough_viewer.vocabulary import hex_to_rgb
from tests.app import browser as b
from tests.app.test_joints_app import PLANTED_JOINTS, SMALL_ROCK_MASS
from tests.visual import figure_browser as fb

pytestmark = pytest.mark.browser
G = 0.25

#: The set table's data as the browser's plotly holds it: header and the joints column.
_SET_TABLE_JS = r"""
() => {
  for (const gd of document.querySelectorAll('.js-plotly-plot')) {
    const t = gd.data && gd.data[0];
    const title = gd.layout && gd.layout.title && gd.layout.title.text || '';
    if (t && t.type === 'table' && /joint sets/.test(title))
      return {header: t.header.values, joints: t.cells.values[5]};
  }
  return null;
}
"""


@pytest.fixture(scope="module")
def live(chromium, tmp_path_factory):
    import viser

    from rough_viewer.app.server import build_app

    folder = tmp_path_factory.mktemp("joints")
    path = folder / "rock.laz"
    write_las(path, generate_rock_mass(SMALL_ROCK_MASS).cloud, scale=1e-4)
    summary = folder / "summary.json"
    assert main(["sets", str(path), "--grid", str(G), "--out", str(folder / "sets.csv"),
                 "--summary-json", str(summary), "--quiet"]) == 0
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = build_app(server, load_points(path), prefetch=False, variogram=False, presets=(G,),
                    settings=MapSettings(cell_size=G))
    assert app.wait_idle(120)
    with b.app_page(chromium, app, viewport=b.WIDE) as page:
        yield app, page, json.loads(summary.read_text())


def near(img: np.ndarray, rgb, tol: int = 30) -> np.ndarray:
    return np.abs(img.astype(int) - np.asarray(rgb, int)).sum(axis=2) < tol


def test_colour_by_joint_counts_the_planted_joints_and_shows_the_clis_jv(live):
    app, page, summary = live
    f = app.feature(SetsFeature)
    page.get_by_role("tab", name="Sets").click()
    b.control(page, L_ON).click()
    b.wait_until(lambda: f.sets is not None and not app.worker.busy, 60, "the sets")
    assert f.sets.n_sets == 3
    # by set: the rock shows the three set colours and none of the palette's others
    extra = [hex_to_rgb(colormaps.zone_colour(k)) for k in range(4, PLANTED_JOINTS + 1)]
    sets_rgb = [hex_to_rgb(colormaps.zone_colour(k)) for k in (1, 2, 3)]
    img = b.wait_pixels(page, lambda im: all(near(im, c).mean() > 0.002 for c in sets_rgb),
                        60, "the three set colours")
    assert sum(near(img, c).mean() > 0.002 for c in extra) == 0
    b.choose(page, L_COLOUR, "joint")
    b.wait_until(lambda: f.colour_by.value == "joint" and not app.worker.busy, 30,
                 "colour by joint on the server")
    # by joint: the colours of joints 4..12 appear on the rock
    img = b.wait_pixels(page, lambda im: sum(near(im, c).mean() > 0.002 for c in extra) >= 5,
                        60, "the joints' colours")
    # the set table the browser shows: its joints column holds the planted numbers
    table = page.wait_for_function(_SET_TABLE_JS, polling=200, timeout=30_000).json_value()
    assert table["header"][5] == "joints"
    joints = [int(v) for v in table["joints"]]
    assert sum(joints) == PLANTED_JOINTS
    assert sorted(joints) == sorted(s.joints for s in SMALL_ROCK_MASS.sets)
    assert joints == [int(s["joints"]) for s in summary["sets"]]  # the CLI's, set by set
    # the rock-mass line: Jv as the command line computed it for the same file
    line = page.get_by_text(re.compile(r"Jv [0-9.]+ joints per m3")).first
    line.wait_for()
    text = line.inner_text()
    assert text.startswith("Rock mass (from the joint spacing): ")
    jv = float(re.search(r"Jv ([0-9.]+) joints per m3", text).group(1))
    assert jv == float(f"{summary['jv']:.4g}")
    assert 4.0 < jv < 6.0  # planted: 1/0.5 + 1/0.8 + 1/0.6 = 4.92
    assert f"RQD estimate {summary['rqd_estimate']:.0f} %" in text and "an estimate" in text
    # the set and joint tables legible at 1600 x 1000 (issue 31 item 4): every header
    # and cell whole in its column, every row in view
    plots = page.locator(".js-plotly-plot")
    measured = {}
    for i in range(plots.count()):
        if plots.nth(i).is_visible():
            m = fb.measure(page, index=i)
            title = " ".join(t["text"] for t in m["texts"] if t["kind"] == "title")
            measured[title[:40]] = fb.problems(m)
    tables = {t: p for t, p in measured.items() if re.match("(3 joint sets\u200b|12 joints)", t)}
    assert len(tables) == 2, list(measured)
    assert all(p == [] for p in tables.values()), tables
    os.makedirs("/tmp/rough-viewer-shots", exist_ok=True)
    page.screenshot(path="/tmp/rough-viewer-shots/sets-by-joint.png", timeout=60_000)
