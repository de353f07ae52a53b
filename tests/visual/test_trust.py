"""Figures and colour layers of the per-cell scanner trust."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.grid.maps import face_raster
from rough_viewer.grid.planes import whole_cloud_plane
from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.io import PointCloud
from rough_viewer.scanner.positions import with_scanner
from rough_viewer.scanner.trust import FLAG_INCIDENCE, FLAG_NOISE, TrustSettings, cell_trust
from rough_viewer.visual import colormaps
from rough_viewer.visual.layers import trust_layer
from rough_viewer.visual.trust import TRUST_CLASSES, trust_codes, trust_map_figure
from rough_viewer.vocabulary import InputError
from tests.helpers import ray_grid, scan_plane


@pytest.fixture(scope="module")
def trust():
    scanner = np.zeros(3)
    centre = np.array([4.0, 10.0, 0.0])
    normal = np.array([0.3, -1.0, 0.0]) / np.hypot(0.3, 1.0)
    pts = scan_plane(scanner, centre, normal, ray_grid(scanner, centre, 0.2, step=2e-3),
                     extent=2.0, noise=0.002)
    cloud = with_scanner(PointCloud.from_xyz(pts), scanner)
    res = grid_roughness(cloud, 0.5, models=("odr",))
    return cloud, res, cell_trust(cloud, res, TrustSettings(trials=1))


def test_trust_codes_name_the_flag_that_failed(trust):
    _, _, t = trust
    codes = trust_codes(t)
    k = t.known
    np.testing.assert_array_equal(codes[k] == 0, t.flags[k] == 0)
    np.testing.assert_array_equal(codes[k] == 1, t.flags[k] == FLAG_INCIDENCE)
    np.testing.assert_array_equal(codes[k] == 4, t.flags[k] == FLAG_INCIDENCE | FLAG_NOISE)
    assert np.all(np.isnan(codes[~k]))


def test_trust_map_figure_draws_both_panels(trust):
    cloud, res, t = trust
    raster = face_raster(res.centre, whole_cloud_plane(cloud), 0.5)
    fig = trust_map_figure(t, raster, grid_size=0.5, axis=res.axis, n_points=cloud.n)
    classes, bias = fig.data
    shown = np.asarray(classes.z, dtype=float)
    assert set(np.unique(shown[np.isfinite(shown)])) <= set(range(len(TRUST_CLASSES)))
    assert np.isfinite(shown).sum() == len({tuple(p) for p in raster.pixel[t.known]})
    pct = 100 * t.bias_pred_m[t.known] / t.theta_m[t.known]
    assert bias.zmax == pytest.approx(np.percentile(np.abs(pct), 98)) and bias.zmin == -bias.zmax
    assert np.nanmean(np.asarray(bias.z, dtype=float)) == pytest.approx(np.mean(pct), rel=0.2)
    assert "grid 0.5 m" in fig.layout.title.text


def test_trust_layer_colours():
    layer = trust_layer("density_ratio", np.array([0.0, 1.0, 2.0, np.nan]))
    lut = colormaps.lut("coolwarm")
    np.testing.assert_array_equal(layer.colours[0], lut[0])
    np.testing.assert_array_equal(layer.colours[2], lut[-1])
    np.testing.assert_array_equal(layer.colours[3], colormaps.NEUTRAL_RGB)
    bias = trust_layer("bias_pred", np.array([-0.001, 0.0005, 0.002]))
    assert bias.colour_range.lo == -bias.colour_range.hi  # 0 in the middle
    with pytest.raises(InputError, match="unknown scanner layer"):
        trust_layer("theta", np.zeros(2))
