"""The Sets tables in headless Chromium at the width of an app panel (480 px and the
540 px of a 1600 x 1000 window) and of the report (1000 px): every header and cell
whole in its column and every row in view, also with map coordinates (UTM centroids
take two lines; issue 31 item 4, the Sets tab)."""

from __future__ import annotations

import pytest

from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.io import PointCloud
from rough_viewer.structure.sets import joint_sets
from rough_viewer.synthetic.joints import generate_rock_mass
from rough_viewer.visual.sets import joints_table_figure, planes_table_figure, sets_table_figure
from tests.app.test_joints_app import SMALL_ROCK_MASS
from tests.visual.figure_browser import measure, problems

pytestmark = pytest.mark.browser
WIDTHS = (480, 540, 1000)
#: A UTM-like origin (m): centroids such as "239163.87, 3765268.97, 333.53".
UTM = (239_000.0, 3_765_000.0, 300.0)


@pytest.fixture(scope="module")
def rendered(chromium):
    from plotly.offline import get_plotlyjs

    rm = generate_rock_mass(SMALL_ROCK_MASS)
    figures = {}
    for where, shift in (("local", (0.0, 0.0, 0.0)), ("utm", UTM)):
        cloud = PointCloud.from_xyz(rm.cloud.xyz() + shift)
        res = grid_roughness(cloud, 0.25, models=("odr",))
        sets = joint_sets(res, cloud)
        assert sets.joints.n_joints == 12
        kw = {"axis": res.axis, "n_points": res.n_points_total}
        figures[f"sets-{where}"] = sets_table_figure(sets, selected=1, **kw)
        figures[f"joints-{where}"] = joints_table_figure(sets, set_id=1, selected=2, **kw)
        # as many rows as its most height holds (longer tables scroll, by design)
        figures[f"planes-{where}"] = planes_table_figure(sets, set_id=1, max_rows=12, **kw)
    divs = [f'<div id="{name}-{w}" style="width:{w}px">' + fig.to_html(
            full_html=False, include_plotlyjs=False, default_width=f"{w}px",
            default_height=f"{int(fig.layout.height)}px") + "</div>"
            for w in WIDTHS for name, fig in figures.items()]
    ctx = chromium.new_context(viewport={"width": 1100, "height": 900}, offline=True)
    ctx.set_default_timeout(180_000)  # 18 figures on a loaded machine
    page = ctx.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.set_content(f"<html><head><script>{get_plotlyjs()}</script></head>"
                     f"<body style='margin:0'>{''.join(divs)}</body></html>")
    page.wait_for_function(f"document.querySelectorAll('.main-svg').length >= {len(divs)}")
    out = {key: measure(page, f"#{key} .js-plotly-plot")
           for key in (f"{n}-{w}" for w in WIDTHS for n in figures)}
    ctx.close()
    assert not errors, errors
    return out


@pytest.mark.parametrize("width", WIDTHS)
@pytest.mark.parametrize("name", ["sets-local", "joints-local", "planes-local", "sets-utm",
                                  "joints-utm", "planes-utm"])
def test_the_sets_tables_are_whole(rendered, name, width):
    m = rendered[f"{name}-{width}"]
    cells = [t for t in m["texts"] if t["kind"] == "cell"]
    assert len(cells) > 20  # the table is there, with its rows
    assert problems(m) == []
