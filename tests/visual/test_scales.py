"""Figures of roughness across scales: the data, units, names and the log grid axis."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.grid.scales import face_scales, point_scales
from rough_viewer.visual.scales import face_scales_figure, point_scales_figure
from rough_viewer.vocabulary import MAP_COLOURS, MAP_LABELS, MODELS
from tests.helpers import face_cloud

SIZES = (0.125, 0.25, 0.5, 1.0)


@pytest.fixture(scope="module")
def results():
    cloud = face_cloud(30_000, seed=3)
    return cloud, [grid_roughness(cloud, g) for g in SIZES]


def test_point_figure_has_one_value_per_grid_and_model(results):
    cloud, res = results
    ps = point_scales(res, 123)
    fig = point_scales_figure(ps, point_xyz=cloud.xyz()[123], n_points=cloud.n)
    assert [t.name for t in fig.data] == [MAP_LABELS[m] for m in MODELS]
    for trace, name in zip(fig.data, MODELS, strict=True):
        np.testing.assert_array_equal(trace.x, SIZES)
        np.testing.assert_allclose(trace.y, ps.values(name) * 1e3)  # millimetres
        assert trace.line.color == MAP_COLOURS[name]
        np.testing.assert_array_equal(trace.customdata, ps.n_points)
    assert fig.layout.xaxis.type == "log"
    assert list(fig.layout.xaxis.tickvals) == list(SIZES)
    assert fig.layout.xaxis.title.text == "grid size (m)"
    assert "(mm)" in fig.layout.yaxis.title.text
    title = fig.layout.title.text
    assert "point #123" in title and "grids 0.125–1 m" in title and "dependent axis y" in title
    assert "30,000 points" in title


def test_point_figure_names_grids_without_a_value():
    pts = np.vstack([np.random.default_rng(0).uniform(0, 2, (500, 3)), [[9.0, 9.0, 9.0]]])
    res = [grid_roughness(pts, g, axis="z", min_points=4) for g in (0.5, 1.0)]
    fig = point_scales_figure(point_scales(res, 500))
    assert "no value at 0.5 m (1 points), 1 m (1 points)" in fig.layout.title.text.replace(
        "<br>", " ").replace("</sup>", "").replace("<sup>", "")
    assert np.isnan(np.asarray(fig.data[0].y, dtype=float)).all()


def test_face_figure_shows_mean_and_binary_share_against_grid_size(results):
    _, res = results
    fs = face_scales(res)
    fig = face_scales_figure(fs)
    assert len(fig.data) == 2 * len(MODELS)
    for k, name in enumerate(MODELS):
        mean, share = fig.data[k], fig.data[len(MODELS) + k]
        np.testing.assert_allclose(mean.y, fs.statistic(name, "mean") * 1e3)
        np.testing.assert_allclose(share.y, fs.rough_share[name] * 100)
        assert mean.name == share.name == MAP_LABELS[name]
        assert mean.showlegend and not share.showlegend
    assert fig.layout.xaxis.type == fig.layout.xaxis2.type == "log"
    assert fig.layout.xaxis2.title.text == "grid size (m)"
    assert fig.layout.yaxis.title.text == "mean θ (mm)"
    assert "0.05" in fig.layout.yaxis2.title.text and "(%)" in fig.layout.yaxis2.title.text
    assert "30,000 points" in fig.layout.title.text
