"""Figures of scanner-bias results: data and captions."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.bias.measurement import effective_radius, fit_piecewise_linear, range_noise
from rough_viewer.bias.simulation import TargetLayout, smoothing_curve
from rough_viewer.visual.bias import (
    board_segments_figure,
    radius_range_figure,
    smoothing_curve_figure,
)
from tests.helpers import board_points, wire_points


def test_smoothing_curve_figure():
    layout = TargetLayout(width_m=0.2, height_m=0.2, centres=np.array([[0.1, 0.1]]),
                          asperity_radius_m=0.019)
    c = smoothing_curve([0.0, 0.004, 0.008], layout=layout, noise_sigma_m=0.0016,
                        spacing_m=0.002)
    fig = smoothing_curve_figure([c], mark=(0.2, -3.0))
    np.testing.assert_allclose(fig.data[0].x, c.er_ratio)
    np.testing.assert_allclose(fig.data[0].y, c.vs_noisy_pct)
    assert fig.data[0].name == "r = 19 mm" and fig.data[1].x == (0.2,)
    assert "noise 1.6 mm" in fig.layout.title.text
    np.testing.assert_allclose(smoothing_curve_figure([c], reference="true").data[0].y,
                               c.error_pct)


def test_board_segments_figure():
    xyz, _ = board_points(n=4_000, noise=0.0016, sag=0.004, seed=40)
    noise = range_noise(xyz)
    fig = board_segments_figure(noise)
    z = np.asarray(fig.data[0].z)
    assert z.shape == (4, 2)
    assert z[0, 0] == pytest.approx(noise.segments[0].offset * 1e3)
    assert np.asarray(board_segments_figure(noise, value="sigma").data[0].z)[3, 1] == \
        pytest.approx(noise.segments[7].sigma * 1e3)


def test_radius_range_figure():
    ranges = [3.0, 8.0, 15.0, 25.0]
    scans = [effective_radius(wire_points(er=0.001 + 1e-4 * r, wire_r=0.0, range_m=r, n=2_000,
                                    seed=i)) for i, r in enumerate(ranges)]
    fit = fit_piecewise_linear([s.range for s in scans], [s.effective_radius for s in scans])
    fig = radius_range_figure(scans, fit)
    np.testing.assert_allclose(fig.data[0].x, ranges, rtol=1e-3)
    assert len(fig.data) == 2 and "break" in fig.layout.title.text
