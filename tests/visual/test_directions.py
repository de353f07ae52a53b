"""Figures and drawing arrays of roughness by direction (issue 25)."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.directions.analysis import DirectionSettings, analyse_directions
from rough_viewer.directions.table import directions_table
from rough_viewer.io import PointCloud
from rough_viewer.synthetic.fbm import fbm_sheet
from rough_viewer.visual.directions import (
    directions_table_figure,
    profile_segments,
    rose_figure,
    segment_colours,
    window_map_figure,
)
from rough_viewer.vocabulary import InputError


@pytest.fixture(scope="module")
def result():
    z = fbm_sheet((80, 80), 0.3, 0.7, spacing=0.002, sigma=0.05, rng=7)
    yy, xx = np.mgrid[0:80, 0:80] * 0.002
    cloud = PointCloud.from_xyz(np.column_stack([xx.ravel(), yy.ravel(), z.ravel()]))
    return analyse_directions(cloud, DirectionSettings(step_deg=30.0, window_map=True,
                                                       window_radius=0.03, window_step=0.04))


def test_rose_closes_each_curve_and_draws_its_band(result):
    t = directions_table(result)
    fig = rose_figure(t, values=("h_mean", "delta_t"))
    band, h, dt = fig.data  # delta_t has no spread: no band
    assert h.name.startswith("Hurst") and dt.name.startswith("ΔT")
    np.testing.assert_array_equal(h.theta, np.append(t["azimuth_deg"], 0.0))
    np.testing.assert_allclose(h.r[:-1], t["h_mean"])
    np.testing.assert_allclose(band.r[:13], np.append(t["h_mean"] + t["h_std"],
                                                      t["h_mean"][0] + t["h_std"][0]))
    assert fig.layout.polar.angularaxis.direction == "counterclockwise"
    with pytest.raises(InputError, match="rose value"):
        rose_figure(t, values=("nonsense",))


def test_table_figure_and_window_map(result):
    t = directions_table(result, unit="mm")
    fig = directions_table_figure(t, unit="mm")
    cells = fig.data[0].cells.values
    assert len(cells[0]) == 12 and list(cells[0][:2]) == ["0", "30"]
    w = result.windows
    m = window_map_figure(w, azimuth_deg=90, unit="mm")
    np.testing.assert_allclose(m.data[0].marker.color, w.delta_t[:, 3])
    np.testing.assert_allclose(m.data[0].x, w.centre_uv[:, 0] * 1e3)
    top = window_map_figure(w)  # largest over the directions
    np.testing.assert_allclose(top.data[0].marker.color, np.nanmax(w.delta_t, axis=1))


def test_profile_segments_draw_each_line_once(result):
    segs, az = profile_segments(result.sets)
    distinct = result.sets[:6]  # 0..150: 180..330 are the same lines
    assert segs.shape == (sum(int(s.used.sum()) for s in distinct), 2, 3)
    assert segs.dtype == np.float32 and set(az) == {s.azimuth_deg for s in distinct}
    s0 = result.sets[0]
    np.testing.assert_allclose(segs[: int(s0.used.sum()), 0], s0.starts[s0.used], rtol=1e-6)
    # each segment runs along its set's direction in the face plane (it rises or falls
    # along the normal with the profile's trend line)
    n = result.frame.normal
    d = segs[:, 1] - segs[:, 0]
    d -= (d @ n)[:, None] * n
    d /= np.linalg.norm(d, axis=1)[:, None]
    for s in distinct:
        sel = az == s.azimuth_deg
        along = np.abs(d[sel] @ s.direction)
        assert np.all(along > 1 - 1e-6)
    rgb = segment_colours(az)
    assert rgb.shape == segs.shape and rgb.dtype == np.uint8
