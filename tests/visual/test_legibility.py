"""The panel figures in headless Chromium at the width of an app panel (480 px) and of
the report (1000 px): no text cut at the figure's edge or in a table cell, no title,
axis title, tick label or legend on top of another (issue 13)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from rough_viewer.grid.roughness import coarsen_prepared, grid_roughness, prepare_grid
from rough_viewer.grid.scales import face_scales, point_scales
from rough_viewer.grid.summary import histogram, normalise, summarise
from rough_viewer.grid.variogram import semivariogram
from rough_viewer.profiles.extraction import extract_profile
from rough_viewer.profiles.fractal import roughness_length
from rough_viewer.profiles.wavelets import denoise_result
from rough_viewer.synthetic.demos import load_demo
from rough_viewer.visual import colormaps
from rough_viewer.visual.app import colour_scale_figure
from rough_viewer.visual.grid import histogram_figure, summary_table_figure, variogram_figure
from rough_viewer.visual.profiles import profile_figure
from rough_viewer.visual.scales import face_scales_figure, point_scales_figure
from rough_viewer.vocabulary import MAPS
from tests.visual.figure_browser import measure, problems

pytestmark = pytest.mark.browser


def _figures():
    cloud = load_demo("outcrop-small")
    fine = prepare_grid(cloud, 0.125)
    grids = [fine] + [coarsen_prepared(fine, k) for k in (2, 4, 8)]
    results = [grid_roughness(cloud, p.cell_size, prepared=p) for p in grids]
    res = results[1]  # 0.25 m
    kw = {"grid_size": 0.25, "axis": res.axis, "n_points": cloud.n}
    xyz = cloud.xyz()
    lo, hi = xyz.min(axis=0), xyz.max(axis=0)
    mid = 0.5 * (lo + hi)
    analyses = []
    for dz in (-0.2, 0.2):
        a = np.array([lo[0] + 0.3, mid[1], mid[2] + dz])
        z = np.array([hi[0] - 0.3, mid[1], mid[2] + dz])
        p = extract_profile(xyz, a, z)
        d = denoise_result(p.heights)
        analyses.append(SimpleNamespace(profile=p, denoised=d,
                                        raw_fit=roughness_length(p.heights, p.spacing),
                                        denoised_fit=roughness_length(d.heights, p.spacing)))
    e_ols = res.values("e_ols")
    return {
        "summary": summary_table_figure({m: summarise(res, m) for m in MAPS}, **kw),
        "histogram": histogram_figure(
            {m: histogram(normalise(res.values(m))) for m in ("odr", "ols", "e_ols")}, **kw),
        "variogram": variogram_figure(
            {m: semivariogram(res.ijk, res.values(m), 0.25) for m in ("hybrid", "odr", "ols",
                                                                       "e_ols")}, **kw),
        "profile": profile_figure(analyses),
        "point_scales": point_scales_figure(point_scales(results, 4321), point_xyz=xyz[4321],
                                            n_points=cloud.n),
        "face_scales": face_scales_figure(face_scales(results)),
        "colour_scale": colour_scale_figure(
            colormaps.resolve(e_ols), colormap=colormaps.default_colormap("e_ols"),
            title="e_OLS · grid 0.25 m · axis y · 153,385 points", no_value=49),
    }


@pytest.fixture(scope="module")
def rendered(chromium):
    """Every figure at 480 px and 1000 px wide (its own height), on one offline page."""
    from plotly.offline import get_plotlyjs

    figures = _figures()
    divs = []
    for width in (480, 1000):
        for name, fig in figures.items():
            w = 300 if name == "colour_scale" and width == 480 else width  # control column
            divs.append(f'<div id="{name}-{width}" style="width:{w}px">' + fig.to_html(
                full_html=False, include_plotlyjs=False, default_width=f"{w}px",
                default_height=f"{int(fig.layout.height)}px") + "</div>")
    ctx = chromium.new_context(viewport={"width": 1100, "height": 900}, offline=True)
    page = ctx.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.set_content(f"<html><head><script>{get_plotlyjs()}</script></head>"
                     f"<body style='margin:0'>{''.join(divs)}</body></html>")
    page.wait_for_function(f"document.querySelectorAll('.main-svg').length >= {len(divs)}")
    out = {name_w: measure(page, f"#{name_w} .js-plotly-plot")
           for name_w in (f"{n}-{w}" for w in (480, 1000) for n in figures)}
    ctx.close()
    assert not errors, errors
    return out


NAMES = ("summary", "histogram", "variogram", "profile", "point_scales", "face_scales",
         "colour_scale")


@pytest.mark.parametrize("width", [480, 1000])
@pytest.mark.parametrize("name", NAMES)
def test_figure_is_legible(rendered, name, width):
    m = rendered[f"{name}-{width}"]
    assert m["width"] >= (300 if name == "colour_scale" and width == 480 else width) - 1
    assert problems(m) == []


def test_table_one_values_are_whole(rendered):
    m = rendered["summary-480"]
    cells = [t for t in m["texts"] if t["kind"] == "cell"]
    texts = [t["text"] for t in cells]
    assert len(cells) == 8 + 8 * 4  # the header and 4 maps
    assert "e_OLS" in texts and "variance(mm²)" in texts and "hybrid" in texts
    for t in cells:
        assert t["cell"]["x0"] <= t["x0"] and t["x1"] <= t["cell"]["x1"] - 1, t["text"]


def test_problems_are_found_when_there_are_some(chromium):
    """The check itself can fail: a clipped table value, a title wider than the figure."""
    import plotly.graph_objects as go
    from plotly.offline import get_plotlyjs

    fig = go.Figure(go.Table(header={"values": ["minimum", "variance"]},  # 70 px columns
                             cells={"values": [["1.78245678e-05"], ["2"]]}))
    fig.update_layout(title="A title much too long for a figure of this narrow width",
                      width=150, height=200, margin={"l": 5, "r": 5, "t": 40, "b": 5})
    page = chromium.new_page()
    page.set_content(f"<html><head><script>{get_plotlyjs()}</script></head><body>"
                     + fig.to_html(full_html=False, include_plotlyjs=False) + "</body></html>")
    page.wait_for_selector(".main-svg")
    found = problems(measure(page))
    page.close()
    assert any("wider than its cell" in p for p in found)
    assert any("outside the figure" in p and "A title" in p for p in found)
