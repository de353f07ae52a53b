"""The colour scale of a resolved stretch: colours, ticks and notes."""

from __future__ import annotations

import numpy as np

from rough_viewer.visual import colormaps
from rough_viewer.visual.app import colour_scale_figure


def test_colour_scale_ticks_and_colours_follow_the_range():
    v = np.r_[np.geomspace(5e-4, 3e-2, 1000), np.nan]
    rng = colormaps.resolve(v)
    fig = colour_scale_figure(rng, colormap="magma", title="e_OLS · grid 0.25 m", no_value=7)
    ticks = colormaps.colour_ticks(rng)
    assert list(fig.layout.xaxis.ticktext) == list(ticks.labels)
    np.testing.assert_allclose(fig.layout.xaxis.tickvals, ticks.positions)
    lut = colormaps.lut("magma")
    assert fig.data[0].colorscale[0][1] == colormaps.rgb_css(lut[0])
    assert fig.data[0].colorscale[-1][1] == colormaps.rgb_css(lut[-1])
    # hover values: the bar's ends are the range's ends, in mm, log-spaced
    hover = np.asarray(fig.data[0].customdata[0], dtype=float)
    np.testing.assert_allclose(hover[[0, -1]], [rng.lo * 1e3, rng.hi * 1e3])
    np.testing.assert_allclose(hover[128] / hover[0], (rng.hi / rng.lo) ** (128 / 255))
    text = fig.layout.xaxis.title.text
    assert "θ (mm)" in text and "percentiles 2–98, log" in text
    assert "2 % below" in text and "2 % above" in text and "7 cells" in text


def test_colour_scale_of_an_absolute_range():
    rng = colormaps.resolve(np.array([0.001]), colormaps.Stretch.absolute_mm(0, 30))
    fig = colour_scale_figure(rng, colormap="viridis")
    assert list(fig.layout.xaxis.ticktext) == ["0", "10", "20", "30"]  # 5s would be 7 ticks
    np.testing.assert_allclose(fig.layout.xaxis.tickvals, [0, 1 / 3, 2 / 3, 1])
    assert "absolute 0–30 mm, linear" in fig.layout.xaxis.title.text


def test_panel_aspect_gives_the_laid_out_height():
    import plotly.graph_objects as go
    import pytest

    from rough_viewer.visual.app import PANEL_WIDTH, panel_aspect

    fig = go.Figure().update_layout(height=240)
    assert panel_aspect(fig) == 240 / PANEL_WIDTH == 0.5
    assert panel_aspect(fig, 300) == 0.8
    with pytest.raises(ValueError):
        panel_aspect(go.Figure())


def test_cells_of_roughness_zero_are_named_not_counted_below():
    """26 % of the cells fit their plane exactly (θ = 0): the caption names them as
    exact-fit cells, and 'below' counts only the other cells under the stretch."""
    v = np.r_[np.zeros(260), np.geomspace(5e-4, 3e-2, 740)]
    rng = colormaps.resolve(v)
    assert rng.below > 0.26  # the zeros and the 2 % under the 2nd percentile
    text = colour_scale_figure(rng, colormap="viridis", exact_fit=260,
                               outliers=3).layout.xaxis.title.text
    assert "260 exact-fit cells (θ = 0)" in text
    assert f"{rng.below * 100:.0f} % below" not in text  # the zeros are not "below"
    assert "cyan: 3 outlier cells (larger than the cell)" in text
