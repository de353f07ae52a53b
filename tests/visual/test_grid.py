"""Tests of rough_viewer.visual.grid: the figures carry the data and the captions."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from rough_viewer.grid.maps import face_maps, face_raster
from rough_viewer.grid.summary import Summary, histogram
from rough_viewer.grid.variogram import semivariogram
from rough_viewer.visual.grid import (
    CAPTION_CHARS,
    describe,
    face_map_figure,
    format_number,
    histogram_figure,
    summary_table_figure,
    title_height,
    variogram_figure,
    wrap_caption,
)
from rough_viewer.vocabulary import MAP_COLOURS

KW = {"grid_size": 0.125, "axis": "y", "n_points": 1_234_567}


def assert_caption(fig, *models):
    text = fig.layout.title.text
    assert "grid 0.125 m" in text and "dependent axis y" in text and "1,234,567 points" in text
    for m in models:
        assert m in text


def test_summary_table():
    s = Summary(cells=53508, mean_points=1222.0, min=0.0, max=0.1202, mean=0.0069,
                variance=4.32e-5, std=0.0066)
    h = Summary(cells=2194, mean_points=69.8, min=6.5e-18, max=5.23884, mean=0.01322,
                variance=0.017918, std=0.13386)
    fig = summary_table_figure({"odr": s, "hybrid": h}, **KW)
    header = fig.data[0].header.values
    cells = fig.data[0].cells.values
    assert list(cells[0]) == ["ODR", "hybrid"]
    # roughness in mm, variance in mm², every value short enough for its column
    assert "(mm)" in header[3] and "(mm²)" in header[6]
    assert [c[0] for c in cells[1:]] == ["53,508", "1,222", "0", "120", "6.90", "43.2", "6.60"]
    assert [c[1] for c in cells[1:]] == ["2,194", "69.8", "6.5e-15", "5,239", "13.2", "17,918",
                                         "134"]
    assert_caption(fig, "ODR", "hybrid")


@pytest.mark.parametrize(("value", "text"), [
    (0.0, "0"), (123456.7, "123,457"), (100.0, "100"), (99.96, "100.0"), (41.14, "41.1"),
    (4.317, "4.32"), (0.5, "0.5"), (0.0523, "0.0523"), (0.001, "0.001"), (6.5e-15, "6.5e-15"),
    (-2.5, "-2.50"), (float("nan"), "–"),
])
def test_format_number(value, text):
    assert format_number(value) == text
    assert len(text) <= 8


def test_captions_wrap_to_fit_a_narrow_panel():
    caption = describe(grid_size=0.125, axis="y", n_points=1_234_567,
                       models=("odr", "ols", "hybrid", "e_ols"))
    wrapped = wrap_caption(caption)
    assert wrapped.replace("<br>", " · ") == caption
    assert all(len(line) <= CAPTION_CHARS for line in wrapped.split("<br>"))
    fig = summary_table_figure({"odr": Summary(1, 1, 0, 0, 0, 0, 0)}, **KW)
    assert fig.layout.margin.t >= title_height(fig.layout.title.to_plotly_json())


def test_histogram_bars_and_first_bin_shares():
    ols = histogram(np.r_[np.zeros(86), np.linspace(0.06, 1, 14)], 0.05)
    odr = histogram(np.r_[np.zeros(63), np.linspace(0.06, 1, 37)], 0.05)
    fig = histogram_figure({"ols": ols, "odr": odr}, **KW)
    np.testing.assert_allclose(fig.data[0].y, ols.fractions * 100)
    np.testing.assert_allclose(fig.data[1].x, 0.5 * (odr.edges[:-1] + odr.edges[1:]))
    assert "OLS 86 %" in fig.layout.title.text and "ODR 63 %" in fig.layout.title.text
    assert_caption(fig, "OLS", "ODR")
    assert len(fig.data) == 2  # no threshold given: bars only


def test_histogram_shows_the_threshold_and_the_suggestions():
    odr = histogram(np.r_[np.zeros(63), np.linspace(0.06, 1, 37)], 0.05)
    fig = histogram_figure({"odr": odr, "ols": odr}, threshold=0.05,
                           suggestions={"odr": 0.31, "ols": None, "hybrid": 0.2}, **KW)
    lines = [t for t in fig.data if t.type == "scatter"]
    assert [(t.name, tuple(t.x)) for t in lines] == [("threshold 0.05", (0.05, 0.05)),
                                                     ("ODR suggested 0.31", (0.31, 0.31))]
    assert lines[0].line.dash == "dash" and lines[1].line.color == MAP_COLOURS["odr"]
    assert all(t.yaxis == "y2" for t in lines) and fig.layout.yaxis2.range == (0, 1)


def test_variogram_points_and_symbols():
    rng = np.random.default_rng(0)
    ijk = np.argwhere(np.ones((12, 12), bool))
    vgs = {n: semivariogram(ijk, rng.normal(size=len(ijk)), 0.125) for n in ("odr", "ols", "e_ols")}
    fig = variogram_figure(vgs, **KW)
    assert [t.name for t in fig.data] == ["ODR", "OLS", "e_OLS"]
    assert fig.data[0].marker.symbol == "circle-open"
    assert fig.data[1].marker.symbol == "triangle-up-open"
    np.testing.assert_allclose(fig.data[2].y, vgs["e_ols"].gamma_normalised)
    np.testing.assert_array_equal(fig.data[2].customdata, vgs["e_ols"].pairs)
    raw = variogram_figure(vgs, normalised=False, **KW)
    np.testing.assert_allclose(raw.data[0].y, vgs["odr"].gamma)
    assert_caption(fig, "ODR", "OLS", "e_OLS")


@pytest.mark.parametrize("kind", ["normalised", "binary"])
def test_face_map_panels(kind):
    plane = SimpleNamespace(centroid=np.zeros(3), normal=np.array([0.0, 1.0, 0.0]))
    centres = np.array([[0.1, 0, 0.1], [0.3, 0, 0.1], [0.1, 0, 0.3]])
    raster = face_raster(centres, plane, 0.25)
    maps = {"ols": face_maps(raster, np.array([0.0, 0.5, 1.0])),
            "odr": face_maps(raster, np.array([1.0, 0.02, 0.0]))}
    fig = face_map_figure(maps, kind=kind, **KW)
    assert len(fig.data) == 2
    want = maps["odr"].normalised.image if kind == "normalised" else maps["odr"].binary.image
    np.testing.assert_array_equal(np.asarray(fig.data[1].z, dtype=float), want)
    assert fig.layout.annotations[0].text.startswith("OLS")
    assert_caption(fig, "OLS", "ODR")
    with pytest.raises(ValueError):
        face_map_figure(maps, kind="other", **KW)


def test_large_face_images_are_shown_by_block_maxima():
    from rough_viewer.visual.grid import _display_image

    rng = np.random.default_rng(0)
    image = rng.random((1500, 1200))
    image[rng.random(image.shape) < 0.3] = np.nan
    u = 0.1 * (np.arange(1200) + 0.5)
    v = 0.1 * (np.arange(1500) + 0.5)
    small, u2, v2, k = _display_image(image, u, v, max_pixels=200_000)
    assert k == 4 and small.shape == (375, 300) and small.size <= 200_000
    np.testing.assert_allclose(small[7, 9], np.nanmax(image[28:32, 36:40]))
    np.testing.assert_allclose(u2[0], u[:4].mean())
    np.testing.assert_allclose(v2[1], v[4:8].mean())
    same, *_, k1 = _display_image(image[:100, :100], u[:100], v[:100], max_pixels=200_000)
    assert k1 == 1 and same is not None
